//! The SR830 lock-in amplifier as Gonio's detector: set-up, settled and averaged
//! readings, autoranging, and recovery from a lost port.
//!
//! [`Sr830`] owns the transport, the clock and the lock-in's session
//! ([`gonio_proto::sr830::Sr830Session`]); each method starts an operation on the
//! session and pumps it. The policy is the session's:
//!
//! [`Sr830::setup`] takes the RS-232 link (`OUTX 0` must come first: replies go to GPIB
//! by default), checks the identity, clears the status bytes, applies the configured
//! sensitivity, time constant and slope, and checks `*ESR?` for refused commands.
//! [`Sr830::read`] then returns a [`Reading`]:
//!
//! 1. wait until the filters have settled (settle factor × time constant after the last
//!    change of sensitivity, time constant or slope; table p. 3-21);
//! 2. `LIAS?` once, to clear the overload bits latched while settling;
//! 3. `SNAP? 1,2` N times, one time constant apart (X and Y at one instant;
//!    R = hypot(X, Y) per sample);
//! 4. `LIAS?` again: every bit set during the samples becomes a [`ReadingFlags`] flag.
//!
//! With autoranging, an input or output overload steps one range less sensitive and
//! reads again; a clean reading whose mean R is under `min_fraction` of full scale
//! steps one range more sensitive and reads again. A reading that cannot be cured (an
//! overload at 1 V, a reference unlock, a filter overload) is returned flagged, never as
//! valid; more than [`MAX_AUTORANGE_STEPS`] range changes in one read is an error.
//!
//! Every wait goes through the [`Clock`], so tests run on virtual time.

use std::time::Duration;

/// Autoranging's rules, and what they make of a steady signal.
pub use gonio_proto::sr830::ranging;
/// Reading to a precision target: the transient fit, the sequential rule, the time
/// estimates.
pub use gonio_proto::sr830::target;
/// What the set-up and a reading's cycle cost on the wire.
pub use gonio_proto::sr830::timing;
use gonio_proto::sr830::{
    Command, EventStatus, FilterSlope, Identity, LiaStatus, Reply, Sr830Session, TimeConstant,
};
pub use gonio_proto::sr830::{
    ConfigError, MAX_AUTORANGE_STEPS, ReadTarget, Reading, ReadingFlags, Sensitivity, Sr830Config,
    Sr830Error,
};
use target::floor_sigma;
use tracing::debug_span;

use crate::clock::Clock;
use crate::heartbeat::Heartbeat;
use crate::pump::{pump, pumped};
use crate::transport::Transport;

/// The SR830 on a transport, waiting on a clock.
#[derive(Debug)]
pub struct Sr830<T: Transport, C: Clock> {
    transport: T,
    clock: C,
    /// The instrument's heartbeat, kept beating through every wait.
    beats: Heartbeat,
    session: Sr830Session,
    /// The port's name, for the wire log.
    port: String,
}

/// Runs one operation of the lock-in's session: starts it with `$start` (a method of
/// the session, given the clock's now) and pumps it over the transport.
macro_rules! run {
    ($d:ident, $start:ident($($arg:expr),*)) => {{
        let now = $d.clock.now();
        let op = $d.session.$start($($arg,)* now);
        pump(pumped!($d), None, op)
    }};
}

impl<T: Transport, C: Clock> Sr830<T, C> {
    /// A driver for the SR830 on `transport`; nothing is sent until [`setup`](Self::setup).
    /// Fails if `config` does not [`validate`](Sr830Config::validate).
    pub fn new(transport: T, clock: C, config: Sr830Config) -> Result<Self, Sr830Error> {
        let port = transport.name();
        let session = Sr830Session::new(config, port.clone(), clock.now())?;
        Ok(Sr830 {
            transport,
            clock,
            beats: Heartbeat::new(),
            session,
            port,
        })
    }

    /// Joins `beats`, the instrument's heartbeat: every wait of this device keeps the
    /// instrument's keep-alives going.
    pub fn set_heartbeat(&mut self, beats: Heartbeat) {
        beats.absorb(&self.beats);
        self.beats = beats;
    }

    /// Takes the link and applies the configuration: `OUTX 0`, `*IDN?` (must be an
    /// SR830), `*CLS`, `SENS`, `OFLT`, `OFSL`, then `*ESR?`, whose reply also proves
    /// every earlier command has run. Starts the settling wait.
    pub fn setup(&mut self) -> Result<Identity, Sr830Error> {
        let c = self.session.config();
        let _span = debug_span!(
            "sr830.setup",
            port = %self.port,
            sensitivity = %c.sensitivity,
            time_constant = %c.time_constant,
            slope = %c.slope,
        )
        .entered();
        run!(self, start_setup())
    }

    /// One averaged reading; see the module docs for the sequence and autoranging.
    /// Faults are errors; an overloaded or unlocked reading is returned flagged.
    pub fn read(&mut self) -> Result<Reading, Sr830Error> {
        let _span = debug_span!(
            "sr830.read",
            port = %self.port,
            sensitivity = %self.session.sensitivity(),
            time_constant = %self.session.time_constant(),
            samples = self.session.config().samples,
        )
        .entered();
        run!(self, start_read())
    }

    /// One reading to `target`, the signal expected about `expected` V (for the time
    /// constant); see [`gonio_proto::sr830::Sr830Session::start_read_targeted`].
    pub fn read_targeted(
        &mut self,
        target: &ReadTarget,
        expected: Option<f64>,
    ) -> Result<Reading, Sr830Error> {
        let _span = debug_span!(
            "sr830.read_targeted",
            port = %self.port,
            sensitivity = %self.session.sensitivity(),
            sigma_relative = target.sigma_relative,
            sigma_absolute = target.sigma_absolute,
            expected,
        )
        .entered();
        run!(self, start_read_targeted(*target, expected))
    }

