//! The controller's operations as the manual's procedures (identify, set-up, home,
//! moves, stop, the queries), and its link policy, which is not `engine::exchange`'s:
//! a vanished port is reopened at once, and only while sending; a request is asked
//! again only after a lost, late or garbled reply, and only then is the input cleared
//! (an error report is a whole message: nothing stale is left). The keep-alive is not
//! an exchange: the pump sends it on its clock ([`AptSession::keepalive`]).

use std::mem::discriminant;
use std::time::Duration;

use tracing::{debug, warn};

use super::{AptSession, AptStatus, Seen};
use crate::TransportError;
use crate::apt::{
    AptInfo, CHANNEL, DcStatus, GenMoveParams, HEADER_LEN, HomeParams, Message, Packet, StopMode,
    VelParams, status,
};
use crate::engine::motion::{self, Motion};
use crate::engine::{self, Link, secs};
use crate::motion::{AxisError, MotionError};
use crate::smc100::{Halt, stop};

/// Polls after a move was sent before a still stage away from its target counts as
/// stopped short (a controller may take a moment to report motion).
const GRACE_POLLS: u32 = 3;

/// A reply that is not the expected one.
fn protocol(sent: &Message, reply: &Message, reason: &str) -> AxisError {
    AxisError::Protocol {
        sent: sent.name().into(),
        reply: format!("{reply:?}"),
        reason: reason.into(),
    }
}

/// The fault a status shows, if any: a limit switch, a drive fault, lost reference or
/// a disabled channel.
fn fault(st: &AptStatus, command: &str, need_homed: bool) -> Option<AxisError> {
    if st.bits & (status::FAULTS | status::HW_LIMITS) != 0 {
        return Some(device(command, st.faults().join(", ")));
    }
    if !st.is_enabled() {
        return Some(device(command, "channel disabled".into()));
    }
    (need_homed && !st.is_homed()).then_some(AxisError::NotHomed)
}

/// A move or home search past its deadline: [`motion::settle`] stops the stage and
/// reads its position.
fn overdue(operation: &'static str, target: f64, waited: Duration) -> Halt {
    Halt::Overdue(0, operation, target, waited)
}

/// The manual's name of a move, relative or absolute.
fn move_name(relative: bool) -> &'static str {
    if relative {
        "MOT_MOVE_RELATIVE"
    } else {
        "MOT_MOVE_ABSOLUTE"
    }
}

/// The controller's fault report on `command`.
fn device(command: &str, reason: String) -> AxisError {
    AxisError::Device {
        command: command.into(),
        reason,
    }
}

/// The answer a message pattern takes, for [`AptSession::ask`] and
/// [`AptSession::receive`]: `pick!(Message::GetPosCounter { position, .. } => *position)`.
macro_rules! pick {
    ($p:pat => $v:expr) => {
        |m: &Message| match m {
            $p => Some($v),
            _ => None,
        }
    };
}

impl AptSession {
    /// Sends `m`. A vanished port is reopened at once, then up to `reconnect_attempts`
    /// more times `reconnect_delay` apart, and `m` sent once more: its bytes never
    /// left, so even a relative move may go.
    async fn transmit(&self, link: &Link, m: &Message) -> Result<(), AxisError> {
        let (attempts, delay) = (self.policy.reconnect_attempts, self.policy.reconnect_delay);
        Ok(engine::send_reopening(link, "apt", attempts, delay, &m.to_bytes()).await?)
    }

