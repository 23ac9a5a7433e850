//! The picoammeter's policy as a sans-IO state machine, [`K6485Session`]: its
//! operations as the manual's procedures (set-up, a reading, one command), each an
//! `async fn` the engine runs, and its exchange (a command and, for a query, its reply
//! once the instrument has finished measuring).

use std::time::Duration;

use tracing::debug;

use super::{
    Command, Current, Identity, K6485Config, K6485Error, MAX_AUTORANGE_STEPS, PicoFlags,
    PicoReading, Range, Reply, ReplyError, Sample, StatusWord,
};
use crate::engine::{self, Fault, Link, Read, SessionCore, Task, secs};
use crate::number;

/// The 6485 as a state machine: its configuration, the range it was last set to, when
/// a reading may start, when the instrument will have finished measuring, and its
/// operations' decisions. It does no I/O and reads no clock.
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
    core: SessionCore<K6485Config, Identity>,
    range: Range,
    /// From this time on, readings are trustworthy.
    settled_at: Duration,
    /// When the instrument will have finished the measurements asked of it.
    busy_until: Duration,
}

engine::line_session! {
    K6485Session: "k6485", K6485Config, Identity, K6485Error; Command, Reply, ReplyError
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
            range: config.range,
            core: SessionCore::new(config, port),
            settled_at: now,
            busy_until: now,
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
        Task::run("k6485.setup", now, self, Self::setup)
    }

    /// One averaged reading: the settling wait, then `samples` × `READ?` (each answers
    /// after its own integration, which paces them); with autoranging, an overflow
    /// steps one range up and a clean reading under `min_fraction` of full scale one
    /// range down, each followed by the range's wait and a new reading. Faults are
    /// errors; an overflow on 20 mA, an overvoltage or a zero-checked reading is
    /// returned flagged, never valid.
    pub fn start_read(&mut self, now: Duration) -> Task<'_, PicoReading, K6485Error> {
        Task::run("k6485.read", now, self, Self::read)
    }

    /// `CURR:RANG`; readings wait the range-change settling.
    pub fn start_set_range(&mut self, range: Range, now: Duration) -> Task<'_, (), K6485Error> {
        Task::run("k6485.set_range", now, self, async move |s, link| {
            s.ask(link, Command::SetRange(range)).await.map(drop)
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
        Task::run("k6485.execute", now, self, async move |s, link| {
            s.ask(link, command).await
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

    /// After a reopen the instrument's state is unknown (it may have restarted): readings
    /// wait as after a range change.
    fn reopened(&mut self, now: Duration) {
        self.busy_until = now;
        let wait = self.config.range_settle().max(self.input_settle_time());
        self.settled_at = self.settled_at.max(now.saturating_add(wait));
    }

    /// Sends `command` and, for a query, reads its reply.
    ///
    /// - The instrument runs commands in order, and `INIT` and `READ?` keep it
    ///   measuring for the integration time × the repeat filter's count: the session
    ///   tracks when it will be free (`busy_until`), and a reply is due the reply
    ///   timeout after that.
    /// - Only a query that reads without side effects (`*IDN?`, `CURR:RANG?`,
    ///   `SYST:LFR?`, `READ?`, `FETC?`) is asked again after a lost or garbled reply,
    ///   up to `retries` times (`READ?` takes a fresh reading, which is what was asked
    ///   for). `SYST:ERR?` and `*ESR?` never are: reading them clears what they report.
    /// - Nothing needs sending first on a reopened RS-232 port (unlike the SR830).
    /// - `CURR:RANG` and `*RST` update the range tracked and start the wait after a
    ///   range change.
    async fn ask(&mut self, link: &Link, command: Command) -> Result<Option<Reply>, K6485Error> {
        let name = name(&command);
        let rereadable =
            command.is_query() && !matches!(command, Command::NextError | Command::EventStatus);
        let retries = if rereadable { self.config.retries } else { 0 };
        let measuring = match command {
            Command::Initiate | Command::Read => self.read_time(),
            _ => Duration::ZERO,
        };
        let timeout = self.config.timeout();
        let receive = async |s: &mut K6485Session| {
            let free = s.busy_until.max(link.now()).saturating_add(measuring);
            s.busy_until = free;
            if !command.is_query() {
                return Ok(None);
            }
            let line = link.line(free.saturating_add(timeout)).await?;
            Reply::parse(&command, &line)
                .map(Some)
                .map_err(|source| Fault::Answer(protocol(&command, &line, source)))
        };
        let bytes = command.to_bytes();
        let reply = engine::exchange(self, link, &name, &bytes, retries, receive).await;
        let reply = reply?;
        match command {
            Command::SetRange(r) => self.range_changed(link.now(), r),
            Command::Reset => self.range_changed(link.now(), Range::default()),
            _ => {}
        }
        Ok(reply)
    }

    /// `commands` in turn, none a query.
    async fn send_all(&mut self, link: &Link, commands: &[Command]) -> Result<(), K6485Error> {
        for c in commands {
            self.ask(link, c.clone()).await?;
        }
        Ok(())
    }

    /// Set-up, as [`K6485Session::start_setup`] lists it.
    async fn setup(&mut self, link: &Link) -> Result<Identity, K6485Error> {
        let c = self.config.clone();
        link.clear_input();
        let identity = match self.ask(link, Command::Identify).await? {
            Some(Reply::Identity(id)) if id.picoammeter().is_some() => id,
            Some(Reply::Identity(id)) => return Err(K6485Error::WrongInstrument(id)),
            other => return Err(unexpected(&Command::Identify, other)),
        };
        debug!(identity = %identity, "k6485: identified");
        self.send_all(link, &[Command::Reset, Command::Clear])
            .await?;
        match self.ask(link, Command::LineFrequency).await? {
            Some(Reply::LineFrequency(lf)) if lf.hz() == c.line_frequency_hz => {}
            Some(Reply::LineFrequency(lf)) => {
                return Err(K6485Error::LineFrequency {
                    configured: c.line_frequency_hz,
                    instrument: lf.hz(),
                });
            }
            other => return Err(unexpected(&Command::LineFrequency, other)),
        }
        let mut configure = vec![
            Command::FormatElements,
            Command::TriggerCount(1),
            Command::SetNplc(c.nplc),
        ];
        if c.filter_on() {
            configure.extend([
                Command::FilterType(c.filter_type),
                Command::FilterCount(c.filter_count),
                Command::Filter(true),
            ]);
        } else {
            configure.push(Command::Filter(false));
        }
        configure.extend([Command::AutoRange(false), Command::ZeroCheck(true)]);
        self.send_all(link, &configure).await?;
        if c.zero_correct {
            // The zero is an input offset current, the same on every range: measured
            // where it is resolved best, the most sensitive range the session may use
            // (the manual's example acquires on 2 nA, then autoranges).
            let zero_range = if c.autorange { Range::MOST } else { c.range };
            self.ask(link, Command::SetRange(zero_range)).await?;
            // The zero is measured only once the range has settled.
            self.settle(link).await;
            let acquire = [
                Command::Initiate,
                Command::ZeroCorrectAcquire,
                Command::ZeroCorrect(true),
            ];
            self.send_all(link, &acquire).await?;
            if zero_range != c.range {
                self.ask(link, Command::SetRange(c.range)).await?;
            }
        } else {
            let range = [Command::SetRange(c.range), Command::ZeroCorrect(false)];
            self.send_all(link, &range).await?;
        }
        self.ask(link, Command::ZeroCheck(false)).await?;
        // Also proves every command before it has run.
        match self.ask(link, Command::NextError).await? {
            Some(Reply::Error(e)) if e.is_none() => {}
            Some(Reply::Error(e)) => return Err(K6485Error::Rejected(e)),
            other => return Err(unexpected(&Command::NextError, other)),
        }
        self.core.identity = Some(identity.clone());
        Ok(identity)
    }

    /// [`start_read`](Self::start_read)'s reading, one [`cycle`](Self::cycle) per range.
    async fn read(&mut self, link: &Link) -> Result<PicoReading, K6485Error> {
        let mut read = Read::new("k6485");
        loop {
            let Some(samples) = self.cycle(link).await? else {
                read.restart(|restarts| K6485Error::Interrupted { restarts })?;
                self.core.retried += 1;
                continue;
            };
            read.restarts = 0;
            let reading = self.reading(&samples, read.steps);
            let f = reading.flags;
            let small =
                !f.any() && reading.mean_a.abs() < self.config.min_fraction * self.range.amps();
            let next = if f.overflow {
                self.range.up()
            } else if small {
                self.range.down()
            } else {
                None
            };
            let Some(next) = next.filter(|_| self.config.autorange) else {
                return Ok(reading);
            };
            if read.exhausted(MAX_AUTORANGE_STEPS) {
                let last = Box::new(reading);
                return Err(K6485Error::Autorange {
                    steps: read.steps,
                    last,
                });
            }
            debug!(from = %self.range, to = %next, flags = ?f, mean = reading.mean_a, "k6485: autorange step");
            self.ask(link, Command::SetRange(next)).await?;
            read.steps += 1;
        }
    }

    /// Waits until readings are trustworthy (`settled_at`).
    async fn settle(&self, link: &Link) {
        if link.now() < self.settled_at {
            debug!(wait = ?(self.settled_at - link.now()), "k6485: waiting for the input to settle");
            link.sleep(self.settled_at).await;
        }
    }

    /// One read cycle. With autorange an overflow ends it at once (the other samples
    /// would overflow too). `None` if the port was reopened meanwhile.
    async fn cycle(&mut self, link: &Link) -> Result<Option<Vec<Sample>>, K6485Error> {
        let reconnects = self.core.reconnects;
        self.settle(link).await;
        let mut samples = Vec::new();
        while samples.len() < self.config.samples {
            let sample = match self.ask(link, Command::Read).await? {
                Some(Reply::Sample(x)) => x,
                other => return Err(unexpected(&Command::Read, other)),
            };
            if self.core.reconnects != reconnects {
                return Ok(None);
            }
            samples.push(sample);
            let overflowed = sample.current == Current::Overflow || sample.status.overflow();
            if overflowed && self.config.autorange && self.range.up().is_some() {
                break;
            }
        }
        Ok(Some(samples))
    }

    /// The reading of a cycle's samples: their mean and spread, flags from the values
    /// and status words.
    fn reading(&self, samples: &[Sample], autorange_steps: usize) -> PicoReading {
        let values: Vec<f64> = samples.iter().filter_map(|x| x.current.amps()).collect();
        let status = StatusWord(samples.iter().fold(0, |acc, x| acc | x.status.0));
        let flags = PicoFlags {
            overflow: status.overflow() || samples.iter().any(|x| x.current == Current::Overflow),
            invalid: samples.iter().any(|x| x.current == Current::Invalid),
            overvoltage: status.overvoltage(),
            zero_check: status.zero_check(),
        };
        let (mean_a, std_a) = number::mean_std(&values);
        PicoReading {
            mean_a,
            std_a,
            n: values.len(),
            samples: self.config.samples,
            range: self.range,
            nplc: self.config.nplc,
            filter_count: self.config.filter_count,
            flags,
            autorange_steps,
            status,
            timestamp_s: samples.last().map_or(f64::NAN, |x| x.time_s),
        }
    }
}
