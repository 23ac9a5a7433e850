//! A chain of Newport SMC100 controllers on one serial line, one rotation stage each.
//!
//! [`Smc100Chain`] owns the transport, the clock and the chain's session
//! ([`gonio_proto::smc100::Smc100Session`]), and each of its methods starts an
//! operation on the session and pumps it. The policy is the session's:
//! - every set or action command is followed by `TE`, and a letter other than `@` is a
//!   typed [`AxisError::Controller`];
//! - soft limits are checked before any byte of a move goes out, so no plan can move a
//!   stage outside them;
//! - moves complete by polling `TS` until READY; DISABLE, NOT REFERENCED, a vanished
//!   port or a deadline stop every stage and return the cause;
//! - only idempotent commands are re-sent after a lost reply: an absolute move may be,
//!   a relative move never (its fate is reported as [`AxisError::Ambiguous`]);
//! - a reply line with a NUL byte means the controller lost power; the state `0A`
//!   mid-run means it was reset; both are errors, and [`Smc100Chain::home`] recovers;
//! - dropping the chain, or raising its [`AbortFlag`], stops every stage;
//! - the configuration is read with `ZT` ([`Smc100Chain::read_config`]) and changed in
//!   CONFIGURATION, from NOT REFERENCED only ([`Smc100Chain::configure`]).

/// What a move, a home search and the identification cost on the wire.
pub use gonio_proto::smc100::timing;
pub use gonio_proto::smc100::{
    AxisConfig, AxisError, ChainPolicy, ControllerInfo, MotionError, Param, Smc100Parameters,
    describe_errors,
};
use gonio_proto::smc100::{Smc100Session, Status};
use tracing::debug_span;

use crate::clock::Clock;
use crate::heartbeat::Heartbeat;
pub use crate::pump::AbortFlag;
use crate::pump::{Slot, pump, pumped};
use crate::transport::Transport;

/// A chain of SMC100 controllers sharing one serial line.
pub struct Smc100Chain<T: Transport, C: Clock> {
    transport: T,
    clock: C,
    /// The instrument's heartbeat, kept beating through every wait.
    beats: Heartbeat,
    session: Smc100Session,
    abort: AbortFlag,
    /// The port's name, for the wire log.
    port: String,
}

impl<T: Transport, C: Clock> std::fmt::Debug for Smc100Chain<T, C> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Smc100Chain")
            .field("port", &self.transport.name())
            .field("axes", &self.session.axes())
            .finish()
    }
}

/// Runs one operation of the chain's session: starts it with `$start` (a method of
/// the session, given the clock's now) and pumps it over the chain's transport.
macro_rules! run {
    ($chain:ident, $start:ident($($arg:expr),*)) => {{
        let now = $chain.clock.now();
        let op = $chain.session.$start($($arg,)* now);
        pump(pumped!($chain), Some(&$chain.abort), op)
    }};
}

impl<T: Transport, C: Clock> Smc100Chain<T, C> {
    /// A chain over `transport`. Axes must have distinct names and addresses 1–31, and
    /// `min < max`.
    pub fn new(
        transport: T,
        clock: C,
        axes: Vec<AxisConfig>,
        policy: ChainPolicy,
    ) -> Result<Self, MotionError> {
        let session = Smc100Session::new(axes, policy)?;
        let port = transport.name();
        Ok(Smc100Chain {
            transport,
            clock,
            beats: Heartbeat::new(),
            session,
            abort: AbortFlag::new(),
            port,
        })
    }

    /// Joins `beats`, the instrument's heartbeat: every wait of this device keeps the
    /// instrument's keep-alives going.
    pub fn set_heartbeat(&mut self, beats: Heartbeat) {
        beats.absorb(&self.beats);
        self.beats = beats;
    }

    /// The flag that aborts waits; clone it to raise it from elsewhere.
    pub fn abort_flag(&self) -> AbortFlag {
        self.abort.clone()
    }

    /// The chain with `flag` as its abort flag: a motion system of several lines
    /// shares one.
    pub fn with_abort_flag(mut self, flag: AbortFlag) -> Self {
        self.abort = flag;
        self
    }

    /// Makes `flag` the chain's abort flag.
    pub fn set_abort_flag(&mut self, flag: AbortFlag) {
        self.abort = flag;
    }

