//! The picoammeter's operations other than reading: set-up, and one command with its
//! answer.

use tracing::debug;

use super::script::{Answer, Next, Op};
use super::{K6485Session, unexpected};
use crate::k6485::{Command, Identity, K6485Config, K6485Error, Range, Reply};
use crate::machine::Cx;

/// Ends the operation on an error, or goes on with the reply.
macro_rules! ok_or_done {
    ($r:expr) => {
        match $r {
            Ok(reply) => reply,
            Err(e) => return Next::Done(Err(e)),
        }
    };
}

/// Set-up: the commands of [`K6485Session::start_setup`] in turn, with the settling
/// wait before the zero is acquired.
#[derive(Debug)]
pub(super) struct Setup {
    commands: Vec<Command>,
    /// The command being exchanged.
    k: usize,
    identity: Option<Identity>,
}

impl Setup {
    pub(super) fn new(c: &K6485Config) -> Self {
        let mut commands = vec![
            Command::Identify,
            Command::Reset,
            Command::Clear,
            Command::LineFrequency,
            Command::FormatElements,
            Command::TriggerCount(1),
            Command::SetNplc(c.nplc),
        ];
        if c.filter_on() {
            commands.push(Command::FilterType(c.filter_type));
            commands.push(Command::FilterCount(c.filter_count));
            commands.push(Command::Filter(true));
        } else {
            commands.push(Command::Filter(false));
        }
        commands.push(Command::AutoRange(false));
        commands.push(Command::ZeroCheck(true));
        if c.zero_correct {
            // The zero is an input offset current, the same on every range: measured
            // where it is resolved best, the most sensitive range the session may use
            // (the manual's example acquires on 2 nA, then autoranges).
            let zero_range = if c.autorange { Range::MOST } else { c.range };
            commands.push(Command::SetRange(zero_range));
            commands.push(Command::Initiate);
            commands.push(Command::ZeroCorrectAcquire);
            commands.push(Command::ZeroCorrect(true));
            if zero_range != c.range {
                commands.push(Command::SetRange(c.range));
            }
        } else {
            commands.push(Command::SetRange(c.range));
            commands.push(Command::ZeroCorrect(false));
        }
        commands.push(Command::ZeroCheck(false));
        commands.push(Command::NextError);
        Setup {
            commands,
            k: 0,
            identity: None,
        }
    }

    fn next(&mut self, s: &K6485Session, cx: &Cx) -> Next<Self> {
        match self.commands.get(self.k) {
            // The zero is measured only once the range has settled.
            Some(Command::Initiate) if cx.now < s.settled_at => Next::Pause {
                until: s.settled_at,
                then: Self::settled,
            },
            Some(c) => Next::exchange(c.clone(), Self::answered),
            None => match self.identity.take() {
                Some(id) => Next::Done(Ok(id)),
                None => Next::Done(Err(unexpected(&Command::Identify, None))),
            },
        }
    }

    fn settled(&mut self, _: &mut K6485Session, _: &mut Cx, (): ()) -> Next<Self> {
        Next::exchange(Command::Initiate, Self::answered)
    }

    fn answered(&mut self, s: &mut K6485Session, cx: &mut Cx, r: Answer) -> Next<Self> {
        let reply = ok_or_done!(r);
        let command = self.commands.get(self.k).cloned();
        match (command, reply) {
            (Some(Command::Identify), Some(Reply::Identity(id))) => {
                if id.picoammeter().is_none() {
                    return Next::Done(Err(K6485Error::WrongInstrument(id)));
                }
                debug!(identity = %id, "k6485: identified");
                self.identity = Some(id);
            }
            (Some(Command::LineFrequency), Some(Reply::LineFrequency(lf)))
                if lf.hz() != s.config.line_frequency_hz =>
            {
                return Next::Done(Err(K6485Error::LineFrequency {
                    configured: s.config.line_frequency_hz,
                    instrument: lf.hz(),
                }));
            }
            (Some(Command::LineFrequency), Some(Reply::LineFrequency(_))) => {}
            (Some(Command::NextError), Some(Reply::Error(e))) => {
                if !e.is_none() {
                    return Next::Done(Err(K6485Error::Rejected(e)));
                }
                s.identity.clone_from(&self.identity);
            }
            (Some(c), other) if c.is_query() => return Next::Done(Err(unexpected(&c, other))),
            _ => {}
        }
        self.k += 1;
        self.next(s, cx)
    }
}

impl Op for Setup {
    type Value = Identity;

    fn start(&mut self, s: &mut K6485Session, cx: &mut Cx) -> Next<Self> {
        cx.clear_input();
        self.next(s, cx)
    }
}

/// One command and its typed answer.
#[derive(Debug)]
pub(super) struct Single<T> {
    command: Command,
    answer: fn(&Command, Option<Reply>) -> Result<T, K6485Error>,
}

impl<T> Single<T> {
    pub(super) fn new(
        command: Command,
        answer: fn(&Command, Option<Reply>) -> Result<T, K6485Error>,
    ) -> Self {
        Single { command, answer }
    }

    fn got(&mut self, _: &mut K6485Session, _: &mut Cx, r: Answer) -> Next<Self> {
        Next::Done(r.and_then(|reply| (self.answer)(&self.command, reply)))
    }
}

impl<T> Op for Single<T> {
    type Value = T;

    fn start(&mut self, _: &mut K6485Session, _: &mut Cx) -> Next<Self> {
        Next::exchange(self.command.clone(), Self::got)
    }
}
