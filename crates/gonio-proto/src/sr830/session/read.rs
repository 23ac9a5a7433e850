//! A reading: settled, averaged, flagged, autoranged.

use tracing::{debug, warn};

use super::Sr830Session;
use super::unexpected;
use crate::engine::{Link, Wire, secs};
use crate::number;
use crate::sr830::{
    Command, MAX_AUTORANGE_STEPS, Reading, ReadingFlags, Reply, SnapParams, Sr830Error, ranging,
};

/// Most times one read starts over after the port was lost and reopened (or the flags'
/// answer was lost).
const MAX_RESTARTS: usize = 2;

impl Sr830Session {
    /// The read: a cycle (see [`cycle`](Self::cycle)), started again when it was
    /// interrupted; with autorange, an input or output overload steps one range less
    /// sensitive, a clean signal under `min_fraction` of full scale one range more,
    /// and the cycle runs again.
    pub(super) async fn read(&mut self, link: &Link) -> Result<Reading, Sr830Error> {
        let mut steps = 0;
        let mut restarts = 0;
        loop {
            let Some(mut reading) = self.cycle(link).await? else {
                restart(&mut restarts)?;
                continue;
            };
            // Only consecutive failures count towards giving up.
            restarts = 0;
            reading.autorange_steps = steps;
            if !self.config.autorange {
                return Ok(reading);
            }
            let f = reading.flags;
            let next = ranging::fixed_next(
                self.sensitivity,
                reading.r_mean,
                f.input_overload || f.output_overload,
                !f.any(),
                self.config.min_fraction,
            );
            let Some(next) = next else {
                return Ok(reading);
            };
            if steps >= MAX_AUTORANGE_STEPS {
                return Err(gave_up(steps, reading));
            }
            debug!(from = %self.sensitivity, to = %next, flags = ?f, r = reading.r_mean, "sr830: autorange step");
            self.ask(link, &Command::SetSensitivity(next)).await?;
            steps += 1;
        }
    }

    /// One cycle: wait until the filters have settled; `LIAS?` to clear the bits
    /// latched while settling (asked again if its answer is lost: its value is not
    /// used); `SNAP? 1,2` `samples` times, one time constant apart; `LIAS?` for the
    /// flags. `None` when it must start again: the port was reopened during it (its
    /// samples may predate an instrument restart), or the flags' answer was lost.
    async fn cycle(&mut self, link: &Link) -> Result<Option<Reading>, Sr830Error> {
        let reconnects = self.core.reconnects;
        if link.now() < self.settled_at {
            debug!(wait = ?(self.settled_at - link.now()), "sr830: waiting for the filters to settle");
            link.sleep(self.settled_at).await;
        }
        let mut left = self.config.retries;
        loop {
            match self.lia_status(link).await {
                Ok(_) => break,
                Err(e) if left > 0 && Self::is_transient(&e) => {
                    left -= 1;
                    self.core.retried += 1;
                }
                Err(e) => return Err(e),
            }
        }
        let spacing = secs(self.time_constant.seconds());
        let (mut xs, mut ys, mut rs) = (Vec::new(), Vec::new(), Vec::new());
        loop {
            let (x, y) = xy(self.ask(link, &SNAP).await?)?;
            if self.core.reconnects != reconnects {
                return Ok(None);
            }
            xs.push(x);
            ys.push(y);
            rs.push(x.hypot(y));
            if rs.len() >= self.config.samples {
                break;
            }
            link.sleep(link.now().saturating_add(spacing)).await;
        }
        let status = match self.lia_status(link).await {
            Ok(status) => status,
            // Reading cleared the flags: the cycle starts again.
            Err(e) if self.flags_lost(&e) => return Ok(None),
            Err(e) => return Err(e),
        };
        if self.core.reconnects != reconnects {
            return Ok(None);
        }
        let (r_mean, r_std) = number::mean_std(&rs);
        Ok(Some(Reading {
            r_mean,
            r_std,
            x_mean: number::mean_std(&xs).0,
            y_mean: number::mean_std(&ys).0,
            n: self.config.samples,
            sensitivity: self.sensitivity,
            time_constant: self.time_constant,
            slope: self.slope,
            status,
            flags: ReadingFlags::from_status(status),
            autorange_steps: 0,
            capped: false,
        }))
    }

    /// Whether a failed `LIAS?` after the snapshots is worth reading again for: a lost
    /// or garbled answer, with re-asks allowed. Reading cleared the flags, so the read
    /// starts over; counted as a retry.
    pub(super) fn flags_lost(&mut self, e: &Sr830Error) -> bool {
        if self.config.retries > 0 && Self::is_transient(e) {
            warn!(error = %e, "sr830: the flags' answer was lost; reading again");
            self.core.retried += 1;
            true
        } else {
            false
        }
    }
}

/// `SNAP? 1,2`.
pub(super) const SNAP: Command = Command::Snap(SnapParams::XY);

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
            _ => Err(unexpected(&SNAP, Some(Reply::Snap(v)))),
        },
        other => Err(unexpected(&SNAP, other)),
    }
}
