//! The operations: identify, set-up, home, moves, stop and the queries.

use std::time::Duration;

use tracing::{debug, warn};

use super::exec::{Aborted, Next, Op, Overdue};
use super::{AptSession, AptStatus, Seen};
use crate::apt::{
    AptInfo, CHANNEL, GenMoveParams, HomeParams, Message, StopMode, VelParams, status,
};
use crate::machine::{Cx, secs};
use crate::motion::AxisError;

/// Polls after a move was sent before a still stage away from its target counts as
/// stopped short (a controller may take a moment to report motion).
const GRACE_POLLS: u32 = 3;

fn is_status(m: &Message) -> bool {
    matches!(
        m,
        Message::GetDcStatusUpdate(_) | Message::GetStatusUpdate(_)
    )
}

/// A reply that is not the expected one.
fn protocol(sent: &Message, reply: &Message, reason: &str) -> AxisError {
    AxisError::Protocol {
        sent: sent.name().into(),
        reply: format!("{reply:?}"),
        reason: reason.into(),
    }
}

/// The reply to a status request, as a status.
fn read_status(s: &AptSession, r: Result<Message, AxisError>) -> Result<AptStatus, AxisError> {
    let m = r?;
    s.status_of(&m)
        .ok_or_else(|| protocol(&s.status_request(), &m, "not this channel's status"))
}

fn status_query<O: Op>(
    s: &AptSession,
    then: super::exec::Then<O, Result<Message, AxisError>>,
) -> Next<O> {
    Next::query(s.status_request(), is_status, then)
}

/// The fault a status shows, if any: a limit switch, a drive fault, lost reference or
/// a disabled channel.
fn fault(st: &AptStatus, command: &str, need_homed: bool) -> Option<AxisError> {
    if st.bits & (status::FAULTS | status::HW_LIMITS) != 0 {
        return Some(AxisError::Device {
            command: command.into(),
            reason: st.faults().join(", "),
        });
    }
    if !st.is_enabled() {
        return Some(AxisError::Device {
            command: command.into(),
            reason: "channel disabled".into(),
        });
    }
    if need_homed && !st.is_homed() {
        return Some(AxisError::NotHomed);
    }
    None
}

// --- identify ---

/// `HW_REQ_INFO`, with the model checked.
#[derive(Debug)]
pub(super) struct Identify;

impl Op for Identify {
    type Value = AptInfo;

    fn start(&mut self, _: &mut AptSession, _: &mut Cx) -> Next<Self> {
        Next::query(
            Message::HwReqInfo,
            |m| matches!(m, Message::HwGetInfo(_)),
            Self::got,
        )
    }
}

impl Identify {
    fn got(&mut self, s: &mut AptSession, _: &mut Cx, r: Result<Message, AxisError>) -> Next<Self> {
        let info = match r {
            Ok(Message::HwGetInfo(i)) => i,
            Ok(other) => {
                return Next::error(s, protocol(&Message::HwReqInfo, &other, "not HW_GET_INFO"));
            }
            Err(e) => return Next::error(s, e),
        };
        let want = s.stage().controller();
        if info.model.trim() != want {
            warn!(model = %info.model, want, "apt: wrong controller");
            return Next::error(
                s,
                AxisError::Device {
                    command: "HW_REQ_INFO".into(),
                    reason: format!(
                        "controller is a {:?}, but the stage {:?} needs a {want}",
                        info.model, s.axis.stage
                    ),
                },
            );
        }
        debug!(%info, "apt: identified");
        Next::Done(Ok(info))
    }
}

// --- set-up ---

/// Flash programming off, channel enabled, parameters set and read back.
#[derive(Debug, Default)]
pub(super) struct Setup {
    vel: Option<VelParams>,
    home: Option<HomeParams>,
    backlash: Option<GenMoveParams>,
}

fn mismatch(what: &str, set: String, got: String) -> AxisError {
    AxisError::Device {
        command: format!("MOT_SET_{what}"),
        reason: format!("read back {got}, set {set}"),
    }
}

impl Op for Setup {
    type Value = ();