    /// Waits until `until` for a message `pick` takes. On the way: a status update is
    /// counted; `MOVE_COMPLETED`, `MOVE_STOPPED` and `MOVE_HOMED` are noted for the
    /// operation; an error report (`HW_RESPONSE`, `HW_RICHRESPONSE`) is
    /// [`AxisError::Device`] after `after`; anything else is skipped.
    async fn receive<T>(
        &mut self,
        link: &Link,
        until: Duration,
        after: &'static str,
        pick: impl Fn(&Message) -> Option<T>,
    ) -> Result<T, AxisError> {
        let reported = |reason: String| {
            warn!(after, %reason, "apt: the controller reported an error");
            device(after, reason)
        };
        loop {
            let bytes = link.line(until).await?;
            let message = match Packet::parse(&bytes) {
                Ok(p) => p.message,
                Err(e) => {
                    debug!(error = %e, "apt: skipping a message that does not parse");
                    continue;
                }
            };
            self.heard(&message, bytes.len().saturating_sub(HEADER_LEN));
            let update = self.status_of(&message).is_some();
            let picked = pick(&message);
            if update && (self.updates_on || picked.is_none()) {
                self.updates += 1;
            }
            if let Some(v) = picked {
                return Ok(v);
            }
            debug!(message = message.name(), "apt: an unsolicited message");
            match message {
                // Updates flow only when asked for (or left on by another host).
                _ if update => self.updates_on = true,
                Message::MoveCompleted { status, .. } => self.completed(status),
                Message::MoveStopped { status, .. } => self.seen.stopped = Some(status),
                Message::MoveHomed { .. } => self.seen.homed = true,
                Message::HwResponse => {
                    return Err(reported("HW_RESPONSE (an unspecified error)".into()));
                }
                Message::HwRichResponse {
                    msg_id,
                    code,
                    notes,
                } => {
                    let reason = format!("error {code} on message {msg_id:#06x}: {notes}");
                    return Err(reported(reason));
                }
                _ => {}
            }
        }
    }

    /// Notes the last move's `MOT_MOVE_COMPLETED`.
    fn completed(&mut self, status: Option<DcStatus>) {
        self.seen.completed = Some(status);
        self.completions += 1;
    }

    /// `request` and the answer `pick` takes, asked again up to `retries` times after
    /// a lost, late or garbled one. While status updates flow a status request is not
    /// sent: the next update is the answer (a reply would queue behind the updates
    /// and be stale).
    async fn ask<T>(
        &mut self,
        link: &Link,
        request: Message,
        pick: impl Fn(&Message) -> Option<T>,
    ) -> Result<T, AxisError> {
        let name = request.name();
        let status = matches!(
            request,
            Message::ReqDcStatusUpdate { .. } | Message::ReqStatusUpdate { .. }
        );
        if self.updates_on && status {
            // Three reply timeouts: longer than the 100 ms update period.
            let wait = self.policy.reply_timeout.saturating_mul(3);
            match self
                .receive(link, link.now().saturating_add(wait), name, &pick)
                .await
            {
                Err(AxisError::Transport(TransportError::Timeout(_))) => {
                    debug!("apt: no status update came; asking for the status");
                    self.updates_on = false;
                }
                r => return r,
            }
        }
        let mut retries = self.policy.retries;
        loop {
            self.transmit(link, &request).await?;
            let until = link.now().saturating_add(self.policy.reply_timeout);
            let e = match self.receive(link, until, name, &pick).await {
                Err(
                    e @ AxisError::Transport(
                        TransportError::Timeout(_)
                        | TransportError::Garbled(_)
                        | TransportError::LineTooLong,
                    ),
                ) => e,
                r => return r,
            };
            link.clear_input();
            if retries == 0 {
                if self.policy.retries > 0 {
                    warn!(request = name, error = %e, "apt: no usable reply");
                }
                return Err(e);
            }
            warn!(request = name, error = %e, "apt: no usable reply; asking again");
            retries -= 1;
            self.retried += 1;
        }
    }

    /// The channel's status (`MOT_REQ_DCSTATUSUPDATE`, `MOT_REQ_STATUSUPDATE` for a
    /// stepper), or the next update while they flow.
    pub(super) async fn status(&mut self, link: &Link) -> Result<AptStatus, AxisError> {
        let request = self.status_request();
        let is_status =
            pick!(m @ (Message::GetDcStatusUpdate(_) | Message::GetStatusUpdate(_)) => m.clone());
        let m = self.ask(link, request.clone(), is_status).await?;
        self.status_of(&m)
            .ok_or_else(|| protocol(&request, &m, "not this channel's status"))
    }

