//! The operations: statement sequences, what each answer means, and the final checks.

use tracing::{debug, warn};

use super::Cs130Session;
use super::script::{Answer, Next, Op};
use crate::cs130::{Command, Cs130Error, ErrorCode, MonoState, Reply, ReplyError, Units};
use crate::machine::Cx;

/// A sequence of statements, then (for the operations that set anything) the status
/// check, and the state.
#[derive(Debug)]
pub(super) struct Sequence {
    commands: Vec<Command>,
    /// The statement being exchanged.
    k: usize,
    /// The wavelength asked for, checked against `WAVE?`.
    target: Option<f64>,
    /// Refused before any byte.
    refused: Option<Cs130Error>,
    /// The queries for the settings still unknown are added at the end.
    fill_unknown: bool,
}

impl Sequence {
    /// An empty sequence.
    fn empty() -> Self {
        Sequence {
            commands: Vec::new(),
            k: 0,
            target: None,
            refused: None,
            fill_unknown: false,
        }
    }

    pub(super) fn init(s: &Cs130Session) -> Self {
        let mut commands = vec![Command::Info, Command::Units(Units::Nm), Command::GratQuery];
        // A unit without a wheel answers `FILTER?` with 0 and flags an error (Model
        // 74000 command table): not asked, or the `STB?` below would fail the init.
        if s.config.filter_wheel {
            commands.push(Command::FilterQuery);
        }
        commands.extend([Command::ShutterQuery, Command::Wave, Command::Stb]);
        Sequence {
            commands,
            ..Self::empty()
        }
    }

    pub(super) fn read_state(s: &Cs130Session) -> Self {
        let mut commands = vec![Command::GratQuery];
        if s.config.filter_wheel {
            commands.push(Command::FilterQuery);
        }
        commands.extend([Command::ShutterQuery, Command::Wave]);
        Sequence {
            commands,
            ..Self::empty()
        }
    }

    pub(super) fn go(s: &Cs130Session, nm: f64) -> Self {
        let mut seq = Sequence {
            target: Some(nm),
            fill_unknown: true,
            ..Self::empty()
        };
        let c = &s.config;
        let grating = match c.grating_for(nm) {
            Ok(g) => g.index,
            Err(e) => {
                seq.refused = Some(e.into());
                return seq;
            }
        };
        // Never a `FILTER n` without a wheel: it would only flag an error (§15.9's
        // code 6). The config refuses `auto_order_filter` without `filter_wheel`.
        let filter = if c.auto_order_filter && c.filter_wheel {
            match c.order_filter_for(nm) {
                Ok(f) => Some(f),
                Err(e) => {
                    seq.refused = Some(e.into());
                    return seq;
                }
            }
        } else {
            None
        };
        if s.known.grating != Some(grating) {
            seq.commands.push(Command::Grat(grating));
        }
        if let Some(f) = filter
            && s.known.filter != Some(f)
        {
            seq.commands.push(Command::Filter(f));
        }
        // A drive's backlash leaves it short when it comes down onto a wavelength:
        // every wavelength is approached from below, so the slack is always taken up
        // the same way (an unknown position counts as above).
        let below = (nm - c.approach_nm).max(c.grating_for(nm).map_or(nm, |g| g.min_nm));
        if c.approach_nm > 0.0 && below < nm && s.known.wavelength_nm.is_none_or(|at| at > nm) {
            seq.commands.push(Command::GoWave(below));
        }
        seq.commands.push(Command::GoWave(nm));
        seq.commands.push(Command::Wai);
        seq.commands.push(Command::Wave);
        seq
    }

    pub(super) fn shutter(_: &Cs130Session, open: bool) -> Self {
        Sequence {
            commands: vec![Command::Shutter(open)],
            fill_unknown: true,
            ..Self::empty()
        }
    }

    fn next(&mut self, s: &Cs130Session) -> Next<Self> {
        if self.k == self.commands.len() && self.fill_unknown {
            self.fill_unknown = false;
            let k = &s.known;
            if k.grating.is_none() {
                self.commands.push(Command::GratQuery);
            }
            // Without a wheel the filter is known from the start (`Known::fresh`).
            if k.filter.is_none() && s.config.filter_wheel {
                self.commands.push(Command::FilterQuery);
            }
            if k.shutter_open.is_none() {
                self.commands.push(Command::ShutterQuery);
            }
            if k.wavelength_nm.is_none() {
                self.commands.push(Command::Wave);
            }
            self.commands.push(Command::Stb);
        }
        match self.commands.get(self.k) {
            Some(c) => Next::Exchange {
                command: c.clone(),
                then: Self::answered,
            },
            None => self.finish(s),
        }
    }

