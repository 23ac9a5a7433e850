//! Homing: each axis brought to READY with a reference, home searches running
//! concurrently; optionally after a controller reset (`reset_and_home`).

use std::mem;
use std::time::Duration;

use tracing::{debug, warn};

use super::script::{Aborted, Next, Op, Overdue};
use super::{Smc100Session, line_text};
use crate::TransportError;
use crate::machine::{Cx, secs};
use crate::smc100::{AxisError, Command, MotionError, ReplyBody};

/// Pause between status polls while a reset controller boots.
const BOOT_POLL: Duration = Duration::from_millis(500);
/// Longest a reset controller may stay silent or busy.
const BOOT_LIMIT: Duration = Duration::from_secs(10);

/// The home operation. Phases: (reset: `RS`, then `TS` every 500 ms until NOT
/// REFERENCED;) each axis' state checked and its home search started (`OR`) or its
/// motor enabled (`MM1`); polling until every search is READY; the configured
/// velocity and acceleration applied.
#[derive(Debug)]
pub(super) struct Home {
    names: Vec<String>,
    reset: bool,
    /// The axes, in request order.
    idx: Vec<usize>,
    /// Position in `idx` while checking states and applying settings.
    k: usize,
    /// `OR` sends whose acknowledgement was lost, for `idx[k]`.
    tries: usize,
    /// Axes whose home search is under way, and those still searching after this
    /// round.
    searching: Vec<usize>,
    still: Vec<usize>,
    /// Position in `searching` during a poll round.
    j: usize,
    /// When polling (or the reset controller's boot) began.
    start: Duration,
}

impl Home {
    pub(super) fn new(names: &[&str], reset: bool) -> Self {
        Home {
            names: names.iter().map(|n| n.to_string()).collect(),
            reset,
            idx: Vec::new(),
            k: 0,
            tries: 0,
            searching: Vec::new(),
            still: Vec::new(),
            j: 0,
            start: Duration::ZERO,
        }
    }
}

impl Op for Home {
    type Value = ();

    fn start(&mut self, s: &mut Smc100Session, cx: &mut Cx) -> Next<Self> {
        let idx: Result<Vec<usize>, MotionError> = self.names.iter().map(|n| s.index(n)).collect();
        self.idx = match idx {
            Ok(idx) => idx,
            Err(e) => return Next::Done(Err(e)),
        };
        match (self.reset, self.idx.first()) {
            (true, Some(&i)) => Next::Send {
                frame: s.frame(i, Command::Reset),
                then: Self::reset_sent,
            },
            _ => self.check_next(s, cx),
        }
    }
}

impl Home {
    // --- reset_and_home: RS, then wait for the boot ---

    fn reset_sent(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        r: Result<(), AxisError>,
    ) -> Next<Self> {
        let i = self.idx[0];
        if let Err(e) = r {
            return Next::Done(Err(s.at(i, e)));
        }
        debug!(axis = %s.axes[i].name, "smc100: controller reset; waiting for it to boot");
        self.start = cx.now;
        Self::boot_pause(cx)
    }

    fn boot_pause(cx: &Cx) -> Next<Self> {
        Next::Pause {
            until: cx.now.saturating_add(BOOT_POLL),
            abortable: false,
            then: Self::boot_poll,
        }
    }

    fn boot_poll(
        &mut self,
        _: &mut Smc100Session,
        _: &mut Cx,
        _: Result<(), Aborted>,
    ) -> Next<Self> {
        Next::query(self.idx[0], Command::TellStatus, Self::boot_status)
    }

    fn boot_status(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let i = self.idx[0];
        match s.status(i, r) {
            Ok(st) if st.state.is_not_referenced() => {
                debug!(axis = %s.axes[i].name, state = %st.state, "smc100: controller booted");
                return self.check_next(s, cx);
            }
            // Still booting: silent, or not yet NOT REFERENCED.
            Ok(_) | Err(AxisError::Transport(TransportError::Timeout(_))) => {}
            Err(e) => return Next::Done(Err(s.at(i, e))),
        }
        if cx.now.saturating_sub(self.start) > BOOT_LIMIT {
            let e = AxisError::Transport(TransportError::Timeout(BOOT_LIMIT));
            return Next::Done(Err(s.at(i, e)));
        }
        Self::boot_pause(cx)
    }

    // --- each axis' state: start its search, enable it, or refuse ---

    fn check_next(&mut self, s: &mut Smc100Session, cx: &mut Cx) -> Next<Self> {
        match self.idx.get(self.k) {
            Some(&i) => Next::query(i, Command::TellStatus, Self::checked),
            None => {
                self.start = cx.now;
                self.poll_round(s, cx)
            }
        }
    }

    fn next_axis(&mut self, s: &mut Smc100Session, cx: &mut Cx) -> Next<Self> {
        self.k += 1;
        self.check_next(s, cx)
    }

    fn checked(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let i = self.idx[self.k];
        let state = match s.status(i, r) {
            Ok(st) => st.state,
            Err(e) => return Next::fail(i, e),
        };
        if state.is_not_referenced() {
            self.tries = 0;
            return Next::command(i, Command::Home, Self::or_sent);
        } else if state.is_homing() {
            self.searching.push(i);
        } else if state.is_disabled() {
            return Next::command(i, Command::Enable(true), Self::enabled);
        } else if state.is_configuration() || state.is_jogging() {
            let operation = "homing";
            return Next::fail(i, AxisError::WrongState { state, operation });
        }
        self.next_axis(s, cx)
    }

