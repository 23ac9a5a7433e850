//! The policy that drives one APT controller, as a sans-IO state machine:
//! [`AptSession`].
//!
//! `ops` holds the controller's link policy (a send, a wait for a message that notes
//! completions and status updates on the way, a request asked again after a lost
//! reply) and the operations, each an `async fn` the engine runs.

mod ops;

use std::time::Duration;

use super::message::name_of;
use super::{AptInfo, CHANNEL, DcStatus, Message, StageKind, status};
use crate::engine::motion;
use crate::engine::{Link, Task};
use crate::link::KeepAlive;
use crate::motion::{AxisError, MotionError};
use crate::smc100::ChainPolicy;
use crate::smc100::Halt;

crate::config::axis_config! {
    /// One stage on one APT controller, and how the session may move it.
    pub struct AptAxisConfig {
        /// The axis' name in plans and configs.
        pub name: String,
        /// The stage, which fixes the controller and the unit conversions.
        pub stage: StageKind,
        limits in "deg", commanded by the "session";
        /// Maximum velocity set up, deg/s; the stage's default otherwise.
        velocity;
        /// Acceleration set up, deg/s²; the stage's default otherwise.
        acceleration;
        /// Backlash distance set up, deg; the controller's own when absent.
        #[serde(default)]
        pub backlash_deg: Option<f64>,
        /// Ask the controller for its periodic status updates at set-up
        /// (`HW_START_UPDATEMSGS`).
        #[serde(default)]
        pub status_updates: bool,
        /// Send the "server alive" message (`MOT_ACK_DCSTATUSUPDATE`) every
        /// [`KEEPALIVE_EVERY`] for the whole session ([`AptSession::keepalive`]). The
        /// manual requires it on USB (p. 130); off only to show what a controller does
        /// without it.
        #[serde(default = "default_keepalive")]
        pub keepalive: bool,
    }
}

/// How often the session's keep-alive goes out. The manual asks for one at least
/// once a second on USB (Issue 28, p. 130: otherwise the controller stops sending
/// status messages, move completions included, after about 50 of them); half that
/// leaves room for a second of host work between two waits.
pub const KEEPALIVE_EVERY: Duration = Duration::from_millis(500);

fn default_keepalive() -> bool {
    true
}

impl AptAxisConfig {
    /// A configuration with the defaults, for `stage` between `min` and `max`.
    pub fn new(name: &str, stage: StageKind, min: f64, max: f64) -> Self {
        AptAxisConfig {
            name: name.into(),
            stage,
            min,
            max,
            velocity: None,
            acceleration: None,
            tolerance: crate::config::default_tolerance(),
            home_timeout_s: crate::config::default_home_timeout(),
            backlash_deg: None,
            status_updates: false,
            keepalive: true,
        }
    }

    /// Checks every field; the error names the field and says why.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        let s = self.stage;
        if self.name.trim().is_empty() {
            return Err(("name", "must not be empty".into()));
        }
        if !(self.min.is_finite() && self.max.is_finite() && self.min < self.max) {
            return Err((
                "min",
                format!(
                    "limits [{}, {}] must be finite with min < max",
                    self.min, self.max
                ),
            ));
        }
        if let Some(v) = self.velocity
            && !(v > 0.0 && v <= s.max_velocity())
        {
            let max = s.max_velocity();
            return Err(("velocity", format!("{v} deg/s is outside (0, {max}]")));
        }
        if let Some(a) = self.acceleration
            && !(a > 0.0 && a <= s.max_acceleration())
        {
            let max = s.max_acceleration();
            return Err(("acceleration", format!("{a} deg/s² is outside (0, {max}]")));
        }
        let count = 1.0 / s.counts_per_deg();
        if !(self.tolerance.is_finite() && self.tolerance >= count && self.tolerance <= 10.0) {
            return Err((
                "tolerance",
                format!(
                    "{} deg is outside [{count:.3e}, 10] (one count to 10°)",
                    self.tolerance
                ),
            ));
        }
        if !(self.home_timeout_s.is_finite() && self.home_timeout_s > 0.0) {
            return Err(("home_timeout_s", "must be finite and positive".into()));
        }
        if let Some(b) = self.backlash_deg
            && !(b.is_finite() && b.abs() <= 10.0)
        {
            return Err(("backlash_deg", format!("{b} deg is outside [-10, 10]")));
        }
        Ok(())
    }

    /// The velocity and acceleration the session sets up, deg/s and deg/s².
    pub fn motion(&self) -> (f64, f64) {
        (
            self.velocity.unwrap_or(self.stage.default_velocity()),
            self.acceleration
                .unwrap_or(self.stage.default_acceleration()),
        )
    }
}

