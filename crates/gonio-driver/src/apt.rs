//! One Thorlabs APT controller (a KDC101 K-Cube with its stage, or a K10CR1 rotation
//! mount) on its own USB serial line.
//!
//! [`AptAxis`] owns the transport, the clock and the controller's session
//! ([`gonio_proto::apt::AptSession`]); each method starts an operation on the session
//! and pumps it. The policy is the session's: soft limits checked before any byte,
//! completion by `MOVE_COMPLETED` or a settled status, re-sends of what may be
//! repeated only, and a stop on any fault or abort. The session's keep-alive (the
//! manual's "server alive", at least once a second) goes into the axis'
//! [`Heartbeat`], which sends it through every wait of every line of the instrument
//! once the axis joins one. Dropping the axis stops the stage.

use gonio_proto::apt::AptSession;
pub use gonio_proto::apt::{AptAxisConfig, AptInfo, AptStatus, StageKind};
use gonio_proto::motion::MotionError;
use gonio_proto::smc100::ChainPolicy;
use tracing::debug_span;

use crate::clock::Clock;
use crate::heartbeat::{Heartbeat, SharedLink};
use crate::pump::{AbortFlag, Mapped, Slot, pump, pumped};
use crate::transport::Transport;

/// The framing and link settings every APT controller uses: 115 200 baud, 8N1,
/// RTS/CTS (the manual's "USB Virtual COM port" set-up).
pub const BAUD: u32 = gonio_proto::apt::timing::BAUD;

/// One APT controller with its stage.
pub struct AptAxis<T: Transport, C: Clock> {
    /// Shared with the heartbeat, which writes the keep-alive between exchanges.
    transport: SharedLink<T>,
    clock: C,
    beats: Heartbeat,
    session: AptSession,
    abort: AbortFlag,
    port: String,
    /// The serial number the config expects, checked at [`identify`](Self::identify).
    serial: Option<u32>,
}

impl<T: Transport, C: Clock> std::fmt::Debug for AptAxis<T, C> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AptAxis")
            .field("port", &self.port)
            .field("axis", self.session.axis())
            .finish()
    }
}

/// Runs one operation of the axis' session over its transport.
macro_rules! run {
    ($a:ident, $start:ident($($arg:expr),*)) => {{
        let now = $a.clock.now();
        let op = $a.session.$start($($arg,)* now);
        pump(pumped!($a), Some(&$a.abort), op)
    }};
}