    /// `HW_REQ_INFO`; the model must be the stage's controller.
    pub(super) async fn identify(&mut self, link: &Link) -> Result<AptInfo, AxisError> {
        let info = pick!(Message::HwGetInfo(i) => i.clone());
        let info = self.ask(link, Message::HwReqInfo, info).await?;
        let want = self.stage().controller();
        if info.model.trim() != want {
            warn!(model = %info.model, want, "apt: wrong controller");
            let stage = self.axis.stage;
            let reason = format!(
                "controller is a {:?}, but the stage {stage:?} needs a {want}",
                info.model
            );
            return Err(device("HW_REQ_INFO", reason));
        }
        debug!(%info, "apt: identified");
        Ok(info)
    }

    /// Flash programming off, the channel enabled, the velocity, home and (when
    /// configured) backlash parameters set and read back, then the status updates
    /// started when configured.
    pub(super) async fn setup(&mut self, link: &Link) -> Result<(), AxisError> {
        let stage = self.stage();
        let (v, a) = self.axis.motion();
        self.transmit(link, &Message::HwNoFlashProgramming).await?;
        let enable = Message::SetChanEnableState {
            chan: 1,
            enable: true,
        };
        self.transmit(link, &enable).await?;
        let enabled = pick!(Message::GetChanEnableState { enabled, .. } => *enabled);
        let ask = Message::ReqChanEnableState { chan: 1 };
        if !self.ask(link, ask, enabled).await? {
            let reason = "the channel stayed disabled".into();
            return Err(device("MOD_SET_CHANENABLESTATE", reason));
        }
        let vel = VelParams {
            chan: CHANNEL,
            min_velocity: 0,
            acceleration: stage.acceleration_to_apt(a),
            max_velocity: stage.velocity_to_apt(v),
        };
        let (set, get) = (Message::SetVelParams, Message::GetVelParams);
        let ask = Message::ReqVelParams { chan: 1 };
        self.write(link, vel, set, ask, get).await?;
        let home = HomeParams {
            chan: CHANNEL,
            direction: stage.home_direction().code(),
            limit_switch: stage.home_limit_switch(),
            velocity: stage.velocity_to_apt(stage.home_velocity()),
            offset: stage.to_counts(stage.home_offset()),
        };
        let (set, get) = (Message::SetHomeParams, Message::GetHomeParams);
        let ask = Message::ReqHomeParams { chan: 1 };
        self.write(link, home, set, ask, get).await?;
        if let Some(b) = self.axis.backlash_deg {
            let backlash = GenMoveParams {
                chan: CHANNEL,
                backlash: stage.to_counts(b),
            };
            let (set, get) = (Message::SetGenMoveParams, Message::GetGenMoveParams);
            let ask = Message::ReqGenMoveParams { chan: 1 };
            self.write(link, backlash, set, ask, get).await?;
        }
        if self.axis.status_updates {
            self.transmit(link, &Message::HwStartUpdateMsgs).await?;
            self.updates_on = true;
            debug!("apt: set up; status updates started");
        }
        Ok(())
    }

    /// `set(params)`, then `ask`, whose answer must be `get(params)`.
    async fn write<P: Copy + std::fmt::Debug>(
        &mut self,
        link: &Link,
        params: P,
        set: fn(P) -> Message,
        ask: Message,
        get: fn(P) -> Message,
    ) -> Result<(), AxisError> {
        self.transmit(link, &set(params)).await?;
        let want = get(params);
        let same_kind = |m: &Message| (discriminant(m) == discriminant(&want)).then(|| m.clone());
        let got = self.ask(link, ask, same_kind).await?;
        if got == want {
            return Ok(());
        }
        let reason = format!("read back {got:?}, set {params:?}");
        Err(device(set(params).name(), reason))
    }

