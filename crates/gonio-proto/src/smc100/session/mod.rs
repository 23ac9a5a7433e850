//! The chain's policy as a sans-IO state machine: [`Smc100Session`].
//!
//! - `wire`: one command on the line, the SMC100's way: a query and its reply (replies
//!   to other commands skipped, a NUL byte is power loss), a set or action checked
//!   with `TE`, a `ZT` dump, the stop of every stage; run by the engine's `exchange`,
//!   with the chain's own reopening of a vanished port;
//! - `ops`: the operations, each an `async fn` the engine runs.

mod ops;
mod wire;

use std::time::Duration;

use super::{
    AxisConfig, AxisError, ChainPolicy, Command, ControllerInfo, Frame, MAX_ADDRESS, MotionError,
    Param, ReplyBody, Smc100Parameters, Status,
};
use crate::engine::motion;
use crate::engine::{Link, Task};
use tracing::debug;

/// A chain of SMC100 controllers on one serial line, as a state machine: the axes,
/// the timing and retry policy, and everything the chain's operations decide: which
/// byte goes out next, what a reply means, when to ask again, reopen the port, stop
/// every stage or give up. It does no I/O and reads no clock.
///
/// Each `start_*` method starts an [`Operation`](crate::link::Operation) that borrows the session until it
/// finishes; its caller hands in bytes, lines, faults and times, and polls out what to
/// do next (see [`Operation`](crate::link::Operation) for the order):
///
/// ```
/// use std::time::Duration;
/// use gonio_proto::link::{Deadline, Io, Operation};
/// use gonio_proto::smc100::{AxisConfig, ChainPolicy, Smc100Session};
///
/// let axis = rotation_stage("source", 1);
/// let mut session = Smc100Session::new(vec![axis], ChainPolicy::default()).unwrap();
/// let mut op = session.start_position("source", Duration::ZERO);
/// assert_eq!(op.poll_io(), Some(Io::Transmit(b"1TP\r\n")));
/// op.handle_sent(Duration::ZERO, Ok(()));
/// assert_eq!(op.poll_timeout(), Some(Deadline::Reply(Duration::from_millis(100))));
/// op.handle_line(Duration::from_millis(12), b"1TP12.5");
/// assert_eq!(op.poll_output(), Some(Ok(12.5)));
/// # fn rotation_stage(name: &str, address: u8) -> AxisConfig {
/// #     AxisConfig { name: name.into(), address, units: "deg".into(), min: -170.0,
/// #         max: 170.0, velocity: None, acceleration: None, tolerance: 0.01,
/// #         home_timeout_s: 60.0 }
/// # }
/// ```
///
/// `gonio_driver::smc100::Smc100Chain` is the pump that runs these operations over a
/// serial port.
#[derive(Clone, Debug, PartialEq)]
pub struct Smc100Session {
    axes: Vec<AxisConfig>,
    policy: ChainPolicy,
    retried: u64,
    /// When the last move was seen to have ended: the arrival of the status reply
    /// that found its last stage READY (`None` until a move ends).
    stopped: Option<Duration>,
}

impl Smc100Session {
    /// A session for `axes`. Axes must have distinct names and addresses 1–31, and
    /// finite limits with `min < max`.
    pub fn new(axes: Vec<AxisConfig>, policy: ChainPolicy) -> Result<Self, MotionError> {
        for (i, a) in axes.iter().enumerate() {
            if !(1..=MAX_ADDRESS).contains(&a.address) {
                return Err(MotionError::Config(format!(
                    "axis {:?}: address {} is outside 1..=31",
                    a.name, a.address
                )));
            }
            if !(a.min.is_finite() && a.max.is_finite() && a.min < a.max) {
                return Err(MotionError::Config(format!(
                    "axis {:?}: limits [{}, {}] must be finite with min < max",
                    a.name, a.min, a.max
                )));
            }
            if let Some(b) = axes[..i]
                .iter()
                .find(|b| b.name == a.name || b.address == a.address)
            {
                return Err(MotionError::Config(format!(
                    "axes {:?} and {:?} share a name or the address {}",
                    b.name, a.name, a.address
                )));
            }
        }
        Ok(Smc100Session {
            axes,
            policy,
            retried: 0,
            stopped: None,
        })
    }

    /// The axes, in configuration order.
    pub fn axes(&self) -> &[AxisConfig] {
        &self.axes
    }

    /// The timing and retry policy.
    pub fn policy(&self) -> &ChainPolicy {
        &self.policy
    }

    /// Exchanges sent again after a lost, late or garbled reply since the session was
    /// made: what a run log reports as retries.
    pub fn retried(&self) -> u64 {
        self.retried
    }

