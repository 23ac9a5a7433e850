//! The picoammeter's operations as its manual's procedures: set-up, a reading, one
//! command; and its exchange (a command and, for a query, its reply once the
//! instrument has finished measuring), run by the engine's link policy.

use std::time::Duration;

use tracing::{debug, warn};

use super::K6485Session;
use crate::engine::{self, Fault, Link, Wire};
use crate::k6485::{
    Command, Current, Identity, K6485Error, MAX_AUTORANGE_STEPS, PicoFlags, PicoReading, Range,
    Reply, ReplyError, Sample, StatusWord,
};
use crate::number;

/// Most times one read starts over after the port was lost and reopened.
const MAX_RESTARTS: usize = 2;

impl Wire for K6485Session {
    engine::line_wire!(K6485Error, "k6485");

    fn reopened(&mut self, now: Duration) {
        self.reconnects += 1;
        // Whatever the instrument was doing is unknown now, and it may have restarted.
        self.busy_until = now;
        self.mark_unsettled(now);
    }
}

/// The command as sent, without terminator, for errors.
fn name(command: &Command) -> String {
    String::from_utf8_lossy(&command.to_bytes())
        .trim_end()
        .to_owned()
}

/// A reply of the wrong kind: cannot happen, since [`Reply::parse`] answers by query;
/// reported as a protocol error rather than a panic.
fn unexpected(command: &Command, reply: Option<Reply>) -> K6485Error {
    K6485Error::Protocol {
        command: name(command),
        reply: reply.map(|r| r.to_bytes()).unwrap_or_default(),
        source: ReplyError::BadValue,
    }
}

impl K6485Session {
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
    pub(super) async fn ask(
        &mut self,
        link: &Link,
        command: Command,
    ) -> Result<Option<Reply>, K6485Error> {
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
            match Reply::parse(&command, &line) {
                Ok(reply) => Ok(Some(reply)),
                Err(source) => Err(Fault::Answer(K6485Error::Protocol {
                    command: name.clone(),
                    reply: line,
                    source,
                })),
            }
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
    pub(super) async fn setup(&mut self, link: &Link) -> Result<Identity, K6485Error> {
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
        self.identity = Some(identity.clone());
        Ok(identity)
    }

    /// A reading, cycle after cycle: see [`cycle`](Self::cycle). With autorange, an
    /// overflow steps one range up, a clean reading under `min_fraction` of full scale
    /// one range down, and the cycle runs again.
    pub(super) async fn read(&mut self, link: &Link) -> Result<PicoReading, K6485Error> {
        let mut steps = 0;
        let mut restarts = 0;
        loop {
            let Some(samples) = self.cycle(link).await? else {
                restarts += 1;
                if restarts > MAX_RESTARTS {
                    warn!(restarts, "k6485: reading interrupted too often");
                    return Err(K6485Error::Interrupted { restarts });
                }
                self.retried += 1;
                debug!(restarts, "k6485: read cycle starts again");
                continue;
            };
            restarts = 0;
            let reading = self.reading(&samples, steps);
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
            if steps >= MAX_AUTORANGE_STEPS {
                warn!(steps, "k6485: autorange gives up");
                return Err(K6485Error::Autorange {
                    steps,
                    last: Box::new(reading),
                });
            }
            debug!(from = %self.range, to = %next, flags = ?f, mean = reading.mean_a, "k6485: autorange step");
            self.ask(link, Command::SetRange(next)).await?;
            steps += 1;
        }
    }

    /// Waits until readings are trustworthy (`settled_at`).
    async fn settle(&self, link: &Link) {
        if link.now() < self.settled_at {
            debug!(wait = ?(self.settled_at - link.now()), "k6485: waiting for the input to settle");
            link.sleep(self.settled_at).await;
        }
    }

    /// One read cycle: wait until settled, then `READ?` `samples` times (each answers
    /// after its own integration, so they are spaced by it). With autorange an
    /// overflow ends it at once (the other samples would overflow too). `None` if the
    /// port was reopened meanwhile.
    async fn cycle(&mut self, link: &Link) -> Result<Option<Vec<Sample>>, K6485Error> {
        let reconnects = self.reconnects;
        self.settle(link).await;
        let mut samples = Vec::new();
        while samples.len() < self.config.samples {
            let sample = match self.ask(link, Command::Read).await? {
                Some(Reply::Sample(x)) => x,
                other => return Err(unexpected(&Command::Read, other)),
            };
            if self.reconnects != reconnects {
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