    fn answered(&mut self, s: &mut Cs130Session, _: &mut Cx, r: Answer) -> Next<Self> {
        let reply = match r {
            Ok(reply) => reply,
            Err(e) => {
                // Whatever this sequence was setting is unknown now.
                s.forget();
                return Next::Done(Err(e));
            }
        };
        let Some(command) = self.commands.get(self.k).cloned() else {
            return Next::Done(Err(unexpected(&Command::Stb, reply)));
        };
        let k = &mut s.known;
        match (&command, reply) {
            (Command::Wave, Some(Reply::Wavelength(v))) => k.wavelength_nm = Some(v),
            (Command::GratQuery, Some(Reply::Grating { number, .. })) => k.grating = Some(number),
            (Command::FilterQuery, Some(Reply::Filter(0))) if s.config.filter_wheel => {
                // "if there is no filter wheel connected, or if the wheel is out of
                // position, 0 is returned and an error is set in the status byte"
                // (Model 74000 command table). The config says there is a wheel: read
                // the error back, so the unit is left clean, and fail naming the field.
                warn!("cs130: a filter wheel is configured but FILTER? answered 0");
                s.forget();
                return Next::Exchange {
                    command: Command::Stb,
                    then: Self::no_wheel_status,
                };
            }
            (Command::FilterQuery, Some(Reply::Filter(n))) => k.filter = Some(n),
            (Command::ShutterQuery, Some(Reply::Shutter(o))) => k.shutter_open = Some(o),
            (Command::Info, Some(Reply::Info(text))) => {
                debug!(info = %text, "cs130: identified");
                s.info = Some(text);
            }
            (Command::Stb, Some(Reply::Status(sb))) => {
                if sb.error() {
                    warn!(status = %sb, "cs130: status byte reports an error");
                    return Next::Exchange {
                        command: Command::Error,
                        then: Self::errored,
                    };
                }
            }
            // Set at the echo; the status byte at the end confirms them all.
            (Command::Grat(n), None) => k.grating = Some(*n),
            (Command::Filter(n), None) => k.filter = Some(*n),
            (Command::Shutter(o), None) => k.shutter_open = Some(*o),
            (Command::GoWave(_), None) => k.wavelength_nm = None,
            (Command::Units(_) | Command::Wai | Command::Abort, None) => {}
            (c, other) => return Next::Done(Err(unexpected(c, other))),
        }
        self.k += 1;
        self.next(s)
    }

    /// The `STB?` after a `FILTER?` that answered 0 with a wheel configured: the
    /// error it flagged is read with `ERROR?`, for the message.
    fn no_wheel_status(&mut self, _: &mut Cs130Session, _: &mut Cx, r: Answer) -> Next<Self> {
        match r {
            Ok(Some(Reply::Status(sb))) if sb.error() => Next::Exchange {
                command: Command::Error,
                then: Self::no_wheel_error,
            },
            // The status byte is clean (the unit set no error) or could not be read:
            // the wheel is missing all the same, which is the error worth reporting.
            other => {
                if let Err(e) = other {
                    warn!(error = %e, "cs130: the status byte after FILTER? 0 was not read");
                }
                Next::Done(Err(Cs130Error::NoFilterWheel { code: None }))
            }
        }
    }

    /// The `ERROR?` after [`no_wheel_status`](Self::no_wheel_status).
    fn no_wheel_error(&mut self, _: &mut Cs130Session, _: &mut Cx, r: Answer) -> Next<Self> {
        let code: Option<ErrorCode> = match r {
            Ok(Some(Reply::Error(code))) => Some(code),
            other => {
                warn!(answer = ?other, "cs130: the error after FILTER? 0 was not read");
                None
            }
        };
        Next::Done(Err(Cs130Error::NoFilterWheel { code }))
    }

    fn errored(&mut self, s: &mut Cs130Session, _: &mut Cx, r: Answer) -> Next<Self> {
        // Which statement failed is unknown: forget every setting.
        s.forget();
        match r {
            Ok(Some(Reply::Error(code))) => Next::Done(Err(Cs130Error::Rejected(code))),
            Ok(other) => Next::Done(Err(unexpected(&Command::Error, other))),
            Err(e) => Next::Done(Err(e)),
        }
    }

    fn finish(&self, s: &Cs130Session) -> Next<Self> {
        let Some(state) = s.known.state() else {
            return Next::Done(Err(unexpected(&Command::Wave, None)));
        };
        if let Some(asked) = self.target {
            let tol = s.config.position_tolerance_nm;
            if (state.wavelength_nm - asked).abs() > tol {
                warn!(
                    asked,
                    read = state.wavelength_nm,
                    "cs130: wavelength not reached"
                );
                return Next::Done(Err(Cs130Error::NotReached {
                    asked_nm: asked,
                    read_nm: state.wavelength_nm,
                    tolerance_nm: tol,
                }));
            }
        }
        debug!(?state, "cs130: state");
        Next::Done(Ok(state))
    }
}

impl Op for Sequence {
    type Value = MonoState;

    fn start(&mut self, s: &mut Cs130Session, cx: &mut Cx) -> Next<Self> {
        if let Some(e) = self.refused.take() {
            warn!(error = %e, "cs130: refused before any byte");
            return Next::Done(Err(e));
        }
        if self.commands.first() == Some(&Command::Info) {
            cx.clear_input();
        }
        self.next(s)
    }
}

/// One statement and its answer.
#[derive(Debug)]
pub(super) struct Single {
    command: Command,
}

impl Single {
    pub(super) fn new(command: Command) -> Self {
        Single { command }
    }

    fn got(&mut self, s: &mut Cs130Session, _: &mut Cx, r: Answer) -> Next<Self> {
        if !self.command.is_query() || r.is_err() {
            s.forget();
        }
        Next::Done(r)
    }
}

impl Op for Single {
    type Value = Option<Reply>;

    fn start(&mut self, _: &mut Cs130Session, _: &mut Cx) -> Next<Self> {
        Next::Exchange {
            command: self.command.clone(),
            then: Self::got,
        }
    }
}

/// An answer of the wrong kind: cannot happen, since [`Reply::parse`] answers by
/// query; reported as a protocol error rather than a panic.
fn unexpected(command: &Command, reply: Option<Reply>) -> Cs130Error {
    let mut name = Vec::new();
    command.encode_body(&mut name);
    Cs130Error::Protocol {
        command: String::from_utf8_lossy(&name).into_owned(),
        reply: reply.map(|r| r.to_bytes()).unwrap_or_default(),
        source: ReplyError::BadValue,
    }
}
