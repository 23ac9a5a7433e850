//! The controller's configuration: read with `ZT`, changed in CONFIGURATION (`PW1`,
//! the sets, `PW0`), as the manual's PW and ZT commands describe.

use std::time::Duration;

use tracing::{debug, warn};

use super::ops::Named;
use super::script::{Aborted, Next, Op};
use super::{Smc100Session, line_text};
use crate::TransportError;
use crate::machine::Cx;
use crate::smc100::{AxisError, Command, ErrorCode, Param, ReplyBody, Smc100Parameters};

/// Pause between status polls while the controller saves its configuration.
const SAVE_POLL: Duration = Duration::from_millis(500);
/// Longest a save may keep the controller silent: the manual's "up to 10 s" for `PW0`,
/// and a margin.
const SAVE_LIMIT: Duration = Duration::from_secs(15);

/// `ZT` to one axis, read whole.
#[derive(Debug)]
pub(super) struct ReadConfig(Named);

impl ReadConfig {
    pub(super) fn new(name: &str) -> Self {
        ReadConfig(Named::new(name))
    }

    fn read(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<Smc100Parameters, AxisError>,
    ) -> Next<Self> {
        let i = self.0.axis;
        if let Ok(p) = &r {
            debug!(axis = %s.axes[i].name, stage = %p.stage, "smc100: configuration read");
        }
        Next::Done(r.map_err(|e| s.at(i, e)))
    }
}

impl Op for ReadConfig {
    type Value = Smc100Parameters;

    fn start(&mut self, s: &mut Smc100Session, _: &mut Cx) -> Next<Self> {
        match self.0.resolve(s) {
            Ok(axis) => Next::Dump {
                axis,
                then: Self::read,
            },
            Err(e) => Next::Done(Err(e)),
        }
    }
}

/// The configure operation. Phases: every change checked before any byte; the state
/// (`TS`): NOT REFERENCED → `PW1` (checked with `TE`), CONFIGURATION → straight on,
/// anything else refused; each set, checked with `TE`; `PW0`, sent without `TE` since
/// the controller is silent while it saves; `TS` every 500 ms, each asked once (the
/// silence is expected, not a retry), until NOT REFERENCED;
/// `TE` for the save's own error (`U`, EEPROM).
#[derive(Debug)]
pub(super) struct Configure {
    axis: Named,
    changes: Vec<(Param, f64)>,
    /// Position in `changes`.
    k: usize,
    /// A refused set: the controller still leaves CONFIGURATION, then this is the end.
    failed: Option<AxisError>,
    /// When `PW0` went out.
    start: Duration,
}

impl Configure {
    pub(super) fn new(name: &str, changes: &[(Param, f64)]) -> Self {
        Configure {
            axis: Named::new(name),
            changes: changes.to_vec(),
            k: 0,
            failed: None,
            start: Duration::ZERO,
        }
    }
}

impl Op for Configure {
    type Value = ();

    fn start(&mut self, s: &mut Smc100Session, _: &mut Cx) -> Next<Self> {
        let i = match self.axis.resolve(s) {
            Ok(i) => i,
            Err(e) => return Next::Done(Err(e)),
        };
        for &(p, value) in &self.changes {
            let reason = if !p.is_configuration() {
                "not a configuration parameter"
            } else if !p.accepts(value) {
                "outside the manual's range"
            } else {
                continue;
            };
            let e = AxisError::InvalidSetting {
                code: p.code(),
                value,
                reason,
            };
            return Next::Done(Err(s.at(i, e)));
        }
        Next::query(i, Command::TellStatus, Self::checked)
    }
}

impl Configure {
    fn checked(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let i = self.axis.axis;
        let state = match s.status(i, r) {
            Ok(st) => st.state,
            Err(e) => return Next::Done(Err(s.at(i, e))),
        };
        if state.is_configuration() {
            debug!(axis = %s.axes[i].name, "smc100: already in CONFIGURATION");
            return self.next_set(s);
        }
        if !state.is_not_referenced() {
            // The manual allows PW1 only from NOT REFERENCED; getting there from READY
            // or DISABLE takes `RS`, which loses the reference: the caller's decision.
            let operation = "configuration (PW1 needs NOT REFERENCED: reset the controller first)";
            return Next::Done(Err(s.at(i, AxisError::WrongState { state, operation })));
        }
        Next::command(i, Command::ConfigurationMode(true), Self::entered)
    }

