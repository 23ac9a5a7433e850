//! The lock-in's operations other than reading: set-up, any command (with `AGAN`'s
//! settings read back), one command with its typed answer.

use tracing::debug;

use super::script::{Next, Op};
use super::{Sr830Session, event_status, unexpected};
use crate::machine::Cx;
use crate::sr830::{Command, Identity, Interface, Reply, Sr830Error};

/// Set-up: input cleared, `OUTX 0`, `*IDN?`, `*CLS`, `SENS`, `OFLT`, `OFSL`, `*ESR?`.
#[derive(Debug, Default)]
pub(super) struct Setup {
    identity: Option<Identity>,
}

impl Op for Setup {
    type Value = Identity;

    fn start(&mut self, _: &mut Sr830Session, cx: &mut Cx) -> Next<Self> {
        cx.clear_input();
        Next::exchange(Command::SetInterface(Interface::Rs232), Self::outx_sent)
    }
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
    fn outx_sent(
        &mut self,
        _: &mut Sr830Session,
        _: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        ok_or_done!(r);
        Next::exchange(Command::Identify, Self::identified)
    }

    fn identified(
        &mut self,
        _: &mut Sr830Session,
        _: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        let id = match ok_or_done!(r) {
            Some(Reply::Identity(id)) => id,
            other => return Next::Done(Err(unexpected(&Command::Identify, other))),
        };
        if !id.is_sr830() {
            return Next::Done(Err(Sr830Error::WrongInstrument(id)));
        }
        debug!(identity = %id, "sr830: identified");
        self.identity = Some(id);
        Next::exchange(Command::Clear, Self::cleared)
    }

    fn cleared(
        &mut self,
        s: &mut Sr830Session,
        _: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        ok_or_done!(r);
        let c = Command::SetSensitivity(s.config.sensitivity);
        Next::exchange(c, Self::sensitivity_set)
    }

    fn sensitivity_set(
        &mut self,
        s: &mut Sr830Session,
        _: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        ok_or_done!(r);
        let c = Command::SetTimeConstant(s.config.time_constant);
        Next::exchange(c, Self::time_constant_set)
    }

    fn time_constant_set(
        &mut self,
        s: &mut Sr830Session,
        _: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        ok_or_done!(r);
        Next::exchange(Command::SetSlope(s.config.slope), Self::slope_set)
    }

    fn slope_set(
        &mut self,
        _: &mut Sr830Session,
        _: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        ok_or_done!(r);
        Next::exchange(Command::EventStatus(None), Self::checked)
    }

    fn checked(
        &mut self,
        s: &mut Sr830Session,
        _: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        let esr = ok_or_done!(r.and_then(|reply| event_status(&Command::EventStatus(None), reply)));
        if esr.has_command_error() {
            return Next::Done(Err(Sr830Error::Rejected(esr)));
        }
        match self.identity.take() {
            Some(id) => {
                s.identity = Some(id.clone());
                Next::Done(Ok(id))
            }
            None => Next::Done(Err(unexpected(&Command::Identify, None))),
        }
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
