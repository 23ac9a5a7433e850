//! A reading: settled, averaged, flagged, autoranged.

use tracing::{debug, warn};

use super::script::{Answer, Next, Op};
use super::{K6485Session, unexpected};
use crate::k6485::{
    Command, Current, K6485Error, MAX_AUTORANGE_STEPS, PicoFlags, PicoReading, Reply, Sample,
    StatusWord,
};
use crate::machine::Cx;

/// Most times one read starts over after the port was lost and reopened.
const MAX_RESTARTS: usize = 2;

/// The read operation. Each cycle: wait until settled; `READ?` `samples` times (each
/// answers after its own integration, so they are spaced by it); flags from the values
/// and status words. A cycle during which the port was reopened starts again. With
/// autorange, an overflow steps one range up at once (the cycle's other samples would
/// overflow too), a clean reading under `min_fraction` of full scale one range down,
/// and the cycle runs again.
#[derive(Debug, Default)]
pub(super) struct Read {
    /// Range changes made.
    steps: usize,
    /// Consecutive cycles started again.
    restarts: usize,
    /// The session's reconnection count when the cycle began.
    reconnects: usize,
    samples: Vec<Sample>,
}

impl Op for Read {
    type Value = PicoReading;

    fn start(&mut self, s: &mut K6485Session, cx: &mut Cx) -> Next<Self> {
        self.begin_cycle(s, cx)
    }
}

impl Read {
    fn begin_cycle(&mut self, s: &K6485Session, cx: &Cx) -> Next<Self> {
        self.reconnects = s.reconnects;
        self.samples.clear();
        if cx.now < s.settled_at {
            debug!(wait = ?(s.settled_at - cx.now), "k6485: waiting for the input to settle");
            return Next::Pause {
                until: s.settled_at,
                then: Self::settled,
            };
        }
        Next::exchange(Command::Read, Self::sampled)
    }

    fn settled(&mut self, _: &mut K6485Session, _: &mut Cx, (): ()) -> Next<Self> {
        Next::exchange(Command::Read, Self::sampled)
    }

    fn sampled(&mut self, s: &mut K6485Session, cx: &mut Cx, r: Answer) -> Next<Self> {
        let sample = match r {
            Ok(Some(Reply::Sample(x))) => x,
            Ok(other) => return Next::Done(Err(unexpected(&Command::Read, other))),
            Err(e) => return Next::Done(Err(e)),
        };
        if s.reconnects != self.reconnects {
            return self.interrupted(s, cx);
        }
        self.samples.push(sample);
        let overflowed = sample.current == Current::Overflow || sample.status.overflow();
        if overflowed && s.config.autorange && s.range.up().is_some() {
            let reading = self.reading(s);
            return self.cycle_done(s, reading);
        }
        if self.samples.len() < s.config.samples {
            return Next::exchange(Command::Read, Self::sampled);
        }
        let reading = self.reading(s);
        self.cycle_done(s, reading)
    }

    fn reading(&self, s: &K6485Session) -> PicoReading {
        let values: Vec<f64> = self
            .samples
            .iter()
            .filter_map(|x| x.current.amps())
            .collect();
        let status = StatusWord(self.samples.iter().fold(0, |acc, x| acc | x.status.0));
        let flags = PicoFlags {
            overflow: status.overflow()
                || self.samples.iter().any(|x| x.current == Current::Overflow),
            invalid: self.samples.iter().any(|x| x.current == Current::Invalid),
            overvoltage: status.overvoltage(),
            zero_check: status.zero_check(),
        };
        let (mean_a, std_a) = mean_std(&values);
        PicoReading {
            mean_a,
            std_a,
            n: values.len(),
            samples: s.config.samples,
            range: s.range,
            nplc: s.config.nplc,
            filter_count: s.config.filter_count,
            flags,
            autorange_steps: self.steps,
            status,
            timestamp_s: self.samples.last().map_or(f64::NAN, |x| x.time_s),
        }
    }

    /// The port was reopened during the cycle: start again, unless that has happened
    /// too often in a row.
    fn interrupted(&mut self, s: &mut K6485Session, cx: &Cx) -> Next<Self> {
        self.restarts += 1;
        if self.restarts > MAX_RESTARTS {
            warn!(
                restarts = self.restarts,
                "k6485: reading interrupted too often"
            );
            return Next::Done(Err(K6485Error::Interrupted {
                restarts: self.restarts,
            }));
        }
        s.retried += 1;
        debug!(restarts = self.restarts, "k6485: read cycle starts again");
        self.begin_cycle(s, cx)
    }

    fn cycle_done(&mut self, s: &K6485Session, reading: PicoReading) -> Next<Self> {
        self.restarts = 0;
        if !s.config.autorange {
            return Next::Done(Ok(reading));
        }
        let f = reading.flags;
        let next = if f.overflow {
            s.range.up()
        } else if !f.any() && reading.mean_a.abs() < s.config.min_fraction * s.range.amps() {
            s.range.down()
        } else {
            None
        };
        let Some(next) = next else {
            return Next::Done(Ok(reading));
        };
        if self.steps >= MAX_AUTORANGE_STEPS {
            warn!(steps = self.steps, "k6485: autorange gives up");
            return Next::Done(Err(K6485Error::Autorange {
                steps: self.steps,
                last: Box::new(reading),
            }));
        }
        debug!(
            from = %s.range,
            to = %next,
            flags = ?f,
            mean = reading.mean_a,
            "k6485: autorange step",
        );
        Next::exchange(Command::SetRange(next), Self::ranged)
    }

    fn ranged(&mut self, s: &mut K6485Session, cx: &mut Cx, r: Answer) -> Next<Self> {
        if let Err(e) = r {
            return Next::Done(Err(e));
        }
        self.steps += 1;
        self.begin_cycle(s, cx)
    }
}

/// Mean and sample standard deviation (n − 1; 0 for one value; NaN for none).
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
