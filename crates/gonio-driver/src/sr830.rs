//! The SR830 lock-in amplifier as Gonio's detector: set-up, settled and averaged
//! readings, autoranging, and recovery from a lost port.
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

use gonio_proto::sr830::{
    Command, EventStatus, FilterSlope, Identity, Interface, LiaStatus, Reply, ReplyError,
    Sensitivity, SnapParams, TimeConstant,
};
pub use gonio_proto::sr830::{
    ConfigError, MAX_AUTORANGE_STEPS, Reading, ReadingFlags, Sr830Config, Sr830Error,
};

use crate::clock::Clock;
use crate::transport::{Transport, TransportError};

/// Most times one [`Sr830::read`] starts over after the port was lost and reopened.
const MAX_RESTARTS: usize = 2;

/// A transport fault: a vanished port is recovered from, anything else is reported.
enum Fault {
    Disconnected(TransportError),
    Other(Sr830Error),
}

/// Queries that read without side effects, so that asking again is harmless.
fn rereadable(c: &Command) -> bool {
    c.expects_reply()
        && !matches!(
            c,
            Command::LiaStatus(_) | Command::ErrorStatus(_) | Command::EventStatus(_)
        )
}

/// Faults a second attempt may not have: a lost, late, garbled or truncated reply.
fn is_transient(e: &Sr830Error) -> bool {
    matches!(
        e,
        Sr830Error::Protocol { .. }
            | Sr830Error::Transport {
                source: TransportError::Timeout(_)
                    | TransportError::LineTooLong
                    | TransportError::Nul,
                ..
            }
    )
}

/// The SR830 on a transport, waiting on a clock.
#[derive(Debug)]
pub struct Sr830<T: Transport, C: Clock> {
    transport: T,
    clock: C,
    config: Sr830Config,
    sensitivity: Sensitivity,
    time_constant: TimeConstant,
    slope: FilterSlope,
    /// Clock time from which readings are trustworthy.
    settled_at: Duration,
    reconnects: usize,
    retried: u64,
    identity: Option<Identity>,
}

impl<T: Transport, C: Clock> Sr830<T, C> {
    /// A driver for the SR830 on `transport`; nothing is sent until [`setup`](Self::setup).
    /// Fails if `config` does not [`validate`](Sr830Config::validate).
    pub fn new(transport: T, clock: C, config: Sr830Config) -> Result<Self, Sr830Error> {
        config.validate()?;
        let settled_at = clock.now();
        Ok(Sr830 {
            transport,
            clock,
            sensitivity: config.sensitivity,
            time_constant: config.time_constant,
            slope: config.slope,
            config,
            settled_at,
            reconnects: 0,
            retried: 0,
            identity: None,
        })
    }

    /// Takes the link and applies the configuration: `OUTX 0`, `*IDN?` (must be an
    /// SR830), `*CLS`, `SENS`, `OFLT`, `OFSL`, then `*ESR?`, whose reply also proves
    /// every earlier command has run. Starts the settling wait.
    pub fn setup(&mut self) -> Result<Identity, Sr830Error> {
        let _ = self.transport.clear_input();
        self.execute(&Command::SetInterface(Interface::Rs232))?;
        let id = match self.execute(&Command::Identify)? {
            Some(Reply::Identity(id)) => id,
            other => return Err(unexpected(&Command::Identify, other)),
        };
        if !id.is_sr830() {
            return Err(Sr830Error::WrongInstrument(id));
        }
        self.execute(&Command::Clear)?;
        self.execute(&Command::SetSensitivity(self.config.sensitivity))?;
        self.execute(&Command::SetTimeConstant(self.config.time_constant))?;
        self.execute(&Command::SetSlope(self.config.slope))?;
        let esr = self.event_status()?;
        if esr.has_command_error() {
            return Err(Sr830Error::Rejected(esr));
        }
        self.identity = Some(id.clone());
        Ok(id)
    }

