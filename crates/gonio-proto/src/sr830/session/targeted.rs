//! A reading to a precision target: the time constant chosen for the signal, the
//! settling measured from the snapshots, the window grown until its mean is precise
//! enough ([`crate::sr830::target`] holds the rule).

use std::time::Duration;

use tracing::{debug, trace, warn};

use super::read::{flags_lost, gave_up, restart, snap, xy};
use super::script::{Next, Op};
use super::{Sr830Session, lia_status};
use crate::machine::{Cx, secs};
use crate::sr830::ranging::{self, OUTPUT_OVERLOAD};
use crate::sr830::target::{FIRST_SNAPSHOT_TC, ReadTarget, Sequential, choose_time_constant};
use crate::sr830::{
    Command, LiaStatus, MAX_AUTORANGE_STEPS, Reading, ReadingFlags, Reply, Sensitivity, Sr830Error,
};

/// An output clips at [`OUTPUT_OVERLOAD`] × full scale (manual, OUTPUT OVLD); a
/// snapshot within 1e-5 of it is taken as clipped.
const CLIP: f64 = OUTPUT_OVERLOAD * (1.0 - 1e-5);

/// A clipped snapshot this many time constants after the change means the value
/// itself is over range: a 24 dB/oct step has come within 1 % by then (manual's
/// settling table, 10 T), so only a step of over a hundred full scales still clips.
const CLIP_SETTLED_TC: f64 = 10.0;

/// The targeted read operation.
#[derive(Debug)]
pub(super) struct TargetedRead {
    target: ReadTarget,
    expected: Option<f64>,
    /// When the read began (for `max_s`).
    started: Duration,
    steps: usize,
    restarts: usize,
    reconnects: usize,
    seq: Sequential,
    /// The change this segment's transient starts from, and its time constant, s.
    t0: Duration,
    tc_s: f64,
    /// The segment began with a range change of this read's: the light is as it was,
    /// so a clipped snapshot is over range at once.
    after_range: bool,
    /// A snapshot clipped at the least sensitive range.
    clipped: bool,
    capped: bool,
}

impl Op for TargetedRead {
    type Value = Reading;

    fn start(&mut self, s: &mut Sr830Session, cx: &mut Cx) -> Next<Self> {
        self.started = cx.now;
        let choice = match (self.expected, &s.config.noise) {
            (Some(e), Some(noise)) if s.config.time_constant_range.is_some() => {
                choose_time_constant(
                    e.abs(),
                    &self.target,
                    noise,
                    s.slope,
                    s.config.time_constant_choices(),
                    s.config.exchange_s,
                )
            }
            _ => None,
        };
        // Sent even when it is already set: the transient then always starts at the
        // same instant after a move, so a resumed run reads what an uninterrupted one
        // did whatever the time constant was left at.
        if let Some(c) = choice {
            debug!(
                expected = self.expected,
                from = %s.time_constant,
                to = %c.time_constant,
                settle_s = c.settle_s,
                averaging_s = c.averaging_s,
                "sr830: time constant for the expected signal"
            );
            return Next::exchange(Command::SetTimeConstant(c.time_constant), Self::tc_set);
        }
        self.begin_segment(s, cx)
    }
}

impl TargetedRead {
    pub(super) fn new(target: ReadTarget, expected: Option<f64>) -> Self {
        TargetedRead {
            target,
            expected,
            started: Duration::ZERO,
            steps: 0,
            restarts: 0,
            reconnects: 0,
            seq: Sequential::new(1, 0.0),
            t0: Duration::ZERO,
            tc_s: 0.0,
            after_range: false,
            clipped: false,
            capped: false,
        }
    }

    fn tc_set(
        &mut self,
        s: &mut Sr830Session,
        cx: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        if let Err(e) = r {
            return Next::Done(Err(e));
        }
        self.begin_segment(s, cx)
    }

    /// A new transient: from the last change, at the present time constant.
    fn begin_segment(&mut self, s: &Sr830Session, cx: &Cx) -> Next<Self> {
        self.reconnects = s.reconnects;
        self.t0 = s.changed_at;
        self.tc_s = s.time_constant.seconds();
        let first = self.t0.saturating_add(secs(FIRST_SNAPSHOT_TC * self.tc_s));
        let first_tau = (first.max(cx.now) - self.t0).as_secs_f64() / self.tc_s;
        self.seq = Sequential::new(usize::from(s.slope.index()) + 1, first_tau);
        self.clipped = false;
        if cx.now < first {
            return Next::Pause {
                until: first,
                then: Self::first_due,
            };
        }
        Next::exchange(snap(), Self::snapped)
    }