    fn entered(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<(), AxisError>,
    ) -> Next<Self> {
        let i = self.axis.axis;
        match r {
            Ok(()) => {
                debug!(axis = %s.axes[i].name, "smc100: in CONFIGURATION (PW1)");
                self.next_set(s)
            }
            // `PW1` must not be re-sent blindly; the state tells whether it ran.
            Err(AxisError::Ambiguous { .. }) => {
                s.retried += 1;
                warn!(axis = %s.axes[i].name, "smc100: PW1 unacknowledged; reading the state");
                Next::query(i, Command::TellStatus, Self::entered_state)
            }
            Err(e) => Next::Done(Err(s.at(i, e))),
        }
    }

    fn entered_state(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let i = self.axis.axis;
        match s.status(i, r) {
            Ok(st) if st.state.is_configuration() => self.next_set(s),
            Ok(_) => {
                let command = line_text(&s.frame(i, Command::ConfigurationMode(true)).to_bytes());
                Next::Done(Err(s.at(i, AxisError::Ambiguous { command })))
            }
            Err(e) => Next::Done(Err(s.at(i, e))),
        }
    }

    fn next_set(&mut self, s: &Smc100Session) -> Next<Self> {
        let i = self.axis.axis;
        match self.changes.get(self.k) {
            Some(&(p, v)) => Next::command(i, Command::set(p, v), Self::set_done),
            None => self.leave(s),
        }
    }

    fn set_done(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<(), AxisError>,
    ) -> Next<Self> {
        match r {
            Ok(()) => {
                self.k += 1;
                self.next_set(s)
            }
            Err(e) => {
                // Only `PW0` leaves CONFIGURATION (`RS` is refused there): leave, so the
                // controller is usable, then report. The sets before this one are saved.
                warn!(error = %e, "smc100: configuration refused; leaving CONFIGURATION");
                self.failed = Some(e);
                self.leave(s)
            }
        }
    }

    fn leave(&mut self, s: &Smc100Session) -> Next<Self> {
        let i = self.axis.axis;
        Next::Send {
            frame: s.frame(i, Command::ConfigurationMode(false)),
            then: Self::saving,
        }
    }

    fn saving(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        r: Result<(), AxisError>,
    ) -> Next<Self> {
        let i = self.axis.axis;
        if let Err(e) = r {
            return Next::Done(Err(s.at(i, e)));
        }
        debug!(axis = %s.axes[i].name, "smc100: PW0 sent; the controller saves");
        self.start = cx.now;
        Self::save_pause(cx)
    }

    fn save_pause(cx: &Cx) -> Next<Self> {
        Next::Pause {
            until: cx.now.saturating_add(SAVE_POLL),
            abortable: false,
            then: Self::save_poll,
        }
    }

    fn save_poll(
        &mut self,
        _: &mut Smc100Session,
        _: &mut Cx,
        _: Result<(), Aborted>,
    ) -> Next<Self> {
        Next::Probe {
            axis: self.axis.axis,
            command: Command::TellStatus,
            then: Self::save_status,
        }
    }

    fn save_status(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let i = self.axis.axis;
        match s.status(i, r) {
            Ok(st) if st.state.is_not_referenced() => {
                debug!(axis = %s.axes[i].name, state = %st.state, "smc100: configuration saved");
                return Next::query(i, Command::TellError, Self::save_checked);
            }
            // Still saving: silent, or not yet out of CONFIGURATION.
            Ok(st) if st.state.is_configuration() => {}
            Err(AxisError::Transport(TransportError::Timeout(_))) => {}
            Ok(st) => {
                let (state, operation) = (st.state, "saving the configuration");
                return Next::Done(Err(s.at(i, AxisError::WrongState { state, operation })));
            }
            Err(e) => return Next::Done(Err(s.at(i, e))),
        }
        if cx.now.saturating_sub(self.start) > SAVE_LIMIT {
            let e = AxisError::Transport(TransportError::Timeout(SAVE_LIMIT));
            return Next::Done(Err(s.at(i, e)));
        }
        Self::save_pause(cx)
    }

    fn save_checked(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let i = self.axis.axis;
        if let Some(e) = self.failed.take() {
            return Next::Done(Err(s.at(i, e)));
        }
        let e = match r {
            Ok(ReplyBody::Error(ErrorCode::None)) => return Next::Done(Ok(())),
            Ok(ReplyBody::Error(code)) => AxisError::Controller {
                command: line_text(&s.frame(i, Command::ConfigurationMode(false)).to_bytes()),
                code,
            },
            Ok(other) => AxisError::Protocol {
                sent: format!("{}TE", s.axes[i].address),
                reply: format!("{other:?}"),
                reason: "not an error letter".into(),
            },
            Err(e) => e,
        };
        Next::Done(Err(s.at(i, e)))
    }
}