    /// One averaged reading; see the module docs for the sequence and autoranging.
    /// Faults are errors; an overloaded or unlocked reading is returned flagged.
    pub fn read(&mut self) -> Result<Reading, Sr830Error> {
        let mut steps = 0;
        let mut restarts = 0;
        loop {
            let Some(mut reading) = self.read_once()? else {
                // The port was lost and reopened (samples taken before may predate an
                // instrument restart), or the flags' answer was lost: read again.
                restarts += 1;
                if restarts > MAX_RESTARTS {
                    return Err(Sr830Error::Interrupted { restarts });
                }
                continue;
            };
            // Only consecutive failures count towards giving up.
            restarts = 0;
            reading.autorange_steps = steps;
            if !self.config.autorange {
                return Ok(reading);
            }
            let f = reading.flags;
            let next = if f.input_overload || f.output_overload {
                self.sensitivity.less_sensitive()
            } else if !f.any()
                && reading.r_mean < self.config.min_fraction * self.sensitivity.volts()
            {
                self.sensitivity.more_sensitive()
            } else {
                None
            };
            let Some(next) = next else {
                return Ok(reading);
            };
            if steps >= MAX_AUTORANGE_STEPS {
                return Err(Sr830Error::Autorange {
                    steps,
                    last: Box::new(reading),
                });
            }
            self.set_sensitivity(next)?;
            steps += 1;
        }
    }

    /// One settled read cycle at the current settings, or `None` if the port was
    /// reopened during it.
    fn read_once(&mut self) -> Result<Option<Reading>, Sr830Error> {
        let start = self.reconnects;
        self.wait_settled();
        // This read only clears latched bits; its value is not used, so a lost answer
        // may be asked again.
        let mut left = self.config.retries;
        loop {
            match self.lia_status() {
                Ok(_) => break,
                Err(e) if left > 0 && is_transient(&e) => {
                    left -= 1;
                    self.retried += 1;
                }
                Err(e) => return Err(e),
            }
        }
        let n = self.config.samples;
        let spacing = secs(self.time_constant.seconds());
        let (mut xs, mut ys, mut rs) = (Vec::new(), Vec::new(), Vec::new());
        for k in 0..n {
            if k > 0 {
                self.clock.sleep(spacing);
            }
            let (x, y) = self.snap_xy()?;
            if self.reconnects != start {
                return Ok(None);
            }
            xs.push(x);
            ys.push(y);
            rs.push(x.hypot(y));
        }
        // The answer that carries the flags: if it is lost, so are they (reading
        // cleared them), and the cycle starts again.
        let status = match self.lia_status() {
            Ok(s) => s,
            Err(e) if self.config.retries > 0 && is_transient(&e) => {
                self.retried += 1;
                return Ok(None);
            }
            Err(e) => return Err(e),
        };
        if self.reconnects != start {
            return Ok(None);
        }
        let (r_mean, r_std) = mean_std(&rs);
        Ok(Some(Reading {
            r_mean,
            r_std,
            x_mean: mean_std(&xs).0,
            y_mean: mean_std(&ys).0,
            n,
            sensitivity: self.sensitivity,
            time_constant: self.time_constant,
            slope: self.slope,
            status,
            flags: ReadingFlags::from_status(status),
            autorange_steps: 0,
        }))
    }

    /// Sets the sensitivity (`SENS`); readings wait for the filters to settle again.
    pub fn set_sensitivity(&mut self, s: Sensitivity) -> Result<(), Sr830Error> {
        self.execute(&Command::SetSensitivity(s)).map(|_| ())
    }

    /// Sets the time constant (`OFLT`); readings wait for the filters to settle again.
    pub fn set_time_constant(&mut self, t: TimeConstant) -> Result<(), Sr830Error> {
        self.execute(&Command::SetTimeConstant(t)).map(|_| ())
    }

    /// Sets the slope (`OFSL`); readings wait for the filters to settle again.
    pub fn set_slope(&mut self, s: FilterSlope) -> Result<(), Sr830Error> {
        self.execute(&Command::SetSlope(s)).map(|_| ())
    }

    /// `LIAS?`: the LIA status byte (reading clears it).
    pub fn lia_status(&mut self) -> Result<LiaStatus, Sr830Error> {
        let c = Command::LiaStatus(None);
        match self.execute(&c)? {
            Some(Reply::LiaStatus(s)) => Ok(s),
            other => Err(unexpected(&c, other)),
        }
    }