    fn start(&mut self, s: &mut AptSession, _: &mut Cx) -> Next<Self> {
        let stage = s.stage();
        let (v, a) = s.axis.motion();
        self.vel = Some(VelParams {
            chan: CHANNEL,
            min_velocity: 0,
            acceleration: stage.acceleration_to_apt(a),
            max_velocity: stage.velocity_to_apt(v),
        });
        self.home = Some(HomeParams {
            chan: CHANNEL,
            direction: match stage.home_direction() {
                crate::apt::Direction::Forward => 1,
                crate::apt::Direction::Reverse => 2,
            },
            limit_switch: stage.home_limit_switch(),
            velocity: stage.velocity_to_apt(stage.home_velocity()),
            offset: stage.to_counts(stage.home_offset()),
        });
        self.backlash = s.axis.backlash_deg.map(|b| GenMoveParams {
            chan: CHANNEL,
            backlash: stage.to_counts(b),
        });
        Next::send(Message::HwNoFlashProgramming, Self::enable)
    }
}

impl Setup {
    fn enable(&mut self, s: &mut AptSession, _: &mut Cx, r: Result<(), AxisError>) -> Next<Self> {
        if let Err(e) = r {
            return Next::error(s, e);
        }
        let m = Message::SetChanEnableState {
            chan: 1,
            enable: true,
        };
        Next::send(m, Self::ask_enabled)
    }

    fn ask_enabled(
        &mut self,
        s: &mut AptSession,
        _: &mut Cx,
        r: Result<(), AxisError>,
    ) -> Next<Self> {
        if let Err(e) = r {
            return Next::error(s, e);
        }
        Next::query(
            Message::ReqChanEnableState { chan: 1 },
            |m| matches!(m, Message::GetChanEnableState { .. }),
            Self::got_enabled,
        )
    }

    fn got_enabled(
        &mut self,
        s: &mut AptSession,
        _: &mut Cx,
        r: Result<Message, AxisError>,
    ) -> Next<Self> {
        match r {
            Ok(Message::GetChanEnableState { enabled: true, .. }) => {}
            Ok(_) => {
                return Next::error(
                    s,
                    AxisError::Device {
                        command: "MOD_SET_CHANENABLESTATE".into(),
                        reason: "the channel stayed disabled".into(),
                    },
                );
            }
            Err(e) => return Next::error(s, e),
        }
        match self.vel {
            Some(v) => Next::send(Message::SetVelParams(v), Self::ask_vel),
            None => self.set_home(s),
        }
    }

    fn ask_vel(&mut self, s: &mut AptSession, _: &mut Cx, r: Result<(), AxisError>) -> Next<Self> {
        if let Err(e) = r {
            return Next::error(s, e);
        }
        Next::query(
            Message::ReqVelParams { chan: 1 },
            |m| matches!(m, Message::GetVelParams(_)),
            Self::got_vel,
        )
    }

    fn got_vel(
        &mut self,
        s: &mut AptSession,
        _: &mut Cx,
        r: Result<Message, AxisError>,
    ) -> Next<Self> {
        match (r, self.vel) {
            (Ok(Message::GetVelParams(got)), Some(set)) if got == set => self.set_home(s),
            (Ok(m), Some(set)) => Next::error(
                s,
                mismatch("VELPARAMS", format!("{set:?}"), format!("{m:?}")),
            ),
            (Err(e), _) => Next::error(s, e),
            (Ok(_), None) => self.set_home(s),
        }
    }

    fn set_home(&mut self, s: &AptSession) -> Next<Self> {
        match self.home {
            Some(h) => Next::send(Message::SetHomeParams(h), Self::ask_home),
            None => self.set_backlash(s),
        }
    }

    fn ask_home(&mut self, s: &mut AptSession, _: &mut Cx, r: Result<(), AxisError>) -> Next<Self> {
        if let Err(e) = r {
            return Next::error(s, e);
        }
        Next::query(
            Message::ReqHomeParams { chan: 1 },
            |m| matches!(m, Message::GetHomeParams(_)),
            Self::got_home,
        )
    }