/// A channel's status, in degrees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AptStatus {
    /// Position, deg.
    pub position_deg: f64,
    /// The DC status' velocity word, raw (`None` from a stepper). Its scale is not
    /// documented consistently, and the session decides nothing on it.
    pub velocity_raw: Option<i16>,
    /// The status bits ([`status`]).
    pub bits: u32,
}

impl AptStatus {
    /// Moving, jogging or homing.
    pub fn is_moving(&self) -> bool {
        self.bits & status::MOTION != 0
    }

    /// Homed: the position is referenced.
    pub fn is_homed(&self) -> bool {
        self.bits & status::HOMED != 0
    }

    /// The channel is enabled.
    pub fn is_enabled(&self) -> bool {
        self.bits & status::CHANNEL_ENABLED != 0
    }

    /// The fault bits set (limit switches included), by name; empty when none.
    pub fn faults(&self) -> Vec<&'static str> {
        status::describe(self.bits & (status::FAULTS | status::HW_LIMITS))
    }
}

/// What the session has seen arrive unasked since an operation began.
#[derive(Clone, Debug, Default, PartialEq)]
struct Seen {
    completed: Option<Option<DcStatus>>,
    stopped: Option<Option<DcStatus>>,
    homed: bool,
}

/// One single-channel APT controller (a KDC101 with a PRM1-Z8, or a K10CR1) on its
/// own serial line, as a state machine: the stage, the timing and retry policy, and
/// every decision about which message goes out next, what a reply means, when to ask
/// again, answer a status update, reopen the port, stop the stage or give up. It does
/// no I/O and reads no clock.
///
/// Each `start_*` method starts an [`Operation`](crate::link::Operation) that borrows the session until it
/// finishes; lines handed in are whole messages (cut by [`AptFramer`](super::AptFramer)):
///
/// ```
/// use std::time::Duration;
/// use gonio_proto::apt::{AptAxisConfig, AptSession, Message, StageKind};
/// use gonio_proto::link::{Deadline, Io, Operation};
/// use gonio_proto::smc100::ChainPolicy;
///
/// let axis = AptAxisConfig::new("sample_rot", StageKind::Prm1Z8, -170.0, 170.0);
/// let mut session = AptSession::new(axis, ChainPolicy::default()).unwrap();
/// let mut op = session.start_position(Duration::ZERO);
/// assert_eq!(op.poll_io(), Some(Io::Transmit(&[0x11, 0x04, 0x01, 0x00, 0x50, 0x01])));
/// op.handle_sent(Duration::ZERO, Ok(()));
/// assert_eq!(op.poll_timeout(), Some(Deadline::Reply(Duration::from_millis(100))));
/// let reply = Message::GetPosCounter { chan: 1, position: 19196 }.to_bytes();
/// op.handle_line(Duration::from_millis(5), &reply);
/// assert_eq!(op.poll_output(), Some(Ok(19196.0 / 1919.6418)));
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct AptSession {
    axis: AptAxisConfig,
    policy: ChainPolicy,
    retried: u64,
    /// Status updates were asked for (or arrived unasked): a status request is
    /// answered by the next update.
    updates_on: bool,
    updates: u64,
    /// `MOVE_COMPLETED` messages received.
    completions: u64,
    /// Every status-kind message received, by id and data length: what a first day on
    /// the hardware records (the stepper status is 14 bytes on a K10CR1, 28 in the
    /// manual).
    lengths: std::collections::BTreeMap<(u16, usize), u64>,
    seen: Seen,
}

impl AptSession {
    /// A session for `axis`, whose configuration must [`validate`](AptAxisConfig::validate).
    pub fn new(axis: AptAxisConfig, policy: ChainPolicy) -> Result<Self, MotionError> {
        if let Err((field, why)) = axis.validate() {
            return Err(MotionError::Config(format!(
                "axis {:?}: {field}: {why}",
                axis.name
            )));
        }
        Ok(AptSession {
            axis,
            policy,
            retried: 0,
            updates_on: false,
            updates: 0,
            completions: 0,
            lengths: std::collections::BTreeMap::new(),
            seen: Seen::default(),
        })
    }