    /// `MOT_MOVE_HOME`, then a status every poll interval until `MOT_MOVE_HOMED` came
    /// or a status shows the search over and the stage homed, within
    /// `home_timeout_s`.
    pub(super) async fn home(&mut self, link: &Link) -> Result<f64, Halt> {
        // Completions of earlier operations must not end this one.
        link.clear_input();
        self.seen = Seen::default();
        let sent = self.transmit(link, &Message::MoveHome { chan: 1 }).await;
        sent.map_err(|e| self.at(e))?;
        debug!(axis = %self.axis.name, "apt: home search started");
        let timeout = secs(self.axis.home_timeout_s);
        let (mut saw_homing, mut homed_at) = (false, 0.0);
        let searching = vec![(0, 0.0)];
        motion::poll(
            self,
            link,
            searching,
            "home search",
            |s, _, _, st, elapsed| {
                saw_homing |= st.bits & status::HOMING != 0;
                // The home switch of a stage homing onto a limit switch is not a fault.
                let limit_only = st.bits & status::FAULTS == 0 && st.is_enabled();
                if let Some(e) = fault(&st, "MOT_MOVE_HOME", false)
                    && !limit_only
                {
                    return Err(Halt::Stop(0, e));
                }
                if s.seen.homed || (saw_homing && !st.is_moving() && st.is_homed()) {
                    debug!(position = st.position_deg, "apt: homed");
                    homed_at = st.position_deg;
                    return Ok(false);
                }
                if elapsed > timeout {
                    return Err(overdue("home", 0.0, timeout));
                }
                Ok(true)
            },
        )
        .await?;
        Ok(homed_at)
    }

    /// What a move to `value` deg (or by it, when `relative`) needs before it is sent:
    /// the status read (the stage must be homed and fault-free; a relative target is
    /// checked against the limits then), and the target, the time allowed and the
    /// message.
    async fn aim(
        &mut self,
        link: &Link,
        value: f64,
        relative: bool,
    ) -> Result<(f64, Duration, Message), AxisError> {
        // A distance need only be finite; its target is checked once the position
        // is known.
        if !relative || !value.is_finite() {
            self.check_limits(value)?;
        }
        link.clear_input();
        self.seen = Seen::default();
        let st = self.status(link).await?;
        if let Some(e) = fault(&st, move_name(relative), true) {
            return Err(e);
        }
        let target = if relative {
            st.position_deg + value
        } else {
            value
        };
        self.check_limits(target)?;
        // The policy's margin plus its factor times the trapezoid's duration.
        let (v, a) = self.axis.motion();
        let t = gonio_core::motion::trapezoid_time(target - st.position_deg, v, a);
        let allow = self.policy.allowance(t);
        let stage = self.stage();
        let command = if relative {
            Message::MoveRelative {
                chan: CHANNEL,
                distance: Some(stage.to_counts(value)),
            }
        } else {
            Message::MoveAbsolute {
                chan: CHANNEL,
                position: Some(stage.to_counts(target)),
            }
        };
        Ok((target, allow, command))
    }

    /// A move to `value` deg, or by it when `relative` ([`Self::aim`]): the move sent,
    /// then a status every poll interval until the stage is still within tolerance of
    /// the target.
    pub(super) async fn motion(
        &mut self,
        link: &Link,
        value: f64,
        relative: bool,
    ) -> Result<f64, Halt> {
        let aimed = self.aim(link, value, relative).await;
        let (target, allow, command) = aimed.map_err(|e| self.at(e))?;
        let name = move_name(relative);
        self.transmit(link, &command).await.map_err(stop(0))?;
        debug!(axis = %self.axis.name, target, "apt: move started");
        let start = link.now();
        let (mut polls, mut resent) = (0, 0);
        loop {
            motion::pause(self, link, "move").await.map_err(stop(0))?;
            let st = match self.status(link).await {
                Ok(st) => st,
                // The outcome is unknown: an absolute move may simply go again.
                Err(e @ AxisError::Transport(_)) if relative => {
                    warn!(error = %e, "apt: lost the outcome of a relative move");
                    let command = name.into();
                    return Err(Halt::Stop(0, AxisError::Ambiguous { command }));
                }
                Err(e @ AxisError::Transport(_)) if resent < self.policy.retries => {
                    resent += 1;
                    self.retried += 1;
                    warn!(error = %e, "apt: lost the outcome of an absolute move; sending it again");
                    self.transmit(link, &command).await.map_err(stop(0))?;
                    continue;
                }
                Err(e) => return Err(Halt::Stop(0, e)),
            };
            polls += 1;
            if let Some(e) = fault(&st, name, true) {
                return Err(Halt::Stop(0, e));
            }
            let tolerance = self.axis.tolerance;
            if !st.is_moving() {
                if (st.position_deg - target).abs() <= tolerance {
                    debug!(position = st.position_deg, "apt: move done");
                    return Ok(st.position_deg);
                }
                let ended = self.seen.completed.is_some() || self.seen.stopped.is_some();
                if ended || polls >= GRACE_POLLS {
                    let position = st.position_deg;
                    let e = AxisError::TargetNotReached {
                        target,
                        position,
                        tolerance,
                    };
                    return Err(Halt::Stop(0, e));
                }
            }
            if link.now().saturating_sub(start) > allow {
                return Err(overdue("move", target, allow));
            }
        }
    }