    fn got_home(
        &mut self,
        s: &mut AptSession,
        _: &mut Cx,
        r: Result<Message, AxisError>,
    ) -> Next<Self> {
        match (r, self.home) {
            (Ok(Message::GetHomeParams(got)), Some(set)) if got == set => self.set_backlash(s),
            (Ok(m), Some(set)) => Next::error(
                s,
                mismatch("HOMEPARAMS", format!("{set:?}"), format!("{m:?}")),
            ),
            (Err(e), _) => Next::error(s, e),
            (Ok(_), None) => self.set_backlash(s),
        }
    }

    fn set_backlash(&mut self, s: &AptSession) -> Next<Self> {
        match self.backlash {
            Some(b) => Next::send(Message::SetGenMoveParams(b), Self::ask_backlash),
            None => self.start_updates(s),
        }
    }

    fn ask_backlash(
        &mut self,
        s: &mut AptSession,
        _: &mut Cx,
        r: Result<(), AxisError>,
    ) -> Next<Self> {
        if let Err(e) = r {
            return Next::error(s, e);
        }
        Next::query(
            Message::ReqGenMoveParams { chan: 1 },
            |m| matches!(m, Message::GetGenMoveParams(_)),
            Self::got_backlash,
        )
    }

    fn got_backlash(
        &mut self,
        s: &mut AptSession,
        _: &mut Cx,
        r: Result<Message, AxisError>,
    ) -> Next<Self> {
        match (r, self.backlash) {
            (Ok(Message::GetGenMoveParams(got)), Some(set)) if got == set => self.start_updates(s),
            (Ok(m), Some(set)) => Next::error(
                s,
                mismatch("GENMOVEPARAMS", format!("{set:?}"), format!("{m:?}")),
            ),
            (Err(e), _) => Next::error(s, e),
            (Ok(_), None) => self.start_updates(s),
        }
    }

    fn start_updates(&mut self, s: &AptSession) -> Next<Self> {
        if s.axis.status_updates {
            Next::send(Message::HwStartUpdateMsgs, Self::updates_started)
        } else {
            Next::Done(Ok(()))
        }
    }

    fn updates_started(
        &mut self,
        s: &mut AptSession,
        _: &mut Cx,
        r: Result<(), AxisError>,
    ) -> Next<Self> {
        match r {
            Ok(()) => {
                s.updates_on = true;
                debug!("apt: set up; status updates started");
                Next::Done(Ok(()))
            }
            Err(e) => Next::error(s, e),
        }
    }
}

// --- home ---

/// `MOT_MOVE_HOME`, then polls until homed.
#[derive(Debug, Default)]
pub(super) struct Home {
    start: Duration,
    /// A status showed the search under way.
    saw_homing: bool,
}

impl Op for Home {
    type Value = f64;

    fn start(&mut self, s: &mut AptSession, cx: &mut Cx) -> Next<Self> {
        // Completions of earlier operations must not end this one.
        cx.clear_input();
        s.seen = Seen::default();
        Next::send(Message::MoveHome { chan: 1 }, Self::sent)
    }
}

impl Home {
    fn sent(&mut self, s: &mut AptSession, cx: &mut Cx, r: Result<(), AxisError>) -> Next<Self> {
        if let Err(e) = r {
            return Next::error(s, e);
        }
        debug!(axis = %s.axis.name, "apt: home search started");
        self.start = cx.now;
        self.pause(s, cx)
    }

    fn pause(&mut self, s: &AptSession, cx: &Cx) -> Next<Self> {
        Next::Pause {
            until: cx.now.saturating_add(s.policy.poll_interval),
            abortable: true,
            then: Self::waited,
        }
    }

    fn waited(&mut self, s: &mut AptSession, _: &mut Cx, r: Result<(), Aborted>) -> Next<Self> {
        if r.is_err() {
            warn!("apt: home search aborted");
            return Next::Fail(AxisError::Aborted);
        }
        status_query(s, Self::polled)
    }