impl<T: Transport + 'static, C: Clock> AptAxis<T, C> {
    /// An axis over `transport`; `serial`, when given, must be the controller's.
    pub fn new(
        transport: T,
        clock: C,
        axis: AptAxisConfig,
        policy: ChainPolicy,
        serial: Option<u32>,
    ) -> Result<Self, MotionError> {
        let session = AptSession::new(axis, policy)?;
        let port = transport.name();
        let transport = SharedLink::new(transport);
        let beats = Heartbeat::new();
        if let Some(duty) = session.keepalive() {
            beats.add(&port, Box::new(transport.clone()), duty);
        }
        Ok(AptAxis {
            transport,
            clock,
            beats,
            session,
            abort: AbortFlag::new(),
            port,
            serial,
        })
    }

    /// The heartbeat the axis' waits keep beating (its own keep-alive among them).
    pub fn heartbeat(&self) -> &Heartbeat {
        &self.beats
    }

    /// Joins `beats`, an instrument's heartbeat: the axis' keep-alive moves into it,
    /// and the axis' waits keep every line's beating.
    pub fn set_heartbeat(&mut self, beats: Heartbeat) {
        beats.absorb(&self.beats);
        self.beats = beats;
    }

    /// The axis with `flag` as its abort flag.
    pub fn with_abort_flag(mut self, flag: AbortFlag) -> Self {
        self.abort = flag;
        self
    }

    /// Makes `flag` the axis's abort flag.
    pub fn set_abort_flag(&mut self, flag: AbortFlag) {
        self.abort = flag;
    }

    /// The axis' configuration.
    pub fn axis(&self) -> &AptAxisConfig {
        self.session.axis()
    }

    /// Exchanges re-sent after a lost or garbled reply.
    pub fn retried(&self) -> u64 {
        self.session.retried()
    }

    /// `MOT_MOVE_COMPLETED` messages received since the axis was built.
    pub fn completions_received(&self) -> u64 {
        self.session.completions_received()
    }

    /// The status-kind messages received, by name and data length, with their counts.
    pub fn status_lengths(&self) -> Vec<(&'static str, usize, u64)> {
        self.session.status_lengths()
    }

    /// `HW_REQ_INFO`: the controller's identity (its model must drive the configured
    /// stage, and its serial number must be the configured one), then the set-up
    /// (channel enabled, velocity, home and backlash parameters written and read
    /// back). Nothing moves.
    pub fn identify(&mut self) -> Result<AptInfo, MotionError> {
        let name = self.session.axis().name.clone();
        let _span = debug_span!("apt.identify", port = %self.port, axis = %name).entered();
        let info = run!(self, start_identify())?;
        if let Some(want) = self.serial
            && info.serial != want
        {
            return Err(MotionError::AtAxis {
                axis: name,
                source: gonio_proto::motion::AxisError::Device {
                    command: "HW_REQ_INFO".into(),
                    reason: format!(
                        "serial number {} answered where the config expects {want} (cables swapped?)",
                        info.serial
                    ),
                },
            });
        }
        run!(self, start_setup())?;
        Ok(info)
    }

    /// Status: position, homed, moving, limit and fault bits.
    pub fn status(&mut self) -> Result<AptStatus, MotionError> {
        let _span = debug_span!("apt.status", port = %self.port).entered();
        run!(self, start_status())
    }

    /// Position, deg.
    pub fn position(&mut self) -> Result<f64, MotionError> {
        let _span = debug_span!("apt.position", port = %self.port).entered();
        run!(self, start_position())
    }

    /// Homes the stage (`MOVE_HOME` → `MOVE_HOMED`).
    pub fn home(&mut self) -> Result<f64, MotionError> {
        let _span = debug_span!("apt.home", port = %self.port).entered();
        run!(self, start_home())
    }

    /// Moves to `target` deg; returns where the stage ended.
    pub fn move_to(&mut self, target: f64) -> Result<f64, MotionError> {
        let _span = debug_span!("apt.move", port = %self.port, target).entered();
        run!(self, start_move(target))
    }

    /// Moves by `delta` deg; never re-sent.
    pub fn move_by(&mut self, delta: f64) -> Result<f64, MotionError> {
        let _span = debug_span!("apt.move_by", port = %self.port, delta).entered();
        run!(self, start_move_by(delta))
    }

    /// Stops the stage: profiled (decelerating) or immediate.
    pub fn stop(&mut self, profiled: bool) -> Result<(), MotionError> {
        let _span = debug_span!("apt.stop", port = %self.port, profiled).entered();
        let now = self.clock.now();
        let op = self.session.start_stop(profiled, now);
        // A stop is never itself aborted.
        pump(pumped!(self), None, op)
    }

    /// Waits up to `wait` for the last move's `MOT_MOVE_COMPLETED` if it has not come
    /// yet; `true` once it is in.
    pub fn await_completion(&mut self, wait: std::time::Duration) -> Result<bool, MotionError> {
        let _span = debug_span!("apt.await_completion", port = %self.port).entered();
        run!(self, start_await_completion(wait))
    }

    /// The velocity and acceleration the controller holds, deg/s and deg/s².
    pub fn velocity_params(&mut self) -> Result<(f64, f64), MotionError> {
        let _span = debug_span!("apt.velocity_params", port = %self.port).entered();
        run!(self, start_velocity_params())
    }

    /// A move to `target`, started but not pumped: one slot of a concurrent move.
    pub(crate) fn move_slot(&mut self, target: f64) -> Slot<'_, Result<Vec<f64>, MotionError>> {
        let now = self.clock.now();
        let op = Mapped::new(self.session.start_move(target, now), |r: Result<f64, _>| {
            r.map(|p| vec![p])
        });
        (&mut self.transport, self.port.as_str(), Box::new(op))
    }
}

impl<T: Transport, C: Clock> Drop for AptAxis<T, C> {
    fn drop(&mut self) {
        // An axis going away must not leave its stage moving.
        let now = self.clock.now();
        let op = self.session.start_stop(true, now);
        let _ = pump(pumped!(self), None, op);
    }
}