    /// `MOT_MOVE_STOP`, then `MOT_MOVE_STOPPED` within the move margin, or else a
    /// status showing the stage still.
    pub(super) async fn stop(&mut self, link: &Link, profiled: bool) -> Result<(), AxisError> {
        self.seen.stopped = None;
        let mode = if profiled {
            StopMode::Profiled
        } else {
            StopMode::Immediate
        };
        self.transmit(link, &Message::MoveStop { chan: 1, mode })
            .await?;
        let until = link.now().saturating_add(self.policy.move_margin);
        let stopped = pick!(Message::MoveStopped { .. } => ());
        match self.receive(link, until, "MOT_MOVE_STOP", stopped).await {
            Err(AxisError::Transport(_)) => {}
            r => return r,
        }
        let st = self.status(link).await?;
        if st.is_moving() {
            let reason = format!("still moving at {} deg", st.position_deg);
            return Err(device("MOT_MOVE_STOP", reason));
        }
        Ok(())
    }

    /// The last move's `MOT_MOVE_COMPLETED`, waited for up to `wait` unless it came.
    pub(super) async fn await_completion(
        &mut self,
        link: &Link,
        wait: Duration,
    ) -> Result<bool, AxisError> {
        if self.seen.completed.is_some() {
            return Ok(true);
        }
        let until = link.now().saturating_add(wait);
        let completed = pick!(Message::MoveCompleted { status, .. } => *status);
        match self
            .receive(link, until, "MOT_MOVE_COMPLETED", completed)
            .await
        {
            Ok(status) => {
                self.completed(status);
                Ok(true)
            }
            Err(AxisError::Transport(_)) => Ok(false),
            Err(e) => Err(e),
        }
    }

    /// `MOT_REQ_POSCOUNTER`, deg.
    pub(super) async fn position(&mut self, link: &Link) -> Result<f64, AxisError> {
        let position = pick!(Message::GetPosCounter { position, .. } => *position);
        let p = self
            .ask(link, Message::ReqPosCounter { chan: 1 }, position)
            .await?;
        Ok(self.stage().to_deg(p))
    }

    /// `MOT_REQ_VELPARAMS`: maximum velocity, deg/s, and acceleration, deg/s².
    pub(super) async fn velocity_params(&mut self, link: &Link) -> Result<(f64, f64), AxisError> {
        let ask = Message::ReqVelParams { chan: 1 };
        let v = self
            .ask(link, ask, pick!(Message::GetVelParams(v) => *v))
            .await?;
        let stage = self.stage();
        Ok((
            stage.velocity_from_apt(v.max_velocity),
            stage.acceleration_from_apt(v.acceleration),
        ))
    }
}

impl Motion for AptSession {
    const FAMILY: &'static str = "apt";
    type Status = AptStatus;
    type AxisError = AxisError;
    type Error = MotionError;

    fn poll_interval(&self) -> Duration {
        self.policy.poll_interval
    }

    fn axis_name(&self, _: usize) -> &str {
        &self.axis.name
    }

    fn at(&self, _: usize, e: AxisError) -> MotionError {
        AptSession::at(self, e)
    }

    async fn poll_status(&mut self, link: &Link, _: usize) -> Result<AptStatus, AxisError> {
        self.status(link).await
    }

    /// A profiled stop.
    async fn stop_every(&mut self, link: &Link) -> Result<(), MotionError> {
        let mode = StopMode::Profiled;
        let sent = self
            .transmit(link, &Message::MoveStop { chan: 1, mode })
            .await;
        sent.map_err(|e| AptSession::at(self, e))
    }

    async fn position_of(&mut self, link: &Link, _: usize) -> Option<f64> {
        self.position(link).await.ok()
    }
}
