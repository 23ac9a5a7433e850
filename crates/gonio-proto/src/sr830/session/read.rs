//! The two reads: the fixed one (settled, averaged over a set count of snapshots,
//! flagged, autoranged) and the one to a precision target (the time constant chosen
//! for the signal, the settling measured from the snapshots, the window grown until
//! its mean is precise enough; [`crate::sr830::target`] holds the rule).

use std::time::Duration;

use tracing::{debug, trace, warn};

use super::{Sr830Session, unexpected};
use crate::engine::{Link, Read, Wire, secs};
use crate::number;
use crate::sr830::buffer::{self, BufferPlan, DisplayDef, EndOfScan, TraceChannel, TraceRange};
use crate::sr830::ranging::{self, OUTPUT_OVERLOAD};
use crate::sr830::target::{
    FIRST_SNAPSHOT_TC, ReadEstimate, ReadTarget, Sequential, WindowMean, choose_time_constant,
    estimate,
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

/// A buffered point within 1e-4 of the clip level is taken as clipped: a stored
/// point carries 15 significant bits (p. 5-17), so a clipped output may be stored up
/// to 2^−15 ≈ 3e-5 below it.
const CLIP_STORED: f64 = OUTPUT_OVERLOAD * (1.0 - 1e-4);

/// A clipped snapshot this many time constants after the change means the value
/// itself is over range: a 24 dB/oct step has come within 1 % by then (manual's
/// settling table, 10 T), so only a step of over a hundred full scales still clips.
const CLIP_SETTLED_TC: f64 = 10.0;

/// The buffer's fixed cost per reading, in `SNAP?` exchanges: `REST` and `STRT`, the
/// look that starts after the last needed point is stored, and its `SPTS?`, `TRCL?`
/// lines and transfer. Measured, not derived: on the simulated hemisphere plan (paint,
/// seed 11, 9600 baud, T = 30 ms, 64 Hz) a buffered reading took 0.39 s longer than
/// the same step read by snapshots at 0.68 s of averaging and 0.05 s longer at
/// 1.87 s, a line extra = 0.585 s − 0.286 × averaging: 0.585 s is 15.6 exchanges of
/// 37.5 ms (`BENCHMARKS.md`, "Reading time").
const BUFFER_OVERHEAD_EXCHANGES: f64 = 16.0;

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

/// A targeted reading's settings chosen ahead of it, and what they were chosen for.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Prepared {
    target: ReadTarget,
    expected: Option<f64>,
    /// The buffer's choice (the time constant chosen is already sent).
    buffered: Option<(ReadEstimate, BufferPlan)>,
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
            fitted: false,
            interval_tc: None,
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

    /// The flags at a window's end ([`Self::flags`]), with the output overload bit
    /// the window's own: the bit latched during the transient too, and the window's
    /// points were checked against the clip level one by one instead.
    async fn window_flags(
        &mut self,
        link: &Link,
        reconnects: usize,
        clipped: bool,
    ) -> Result<Option<LiaStatus>, Sr830Error> {
        let own = if clipped {
            LiaStatus::OUTPUT_OVERLOAD
        } else {
            0
        };
        Ok(self
            .flags(link, reconnects)
            .await?
            .map(|s| LiaStatus((s.0 & !LiaStatus::OUTPUT_OVERLOAD) | own)))
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
            fitted: w.is_some_and(|w| w.fitted),
            snapshot_interval_s: w
                .and_then(|w| w.interval_tc)
                .map(|i| i * self.time_constant.seconds()),
            sample_rate: None,
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
        let prepared = self
            .prepared
            .take()
            .filter(|p| p.target == target && p.expected == expected);
        let buffered = match prepared {
            Some(p) => p.buffered,
            None => self.prepare_targeted(link, target, expected).await?,
        };
        self.prepared = None;
        let mut read = Read::new("sr830");
        loop {
            let end = match buffered {
                Some((est, plan)) => {
                    self.segment_buffered(link, &mut t, read.steps, plan, est)
                        .await?
                }
                None => self.segment(link, &mut t, read.steps).await?,
            };
            let next = match end {
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

    /// The time constant (and whether to read through the buffer) for a signal of
    /// `expected` V, chosen and sent; kept for the reading to `target` that follows.
    /// Returns the buffer's choice.
    pub(super) async fn prepare_targeted(
        &mut self,
        link: &Link,
        target: ReadTarget,
        expected: Option<f64>,
    ) -> Result<Option<(ReadEstimate, BufferPlan)>, Sr830Error> {
        self.prepared = None;
        let choice = match (expected, &self.config.noise) {
            (Some(e), Some(noise)) if self.config.time_constant_range.is_some() => {
                choose_time_constant(
                    e.abs(),
                    &target,
                    noise,
                    self.slope,
                    self.config.time_constant_choices(),
                    self.config.exchange_s,
                )
            }
            _ => None,
        };
        let buffered = expected.and_then(|e| self.buffer_choice(e.abs(), &target, choice));
        let choice = buffered.map(|(c, _)| c).or(choice);
        // Sent even when it is already set: the transient then always starts at the
        // same instant, so a resumed run reads what an uninterrupted one did whatever
        // the time constant was left at.
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
        self.prepared = Some(Prepared {
            target,
            expected,
            buffered,
        });
        Ok(buffered)
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
            // The lock-in takes the values when the query's line has arrived: a fixed
            // time after it is sent (its length is fixed), which the model absorbs,
            // where the reply's arrival varies with its digits and signs by a few ms
            // — at 30 ms a few percent of T, on a transient's slope far more than
            // the noise.
            let (sent, retried) = (link.now(), self.core.retried);
            let Some((x, y)) = self.snap(link, reconnects).await? else {
                return Ok(End::Interrupted);
            };
            let tau = (sent.saturating_sub(t0)).as_secs_f64() / tc_s;
            let fs = self.sensitivity.volts();
            if self.core.retried != retried {
                // Sent again: when its values were taken is not known.
                trace!(tau, "sr830: snapshot after a re-send, not used");
            } else if [x, y, x.hypot(y)].iter().any(|v| v.abs() >= CLIP * fs) {
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
        let Some(status) = self.window_flags(link, reconnects, t.clipped).await? else {
            return Ok(End::Interrupted);
        };
        Ok(End::Read(self.reading(
            t.seq.result(),
            status,
            steps,
            t.capped,
        )))
    }

    /// Whether to read through the buffer, and at which time constant and rate: the
    /// fastest estimate over the allowed time constants with the buffer's samples
    /// ([`estimate`] at the rate [`buffer::buffer_plan`] allows, plus the buffer's
    /// per-reading overhead, [`BUFFER_OVERHEAD_EXCHANGES`] exchanges) against `snap`,
    /// the `SNAP?` choice. `None` without `buffer`, a noise law, or a gain, and for a
    /// signal outside the present range or within ten noise σ of zero.
    fn buffer_choice(
        &self,
        expected: f64,
        target: &ReadTarget,
        snap: Option<ReadEstimate>,
    ) -> Option<(ReadEstimate, BufferPlan)> {
        let c = &self.config;
        let noise = c.noise.as_ref().filter(|_| c.buffer)?;
        // Only a signal the present range fits, well above the noise: a range change
        // costs a whole buffered look where a snapshot shows it at once, and a dark's
        // R (noise alone) is no value the transient rule's estimate models.
        let fs = self.sensitivity.volts();
        let snr2 =
            expected * expected / noise.snapshot_variance(expected, self.slope, self.time_constant);
        if !(c.min_fraction * fs..=0.9 * fs).contains(&expected) || snr2 < 100.0 {
            return None;
        }
        let overhead = BUFFER_OVERHEAD_EXCHANGES * c.exchange_s;
        let best = c
            .time_constant_choices()
            .into_iter()
            .filter_map(|tc| {
                let plan = buffer::buffer_plan(tc, c.baud, buffer::BUFFER_LOAD)?;
                let step = 0.25 * expected;
                let e = estimate(expected, step, target, noise, self.slope, tc, 1.0 / plan.hz);
                Some((e, plan))
            })
            .min_by(|a, b| a.0.total_s().total_cmp(&b.0.total_s()))?;
        let snap_s = snap.map_or(f64::INFINITY, |s| s.total_s());
        let faster = best.0.total_s() + overhead < snap_s;
        debug!(
            expected,
            buffered_s = best.0.total_s() + overhead,
            snap_s,
            faster,
            "sr830: buffer or snapshots"
        );
        faster.then_some(best)
    }

    /// Sets the buffer up for `plan`'s rate (once until the port is reopened): CH1
    /// and CH2 show X and Y, 1 Shot, the rate.
    async fn buffer_setup(&mut self, link: &Link, plan: &BufferPlan) -> Result<(), Sr830Error> {
        if self.buffer_rate == Some(plan.rate) {
            return Ok(());
        }
        if self.buffer_rate.is_none() {
            for d in DisplayDef::XY {
                self.ask(link, &Command::SetDisplay(d)).await?;
            }
            self.ask(link, &Command::SetEndOfScan(EndOfScan::OneShot))
                .await?;
        }
        self.ask(link, &Command::SetSampleRate(plan.rate)).await?;
        self.buffer_rate = Some(plan.rate);
        Ok(())
    }

    /// `count` points of `channel` from bin `start`, by `TRCL?`.
    async fn trace(
        &mut self,
        link: &Link,
        channel: TraceChannel,
        start: u16,
        count: u16,
    ) -> Result<Vec<f64>, Sr830Error> {
        let Some(range) = TraceRange::new(channel, start, count) else {
            unreachable!("bins within SPTS?, which is at most the buffer's length");
        };
        let command = Command::TraceStored(range);
        match self.ask(link, &command).await? {
            Some(Reply::TraceStored(v)) => Ok(v.into_iter().map(|p| p.value()).collect()),
            other => Err(unexpected(&command, other)),
        }
    }

    /// One transient read through the buffer: `REST`, `STRT`, then, from when a
    /// clipped output would mean over range (or the estimate `est` expects the target
    /// met, if sooner), `SPTS?` and the new points of X and Y by `TRCL?`, again and
    /// again (storage goes on meanwhile: 1 Shot bins keep their numbers), each
    /// point at its sample instant in the rule, until the rule is met, the cap or the
    /// buffer's end is reached; then `LIAS?` for the flags. Clipped points are
    /// treated as [`segment`](Self::segment) treats clipped snapshots.
    async fn segment_buffered(
        &mut self,
        link: &Link,
        t: &mut Targeted,
        steps: usize,
        plan: BufferPlan,
        est: ReadEstimate,
    ) -> Result<End, Sr830Error> {
        let reconnects = self.core.reconnects;
        self.buffer_setup(link, &plan).await?;
        self.ask(link, &Command::ResetStorage).await?;
        self.ask(link, &Command::StartStorage).await?;
        // The first point one period after STRT arrived (the twin's assumption; the
        // fit is invariant under a shift of the time origin, so an instrument that
        // samples a little earlier or later does not bias it).
        let started = link.now();
        let t0 = self.changed_at.min(started);
        let tc_s = self.time_constant.seconds();
        let period = 1.0 / plan.hz;
        let tau_of = |i: usize| ((started - t0).as_secs_f64() + (i + 1) as f64 * period) / tc_s;
        t.seq = Sequential::new(usize::from(self.slope.index()) + 1, tau_of(0));
        t.clipped = false;
        // A first look once a clipped output would mean over range (10 T), so that a
        // wrong range costs no more than with snapshots; then when the estimate
        // expects the target met.
        let clip_look = t0.saturating_add(secs((CLIP_SETTLED_TC + 1.0) * tc_s));
        let first_look = t0.saturating_add(secs(est.total_s())).min(clip_look);
        if link.now() < first_look {
            link.sleep(first_look).await;
        }
        let mut have: u16 = 0;
        let cap = t.started.saturating_add(secs(t.target.max_s));
        loop {
            let n = match self.ask(link, &Command::StoredPoints).await? {
                Some(Reply::StoredPoints(n)) => n,
                other => return Err(unexpected(&Command::StoredPoints, other)),
            };
            if self.core.reconnects != reconnects {
                return Ok(End::Interrupted);
            }
            if n > have {
                let k = n - have;
                let xs = self.trace(link, TraceChannel::Ch1, have, k).await?;
                let ys = self.trace(link, TraceChannel::Ch2, have, k).await?;
                if self.core.reconnects != reconnects {
                    return Ok(End::Interrupted);
                }
                let fs = self.sensitivity.volts();
                for (i, (x, y)) in xs.into_iter().zip(ys).enumerate() {
                    let tau = tau_of(usize::from(have) + i);
                    if [x, y, x.hypot(y)]
                        .iter()
                        .any(|v| v.abs() >= CLIP_STORED * fs)
                    {
                        let late = tau >= CLIP_SETTLED_TC || t.after_range;
                        if t.seq.window_start().is_some() || late {
                            if let Some(next) = ranging::overload_range(self.sensitivity) {
                                debug!(
                                    tau,
                                    x, y, "sr830: buffered output clipped after the transient"
                                );
                                return Ok(End::Range(next));
                            }
                            t.clipped = true;
                        }
                        continue;
                    }
                    t.after_range = false;
                    t.seq.push(tau, x, y);
                }
                have = n;
                if self.assess(t) {
                    break;
                }
            }
            let finish = link.now().saturating_add(secs(self.config.exchange_s));
            if finish > cap || have >= buffer::BUFFER_POINTS {
                warn!(
                    max_s = t.target.max_s,
                    points = have,
                    "sr830: buffered reading capped before its target"
                );
                t.capped = true;
                break;
            }
            // Looked at again at once: the transfer then runs while storage goes on,
            // and only the last look's points are left to carry at the end.
            if n == have {
                link.sleep(link.now().saturating_add(secs(period))).await;
            }
        }
        let Some(status) = self.window_flags(link, reconnects, t.clipped).await? else {
            return Ok(End::Interrupted);
        };
        let mut reading = self.reading(t.seq.result(), status, steps, t.capped);
        reading.sample_rate = Some(plan.rate);
        Ok(End::Read(reading))
    }

    /// Assesses the segment's samples against the target: whether the window's mean
    /// meets it.
    fn assess(&self, t: &mut Targeted) -> bool {
        let noise = self.config.noise;
        let (slope, tc) = (self.slope, self.time_constant);
        let law = noise.map(|n| move |r: f64| n.snapshot_variance(r, slope, tc));
        let a = t
            .seq
            .assess(&t.target, law.as_ref().map(|f| f as &dyn Fn(f64) -> f64));
        debug!(
            samples = t.seq.len(),
            window = ?a.window_start,
            sigma_mean = a.sigma_mean,
            target = a.target,
            "sr830: buffered samples assessed"
        );
        a.done
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
