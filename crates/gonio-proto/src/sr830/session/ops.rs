//! The lock-in's operations other than reading: set-up, any command (with `AGAN`'s
//! settings read back), one command with its typed answer.

use tracing::debug;

use super::script::{Next, Op};
use super::{Sr830Session, event_status, unexpected};
use crate::machine::Cx;
use crate::sr830::{Command, EventStatus, Identity, Interface, Reply, Sr830Error};

/// Set-up: input cleared, then each of [`Setup::command`] in turn; `*IDN?` must name an
/// SR830 and `*ESR?` must show no refused command (EXE, CMD) and no lost one: an
/// overflowed input or output buffer clears both (manual p. 5-2), so INP or QRY means
/// a command of the set-up may never have run.
#[derive(Debug, Default)]
pub(super) struct Setup {
    /// The command being exchanged.
    k: usize,
    identity: Option<Identity>,
}

/// Ends the operation on an error, or goes on with the reply.
macro_rules! ok_or_done {
    ($r:expr) => {
        match $r {
            Ok(reply) => reply,
            Err(e) => return Next::Done(Err(e)),
        }
    };
}

impl Setup {
    /// The set-up's `k`-th command: `OUTX 0` (replies go to GPIB until then), `*IDN?`,
    /// `*CLS`, the configured `SENS`, `OFLT`, `OFSL`, and `*ESR?`, whose answer also
    /// proves every earlier command has run.
    fn command(s: &Sr830Session, k: usize) -> Option<Command> {
        Some(match k {
            0 => Command::SetInterface(Interface::Rs232),
            1 => Command::Identify,
            2 => Command::Clear,
            3 => Command::SetSensitivity(s.config.sensitivity),
            4 => Command::SetTimeConstant(s.config.time_constant),
            5 => Command::SetSlope(s.config.slope),
            6 => Command::EventStatus(None),
            _ => return None,
        })
    }

    fn next(&mut self, s: &Sr830Session) -> Next<Self> {
        match Self::command(s, self.k) {
            Some(c) => Next::exchange(c, Self::answered),
            None => match self.identity.take() {
                Some(id) => Next::Done(Ok(id)),
                None => Next::Done(Err(unexpected(&Command::Identify, None))),
            },
        }
    }

    fn answered(
        &mut self,
        s: &mut Sr830Session,
        _: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        let reply = ok_or_done!(r);
        match Self::command(s, self.k) {
            Some(Command::Identify) => {
                let id = match reply {
                    Some(Reply::Identity(id)) => id,
                    other => return Next::Done(Err(unexpected(&Command::Identify, other))),
                };
                if !id.is_sr830() {
                    return Next::Done(Err(Sr830Error::WrongInstrument(id)));
                }
                debug!(identity = %id, "sr830: identified");
                self.identity = Some(id);
            }
            Some(c @ Command::EventStatus(_)) => {
                let esr = ok_or_done!(event_status(&c, reply));
                let lost = EventStatus::INP | EventStatus::QRY;
                if esr.has_command_error() || esr.0 & lost != 0 {
                    return Next::Done(Err(Sr830Error::Rejected(esr)));
                }
                s.identity.clone_from(&self.identity);
            }
            _ => {}
        }
        self.k += 1;
        self.next(s)
    }
}

impl Op for Setup {
    type Value = Identity;

    fn start(&mut self, s: &mut Sr830Session, cx: &mut Cx) -> Next<Self> {
        cx.clear_input();
        self.next(s)
    }
}

/// The settings queries `refresh_settings` reads back, in order.
const SETTINGS: [Command; 3] = [
    Command::QuerySensitivity,
    Command::QueryTimeConstant,
    Command::QuerySlope,
];

/// Any command (or none, for a settings read-back alone); after `AGAN`, or alone, the
/// settings are read back (`SENS?`, `OFLT?`, `OFSL?`) and the settling wait restarts.
#[derive(Debug)]
pub(super) struct Execute<T> {
    command: Option<Command>,
    reply: Option<Reply>,
    /// Position in [`SETTINGS`].
    k: usize,
    finish: fn(Option<Reply>) -> T,
}

impl<T> Execute<T> {
    pub(super) fn new(command: Option<Command>, finish: fn(Option<Reply>) -> T) -> Self {
        Execute {
            command,
            reply: None,
            k: 0,
            finish,
        }
    }

    fn executed(
        &mut self,
        _: &mut Sr830Session,
        _: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        self.reply = ok_or_done!(r);
        if self.command == Some(Command::AutoGain) {
            debug!("sr830: auto gain done; reading the settings back");
            self.read_back()
        } else {
            Next::Done(Ok((self.finish)(self.reply.take())))
        }
    }

    fn read_back(&mut self) -> Next<Self> {
        match SETTINGS.get(self.k) {
            Some(c) => Next::exchange(c.clone(), Self::read),
            None => Next::Done(Ok((self.finish)(self.reply.take()))),
        }
    }

    fn read(
        &mut self,
        s: &mut Sr830Session,
        cx: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        match ok_or_done!(r) {
            Some(Reply::Sensitivity(x)) => s.sensitivity = x,
            Some(Reply::TimeConstant(t)) => s.time_constant = t,
            Some(Reply::Slope(x)) => s.slope = x,
            other => return Next::Done(Err(unexpected(&SETTINGS[self.k], other))),
        }
        self.k += 1;
        if self.k == SETTINGS.len() {
            s.mark_unsettled(cx.now);
        }
        self.read_back()
    }
}

impl<T> Op for Execute<T> {
    type Value = T;

    fn start(&mut self, _: &mut Sr830Session, _: &mut Cx) -> Next<Self> {
        match &self.command {
            Some(c) => Next::exchange(c.clone(), Self::executed),
            None => self.read_back(),
        }
    }
}

/// One command and its typed answer.
#[derive(Debug)]
pub(super) struct Single<T> {
    command: Command,
    answer: fn(&Command, Option<Reply>) -> Result<T, Sr830Error>,
}

impl<T> Single<T> {
    pub(super) fn new(
        command: Command,
        answer: fn(&Command, Option<Reply>) -> Result<T, Sr830Error>,
    ) -> Self {
        Single { command, answer }
    }

    fn got(
        &mut self,
        _: &mut Sr830Session,
        _: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        Next::Done(r.and_then(|reply| (self.answer)(&self.command, reply)))
    }
}

impl<T> Op for Single<T> {
    type Value = T;

    fn start(&mut self, _: &mut Sr830Session, _: &mut Cx) -> Next<Self> {
        Next::exchange(self.command.clone(), Self::got)
    }
}
