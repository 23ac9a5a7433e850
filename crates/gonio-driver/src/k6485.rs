//! The Keithley 6485 picoammeter as Gonio's DC detector: set-up with zero correction,
//! averaged and autoranged readings, and recovery from a lost port.
//!
//! [`K6485`] owns the transport, the clock and the picoammeter's session
//! ([`gonio_proto::k6485::K6485Session`]); each method starts an operation on the
//! session and pumps it. The policy is the session's:
//!
//! [`K6485::setup`] identifies the instrument (a 6485 or 6487), resets it, checks the
//! line frequency, sets the reading format, integration and filter, and performs the
//! manual's zero correction (zero check on, range, `INIT`, `SYST:ZCOR:ACQ`,
//! `SYST:ZCOR ON`, zero check off), then checks `SYST:ERR?`. [`K6485::read`] then
//! returns a [`PicoReading`]: after the settling wait, `samples` × `READ?`, each
//! answered when its integration (× the repeat filter's count) is done. With
//! autoranging, an overflow steps one range up and a small clean signal one range
//! down, and the reading is taken again; an overflow on 20 mA is returned flagged,
//! never valid.
//!
//! The serial port must be set to CR as the instrument's terminator, 8N1, no flow
//! control (see [`gonio_proto::k6485`]). Every wait goes through the [`Clock`], so
//! tests run on virtual time.

use std::time::Duration;

use gonio_proto::k6485::{Command, Identity, K6485Session, Range, Reply};
pub use gonio_proto::k6485::{
    ConfigError, K6485Config, K6485Error, MAX_AUTORANGE_STEPS, PicoFlags, PicoReading, accuracy_a,
};
use tracing::debug_span;

use crate::clock::Clock;
use crate::heartbeat::Heartbeat;
use crate::pump::{pump, pumped};
use crate::transport::Transport;

/// The 6485 on a transport, waiting on a clock.
#[derive(Debug)]
pub struct K6485<T: Transport, C: Clock> {
    transport: T,
    clock: C,
    /// The instrument's heartbeat, kept beating through every wait.
    beats: Heartbeat,
    session: K6485Session,
    /// The port's name, for the wire log.
    port: String,
}

/// Runs one operation of the session: starts it with `$start` (a method of the
/// session, given the clock's now) and pumps it over the transport.
macro_rules! run {
    ($d:ident, $start:ident($($arg:expr),*)) => {{
        let now = $d.clock.now();
        let op = $d.session.$start($($arg,)* now);
        pump(pumped!($d), None, op)
    }};
}

impl<T: Transport, C: Clock> K6485<T, C> {
    /// A driver for the 6485 on `transport`; nothing is sent until
    /// [`setup`](Self::setup). Fails if `config` does not
    /// [`validate`](K6485Config::validate).
    pub fn new(transport: T, clock: C, config: K6485Config) -> Result<Self, K6485Error> {
        let port = transport.name();
        let session = K6485Session::new(config, port.clone(), clock.now())?;
        Ok(K6485 {
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

    /// Identifies, resets and configures the instrument and acquires its zero
    /// correction; see the module docs and [`K6485Session::start_setup`].
    pub fn setup(&mut self) -> Result<Identity, K6485Error> {
        let c = self.session.config();
        let _span = debug_span!(
            "k6485.setup",
            port = %self.port,
            range = %c.range,
            nplc = c.nplc,
            filter_count = c.filter_count,
            zero_correct = c.zero_correct,
        )
        .entered();
        run!(self, start_setup())
    }

    /// One averaged reading; see the module docs for the sequence and autoranging.
    /// Faults are errors; an overflowed, overvoltage or zero-checked reading is
    /// returned flagged.
    pub fn read(&mut self) -> Result<PicoReading, K6485Error> {
        let _span = debug_span!(
            "k6485.read",
            port = %self.port,
            range = %self.session.range(),
            samples = self.session.config().samples,
        )
        .entered();
        run!(self, start_read())
    }

    /// Sets the range (`CURR:RANG`); readings wait the range-change settling.
    pub fn set_range(&mut self, range: Range) -> Result<(), K6485Error> {
        let _span = debug_span!("k6485.set_range", port = %self.port, to = %range).entered();
        run!(self, start_set_range(range))
    }

    /// Sends any command and, for a query, reads its reply, with the session's link
    /// policy (reconnects, re-asks of rereadable queries).
    pub fn execute(&mut self, command: &Command) -> Result<Option<Reply>, K6485Error> {
        let _span = debug_span!("k6485.execute", port = %self.port, command = ?command).entered();
        run!(self, start_execute(command))
    }

    /// The light on the detector changed (a stage moved, a shutter opened): the next
    /// reading waits for the analog front end to settle on the present range.
    pub fn input_changed(&mut self) {
        self.session.input_changed(self.clock.now());
    }

    /// The analog settling time after a change of the input, on the present range.
    pub fn input_settle_time(&self) -> Duration {
        self.session.input_settle_time()
    }

    /// The range the instrument is set to (as far as the driver knows).
    pub fn range(&self) -> Range {
        self.session.range()
    }

    /// The configuration.
    pub fn config(&self) -> &K6485Config {
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
