//! The picoammeter's policy as a sans-IO state machine: [`K6485Session`].
//!
//! `ops` holds the exchange (a command and, for a query, its reply once the instrument
//! has finished measuring) and the operations (set-up, a reading, one command), each an
//! `async fn` the engine runs.

mod ops;

use std::time::Duration;

use super::{Command, Identity, K6485Config, K6485Error, PicoReading, Range, Reply};
use crate::engine::{Task, secs};

/// The 6485 as a state machine: its configuration, the range it was last set to, when
/// a reading may start (after a range change or a change of the light), when the
/// instrument will have finished measuring, and every decision of its operations. It
/// does no I/O and reads no clock.
///
/// Each `start_*` method starts an [`Operation`](crate::link::Operation) that borrows the session until it
/// finishes; see [`Operation`](crate::link::Operation) for the order in which a caller drives it:
///
/// ```
/// use std::time::Duration;
/// use gonio_proto::link::{Deadline, Io, Operation};
/// use gonio_proto::k6485::{K6485Config, K6485Session, Range};
///
/// let config = K6485Config { range: Range::MOST, autorange: false, samples: 1, ..K6485Config::default() };
/// let mut session = K6485Session::new(config, "sim", Duration::ZERO).unwrap();
/// let mut op = session.start_read(Duration::ZERO);
/// assert_eq!(op.poll_io(), Some(Io::Transmit(b"READ?\r")));
/// op.handle_sent(Duration::ZERO, Ok(()));
/// // 1 PLC at 50 Hz = 20 ms of measuring, then the 1 s reply timeout.
/// assert_eq!(op.poll_timeout(), Some(Deadline::Reply(Duration::from_millis(1020))));
/// op.handle_line(Duration::from_millis(25), b"+1.000000E-09A,+1.000000E+00,+0.000000E+00");
/// let reading = op.poll_output().unwrap().unwrap();
/// assert_eq!(reading.current(), Some(1e-9));
/// ```
///
/// `gonio_driver::k6485::K6485` is the pump that runs these operations over a serial
/// port.
#[derive(Clone, Debug, PartialEq)]
pub struct K6485Session {
    config: K6485Config,
    /// The port's name, for errors.
    port: String,
    range: Range,
    /// From this time on, readings are trustworthy.
    settled_at: Duration,
    /// When the instrument will have finished the measurements asked of it.
    busy_until: Duration,
    reconnects: usize,
    retried: u64,
    identity: Option<Identity>,
}

impl K6485Session {
    /// A session for the picoammeter on `port` (its name, for errors), at `now`;
    /// nothing is sent until [`start_setup`](Self::start_setup). Fails if `config` does
    /// not [`validate`](K6485Config::validate).
    pub fn new(
        config: K6485Config,
        port: impl Into<String>,
        now: Duration,
    ) -> Result<Self, K6485Error> {
        config.validate()?;
        Ok(K6485Session {
            port: port.into(),
            range: config.range,
            config,
            settled_at: now,
            busy_until: now,
            reconnects: 0,
            retried: 0,
            identity: None,
        })
    }