    /// When the last move (`start_move`, `start_move_by`) was seen to have ended: the
    /// arrival of the status reply that found its last stage READY, before the
    /// positions are read back. Every stage has stopped by then, so what depends on
    /// where the stages stand (the light on a detector) holds from this instant on.
    /// `None` while a move runs, after one that failed, and before the first.
    pub fn stopped_at(&self) -> Option<Duration> {
        self.stopped
    }

    /// Reads every controller's version, stage name and state (`VE`, `ID?`, `TS`).
    pub fn start_identify(&mut self, now: Duration) -> Task<'_, Vec<ControllerInfo>, MotionError> {
        Task::run("smc100.identify", now, self, Self::identify)
    }

    /// The named axis' status (`TS`).
    pub fn start_status(&mut self, name: &str, now: Duration) -> Task<'_, Status, MotionError> {
        self.on_axis("smc100.status", name, now, Self::read_status)
    }

    /// The named axis' encoder position (`TP`), units.
    pub fn start_position(&mut self, name: &str, now: Duration) -> Task<'_, f64, MotionError> {
        self.on_axis("smc100.position", name, now, async |s, link, i| {
            s.read_number(link, i, Command::TellPosition).await
        })
    }

    /// How long the named axis' controller says a move of `distance` units takes with
    /// its working velocity, acceleration and jerk time (`PT`, manual p. 43: "The
    /// controller does not execute any motion"), s.
    pub fn start_motion_time(
        &mut self,
        name: &str,
        distance: f64,
        now: Duration,
    ) -> Task<'_, f64, MotionError> {
        let pt = Command::MotionTime(distance.abs());
        self.on_axis("smc100.motion_time", name, now, async |s, link, i| {
            s.read_number(link, i, pt).await
        })
    }

    /// Stops every stage: the broadcast `ST`, then each controller's own `ST` if the
    /// broadcast could not be sent. Every stage gets its stop; the first failure is
    /// returned.
    pub fn start_stop_all(&mut self, now: Duration) -> Task<'_, (), MotionError> {
        Task::run("smc100.stop_all", now, self, Self::stop_all)
    }

    /// Stops one stage (`ST`, then `TE`).
    pub fn start_stop(&mut self, name: &str, now: Duration) -> Task<'_, (), MotionError> {
        self.on_axis("smc100.stop", name, now, async |s, link, i| {
            s.command(link, i, Command::Stop).await
        })
    }

    /// Brings the named axes to READY with a reference: a home search (`OR`) from NOT
    /// REFERENCED, `MM1` from DISABLE, nothing when already READY; then applies the
    /// configured velocity and acceleration. Home searches run concurrently; the wait
    /// between status polls is an abort point.
    pub fn start_home(&mut self, names: &[&str], now: Duration) -> Task<'_, (), MotionError> {
        let names: Vec<String> = names.iter().map(|n| n.to_string()).collect();
        motion::task(self, "smc100.home", now, async move |s, link| {
            s.home(link, &names, false).await
        })
    }

    /// Homes every axis.
    pub fn start_home_all(&mut self, now: Duration) -> Task<'_, (), MotionError> {
        let names: Vec<String> = self.axes.iter().map(|a| a.name.clone()).collect();
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        self.start_home(&refs, now)
    }

    /// Resets the named controller (`RS`), waits for it to come back NOT REFERENCED
    /// (power-up takes under 5 s; 10 s are allowed), and homes it: the recovery after
    /// [`AxisError::ControllerReset`] or a fault that only a reset clears.
    pub fn start_reset_and_home(&mut self, name: &str, now: Duration) -> Task<'_, (), MotionError> {
        let names = vec![name.to_string()];
        motion::task(self, "smc100.reset_and_home", now, async move |s, link| {
            s.home(link, &names, true).await
        })
    }

    /// Moves the named axes to absolute targets, concurrently, and waits until every
    /// one is READY at its target; the positions read at the end are the output. Every
    /// target is checked against its axis' limits before any byte is sent. The wait
    /// between status polls is an abort point.
    pub fn start_move(
        &mut self,
        targets: &[(&str, f64)],
        now: Duration,
    ) -> Task<'_, Vec<f64>, MotionError> {
        let targets: Vec<(String, f64)> =
            targets.iter().map(|(n, t)| (n.to_string(), *t)).collect();
        motion::task(self, "smc100.move", now, async move |s, link| {
            s.move_to(link, &targets).await
        })
    }

    /// Moves one axis by `delta` from its current target (`PR`), checked against the
    /// limits from the set-point (`TH`). A relative move is never re-sent: a lost
    /// acknowledgement is [`AxisError::Ambiguous`].
    pub fn start_move_by(
        &mut self,
        name: &str,
        delta: f64,
        now: Duration,
    ) -> Task<'_, f64, MotionError> {
        let name = name.to_string();
        motion::task(self, "smc100.move_by", now, async move |s, link| {
            s.move_by(link, &name, delta).await
        })
    }

    /// Reads the named controller's configuration: `ZT`, and its dump up to `PW0`
    /// (manual, ZT command; accepted in every state but while it saves). The dump is
    /// read again, whole, after a lost or garbled line.
    pub fn start_read_config(
        &mut self,
        name: &str,
        now: Duration,
    ) -> Task<'_, Smc100Parameters, MotionError> {
        self.on_axis("smc100.read_config", name, now, async |s, link, i| {
            let params = s.dump(link, i).await?;
            debug!(axis = %s.axes[i].name, stage = %params.stage, "smc100: configuration read");
            Ok(params)
        })
    }

    /// Changes and saves the named controller's configuration (manual, PW command):
    /// from NOT REFERENCED, `PW1`; each change set and checked with `TE`; `PW0`, which
    /// saves to the controller's memory while it answers nothing (up to 10 s); `TS`
    /// polled until NOT REFERENCED (15 s at most), and `TE` for the save's own error.
    ///
    /// Every change is checked first ([`Param::is_configuration`], [`Param::accepts`]):
    /// one the controller would refuse is [`AxisError::InvalidSetting`] and nothing is
    /// sent. A controller in READY, DISABLE or moving is refused with
    /// [`AxisError::WrongState`]: the manual allows `PW1` only from NOT REFERENCED, and
    /// getting there takes `RS`, which loses the reference, so it is left to the
    /// caller. One already in CONFIGURATION is taken as it is. If the controller
    /// refuses a set, the operation still leaves with `PW0` (the only way out; `RS` is
    /// refused in CONFIGURATION), so the sets before the refused one are saved, and
    /// returns the refusal. The stage stays NOT REFERENCED: home it before moving.
    pub fn start_configure(
        &mut self,
        name: &str,
        changes: &[(Param, f64)],
        now: Duration,
    ) -> Task<'_, (), MotionError> {
        let changes = changes.to_vec();
        self.on_axis("smc100.configure", name, now, async move |s, link, i| {
            s.configure(link, i, &changes).await
        })
    }

    /// Runs `op` on the axis named `axis` as the operation `name`, its failure
    /// reported at that axis.
    fn on_axis<'a, T: 'a>(
        &'a mut self,
        name: &'static str,
        axis: &str,
        now: Duration,
        op: impl AsyncFnOnce(&mut Self, &Link, usize) -> Result<T, AxisError> + 'a,
    ) -> Task<'a, T, MotionError> {
        let axis = axis.to_string();
        Task::run(name, now, self, async move |s, link| {
            s.on(&axis, async |s, i| op(s, link, i).await).await
        })
    }

    fn index(&self, name: &str) -> Result<usize, MotionError> {
        self.axes
            .iter()
            .position(|a| a.name == name)
            .ok_or_else(|| MotionError::UnknownAxis(name.to_string()))
    }

    fn at(&self, i: usize, source: AxisError) -> MotionError {
        MotionError::AtAxis {
            axis: self.axes[i].name.clone(),
            source,
        }
    }

    fn frame(&self, i: usize, command: Command) -> Frame {
        Frame::addressed(self.axes[i].address, command)
    }

    fn check_limits(&self, i: usize, target: f64) -> Result<(), AxisError> {
        let a = &self.axes[i];
        AxisError::check_limits(target, a.min, a.max, &a.units)
    }

    /// A reply read as a status (`TS`).
    fn status(&self, i: usize, r: Result<ReplyBody, AxisError>) -> Result<Status, AxisError> {
        match r? {
            ReplyBody::Status(s) => Ok(s),
            other => Err(self.unexpected(i, "TS", other, "not a status")),
        }
    }

    /// A reply to axis `i`'s `code` of another kind than asked.
    fn unexpected(&self, i: usize, code: &str, reply: ReplyBody, reason: &str) -> AxisError {
        AxisError::Protocol {
            sent: format!("{}{code}", self.axes[i].address),
            reply: format!("{reply:?}"),
            reason: reason.into(),
        }
    }
}

/// A line as text, terminator removed.
fn line_text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes)
        .trim_end_matches(['\r', '\n'])
        .to_string()
}