    fn polled(
        &mut self,
        s: &mut AptSession,
        cx: &mut Cx,
        r: Result<Message, AxisError>,
    ) -> Next<Self> {
        let st = match read_status(s, r) {
            Ok(st) => st,
            Err(e) => return Next::Fail(e),
        };
        if st.bits & status::HOMING != 0 {
            self.saw_homing = true;
        }
        if let Some(e) = fault(&st, "MOT_MOVE_HOME", false) {
            // The home switch of a stage homing onto a limit switch is not a fault.
            let limit_only = st.bits & status::FAULTS == 0 && st.is_enabled();
            if !limit_only {
                return Next::Fail(e);
            }
        }
        let over = !st.is_moving() && st.is_homed();
        if s.seen.homed || (self.saw_homing && over) {
            debug!(position = st.position_deg, "apt: homed");
            return Next::Done(Ok(st.position_deg));
        }
        let waited = secs(s.axis.home_timeout_s);
        if cx.now.saturating_sub(self.start) > waited {
            return Next::Overdue(Overdue {
                operation: "home",
                target: 0.0,
                waited,
            });
        }
        self.pause(s, cx)
    }
}

// --- moves ---

/// How long a move of `distance` deg may take: the policy's margin plus its factor
/// times the trapezoid's duration at the configured velocity and acceleration.
fn allowance(s: &AptSession, distance: f64) -> Duration {
    let (v, a) = s.axis.motion();
    let t = gonio_core::motion::trapezoid_time(distance, v, a);
    s.policy
        .move_margin
        .saturating_add(secs(t * s.policy.move_factor))
}

/// An absolute move (`delta` `None`) or a relative one.
#[derive(Debug)]
pub(super) struct Motion {
    target: f64,
    delta: Option<f64>,
    start: Duration,
    allow: Duration,
    polls: u32,
    resent: usize,
}

impl Motion {
    pub(super) fn to(target: f64) -> Self {
        Motion {
            target,
            delta: None,
            start: Duration::ZERO,
            allow: Duration::ZERO,
            polls: 0,
            resent: 0,
        }
    }

    pub(super) fn by(delta: f64) -> Self {
        Motion {
            target: f64::NAN,
            delta: Some(delta),
            ..Motion::to(f64::NAN)
        }
    }

    fn command(&self, s: &AptSession) -> Message {
        let stage = s.stage();
        match self.delta {
            None => Message::MoveAbsolute {
                chan: CHANNEL,
                position: Some(stage.to_counts(self.target)),
            },
            Some(d) => Message::MoveRelative {
                chan: CHANNEL,
                distance: Some(stage.to_counts(d)),
            },
        }
    }

    fn name(&self) -> &'static str {
        if self.delta.is_some() {
            "MOT_MOVE_RELATIVE"
        } else {
            "MOT_MOVE_ABSOLUTE"
        }
    }
}

impl Op for Motion {
    type Value = f64;

    fn start(&mut self, s: &mut AptSession, cx: &mut Cx) -> Next<Self> {
        if self.delta.is_none()
            && let Err(e) = s.check_limits(self.target)
        {
            return Next::error(s, e);
        }
        if let Some(d) = self.delta
            && !d.is_finite()
        {
            return Next::error(
                s,
                AxisError::OutOfLimits {
                    target: d,
                    min: s.axis.min,
                    max: s.axis.max,
                    units: "deg".into(),
                },
            );
        }
        cx.clear_input();
        s.seen = Seen::default();
        status_query(s, Self::got_start)
    }
}

impl Motion {
    fn got_start(
        &mut self,
        s: &mut AptSession,
        _: &mut Cx,
        r: Result<Message, AxisError>,
    ) -> Next<Self> {
        let st = match read_status(s, r) {
            Ok(st) => st,
            Err(e) => return Next::error(s, e),
        };
        if let Some(e) = fault(&st, self.name(), true) {
            return Next::error(s, e);
        }
        if let Some(d) = self.delta {
            self.target = st.position_deg + d;
            if let Err(e) = s.check_limits(self.target) {
                return Next::error(s, e);
            }
        }
        self.allow = allowance(s, self.target - st.position_deg);
        Next::send(self.command(s), Self::sent)
    }

    fn sent(&mut self, s: &mut AptSession, cx: &mut Cx, r: Result<(), AxisError>) -> Next<Self> {
        if let Err(e) = r {
            return Next::Fail(e);
        }
        debug!(axis = %s.axis.name, target = self.target, "apt: move started");
        self.start = cx.now;
        self.polls = 0;
        self.pause(s, cx)
    }

