//! The two reads: the fixed one (settled, averaged over a set count of snapshots,
//! flagged, autoranged) and the one to a precision target (the time constant chosen
//! for the signal, the settling measured from the snapshots, the window grown until
//! its mean is precise enough; [`crate::sr830::target`] holds the rule).

use std::time::Duration;

use tracing::{debug, trace, warn};

use super::{Sr830Session, unexpected};
use crate::engine::{Link, Read, Wire, secs};
use crate::number;
use crate::sr830::ranging::{self, OUTPUT_OVERLOAD};
use crate::sr830::target::{
    FIRST_SNAPSHOT_TC, ReadTarget, Sequential, WindowMean, choose_time_constant,
};
use crate::sr830::{
    Command, LiaStatus, MAX_AUTORANGE_STEPS, Reading, ReadingFlags, Reply, Sensitivity, SnapParams,
    Sr830Error,
};

/// `SNAP? 1,2`.
const SNAP: Command = Command::Snap(SnapParams::XY);

/// An output clips at [`OUTPUT_OVERLOAD`] × full scale (manual, OUTPUT OVLD); a
/// snapshot within 1e-5 of it is taken as clipped.
const CLIP: f64 = OUTPUT_OVERLOAD * (1.0 - 1e-5);

/// A clipped snapshot this many time constants after the change means the value
/// itself is over range: a 24 dB/oct step has come within 1 % by then (manual's
/// settling table, 10 T), so only a step of over a hundred full scales still clips.
const CLIP_SETTLED_TC: f64 = 10.0;

/// What a targeted read carries from one segment (one transient) to the next.
struct Targeted {
    target: ReadTarget,
    /// When the read began (for `max_s`).
    started: Duration,
    /// The segment's snapshots and the rule that weighs them.
    seq: Sequential,
    /// The segment began with a range change of this read's: the light is as it was,
    /// so a clipped snapshot is over range at once.
    after_range: bool,
    /// A snapshot clipped at the least sensitive range.
    clipped: bool,
    /// The read reached `max_s` before its target.
    capped: bool,
}

/// How a segment ends.
enum End {
    /// The port was reopened during it, or the flags' answer was lost.
    Interrupted,
    /// Its output clipped after the transient: this range fits better.
    Range(Sensitivity),
    /// The window's mean, flagged.
    Read(Reading),
}

impl Sr830Session {
    /// The fixed read: a [`cycle`](Self::cycle), run again when interrupted or ranged.
    pub(super) async fn read(&mut self, link: &Link) -> Result<Reading, Sr830Error> {
        let mut read = Read::new("sr830");
        loop {
            let Some(mut reading) = self.cycle(link).await? else {
                read.restart(|restarts| Sr830Error::Interrupted { restarts })?;
                continue;
            };
            read.restarts = 0;
            reading.autorange_steps = read.steps;
            let Some(next) = self.next_range(&reading, false) else {
                return Ok(reading);
            };
            if read.exhausted(MAX_AUTORANGE_STEPS) {
                return Err(gave_up(read.steps, reading));
            }
            debug!(from = %self.sensitivity, to = %next, flags = ?reading.flags, r = reading.r_mean, "sr830: autorange step");
            self.ask(link, &Command::SetSensitivity(next)).await?;
            read.steps += 1;
        }
    }