    /// `*ESR?`: the standard event status byte (reading clears it).
    pub fn event_status(&mut self) -> Result<EventStatus, Sr830Error> {
        let c = Command::EventStatus(None);
        match self.execute(&c)? {
            Some(Reply::EventStatus(s)) => Ok(s),
            other => Err(unexpected(&c, other)),
        }
    }

    /// `SNAP? 1,2`: X and Y at one instant, volts.
    fn snap_xy(&mut self) -> Result<(f64, f64), Sr830Error> {
        let c = Command::Snap(SnapParams::XY);
        match self.execute(&c)? {
            Some(Reply::Snap(v)) => match v.as_slice() {
                [x, y] => Ok((*x, *y)),
                _ => Err(unexpected(&c, Some(Reply::Snap(v)))),
            },
            other => Err(unexpected(&c, other)),
        }
    }

    /// Sends any command and, for a query, reads its reply. A vanished port is
    /// reopened (up to `reconnect_attempts` times, `reconnect_delay_ms` apart, with
    /// `OUTX 0` re-sent) and the command sent again: every command the driver uses is
    /// idempotent. `SENS`, `OFLT`, `OFSL`, `*RST` and `AGAN` update the settings the
    /// driver tracks and restart the settling wait.
    pub fn execute(&mut self, command: &Command) -> Result<Option<Reply>, Sr830Error> {
        let bytes = command.to_bytes();
        let mut budget = self.config.reconnect_attempts;
        // A lost or garbled answer to a query that only reads is asked again; the
        // status bytes are not (reading them clears them: a second read could report
        // a latched overload as gone).
        let mut retries = if rereadable(command) {
            self.config.retries
        } else {
            0
        };
        let reply = loop {
            match self.attempt(command, &bytes) {
                Ok(r) => break r,
                Err(Fault::Disconnected(e)) => self.recover(e, &mut budget)?,
                Err(Fault::Other(e)) => {
                    // A late or partial reply must not be read as the next one's.
                    let _ = self.transport.clear_input();
                    if retries > 0 && is_transient(&e) {
                        retries -= 1;
                        self.retried += 1;
                        continue;
                    }
                    return Err(e);
                }
            }
        };
        match command {
            Command::SetSensitivity(s) => self.sensitivity = *s,
            Command::SetTimeConstant(t) => self.time_constant = *t,
            Command::SetSlope(s) => self.slope = *s,
            Command::Reset => {
                self.sensitivity = Sensitivity::default();
                self.time_constant = TimeConstant::default();
                self.slope = FilterSlope::default();
            }
            Command::AutoGain => self.refresh_settings()?,
            _ => return Ok(reply),
        }
        self.mark_unsettled();
        Ok(reply)
    }

    /// Reads back `SENS?`, `OFLT?`, `OFSL?` into the settings the driver tracks (after
    /// `AGAN`, or a change from the front panel).
    pub fn refresh_settings(&mut self) -> Result<(), Sr830Error> {
        for c in [
            Command::QuerySensitivity,
            Command::QueryTimeConstant,
            Command::QuerySlope,
        ] {
            match self.execute(&c)? {
                Some(Reply::Sensitivity(s)) => self.sensitivity = s,
                Some(Reply::TimeConstant(t)) => self.time_constant = t,
                Some(Reply::Slope(s)) => self.slope = s,
                other => return Err(unexpected(&c, other)),
            }
        }
        self.mark_unsettled();
        Ok(())
    }

    /// One try: send, and read the reply of a query.
    fn attempt(&mut self, command: &Command, bytes: &[u8]) -> Result<Option<Reply>, Fault> {
        let name = || String::from_utf8_lossy(bytes).trim_end().to_string();
        let fault = |e: TransportError| match e {
            TransportError::Disconnected { .. } => Fault::Disconnected(e),
            source => Fault::Other(Sr830Error::Transport {
                command: name(),
                source,
            }),
        };
        self.transport.send(bytes).map_err(fault)?;
        if !command.expects_reply() {
            return Ok(None);
        }
        let line = self
            .transport
            .receive_line(self.config.timeout())
            .map_err(fault)?;
        match Reply::parse(command, &line) {
            Ok(r) => Ok(Some(r)),
            Err(source) => Err(Fault::Other(Sr830Error::Protocol {
                command: name(),
                reply: line,
                source,
            })),
        }
    }