    /// The absolute floor of a target without one: the precision the cap allows on
    /// the dimmest signal, by the configured noise law
    /// ([`gonio_proto::sr830::target::floor_sigma`]); `None` without a law.
    pub fn target_floor(&self, target: &ReadTarget) -> Option<f64> {
        let c = self.session.config();
        let noise = c.noise.as_ref()?;
        floor_sigma(
            target,
            noise,
            self.session.slope(),
            &c.time_constant_choices(),
            c.exchange_s,
        )
    }

    /// Sets the sensitivity (`SENS`); readings wait for the filters to settle again.
    pub fn set_sensitivity(&mut self, s: Sensitivity) -> Result<(), Sr830Error> {
        let _span = debug_span!("sr830.set_sensitivity", port = %self.port, to = %s).entered();
        run!(self, start_set_sensitivity(s))
    }

    /// Sets the time constant (`OFLT`); readings wait for the filters to settle again.
    pub fn set_time_constant(&mut self, t: TimeConstant) -> Result<(), Sr830Error> {
        let _span = debug_span!("sr830.set_time_constant", port = %self.port, to = %t).entered();
        run!(self, start_set_time_constant(t))
    }

    /// Sets the slope (`OFSL`); readings wait for the filters to settle again.
    pub fn set_slope(&mut self, s: FilterSlope) -> Result<(), Sr830Error> {
        let _span = debug_span!("sr830.set_slope", port = %self.port, to = %s).entered();
        run!(self, start_set_slope(s))
    }

    /// `LIAS?`: the LIA status byte (reading clears it).
    pub fn lia_status(&mut self) -> Result<LiaStatus, Sr830Error> {
        let _span = debug_span!("sr830.lia_status", port = %self.port).entered();
        run!(self, start_lia_status())
    }

    /// `*ESR?`: the standard event status byte (reading clears it).
    pub fn event_status(&mut self) -> Result<EventStatus, Sr830Error> {
        let _span = debug_span!("sr830.event_status", port = %self.port).entered();
        run!(self, start_event_status())
    }

    /// Sends any command and, for a query, reads its reply. A vanished port is
    /// reopened (up to `reconnect_attempts` times, `reconnect_delay_ms` apart, with
    /// `OUTX 0` re-sent) and the command sent again: every command the driver uses is
    /// idempotent. `SENS`, `OFLT`, `OFSL`, `*RST` and `AGAN` update the settings the
    /// driver tracks and restart the settling wait.
    pub fn execute(&mut self, command: &Command) -> Result<Option<Reply>, Sr830Error> {
        let _span = debug_span!("sr830.execute", port = %self.port, command = ?command).entered();
        run!(self, start_execute(command))
    }

    /// Reads back `SENS?`, `OFLT?`, `OFSL?` into the settings the driver tracks (after
    /// `AGAN`, or a change from the front panel).
    pub fn refresh_settings(&mut self) -> Result<(), Sr830Error> {
        let _span = debug_span!("sr830.refresh_settings", port = %self.port).entered();
        run!(self, start_refresh_settings())
    }

    /// Settling time at the current time constant and slope, to the config's
    /// `settle_residual`.
    pub fn settle_time(&self) -> Duration {
        self.session.settle_time()
    }

    /// The light on the detector changed (a stage moved, a shutter opened): the next
    /// reading waits a full settling time from now, as after a change of settings.
    /// Without it, readings taken right after a move average the filters' response to
    /// the step — biased towards the previous point.
    pub fn input_changed(&mut self) {
        self.session.input_changed(self.clock.now());
    }

    /// The light on the detector changed at `at` (the stages stopped then; no later
    /// than now): the next reading waits a full settling time from `at`, and a targeted
    /// reading times its transient from it.
    pub fn input_changed_at(&mut self, at: Duration) {
        self.session.input_changed(at.min(self.clock.now()));
    }

    /// Sets up ahead what a reading to `target` of a signal about `expected` V needs
    /// before light reaches the detector (the time constant, `OFLT`), as
    /// [`read_targeted`](Self::read_targeted) would first do: the engine sends it while
    /// the stages move to the point. See
    /// [`gonio_proto::sr830::Sr830Session::start_prepare_targeted`].
    pub fn prepare_targeted(
        &mut self,
        target: &ReadTarget,
        expected: Option<f64>,
    ) -> Result<(), Sr830Error> {
        let _span = debug_span!("sr830.prepare_targeted", port = %self.port, expected).entered();
        run!(self, start_prepare_targeted(*target, expected))
    }

    /// The sensitivity the instrument is set to (as far as the driver knows).
    pub fn sensitivity(&self) -> Sensitivity {
        self.session.sensitivity()
    }

    /// The time constant.
    pub fn time_constant(&self) -> TimeConstant {
        self.session.time_constant()
    }

    /// The filter slope.
    pub fn slope(&self) -> FilterSlope {
        self.session.slope()
    }

    /// The configuration.
    pub fn config(&self) -> &Sr830Config {
        self.session.config()
    }

    /// The identity `setup` read, once it has run.
    pub fn identity(&self) -> Option<&Identity> {
        self.session.identity()
    }

    /// How many times the port was reopened.
    pub fn reconnects(&self) -> usize {
        self.session.reconnects()
    }

    /// Queries asked again (or read cycles restarted) after a lost, late or garbled
    /// reply: what a run log reports as retries.
    pub fn retried(&self) -> u64 {
        self.session.retried()
    }

    /// Hands back the transport and the clock.
    pub fn into_inner(self) -> (T, C) {
        (self.transport, self.clock)
    }
}