    fn first_due(&mut self, _: &mut Sr830Session, _: &mut Cx, (): ()) -> Next<Self> {
        Next::exchange(snap(), Self::snapped)
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
        let tau = (cx.now.saturating_sub(self.t0)).as_secs_f64() / self.tc_s;
        let fs = s.sensitivity.volts();
        let clipped = [x, y, x.hypot(y)].iter().any(|v| v.abs() >= CLIP * fs);
        if clipped {
            if self.seq.window_start().is_some() || tau >= CLIP_SETTLED_TC || self.after_range {
                if let Some(next) = ranging::overload_range(s.sensitivity) {
                    debug!(tau, x, y, "sr830: output clipped after the transient");
                    return Self::range_to(next);
                }
                self.clipped = true;
            }
            trace!(
                tau,
                "sr830: snapshot clipped during the transient, not used"
            );
            return self.next_snapshot(s, cx);
        }
        let had_window = self.seq.window_start().is_some();
        self.after_range = false;
        self.seq.push(tau, x, y);
        let noise = s.config.noise;
        let (slope, tc) = (s.slope, s.time_constant);
        let law = noise.map(|n| move |r: f64| n.snapshot_variance(r, slope, tc));
        let a = self
            .seq
            .assess(&self.target, law.as_ref().map(|f| f as &dyn Fn(f64) -> f64));
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
                settle_s = tau * self.tc_s,
                window_start = a.window_start,
                "sr830: settled (transient under its bound)"
            );
        }
        if a.done {
            return Next::exchange(Command::LiaStatus(None), Self::flags_read);
        }
        self.next_snapshot(s, cx)
    }

    /// The next snapshot at once, unless it would pass the cap: snapshots go back to
    /// back, one exchange apart, their correlation counted by the rule (and by the
    /// reduction, from the reading's `sequential` flag) rather than spaced out.
    fn next_snapshot(&mut self, s: &Sr830Session, cx: &Cx) -> Next<Self> {
        let finish = cx.now.saturating_add(secs(s.config.exchange_s));
        let cap = self.started.saturating_add(secs(self.target.max_s));
        if finish > cap {
            warn!(
                max_s = self.target.max_s,
                snapshots = self.seq.len(),
                "sr830: reading capped before its target"
            );
            self.capped = true;
            return Next::exchange(Command::LiaStatus(None), Self::flags_read);
        }
        Next::exchange(snap(), Self::snapped)
    }

    fn flags_read(
        &mut self,
        s: &mut Sr830Session,
        cx: &mut Cx,
        r: Result<Option<Reply>, Sr830Error>,
    ) -> Next<Self> {
        let status = match r.and_then(|reply| lia_status(&Command::LiaStatus(None), reply)) {
            // The output overload bit latched during the transient too; the window's
            // snapshots were checked against the clip level one by one instead.
            Ok(status) => {
                let own = if self.clipped {
                    LiaStatus::OUTPUT_OVERLOAD
                } else {
                    0
                };
                LiaStatus((status.0 & !LiaStatus::OUTPUT_OVERLOAD) | own)
            }
            Err(e) if flags_lost(s, &e) => return self.interrupted(s, cx),
            Err(e) => return Next::Done(Err(e)),
        };
        if s.reconnects != self.reconnects {
            return self.interrupted(s, cx);
        }
        let Some(w) = self.seq.result() else {
            // Every snapshot clipped until the cap: an overload.
            return self.finish(s, self.reading_of(s, status, None));
        };
        let reading = self.reading_of(s, status, Some(w));
        self.finish(s, reading)
    }

    fn reading_of(
        &self,
        s: &Sr830Session,
        status: LiaStatus,
        w: Option<crate::sr830::target::WindowMean>,
    ) -> Reading {
        let mut status = status;
        if w.is_none() {
            status = LiaStatus(status.0 | LiaStatus::OUTPUT_OVERLOAD);
        }
        let nan = f64::NAN;
        Reading {
            r_mean: w.map_or(nan, |w| w.r_mean),
            r_std: w.map_or(nan, |w| w.r_std),
            x_mean: w.map_or(nan, |w| w.x_mean),
            y_mean: w.map_or(nan, |w| w.y_mean),
            n: w.map_or(0, |w| w.n),
            sensitivity: s.sensitivity,
            time_constant: s.time_constant,
            slope: s.slope,
            status,
            flags: ReadingFlags::from_status(status),
            autorange_steps: self.steps,
            capped: self.capped,
        }
    }

    fn finish(&mut self, s: &Sr830Session, reading: Reading) -> Next<Self> {
        self.restarts = 0;
        if !s.config.autorange || self.capped {
            return Next::Done(Ok(reading));
        }
        let f = reading.flags;
        let next = ranging::targeted_next(
            s.sensitivity,
            reading.r_mean,
            reading.r_std,
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
        debug!(from = %s.sensitivity, to = %next, flags = ?f, r = reading.r_mean, "sr830: autorange");
        Self::range_to(next)
    }

    fn range_to(next: Sensitivity) -> Next<Self> {
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
        self.after_range = true;
        if self.steps > MAX_AUTORANGE_STEPS {
            let w = self.seq.result();
            let last = self.reading_of(s, LiaStatus(0), w);
            return Next::Done(Err(gave_up(self.steps, last)));
        }
        self.begin_segment(s, cx)
    }

    /// The port was reopened during the segment, or the flags' answer was lost: start
    /// the segment again, unless that has happened too often in a row.
    fn interrupted(&mut self, s: &Sr830Session, cx: &Cx) -> Next<Self> {
        if let Err(e) = restart(&mut self.restarts) {
            return Next::Done(Err(e));
        }
        self.begin_segment(s, cx)
    }
}