    /// Takes the instrument over and applies the configuration, in the manual's
    /// zero-correction order (Section 2, "Zero check and zero correct"): input cleared;
    /// `*IDN?` (must be a 6485 or 6487); `*RST`; `*CLS`; `SYST:LFR?` (must match the
    /// config); `FORM:ELEM READ,TIME,STAT`; `TRIG:COUN 1`; `CURR:NPLC`; the filter
    /// (`AVER:TCON`, `AVER:COUN`, `AVER ON`, or `AVER OFF`); `CURR:RANG:AUTO OFF`;
    /// `SYST:ZCH ON`; then, with `zero_correct`, `CURR:RANG` of the zero's range (2 nA
    /// with autorange, as in the manual's example, else the configured range), the
    /// range's settling wait, `INIT`, `SYST:ZCOR:ACQ`, `SYST:ZCOR ON` and `CURR:RANG`
    /// of the configured range if it differs; without, `CURR:RANG` and
    /// `SYST:ZCOR OFF`; then `SYST:ZCH OFF`; and `SYST:ERR?`, which must answer
    /// `0,"No error"` and also proves every command before it has run.
    ///
    /// Integration and filter are set before the zero is acquired so that the zero is
    /// measured as the readings will be.
    pub fn start_setup(&mut self, now: Duration) -> Task<'_, Identity, K6485Error> {
        Task::new(
            "k6485.setup",
            now,
            |link| async move { self.setup(&link).await },
        )
    }

    /// One averaged reading: the settling wait, then `samples` × `READ?` (each answers
    /// after its own integration, which paces them); with autoranging, an overflow
    /// steps one range up and a clean reading under `min_fraction` of full scale one
    /// range down, each followed by the range's wait and a new reading. Faults are
    /// errors; an overflow on 20 mA, an overvoltage or a zero-checked reading is
    /// returned flagged, never valid.
    pub fn start_read(&mut self, now: Duration) -> Task<'_, PicoReading, K6485Error> {
        Task::new(
            "k6485.read",
            now,
            |link| async move { self.read(&link).await },
        )
    }

    /// Sets the range (`CURR:RANG`); readings wait the range-change settling.
    pub fn start_set_range(&mut self, range: Range, now: Duration) -> Task<'_, (), K6485Error> {
        Task::new("k6485.set_range", now, move |link| async move {
            self.ask(&link, Command::SetRange(range)).await.map(|_| ())
        })
    }

    /// Sends any command and, for a query, reads its reply, with the link policy of
    /// every exchange (reconnects, re-asks of rereadable queries). `CURR:RANG` updates
    /// the tracked range; `*RST` returns the instrument to its defaults (zero check on,
    /// its own autorange), after which [`start_setup`](Self::start_setup) must run
    /// again.
    pub fn start_execute<'s>(
        &'s mut self,
        command: &Command,
        now: Duration,
    ) -> Task<'s, Option<Reply>, K6485Error> {
        let command = command.clone();
        Task::new("k6485.execute", now, move |link| async move {
            self.ask(&link, command).await
        })
    }

    /// The light on the detector changed at `now` (a stage moved, a shutter opened):
    /// the next reading waits until the analog front end has settled to
    /// `settle_residual` on the present range (its rise time, Appendix A), or any
    /// longer wait already pending.
    pub fn input_changed(&mut self, now: Duration) {
        let until = now.saturating_add(self.input_settle_time());
        self.settled_at = self.settled_at.max(until);
        tracing::debug!(settle = ?self.input_settle_time(), range = %self.range, "k6485: input changed");
    }

    /// The analog settling time after a change of the input, on the present range.
    pub fn input_settle_time(&self) -> Duration {
        secs(self.range.settle_s(self.config.settle_residual))
    }

    /// When readings may start.
    pub fn settled_at(&self) -> Duration {
        self.settled_at
    }

    /// When the instrument will have finished what it was asked to measure.
    pub fn busy_until(&self) -> Duration {
        self.busy_until
    }

    /// The range the instrument is set to (as far as the session knows).
    pub fn range(&self) -> Range {
        self.range
    }

    /// The configuration.
    pub fn config(&self) -> &K6485Config {
        &self.config
    }

    /// The identity set-up read, once it has run.
    pub fn identity(&self) -> Option<&Identity> {
        self.identity.as_ref()
    }

    /// How many times the port was reopened.
    pub fn reconnects(&self) -> usize {
        self.reconnects
    }

    /// Queries asked again (or read cycles restarted) after a lost, late or garbled
    /// reply.
    pub fn retried(&self) -> u64 {
        self.retried
    }

    /// The instrument's measuring time for one `READ?` or `INIT`.
    fn read_time(&self) -> Duration {
        secs(self.config.read_s())
    }

    /// The range is now `r` (from `now`): readings wait the range-change settling and
    /// the analog settling of the new range, whichever is longer.
    fn range_changed(&mut self, now: Duration, r: Range) {
        self.range = r;
        let wait = self.config.range_settle().max(self.input_settle_time());
        self.settled_at = now.saturating_add(wait);
        tracing::debug!(range = %r, settle = ?wait, "k6485: range set");
    }

    /// After a reconnection: the instrument may have restarted, so wait as after a
    /// range change.
    fn mark_unsettled(&mut self, now: Duration) {
        let wait = self.config.range_settle().max(self.input_settle_time());
        self.settled_at = self.settled_at.max(now.saturating_add(wait));
    }
}