    /// A move of the chain's axes among `targets`, started but not pumped: one slot of
    /// a concurrent move over several lines.
    pub(crate) fn move_slot<'a>(
        &'a mut self,
        targets: &[(&str, f64)],
    ) -> Slot<'a, Result<Vec<f64>, MotionError>> {
        let now = self.clock.now();
        let op = self.session.start_move(targets, now);
        (&mut self.transport, self.port.as_str(), Box::new(op))
    }

    /// Exchanges sent again after a lost, late or garbled reply since the chain was
    /// built: what a run log reports as retries.
    pub fn retried(&self) -> u64 {
        self.session.retried()
    }

    /// When the last move was seen to have ended (the status reply that found its last
    /// stage READY, before the positions were read back); `None` before the first and
    /// after one that failed.
    pub fn stopped_at(&self) -> Option<std::time::Duration> {
        self.session.stopped_at()
    }

    /// The axes, in configuration order.
    pub fn axes(&self) -> &[AxisConfig] {
        self.session.axes()
    }

    /// The clock the chain waits on.
    pub fn clock(&self) -> &C {
        &self.clock
    }

    /// Status of the named axis (`TS`).
    pub fn status(&mut self, name: &str) -> Result<Status, MotionError> {
        let _span = debug_span!("smc100.status", port = %self.port, axis = name).entered();
        run!(self, start_status(name))
    }

    /// Encoder position of the named axis (`TP`), units.
    pub fn position(&mut self, name: &str) -> Result<f64, MotionError> {
        let _span = debug_span!("smc100.position", port = %self.port, axis = name).entered();
        run!(self, start_position(name))
    }

    /// Reads every controller's version, stage name and state (`VE`, `ID?`, `TS`):
    /// what Gonio sends at start-up. Proves each address answers.
    pub fn identify(&mut self) -> Result<Vec<ControllerInfo>, MotionError> {
        let _span = debug_span!("smc100.identify", port = %self.port).entered();
        run!(self, start_identify())
    }

    /// Stops every stage: the broadcast `ST`, then each controller's own `ST` if the
    /// broadcast could not be sent. Errors are collected, not early-returned: every
    /// stage gets its stop.
    pub fn stop_all(&mut self) -> Result<(), MotionError> {
        let _span = debug_span!("smc100.stop_all", port = %self.port).entered();
        run!(self, start_stop_all())
    }

    /// Stops one stage (`ST`, then `TE`).
    pub fn stop(&mut self, name: &str) -> Result<(), MotionError> {
        let _span = debug_span!("smc100.stop", port = %self.port, axis = name).entered();
        run!(self, start_stop(name))
    }

    /// Brings the named axes to READY with a reference: a home search (`OR`) from NOT
    /// REFERENCED, `MM1` from DISABLE, nothing when already READY; then applies the
    /// configured velocity and acceleration. Home searches run concurrently.
    pub fn home(&mut self, names: &[&str]) -> Result<(), MotionError> {
        let _span = debug_span!("smc100.home", port = %self.port, axes = ?names).entered();
        run!(self, start_home(names))
    }

    /// Homes every axis.
    pub fn home_all(&mut self) -> Result<(), MotionError> {
        let _span = debug_span!("smc100.home", port = %self.port, axes = "all").entered();
        run!(self, start_home_all())
    }

    /// Moves the named axes to absolute targets, concurrently, and waits until every
    /// one is READY at its target. Every target is checked against its axis' limits
    /// before any byte is sent. Returns the positions read at the end.
    pub fn move_to(&mut self, targets: &[(&str, f64)]) -> Result<Vec<f64>, MotionError> {
        let _span = debug_span!("smc100.move", port = %self.port, targets = ?targets).entered();
        run!(self, start_move(targets))
    }

    /// Moves one axis by `delta` from its current target (`PR`). Checked against the
    /// limits from the set-point (`TH`); never re-sent.
    pub fn move_by(&mut self, name: &str, delta: f64) -> Result<f64, MotionError> {
        let _span = debug_span!("smc100.move_by", port = %self.port, axis = name, delta).entered();
        run!(self, start_move_by(name, delta))
    }

    /// How long the controller says a move of `distance` units of the named axis takes
    /// (`PT`), s; nothing moves.
    pub fn motion_time(&mut self, name: &str, distance: f64) -> Result<f64, MotionError> {
        let _span = debug_span!("smc100.motion_time", port = %self.port, axis = name).entered();
        run!(self, start_motion_time(name, distance))
    }

    /// Reads the named controller's configuration (`ZT`, its dump up to its closing
    /// line): the stage name and every parameter, in the dump's order.
    pub fn read_config(&mut self, name: &str) -> Result<Smc100Parameters, MotionError> {
        let _span = debug_span!("smc100.read_config", port = %self.port, axis = name).entered();
        run!(self, start_read_config(name))
    }

    /// Changes and saves the named controller's configuration: `PW1`, each change set
    /// and checked with `TE`, `PW0`, and the wait while the controller saves (up to
    /// 10 s, silent). Only from NOT REFERENCED (a READY controller is
    /// [`AxisError::WrongState`]: the manual needs `RS` first, which loses the
    /// reference); a change the controller would refuse is
    /// [`AxisError::InvalidSetting`] before any byte. The stage is NOT REFERENCED
    /// afterwards: home it before moving. See
    /// [`Smc100Session::start_configure`](gonio_proto::smc100::Smc100Session::start_configure).
    pub fn configure(&mut self, name: &str, changes: &[(Param, f64)]) -> Result<(), MotionError> {
        let _span =
            debug_span!("smc100.configure", port = %self.port, axis = name, changes = ?changes)
                .entered();
        run!(self, start_configure(name, changes))
    }

    /// Resets the named controller (`RS`), waits for it to come back NOT REFERENCED
    /// from reset (power-up takes < 5 s), and homes it: the recovery after
    /// [`AxisError::ControllerReset`] or a fault that only a reset clears.
    pub fn reset_and_home(&mut self, name: &str) -> Result<(), MotionError> {
        let _span = debug_span!("smc100.reset_and_home", port = %self.port, axis = name).entered();
        run!(self, start_reset_and_home(name))
    }
}

impl<T: Transport, C: Clock> Drop for Smc100Chain<T, C> {
    fn drop(&mut self) {
        // A chain going away must not leave a stage moving.
        let _ = self.stop_all();
    }
}