    /// The axis.
    pub fn axis(&self) -> &AptAxisConfig {
        &self.axis
    }

    /// The timing and retry policy.
    pub fn policy(&self) -> &ChainPolicy {
        &self.policy
    }

    /// Exchanges repeated after a lost, late or garbled reply since the session began.
    pub fn retried(&self) -> u64 {
        self.retried
    }

    /// `MOT_MOVE_COMPLETED` messages received since the session began: one a move on a
    /// controller that keeps talking (they stop without the keep-alive).
    pub fn completions_received(&self) -> u64 {
        self.completions
    }

    /// The status-kind messages received (statuses, completions, homed), by name and
    /// data length in bytes, with their counts, in order of message id.
    pub fn status_lengths(&self) -> Vec<(&'static str, usize, u64)> {
        self.lengths
            .iter()
            .map(|(&(id, len), &n)| (name_of(id).unwrap_or("other"), len, n))
            .collect()
    }

    fn heard(&mut self, m: &Message, data_len: usize) {
        if matches!(
            m,
            Message::GetStatusUpdate(_)
                | Message::GetDcStatusUpdate(_)
                | Message::GetStatusBits { .. }
                | Message::MoveCompleted { .. }
                | Message::MoveStopped { .. }
                | Message::MoveHomed { .. }
        ) {
            *self.lengths.entry((m.id(), data_len)).or_default() += 1;
        }
    }

    /// The message the line must carry for as long as it is open, whatever else is
    /// going on: `MOT_ACK_DCSTATUSUPDATE` every [`KEEPALIVE_EVERY`] (the manual's
    /// "server alive", p. 130), from the start of the session. The pump sends it;
    /// `None` when the axis' `keepalive` is off.
    pub fn keepalive(&self) -> Option<KeepAlive> {
        self.axis.keepalive.then(|| KeepAlive {
            bytes: Message::AckDcStatusUpdate.to_bytes(),
            every: KEEPALIVE_EVERY,
            name: Message::AckDcStatusUpdate.name(),
        })
    }

    /// Status updates that arrived unasked since the session began.
    pub fn updates_received(&self) -> u64 {
        self.updates
    }