    fn enabled(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        r: Result<(), AxisError>,
    ) -> Next<Self> {
        let i = self.idx[self.k];
        if let Err(e) = r {
            return Next::fail(i, e);
        }
        debug!(axis = %s.axes[i].name, "smc100: motor enabled (MM1)");
        self.next_axis(s, cx)
    }

    fn searching(&mut self, s: &mut Smc100Session, cx: &mut Cx) -> Next<Self> {
        let i = self.idx[self.k];
        debug!(axis = %s.axes[i].name, "smc100: home search started");
        self.searching.push(i);
        self.next_axis(s, cx)
    }

    /// `OR` must not be re-sent blindly, but a lost acknowledgement is not a lost
    /// command: the state tells which. HOMING (or READY) means it ran; still NOT
    /// REFERENCED means it never arrived, and it is sent again (up to `retries` times).
    fn or_sent(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        r: Result<(), AxisError>,
    ) -> Next<Self> {
        let i = self.idx[self.k];
        match r {
            Ok(()) => self.searching(s, cx),
            Err(AxisError::Ambiguous { .. }) => {
                s.retried += 1;
                warn!(axis = %s.axes[i].name, "smc100: OR unacknowledged; reading the state");
                Next::query(i, Command::TellStatus, Self::or_state)
            }
            Err(e) => Next::fail(i, e),
        }
    }

    fn or_state(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let i = self.idx[self.k];
        let st = match s.status(i, r) {
            Ok(st) => st,
            Err(e) => return Next::fail(i, e),
        };
        if st.state.is_homing() || st.state.is_ready() {
            return self.searching(s, cx);
        }
        if !st.state.is_not_referenced() {
            let (state, errors) = (st.state, st.errors.0);
            return Next::fail(i, AxisError::HomingFailed { state, errors });
        }
        self.tries += 1;
        if self.tries <= s.policy.retries {
            return Next::command(i, Command::Home, Self::or_sent);
        }
        let command = line_text(&s.frame(i, Command::Home).to_bytes());
        Next::fail(i, AxisError::Ambiguous { command })
    }

    // --- polling until every search is READY ---

    fn poll_round(&mut self, s: &Smc100Session, cx: &Cx) -> Next<Self> {
        if self.searching.is_empty() {
            self.k = 0;
            return self.apply_settings(s);
        }
        Next::Pause {
            until: cx.now.saturating_add(s.policy.poll_interval),
            abortable: true,
            then: Self::polled,
        }
    }

    fn polled(&mut self, s: &mut Smc100Session, cx: &mut Cx, r: Result<(), Aborted>) -> Next<Self> {
        if r.is_err() {
            warn!("smc100: home search aborted");
            return Next::fail(self.searching[0], AxisError::Aborted);
        }
        self.j = 0;
        self.still.clear();
        self.poll_next(s, cx)
    }

    fn poll_next(&mut self, s: &Smc100Session, cx: &Cx) -> Next<Self> {
        match self.searching.get(self.j) {
            Some(&i) => Next::query(i, Command::TellStatus, Self::poll_status),
            None => {
                self.searching = mem::take(&mut self.still);
                self.poll_round(s, cx)
            }
        }
    }

    fn poll_status(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let i = self.searching[self.j];
        let st = match s.status(i, r) {
            Ok(st) => st,
            Err(e) => return Next::fail(i, e),
        };
        if st.state.is_ready() {
            debug!(axis = %s.axes[i].name, state = %st.state, "smc100: stage READY");
        } else if st.state.is_homing() {
            let limit = secs(s.axes[i].home_timeout_s);
            if cx.now.saturating_sub(self.start) > limit {
                return Next::Overdue(Overdue {
                    axis: i,
                    operation: "home",
                    target: 0.0,
                    waited: limit,
                });
            }
            self.still.push(i);
        } else {
            let (state, errors) = (st.state, st.errors.0);
            return Next::fail(i, AxisError::HomingFailed { state, errors });
        }
        self.j += 1;
        self.poll_next(s, cx)
    }

    // --- the configured velocity and acceleration ---

    fn apply_settings(&mut self, s: &Smc100Session) -> Next<Self> {
        let Some(&i) = self.idx.get(self.k) else {
            return Next::Done(Ok(()));
        };
        match s.axes[i].velocity {
            Some(v) => Next::command(i, Command::SetVelocity(v), Self::velocity_set),
            None => self.apply_acceleration(s),
        }
    }

    fn velocity_set(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<(), AxisError>,
    ) -> Next<Self> {
        match r {
            Ok(()) => self.apply_acceleration(s),
            Err(e) => Next::fail(self.idx[self.k], e),
        }
    }

    fn apply_acceleration(&mut self, s: &Smc100Session) -> Next<Self> {
        let i = self.idx[self.k];
        match s.axes[i].acceleration {
            Some(a) => Next::command(i, Command::SetAcceleration(a), Self::acceleration_set),
            None => {
                self.k += 1;
                self.apply_settings(s)
            }
        }
    }

    fn acceleration_set(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<(), AxisError>,
    ) -> Next<Self> {
        match r {
            Ok(()) => {
                self.k += 1;
                self.apply_settings(s)
            }
            Err(e) => Next::fail(self.idx[self.k], e),
        }
    }
}