    /// One cycle, as [`start_read`](Sr830Session::start_read) lists it; the first `LIAS?`
    /// is asked again if its answer is lost (its value is not used). `None` when it must
    /// start again: the port was reopened during it (its
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
            let Some((x, y)) = self.snap(link, reconnects).await? else {
                return Ok(None);
            };
            xs.push(x);
            ys.push(y);
            rs.push(x.hypot(y));
            if rs.len() >= self.config.samples {
                break;
            }
            link.sleep(link.now().saturating_add(spacing)).await;
        }
        let Some(status) = self.flags(link, reconnects).await? else {
            return Ok(None);
        };
        let (r_mean, r_std) = number::mean_std(&rs);
        let w = WindowMean {
            r_mean,
            r_std,
            x_mean: number::mean_std(&xs).0,
            y_mean: number::mean_std(&ys).0,
            n: self.config.samples,
            settle_tc: 0.0,
        };
        Ok(Some(self.reading(Some(w), status, 0, false)))
    }

    /// X and Y from `SNAP? 1,2`; `None` if the port was reopened since `reconnects`
    /// (the read starts again).
    async fn snap(
        &mut self,
        link: &Link,
        reconnects: usize,
    ) -> Result<Option<(f64, f64)>, Sr830Error> {
        let xy = match self.ask(link, &SNAP).await? {
            Some(Reply::Snap(v)) => match v.as_slice() {
                [x, y] => (*x, *y),
                _ => return Err(unexpected(&SNAP, Some(Reply::Snap(v)))),
            },
            other => return Err(unexpected(&SNAP, other)),
        };
        Ok((self.core.reconnects == reconnects).then_some(xy))
    }

    /// `LIAS?` after the snapshots, for the flags; `None` when the read must start
    /// again: the port was reopened since `reconnects`, or the answer was lost or
    /// garbled with re-asks allowed (reading cleared the flags; counted as a retry).
    async fn flags(
        &mut self,
        link: &Link,
        reconnects: usize,
    ) -> Result<Option<LiaStatus>, Sr830Error> {
        match self.lia_status(link).await {
            Ok(status) => Ok((self.core.reconnects == reconnects).then_some(status)),
            Err(e) if self.config.retries > 0 && Self::is_transient(&e) => {
                warn!(error = %e, "sr830: the flags' answer was lost; reading again");
                self.core.retried += 1;
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }

    /// The range autoranging moves to after `reading`, by the targeted rule or the
    /// fixed one ([`ranging`]); `None` to keep it, or without autorange.
    fn next_range(&self, reading: &Reading, targeted: bool) -> Option<Sensitivity> {
        let f = reading.flags;
        let (at, r, min) = (self.sensitivity, reading.r_mean, self.config.min_fraction);
        let (over, clean) = (f.input_overload || f.output_overload, !f.any());
        match (self.config.autorange, targeted) {
            (false, _) => None,
            (true, false) => ranging::fixed_next(at, r, over, clean, min),
            (true, true) => ranging::targeted_next(at, r, reading.r_std, over, clean, min),
        }
    }

    /// The reading of a window `w` at the present settings, flagged from `status`;
    /// without a window (every snapshot clipped until the cap), an overload.
    fn reading(
        &self,
        w: Option<WindowMean>,
        status: LiaStatus,
        steps: usize,
        capped: bool,
    ) -> Reading {
        let status = match w {
            Some(_) => status,
            None => LiaStatus(status.0 | LiaStatus::OUTPUT_OVERLOAD),
        };
        let nan = f64::NAN;
        Reading {
            r_mean: w.map_or(nan, |w| w.r_mean),
            r_std: w.map_or(nan, |w| w.r_std),
            x_mean: w.map_or(nan, |w| w.x_mean),
            y_mean: w.map_or(nan, |w| w.y_mean),
            n: w.map_or(0, |w| w.n),
            sensitivity: self.sensitivity,
            time_constant: self.time_constant,
            slope: self.slope,
            status,
            flags: ReadingFlags::from_status(status),
            autorange_steps: steps,
            capped,
        }
    }

    /// The targeted read: segments until one yields a reading that autoranging keeps.
    pub(super) async fn read_targeted(
        &mut self,
        link: &Link,
        target: ReadTarget,
        expected: Option<f64>,
    ) -> Result<Reading, Sr830Error> {
        let mut t = Targeted {
            target,
            started: link.now(),
            seq: Sequential::new(1, 0.0),
            after_range: false,
            clipped: false,
            capped: false,
        };
        let choice = match (expected, &self.config.noise) {
            (Some(e), Some(noise)) if self.config.time_constant_range.is_some() => {
                choose_time_constant(
                    e.abs(),
                    &t.target,
                    noise,
                    self.slope,
                    self.config.time_constant_choices(),
                    self.config.exchange_s,
                )
            }
            _ => None,
        };
        // Sent even when it is already set: the transient then always starts at the
        // same instant after a move, so a resumed run reads what an uninterrupted one
        // did whatever the time constant was left at.
        if let Some(c) = choice {
            debug!(
                expected,
                from = %self.time_constant,
                to = %c.time_constant,
                settle_s = c.settle_s,
                averaging_s = c.averaging_s,
                "sr830: time constant for the expected signal"
            );
            self.ask(link, &Command::SetTimeConstant(c.time_constant))
                .await?;
        }
        let mut read = Read::new("sr830");
        loop {
            let next = match self.segment(link, &mut t, read.steps).await? {
                End::Interrupted => {
                    read.restart(|restarts| Sr830Error::Interrupted { restarts })?;
                    continue;
                }
                End::Range(next) => next,
                End::Read(reading) => {
                    read.restarts = 0;
                    let next = self.next_range(&reading, true).filter(|_| !t.capped);
                    let Some(next) = next else {
                        return Ok(reading);
                    };
                    if read.exhausted(MAX_AUTORANGE_STEPS) {
                        return Err(gave_up(read.steps, reading));
                    }
                    debug!(from = %self.sensitivity, to = %next, flags = ?reading.flags, r = reading.r_mean, "sr830: autorange");
                    next
                }
            };
            self.ask(link, &Command::SetSensitivity(next)).await?;
            read.steps += 1;
            t.after_range = true;
            if read.exhausted(MAX_AUTORANGE_STEPS + 1) {
                let last = self.reading(t.seq.result(), LiaStatus(0), read.steps, t.capped);
                return Err(gave_up(read.steps, last));
            }
        }
    }

    /// One transient, from the last change at the present time constant: snapshots
    /// from [`FIRST_SNAPSHOT_TC`] after it, back to back, one exchange apart (their
    /// correlation is counted by the rule, and by the reduction from the reading's
    /// `sequential` flag, rather than spaced out), until the rule is met or the next
    /// would pass the cap; then `LIAS?` for the flags.
    async fn segment(
        &mut self,
        link: &Link,
        t: &mut Targeted,
        steps: usize,
    ) -> Result<End, Sr830Error> {
        let reconnects = self.core.reconnects;
        let t0 = self.changed_at;
        let tc_s = self.time_constant.seconds();
        let first = t0.saturating_add(secs(FIRST_SNAPSHOT_TC * tc_s));
        let first_tau = (first.max(link.now()) - t0).as_secs_f64() / tc_s;
        t.seq = Sequential::new(usize::from(self.slope.index()) + 1, first_tau);
        t.clipped = false;
        if link.now() < first {
            link.sleep(first).await;
        }
        loop {
            let Some((x, y)) = self.snap(link, reconnects).await? else {
                return Ok(End::Interrupted);
            };
            let tau = (link.now().saturating_sub(t0)).as_secs_f64() / tc_s;
            let fs = self.sensitivity.volts();
            if [x, y, x.hypot(y)].iter().any(|v| v.abs() >= CLIP * fs) {
                if t.seq.window_start().is_some() || tau >= CLIP_SETTLED_TC || t.after_range {
                    if let Some(next) = ranging::overload_range(self.sensitivity) {
                        debug!(tau, x, y, "sr830: output clipped after the transient");
                        return Ok(End::Range(next));
                    }
                    t.clipped = true;
                }
                trace!(
                    tau,
                    "sr830: snapshot clipped during the transient, not used"
                );
            } else if self.snapshot(t, tau, x, y) {
                break;
            }
            let finish = link.now().saturating_add(secs(self.config.exchange_s));
            if finish > t.started.saturating_add(secs(t.target.max_s)) {
                warn!(
                    max_s = t.target.max_s,
                    snapshots = t.seq.len(),
                    "sr830: reading capped before its target"
                );
                t.capped = true;
                break;
            }
        }
        let Some(status) = self.flags(link, reconnects).await? else {
            return Ok(End::Interrupted);
        };
        // The output overload bit latched during the transient too; the window's
        // snapshots were checked against the clip level one by one instead.
        let own = if t.clipped {
            LiaStatus::OUTPUT_OVERLOAD
        } else {
            0
        };
        let status = LiaStatus((status.0 & !LiaStatus::OUTPUT_OVERLOAD) | own);
        Ok(End::Read(self.reading(
            t.seq.result(),
            status,
            steps,
            t.capped,
        )))
    }

    /// Adds an unclipped snapshot at `tau` to the segment: whether the window's mean
    /// now meets the target.
    fn snapshot(&self, t: &mut Targeted, tau: f64, x: f64, y: f64) -> bool {
        let had_window = t.seq.window_start().is_some();
        t.after_range = false;
        t.seq.push(tau, x, y);
        let noise = self.config.noise;
        let (slope, tc) = (self.slope, self.time_constant);
        let law = noise.map(|n| move |r: f64| n.snapshot_variance(r, slope, tc));
        let a = t
            .seq
            .assess(&t.target, law.as_ref().map(|f| f as &dyn Fn(f64) -> f64));
        trace!(
            tau,
            r = x.hypot(y),
            window = ?a.window_start,
            sigma_mean = a.sigma_mean,
            target = a.target,
            "sr830: snapshot"
        );
        if !had_window && a.window_start.is_some() {
            debug!(
                settle_s = tau * self.time_constant.seconds(),
                window_start = a.window_start,
                "sr830: settled (transient under its bound)"
            );
        }
        a.done
    }
}

/// Autoranging gave up after `steps` range changes; `last` is the last reading.
fn gave_up(steps: usize, last: Reading) -> Sr830Error {
    Sr830Error::Autorange {
        steps,
        last: Box::new(last),
    }
}