    /// Reads the controller's identity (`HW_REQ_INFO`) and checks that its model is
    /// the configured stage's controller.
    pub fn start_identify(&mut self, now: Duration) -> Task<'_, AptInfo, MotionError> {
        self.task("apt.identify", now, Self::identify)
    }

    /// Prepares the channel: `HW_NO_FLASH_PROGRAMMING`, the channel enabled, then the
    /// velocity, home and (when configured) backlash parameters set and each read back
    /// and compared; finally the status updates started when configured.
    pub fn start_setup(&mut self, now: Duration) -> Task<'_, (), MotionError> {
        self.task("apt.setup", now, Self::setup)
    }

    /// Homes the stage (`MOT_MOVE_HOME`) and waits for `MOT_MOVE_HOMED`, or a status
    /// showing the search over and the stage homed, within `home_timeout_s`. The pause
    /// between status polls is an abort point.
    pub fn start_home(&mut self, now: Duration) -> Task<'_, f64, MotionError> {
        motion::task(self, "apt.home", now, Self::home)
    }

    /// Moves to `target_deg` (`MOT_MOVE_ABSOLUTE`, long form), checked against the
    /// limits before any byte, refused when the stage is not homed, and waited for
    /// until `MOT_MOVE_COMPLETED` or a status showing it settled within tolerance; the
    /// final position is the output. An absolute move is idempotent: when its outcome
    /// is lost it is sent again. The pause between polls is an abort point.
    pub fn start_move(&mut self, target_deg: f64, now: Duration) -> Task<'_, f64, MotionError> {
        motion::task(self, "apt.move", now, async move |s, link| {
            s.motion(link, target_deg, false).await
        })
    }

    /// Moves by `delta_deg` from the current position (`MOT_MOVE_RELATIVE`), checked
    /// against the limits first. Never sent twice: a lost outcome is
    /// [`AxisError::Ambiguous`].
    pub fn start_move_by(&mut self, delta_deg: f64, now: Duration) -> Task<'_, f64, MotionError> {
        motion::task(self, "apt.move_by", now, async move |s, link| {
            s.motion(link, delta_deg, true).await
        })
    }

    /// Stops the stage (`MOT_MOVE_STOP`, profiled or immediate) and waits for
    /// `MOT_MOVE_STOPPED` (or a status showing it still).
    pub fn start_stop(&mut self, profiled: bool, now: Duration) -> Task<'_, (), MotionError> {
        self.task("apt.stop", now, async move |s, link| {
            s.stop(link, profiled).await
        })
    }

    /// Waits up to `wait` for the last move's `MOT_MOVE_COMPLETED` when it has not
    /// come yet (a move can end on a settled status before it): `true` once it is in.
    /// Nothing is sent.
    pub fn start_await_completion(
        &mut self,
        wait: Duration,
        now: Duration,
    ) -> Task<'_, bool, MotionError> {
        self.task("apt.await_completion", now, async move |s, link| {
            s.await_completion(link, wait).await
        })
    }

    /// The position counter (`MOT_REQ_POSCOUNTER`), deg.
    pub fn start_position(&mut self, now: Duration) -> Task<'_, f64, MotionError> {
        self.task("apt.position", now, Self::position)
    }

    /// The channel's status (`MOT_REQ_DCSTATUSUPDATE`, or `MOT_REQ_STATUSUPDATE` for a
    /// stepper).
    pub fn start_status(&mut self, now: Duration) -> Task<'_, AptStatus, MotionError> {
        self.task("apt.status", now, Self::status)
    }

    /// The velocity parameters (`MOT_REQ_VELPARAMS`): maximum velocity in deg/s and
    /// acceleration in deg/s².
    pub fn start_velocity_params(&mut self, now: Duration) -> Task<'_, (f64, f64), MotionError> {
        self.task("apt.velocity_params", now, Self::velocity_params)
    }

    /// Runs `op` as the operation `name`, its error on this axis.
    fn task<'a, T: 'a>(
        &'a mut self,
        name: &'static str,
        now: Duration,
        op: impl AsyncFnOnce(&mut Self, &Link) -> Result<T, AxisError> + 'a,
    ) -> Task<'a, T, MotionError> {
        motion::task(self, name, now, async move |s, link| {
            op(s, link).await.map_err(|e| Halt::End(s.at(e)))
        })
    }

    fn at(&self, source: AxisError) -> MotionError {
        MotionError::AtAxis {
            axis: self.axis.name.clone(),
            source,
        }
    }

    fn stage(&self) -> StageKind {
        self.axis.stage
    }

    /// The status request for this stage's drive.
    fn status_request(&self) -> Message {
        if self.stage().is_dc_servo() {
            Message::ReqDcStatusUpdate { chan: 1 }
        } else {
            Message::ReqStatusUpdate { chan: 1 }
        }
    }

    /// A message read as a status, if it is one of this channel's.
    fn status_of(&self, m: &Message) -> Option<AptStatus> {
        let (position, velocity_raw, bits) = match m {
            Message::GetDcStatusUpdate(s) if s.chan == CHANNEL => {
                (s.position, Some(s.velocity), s.bits)
            }
            Message::GetStatusUpdate(s) if s.chan == CHANNEL => (s.position, None, s.bits),
            _ => return None,
        };
        let position_deg = self.stage().to_deg(position);
        Some(AptStatus {
            position_deg,
            velocity_raw,
            bits,
        })
    }

    fn check_limits(&self, target: f64) -> Result<(), AxisError> {
        AxisError::check_limits(target, self.axis.min, self.axis.max, "deg")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stepper_asks_for_the_stepper_status() {
        let s = AptSession::new(
            AptAxisConfig::new("rot", StageKind::K10cr1, 0.0, 90.0),
            ChainPolicy::default(),
        )
        .unwrap();
        assert_eq!(s.status_request(), Message::ReqStatusUpdate { chan: 1 });
        let dc = Message::GetDcStatusUpdate(DcStatus {
            chan: 2,
            position: 0,
            velocity: 0,
            reserved: 0,
            bits: 0,
        });
        // Another channel's status is not this axis'.
        assert_eq!(s.status_of(&dc), None);
        assert!(s.check_limits(90.5).is_err());
        assert!(s.check_limits(f64::NAN).is_err());
        assert_eq!(s.check_limits(45.0), Ok(()));
    }
}