    fn pause(&mut self, s: &AptSession, cx: &Cx) -> Next<Self> {
        Next::Pause {
            until: cx.now.saturating_add(s.policy.poll_interval),
            abortable: true,
            then: Self::waited,
        }
    }

    fn waited(&mut self, s: &mut AptSession, _: &mut Cx, r: Result<(), Aborted>) -> Next<Self> {
        if r.is_err() {
            warn!("apt: move aborted");
            return Next::Fail(AxisError::Aborted);
        }
        status_query(s, Self::polled)
    }

    fn polled(
        &mut self,
        s: &mut AptSession,
        cx: &mut Cx,
        r: Result<Message, AxisError>,
    ) -> Next<Self> {
        let st = match read_status(s, r) {
            Ok(st) => st,
            Err(e @ AxisError::Transport(_)) => {
                // The outcome is unknown: an absolute move may simply go again.
                if self.delta.is_some() {
                    warn!(error = %e, "apt: lost the outcome of a relative move");
                    return Next::Fail(AxisError::Ambiguous {
                        command: self.name().into(),
                    });
                }
                if self.resent >= s.policy.retries {
                    return Next::Fail(e);
                }
                self.resent += 1;
                s.retried += 1;
                warn!(error = %e, "apt: lost the outcome of an absolute move; sending it again");
                return Next::send(self.command(s), Self::sent_again);
            }
            Err(e) => return Next::Fail(e),
        };
        self.polls += 1;
        if let Some(e) = fault(&st, self.name(), true) {
            return Next::Fail(e);
        }
        let tolerance = s.axis.tolerance;
        let completed = s.seen.completed.is_some() || s.seen.stopped.is_some();
        if !st.is_moving() {
            if (st.position_deg - self.target).abs() <= tolerance {
                debug!(position = st.position_deg, "apt: move done");
                return Next::Done(Ok(st.position_deg));
            }
            if completed || self.polls >= GRACE_POLLS {
                return Next::Fail(AxisError::TargetNotReached {
                    target: self.target,
                    position: st.position_deg,
                    tolerance,
                });
            }
        }
        if cx.now.saturating_sub(self.start) > self.allow {
            return Next::Overdue(Overdue {
                operation: "move",
                target: self.target,
                waited: self.allow,
            });
        }
        self.pause(s, cx)
    }

    fn sent_again(
        &mut self,
        s: &mut AptSession,
        cx: &mut Cx,
        r: Result<(), AxisError>,
    ) -> Next<Self> {
        if let Err(e) = r {
            return Next::Fail(e);
        }
        self.pause(s, cx)
    }
}

// --- stop ---

/// `MOT_MOVE_STOP`, then `MOT_MOVE_STOPPED` or a still status.
#[derive(Debug)]
pub(super) struct Stop {
    mode: StopMode,
}

impl Stop {
    pub(super) fn new(profiled: bool) -> Self {
        Stop {
            mode: if profiled {
                StopMode::Profiled
            } else {
                StopMode::Immediate
            },
        }
    }
}

impl Op for Stop {
    type Value = ();

    fn start(&mut self, s: &mut AptSession, _: &mut Cx) -> Next<Self> {
        s.seen.stopped = None;
        let m = Message::MoveStop {
            chan: 1,
            mode: self.mode,
        };
        Next::send(m, Self::sent)
    }
}

impl Stop {
    fn sent(&mut self, s: &mut AptSession, cx: &mut Cx, r: Result<(), AxisError>) -> Next<Self> {
        if let Err(e) = r {
            return Next::error(s, e);
        }
        Next::Await {
            want: |m| matches!(m, Message::MoveStopped { .. }),
            until: cx.now.saturating_add(s.policy.move_margin),
            after: "MOT_MOVE_STOP",
            then: Self::stopped,
        }
    }

