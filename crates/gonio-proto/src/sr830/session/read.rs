//! A reading: settled, averaged, flagged, autoranged.

use std::time::Duration;

use tracing::{debug, warn};

use super::script::{Next, Op};
use super::{Sr830Session, is_transient, lia_status, unexpected};
use crate::machine::{Cx, secs};
use crate::sr830::{
    Command, LiaStatus, MAX_AUTORANGE_STEPS, Reading, ReadingFlags, Reply, SnapParams, Sr830Error,
    ranging,
};

/// Most times one read starts over after the port was lost and reopened (or the flags'
/// answer was lost).
const MAX_RESTARTS: usize = 2;

/// The read operation. Each cycle: wait until the filters have settled; `LIAS?` to
/// clear the bits latched while settling (asked again if its answer is lost: its value
/// is not used); `SNAP? 1,2` `samples` times, one time constant apart; `LIAS?` for the
/// flags (if its answer is lost, so are the flags, and the cycle starts again). A cycle
/// during which the port was reopened starts again, since its samples may predate an
/// instrument restart. With autorange, an input or output overload steps one range
/// less sensitive, a clean signal under `min_fraction` of full scale one range more,
/// and the cycle runs again.
#[derive(Debug, Default)]
pub(super) struct Read {
    /// Range changes made.
    steps: usize,
    /// Consecutive cycles started again.
    restarts: usize,
    /// The session's reconnection count when the cycle began.
    reconnects: usize,
    /// Re-asks left for the clearing `LIAS?`.
    left: u32,
    /// Samples taken in this cycle, and their spacing.
    k: usize,
    spacing: Duration,
    xs: Vec<f64>,
    ys: Vec<f64>,
    rs: Vec<f64>,
}

impl Op for Read {
    type Value = Reading;

    fn start(&mut self, s: &mut Sr830Session, cx: &mut Cx) -> Next<Self> {
        self.begin_cycle(s, cx)
    }
}

pub(super) fn snap() -> Command {
    Command::Snap(SnapParams::XY)
}

impl Read {
    fn begin_cycle(&mut self, s: &Sr830Session, cx: &Cx) -> Next<Self> {
        self.reconnects = s.reconnects;
        if cx.now < s.settled_at {
            debug!(wait = ?(s.settled_at - cx.now), "sr830: waiting for the filters to settle");
            return Next::Pause {
                until: s.settled_at,
                then: Self::settled,
            };
        }
        self.clear_flags(s)
    }

    fn settled(&mut self, s: &mut Sr830Session, _: &mut Cx, (): ()) -> Next<Self> {
        self.clear_flags(s)
    }

    fn clear_flags(&mut self, s: &Sr830Session) -> Next<Self> {
        self.left = s.config.retries;
        Next::exchange(Command::LiaStatus(None), Self::flags_cleared)
    }

    fn flags_cleared(
        &mut self,
        s: &mut Sr830Session,
        _: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        match r.and_then(|reply| lia_status(&Command::LiaStatus(None), reply)) {
            Ok(_) => {
                self.k = 0;
                self.spacing = secs(s.time_constant.seconds());
                self.xs.clear();
                self.ys.clear();
                self.rs.clear();
                Next::exchange(snap(), Self::snapped)
            }
            Err(e) if self.left > 0 && is_transient(&e) => {
                self.left -= 1;
                s.retried += 1;
                Next::exchange(Command::LiaStatus(None), Self::flags_cleared)
            }
            Err(e) => Next::Done(Err(e)),
        }
    }

    fn snapped(
        &mut self,
        s: &mut Sr830Session,
        cx: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        let (x, y) = match r.and_then(xy) {
            Ok(v) => v,
            Err(e) => return Next::Done(Err(e)),
        };
        if s.reconnects != self.reconnects {
            return self.interrupted(s, cx);
        }
        self.xs.push(x);
        self.ys.push(y);
        self.rs.push(x.hypot(y));
        self.k += 1;
        if self.k < s.config.samples {
            return Next::Pause {
                until: cx.now.saturating_add(self.spacing),
                then: Self::spaced,
            };
        }
        Next::exchange(Command::LiaStatus(None), Self::flags_read)
    }

    fn spaced(&mut self, _: &mut Sr830Session, _: &mut Cx, (): ()) -> Next<Self> {
        Next::exchange(snap(), Self::snapped)
    }