    /// Reopens a vanished port and re-sends `OUTX 0`, spending `budget` attempts.
    fn recover(&mut self, mut last: TransportError, budget: &mut u32) -> Result<(), Sr830Error> {
        let outx = Command::SetInterface(Interface::Rs232).to_bytes();
        while *budget > 0 {
            *budget -= 1;
            self.clock.sleep(self.config.reconnect_delay());
            let r = self
                .transport
                .reconnect()
                .and_then(|()| self.transport.send(&outx));
            match r {
                Ok(()) => {
                    self.reconnects += 1;
                    // The instrument may have restarted: let its filters settle again.
                    self.mark_unsettled();
                    return Ok(());
                }
                Err(e @ TransportError::Disconnected { .. }) => last = e,
                Err(source) => {
                    return Err(Sr830Error::Transport {
                        command: "OUTX 0".into(),
                        source,
                    });
                }
            }
        }
        Err(Sr830Error::Disconnected {
            port: self.transport.name(),
            attempts: self.config.reconnect_attempts,
            source: last,
        })
    }

    /// Settling time at the current time constant and slope, to the config's
    /// `settle_residual`.
    pub fn settle_time(&self) -> Duration {
        secs(self.config.settle_seconds(self.slope, self.time_constant))
    }

    /// The light on the detector changed (a stage moved, a shutter opened): the next
    /// reading waits a full settling time from now, as after a change of settings.
    /// Without it, readings taken right after a move average the filters' response to
    /// the step — biased towards the previous point.
    pub fn input_changed(&mut self) {
        self.mark_unsettled();
    }

    /// Readings wait a full settling time from now, at the current settings. A
    /// pending longer wait is replaced, not kept: the filters now run at the new
    /// settings, so a mistaken 30 ks set and undone does not cost days.
    fn mark_unsettled(&mut self) {
        self.settled_at = self.clock.now().saturating_add(self.settle_time());
    }

    fn wait_settled(&mut self) {
        let now = self.clock.now();
        if now < self.settled_at {
            self.clock.sleep(self.settled_at - now);
        }
    }

    /// The sensitivity the instrument is set to (as far as the driver knows).
    pub fn sensitivity(&self) -> Sensitivity {
        self.sensitivity
    }

    /// The time constant.
    pub fn time_constant(&self) -> TimeConstant {
        self.time_constant
    }

    /// The filter slope.
    pub fn slope(&self) -> FilterSlope {
        self.slope
    }

    /// The configuration.
    pub fn config(&self) -> &Sr830Config {
        &self.config
    }

    /// The identity `setup` read, once it has run.
    pub fn identity(&self) -> Option<&Identity> {
        self.identity.as_ref()
    }

    /// How many times the port was reopened.
    pub fn reconnects(&self) -> usize {
        self.reconnects
    }

    /// Queries asked again (or read cycles restarted) after a lost, late or garbled
    /// reply: what a run log reports as retries.
    pub fn retried(&self) -> u64 {
        self.retried
    }

    /// Hands back the transport and the clock.
    pub fn into_inner(self) -> (T, C) {
        (self.transport, self.clock)
    }
}

/// A reply of the wrong kind: cannot happen, since [`Reply::parse`] answers by query;
/// reported as a protocol error rather than a panic.
fn unexpected(command: &Command, reply: Option<Reply>) -> Sr830Error {
    let mut name = Vec::new();
    command.encode_body(&mut name);
    Sr830Error::Protocol {
        command: String::from_utf8_lossy(&name).into_owned(),
        reply: reply.map(|r| r.to_bytes()).unwrap_or_default(),
        source: ReplyError::BadValue,
    }
}

/// `s` seconds as a duration (saturating; `s` is never negative or NaN here).
fn secs(s: f64) -> Duration {
    Duration::try_from_secs_f64(s).unwrap_or(Duration::MAX)
}

/// Mean and sample standard deviation (n − 1; 0 for fewer than two values).
fn mean_std(v: &[f64]) -> (f64, f64) {
    if v.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    if v.len() < 2 {
        return (mean, 0.0);
    }
    let ss: f64 = v.iter().map(|x| (x - mean).powi(2)).sum();
    (mean, (ss / (n - 1.0)).sqrt())
}