    fn stopped(
        &mut self,
        s: &mut AptSession,
        _: &mut Cx,
        r: Result<Message, AxisError>,
    ) -> Next<Self> {
        match r {
            Ok(_) => Next::Done(Ok(())),
            Err(AxisError::Transport(_)) => status_query(s, Self::checked),
            Err(e) => Next::error(s, e),
        }
    }

    fn checked(
        &mut self,
        s: &mut AptSession,
        _: &mut Cx,
        r: Result<Message, AxisError>,
    ) -> Next<Self> {
        match read_status(s, r) {
            Ok(st) if !st.is_moving() => Next::Done(Ok(())),
            Ok(st) => Next::error(
                s,
                AxisError::Device {
                    command: "MOT_MOVE_STOP".into(),
                    reason: format!("still moving at {} deg", st.position_deg),
                },
            ),
            Err(e) => Next::error(s, e),
        }
    }
}

// --- a late completion ---

/// Waits for the last move's `MOT_MOVE_COMPLETED`, if it has not come.
#[derive(Debug)]
pub(super) struct AwaitCompletion {
    wait: Duration,
}

impl AwaitCompletion {
    pub(super) fn new(wait: Duration) -> Self {
        AwaitCompletion { wait }
    }
}

impl Op for AwaitCompletion {
    type Value = bool;

    fn start(&mut self, s: &mut AptSession, cx: &mut Cx) -> Next<Self> {
        if s.seen.completed.is_some() {
            return Next::Done(Ok(true));
        }
        Next::Await {
            want: |m| matches!(m, Message::MoveCompleted { .. }),
            until: cx.now.saturating_add(self.wait),
            after: "MOT_MOVE_COMPLETED",
            then: |_, s, _, r| match r {
                Ok(Message::MoveCompleted { status, .. }) => {
                    s.seen.completed = Some(status);
                    s.completions += 1;
                    Next::Done(Ok(true))
                }
                Ok(_) | Err(AxisError::Transport(_)) => Next::Done(Ok(false)),
                Err(e) => Next::error(s, e),
            },
        }
    }
}

// --- queries ---

/// `MOT_REQ_POSCOUNTER`.
#[derive(Debug)]
pub(super) struct Position;

impl Op for Position {
    type Value = f64;

    fn start(&mut self, _: &mut AptSession, _: &mut Cx) -> Next<Self> {
        Next::query(
            Message::ReqPosCounter { chan: 1 },
            |m| matches!(m, Message::GetPosCounter { .. }),
            |_, s, _, r| match r {
                Ok(Message::GetPosCounter { position, .. }) => {
                    Next::Done(Ok(s.stage().to_deg(position)))
                }
                Ok(m) => Next::error(
                    s,
                    protocol(&Message::ReqPosCounter { chan: 1 }, &m, "not a position"),
                ),
                Err(e) => Next::error(s, e),
            },
        )
    }
}

/// The status request of the stage's drive.
#[derive(Debug)]
pub(super) struct StatusQuery;

impl Op for StatusQuery {
    type Value = AptStatus;

    fn start(&mut self, s: &mut AptSession, _: &mut Cx) -> Next<Self> {
        status_query(s, |_, s, _, r| match read_status(s, r) {
            Ok(st) => Next::Done(Ok(st)),
            Err(e) => Next::error(s, e),
        })
    }
}

/// `MOT_REQ_VELPARAMS`.
#[derive(Debug)]
pub(super) struct VelQuery;

impl Op for VelQuery {
    type Value = (f64, f64);

    fn start(&mut self, _: &mut AptSession, _: &mut Cx) -> Next<Self> {
        Next::query(
            Message::ReqVelParams { chan: 1 },
            |m| matches!(m, Message::GetVelParams(_)),
            |_, s, _, r| match r {
                Ok(Message::GetVelParams(v)) => {
                    let stage = s.stage();
                    Next::Done(Ok((
                        stage.velocity_from_apt(v.max_velocity),
                        stage.acceleration_from_apt(v.acceleration),
                    )))
                }
                Ok(m) => Next::error(
                    s,
                    protocol(
                        &Message::ReqVelParams { chan: 1 },
                        &m,
                        "not velocity parameters",
                    ),
                ),
                Err(e) => Next::error(s, e),
            },
        )
    }
}