    fn flags_read(
        &mut self,
        s: &mut Sr830Session,
        cx: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        let status = match r.and_then(|reply| lia_status(&Command::LiaStatus(None), reply)) {
            Ok(status) => status,
            // Reading cleared the flags: the cycle starts again.
            Err(e) if flags_lost(s, &e) => return self.interrupted(s, cx),
            Err(e) => return Next::Done(Err(e)),
        };
        if s.reconnects != self.reconnects {
            return self.interrupted(s, cx);
        }
        let reading = self.reading(s, status);
        self.cycle_done(s, reading)
    }

    fn reading(&self, s: &Sr830Session, status: LiaStatus) -> Reading {
        let (r_mean, r_std) = mean_std(&self.rs);
        Reading {
            r_mean,
            r_std,
            x_mean: mean_std(&self.xs).0,
            y_mean: mean_std(&self.ys).0,
            n: s.config.samples,
            sensitivity: s.sensitivity,
            time_constant: s.time_constant,
            slope: s.slope,
            status,
            flags: ReadingFlags::from_status(status),
            autorange_steps: 0,
            capped: false,
        }
    }

    /// The port was reopened during the cycle, or the flags' answer was lost: start
    /// again, unless that has happened too often in a row.
    fn interrupted(&mut self, s: &Sr830Session, cx: &Cx) -> Next<Self> {
        if let Err(e) = restart(&mut self.restarts) {
            return Next::Done(Err(e));
        }
        self.begin_cycle(s, cx)
    }

    fn cycle_done(&mut self, s: &Sr830Session, mut reading: Reading) -> Next<Self> {
        // Only consecutive failures count towards giving up.
        self.restarts = 0;
        reading.autorange_steps = self.steps;
        if !s.config.autorange {
            return Next::Done(Ok(reading));
        }
        let f = reading.flags;
        let next = ranging::fixed_next(
            s.sensitivity,
            reading.r_mean,
            f.input_overload || f.output_overload,
            !f.any(),
            s.config.min_fraction,
        );
        let Some(next) = next else {
            return Next::Done(Ok(reading));
        };
        if self.steps >= MAX_AUTORANGE_STEPS {
            return Next::Done(Err(gave_up(self.steps, reading)));
        }
        debug!(
            from = %s.sensitivity,
            to = %next,
            flags = ?f,
            r = reading.r_mean,
            "sr830: autorange step",
        );
        Next::exchange(Command::SetSensitivity(next), Self::ranged)
    }

    fn ranged(
        &mut self,
        s: &mut Sr830Session,
        cx: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        if let Err(e) = r {
            return Next::Done(Err(e));
        }
        self.steps += 1;
        self.begin_cycle(s, cx)
    }
}

/// One more restart of a read after the port was reopened or the flags' answer was
/// lost: an error once that has happened more than [`MAX_RESTARTS`] times in a row.
pub(super) fn restart(restarts: &mut usize) -> Result<(), Sr830Error> {
    *restarts += 1;
    if *restarts > MAX_RESTARTS {
        warn!(restarts = *restarts, "sr830: reading interrupted too often");
        return Err(Sr830Error::Interrupted {
            restarts: *restarts,
        });
    }
    debug!(restarts = *restarts, "sr830: read starts again");
    Ok(())
}

/// Whether a failed `LIAS?` after the snapshots is worth reading again for: a lost or
/// garbled answer, with re-asks allowed. Reading cleared the flags, so the read starts
/// over; counted as a retry.
pub(super) fn flags_lost(s: &mut Sr830Session, e: &Sr830Error) -> bool {
    if s.config.retries > 0 && is_transient(e) {
        warn!(error = %e, "sr830: the flags' answer was lost; reading again");
        s.retried += 1;
        true
    } else {
        false
    }
}

/// Autoranging gives up after `steps` range changes; `last` is the last reading.
pub(super) fn gave_up(steps: usize, last: Reading) -> Sr830Error {
    warn!(steps, "sr830: autorange gives up");
    Sr830Error::Autorange {
        steps,
        last: Box::new(last),
    }
}

/// X and Y from a `SNAP? 1,2` answer.
pub(super) fn xy(reply: Option<Reply>) -> Result<(f64, f64), Sr830Error> {
    match reply {
        Some(Reply::Snap(v)) => match v.as_slice() {
            [x, y] => Ok((*x, *y)),
            _ => Err(unexpected(&snap(), Some(Reply::Snap(v)))),
        },
        other => Err(unexpected(&snap(), other)),
    }
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
