//! The rig: the instrument, the bench and the run file that travel together into
//! each step, and what one step, the session's start-up and its end do with them.

use std::time::Duration;

use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use gonio_core::kinematics;
use gonio_driver::detector::{DetectorError, Disposition, Reading};
use gonio_driver::motion::AxisState;
use gonio_driver::smc100::{AxisError, MotionError};
use gonio_driver::{Clock, Goniometer, SpectralError, TransportError};
use tokio::sync::broadcast;

use gonio_core::goniometer::Mechanics;
use gonio_driver::bench::{Bench, BenchError, Setup};
use gonio_plan::StepKind;
use gonio_run::{EventRecord, ReadingRecord, RunStore, StoreError, StoredStep, flags, wall_now};

use super::{EngineConfig, Event, Outcome, Planner, ReadTarget, SessionReport, setup_for};

/// How one step went.
pub(super) enum StepOutcome {
    Measured(Box<ReadingRecord>),
    /// Recovered from a fault; measure the step again.
    Again(String),
    Skip(String),
    Stop(Outcome),
}

/// What asking the planner gave.
pub(super) enum Planned {
    /// A batch was appended: its steps, and the run's steps now.
    Batch {
        steps: Vec<StoredStep>,
        total: usize,
    },
    /// No further batch: the run is complete.
    Done,
    /// The session ends so (the planner failed).
    Stop(Outcome),
}

/// The instrument, the bench and the store: what travels into each step.
pub(super) struct Rig<C: Clock + Clone, B: Bench> {
    pub(super) gonio: Goniometer<C>,
    pub(super) bench: B,
    pub(super) store: RunStore,
    pub(super) mech: Mechanics,
    pub(super) cfg: EngineConfig,
    pub(super) setup: Option<Setup>,
    pub(super) channel: Option<String>,
    /// The band selector's shutter as last set (`None`: not yet this session).
    pub(super) shutter_open: Option<bool>,
    pub(super) t0: Duration,
    pub(super) events: broadcast::Sender<Event>,
    /// The session's span: each step's span is its child, on whichever thread runs it.
    pub(super) span: tracing::Span,
    /// The targets' absolute floor from the detector, once asked this session.
    pub(super) floor: Option<f64>,
}

/// What start-up found.
pub(super) struct Start {
    pub(super) pending: Vec<StoredStep>,
    pub(super) total: usize,
    pub(super) finished: usize,
}

/// The role axes with their targets, for `move_to`.
fn targets<'a>(axes: &'a [String; 4], stages: &[f64; 4]) -> Vec<(&'a str, f64)> {
    axes.iter()
        .map(String::as_str)
        .zip(stages.iter().copied())
        .collect()
}

/// A pair in degrees from directions.
fn pair_deg(d: gonio_core::DirPair) -> PairDeg {
    PairDeg {
        incident: SphericalDeg::from(d.wi),
        outgoing: SphericalDeg::from(d.wo),
    }
}

/// The axis and cause of a motion error.
fn axis_fault(e: &MotionError) -> Option<(&str, &AxisError)> {
    match e {
        MotionError::AtAxis { axis, source } => Some((axis.as_str(), source)),
        _ => None,
    }
}

impl<C: Clock + Clone, B: Bench> Rig<C, B> {
    fn physical_s(&self) -> f64 {
        self.gonio
            .motion
            .clock()
            .now()
            .saturating_sub(self.t0)
            .as_secs_f64()
    }

    fn retried(&self) -> u64 {
        self.gonio.motion.retried()
            + self.gonio.detector.retried()
            + self.gonio.spectral.as_ref().map_or(0, |s| s.retried())
    }

    fn fault(
        &mut self,
        step: Option<i64>,
        message: &str,
        recovering: bool,
    ) -> Result<(), StoreError> {
        tracing::warn!(parent: &self.span, step = ?step, recovering, "fault: {message}");
        let _ = self.events.send(Event::Fault {
            step_id: step,
            message: message.to_string(),
            recovering,
        });
        self.store.event("fault", step, message)
    }

    /// An engine state change of the session's own (a pause), logged, stored and
    /// told to listeners.
    pub(super) fn note(
        &mut self,
        event: Event,
        kind: &str,
        message: &str,
    ) -> Result<(), StoreError> {
        tracing::info!(parent: &self.span, "{message}");
        let _ = self.events.send(event);
        self.store.event(kind, None, message)
    }

    /// Session start-up: a session row, the instrument identified and set up, the
    /// axes that lost their reference homed, the detector's range restored to where
    /// the run left it. `Ok(Err(outcome))` when the instrument cannot start.
    pub(super) fn start(&mut self) -> Result<Result<Start, Outcome>, StoreError> {
        let span = self.span.clone();
        let _entered = span.enter();
        let sessions = self.store.sessions()?;
        self.store.begin_session(&self.cfg.software)?;
        let steps = self.store.steps()?;
        let total = steps.len();
        let pending: Vec<StoredStep> = steps.into_iter().filter(|s| s.state == "pending").collect();
        let finished = total - pending.len();
        let resumed = !sessions.is_empty();
        if sessions.last().is_some_and(|s| s.ended_s.is_none()) {
            self.store.event(
                "note",
                None,
                "the previous session ended without a clean stop (killed or power lost)",
            )?;
        }
        self.store.event(
            if resumed { "resume" } else { "start" },
            None,
            &format!("{finished} of {total} steps finished before this session"),
        )?;
        tracing::info!(finished, total, resumed, "session started");
        let _ = self.events.send(Event::Started {
            done: finished,
            total,
            resumed,
        });
        self.t0 = self.gonio.motion.clock().now();
        let report = match self.gonio.start() {
            Ok(r) => r,
            Err(e) => {
                let m = format!("instrument start-up failed: {e}");
                self.fault(None, &m, false)?;
                return Ok(Err(Outcome::Faulted(m)));
            }
        };
        self.store.event(
            "instrument",
            None,
            &format!(
                "detector {}; axes {}",
                report.detector,
                report
                    .axes
                    .iter()
                    .map(|(n, i)| format!("{n}: {}", i.description()))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )?;
        let unreferenced: Vec<String> = report
            .axes
            .iter()
            .filter(|(_, i)| !i.referenced)
            .map(|(n, _)| n.clone())
            .collect();
        if !unreferenced.is_empty() {
            let names: Vec<&str> = unreferenced.iter().map(String::as_str).collect();
            if let Err(e) = self.gonio.motion.home(&names) {
                let m = format!("homing failed: {e}");
                let aborted = matches!(axis_fault(&e), Some((_, AxisError::Aborted)));
                self.fault(None, &m, false)?;
                return Ok(Err(if aborted {
                    Outcome::Interrupted
                } else {
                    Outcome::Faulted(m)
                }));
            }
            tracing::info!(axes = ?unreferenced, "homed");
            self.store
                .event("home", None, &format!("homed {}", unreferenced.join(", ")))?;
            let _ = self.events.send(Event::Homed { axes: unreferenced });
        }
        if let Some(first) = pending.first()
            && let Err(outcome) = self.restore_range(first.id)?
        {
            return Ok(Err(outcome));
        }
        Ok(Ok(Start {
            pending,
            total,
            finished,
        }))
    }

    /// Puts the detector's range (and time constant) where the reading before step
    /// `next` left them, so that autoranging takes the same path, and a point starts
    /// from the same filter state, as without an interruption (nothing to do when
    /// they are there already).
    fn restore_range(&mut self, next: i64) -> Result<Result<(), Outcome>, StoreError> {
        let Some(last) = self.store.last_reading_before(next)? else {
            return Ok(Ok(()));
        };
        if last.time_constant != self.gonio.detector.integration() {
            match self.gonio.detector.restore_integration(last.time_constant) {
                Ok(Some(tc)) => self.store.event(
                    "detector",
                    None,
                    &format!("time constant restored to {tc}"),
                )?,
                Ok(None) => {}
                Err(e) => {
                    let m = format!("restoring the time constant failed: {e}");
                    self.fault(None, &m, false)?;
                    return Ok(Err(Outcome::Faulted(m)));
                }
            }
        }
        if last.sensitivity == self.gonio.detector.range() {
            return Ok(Ok(()));
        }
        match self.gonio.detector.restore_range(last.sensitivity) {
            Ok(Some(range)) => self.store.event(
                "detector",
                None,
                &format!("sensitivity restored to {range}"),
            )?,
            Ok(None) => {}
            Err(e) => {
                let m = format!("restoring the sensitivity failed: {e}");
                self.fault(None, &m, false)?;
                return Ok(Err(Outcome::Faulted(m)));
            }
        }
        Ok(Ok(()))
    }

    /// Asks the adaptive plan's planner for the next batch (no step is pending) and
    /// appends it to the run file in one transaction, with its decision and its
    /// `batch` event. `total` is the run's steps before it.
    pub(super) fn plan(
        &mut self,
        planner: &mut Planner,
        total: usize,
    ) -> Result<Planned, StoreError> {
        let span = tracing::info_span!(parent: &self.span, "planner");
        let _entered = span.enter();
        let t = std::time::Instant::now();
        let decided = planner(&self.store);
        let took_s = t.elapsed().as_secs_f64();
        let batch = match decided {
            Ok(Some(b)) => b,
            Ok(None) => {
                tracing::info!(took_s, "planner: no further batch");
                return Ok(Planned::Done);
            }
            Err(why) => return self.planner_failed(why, took_s),
        };
        tracing::debug!(
            took_s,
            steps = batch.steps.len(),
            points = batch.decision.points,
            "planner decided"
        );
        let (d, steps) = match self.store.append_batch(&batch) {
            Ok(a) => a,
            // The planner's fault (a batch without steps), not the file's.
            Err(e @ StoreError::BadBatch { .. }) => {
                return self.planner_failed(e.to_string(), took_s);
            }
            Err(e) => return Err(e),
        };
        let total = total + steps.len();
        tracing::info!(
            batch = d.id,
            points = d.points,
            steps = d.steps,
            first_step = d.first_step,
            readings = d.readings,
            method = %d.method,
            total,
            took_s,
            "batch {}: {} points, {} steps ({})",
            d.id,
            d.points,
            d.steps,
            d.method
        );
        let _ = self.events.send(Event::Batch {
            batch: d.id,
            points: d.points,
            steps: steps.len(),
            total,
        });
        if let Some(first) = steps.first()
            && let Err(outcome) = self.restore_range(first.id)?
        {
            return Ok(Planned::Stop(outcome));
        }
        Ok(Planned::Batch { steps, total })
    }

    fn planner_failed(&mut self, why: String, took_s: f64) -> Result<Planned, StoreError> {
        let m = format!("adaptive planner: {why}");
        tracing::debug!(took_s, "planner failed");
        self.fault(None, &m, false)?;
        Ok(Planned::Stop(Outcome::Faulted(m)))
    }

    /// Takes one step: bench, motion, reading, commit.
    pub(super) fn step(&mut self, s: &StoredStep) -> Result<StepOutcome, StoreError> {
        let _span = tracing::info_span!(
            parent: &self.span,
            "step",
            id = s.id,
            kind = s.step.kind.as_str(),
            channel = s.step.channel.as_deref()
        )
        .entered();
        let retried_before = self.retried();
        let id = s.id;
        if let Some(ch) = &s.step.channel
            && self.channel.as_ref() != Some(ch)
        {
            let what = match &mut self.gonio.spectral {
                // A monochromator or filter wheel selects the band itself.
                Some(sel) => {
                    match gonio_driver::spectral::channel_nm(ch).and_then(|nm| sel.select(nm)) {
                        Ok(band) => format!("band {ch}: {} at {band}", sel.family()),
                        Err(e) => return self.spectral_failed(id, e),
                    }
                }
                None => {
                    if let Err(e) = self.ask_bench(|b| b.select_channel(ch)) {
                        return self.bench_failed(id, e);
                    }
                    format!("band {ch}")
                }
            };
            tracing::info!("bench: {what}");
            self.store.event("bench", Some(id), &what)?;
            let _ = self.events.send(Event::Bench { what });
            self.channel = Some(ch.clone());
        }
        let setup = setup_for(s.step.kind, self.cfg.incident_transmittance);
        // With a shutter, a dark reading closes it rather than asking the bench.
        let shuttered = self
            .gonio
            .spectral
            .as_ref()
            .is_some_and(|sel| sel.has_shutter());
        let by_shutter = shuttered && setup == Setup::Dark;
        if shuttered && self.shutter_open != Some(!by_shutter) {
            let open = !by_shutter;
            if let Some(sel) = &mut self.gonio.spectral
                && let Err(e) = sel.set_shutter(open)
            {
                return self.spectral_failed(id, e);
            }
            let what = format!("shutter {}", if open { "open" } else { "closed" });
            tracing::info!("bench: {what}");
            self.store.event("bench", Some(id), &what)?;
            let _ = self.events.send(Event::Bench { what });
            self.shutter_open = Some(open);
        }
        if !by_shutter && self.setup != Some(setup) {
            if let Err(e) = self.ask_bench(|b| b.set_up(setup)) {
                return self.bench_failed(id, e);
            }
            let what = setup.instruction();
            tracing::info!("bench: {what}");
            self.store.event("bench", Some(id), &what)?;
            let _ = self.events.send(Event::Bench { what });
            self.setup = Some(setup);
        }
        // What the filters held before the move, and the level to expect: the last
        // reading before this step in the run file, so a resumed run sees what an
        // uninterrupted one saw.
        let previous = self.store.last_reading_before(id)?;
        let held = previous
            .as_ref()
            .map(|r| [r.x_mean, r.y_mean])
            .filter(|v| v.iter().all(|x| x.is_finite()));
        let expected = previous
            .as_ref()
            .map(|r| r.r_mean)
            .filter(|r| r.is_finite() && *r > 0.0);
        let target = self.target_for(s.step.kind)?;
        let move_start = self.physical_s();
        // What the reading sets before it needs light (the lock-in's time constant for
        // the expected level) goes out before the move, not after it: the filters
        // then meet the new light at their new settings.
        if let Some(t) = &target
            && let Err(e) = self.gonio.detector.prepare(t, expected)
        {
            return self.detector_failed(id, e);
        }
        let axes = self.mech.axes.clone();
        let moved = match &s.step.stages {
            Some(t) => self.gonio.motion.move_to(&targets(&axes, t)),
            None => axes
                .iter()
                .map(|a| self.gonio.motion.position(a))
                .collect::<Result<Vec<f64>, _>>(),
        };
        let positions = match moved {
            Ok(p) => p,
            Err(e) => return self.motion_failed(id, e),
        };
        let position = [positions[0], positions[1], positions[2], positions[3]];
        let read_start = self.physical_s();
        // The light is the point's from when the controllers saw the stages stop, not
        // from after the positions were read back: the filters' settling is timed
        // from there.
        let now = self.gonio.motion.clock().now();
        let stopped = match s.step.stages {
            Some(_) => self.gonio.motion.stopped_at().unwrap_or(now).min(now),
            None => now,
        };
        self.bench.at_step_since(id, held, stopped);
        self.gonio.detector.input_changed_at(stopped);
        let mut reading = match self.read(target.as_ref(), expected) {
            Ok(r) => r,
            Err(e) => return self.detector_failed(id, e),
        };
        let mut rereads = 0;
        while !reading.is_valid() && rereads < self.cfg.flagged_rereads {
            rereads += 1;
            self.store.event(
                "flagged",
                Some(id),
                &format!("reading flagged {}; reading again", reading.flags_text()),
            )?;
            // What flagged it (an unlock: nothing demodulated; an overload) upset the
            // filters: the next reading waits a full settling time, as after a move.
            self.gonio.detector.input_changed();
            reading = match self.read(target.as_ref(), expected) {
                Ok(r) => r,
                Err(e) => return self.detector_failed(id, e),
            };
        }
        let record = self.record(s, position, &reading, retried_before, target.is_some());
        // Where the instrument's time went, for the reading-time budget (the `truth`
        // example sums these).
        tracing::debug!(
            moving_s = read_start - move_start,
            reading_s = record.physical_s - read_start,
            rereads,
            "step timing"
        );
        let mut events = Vec::new();
        if record.retries > 0 {
            events.push(EventRecord {
                wall_s: record.wall_s,
                kind: "retry".into(),
                step_id: Some(id),
                message: format!("{} exchanges retried", record.retries),
            });
        }
        self.store.commit(&record, &events)?;
        tracing::debug!(
            r_mean = record.r_mean,
            r_std = record.r_std,
            flags = record.flags,
            retries = record.retries,
            "step committed"
        );
        Ok(StepOutcome::Measured(Box::new(record)))
    }

    /// One reading: to `target` when the plan sets one, else the detector's fixed
    /// reading.
    fn read(
        &mut self,
        target: Option<&ReadTarget>,
        expected: Option<f64>,
    ) -> Result<Reading, DetectorError> {
        match target {
            Some(t) => self.gonio.detector.read_to(t, expected),
            None => self.gonio.detector.read(),
        }
    }

    /// The target of a step's reading ([`super::target_for_kind`]); the detector's
    /// floor is asked once a session.
    fn target_for(&mut self, kind: StepKind) -> Result<Option<ReadTarget>, StoreError> {
        let Some(base) = self.cfg.reading else {
            return Ok(None);
        };
        if self.floor.is_none() {
            let floor = self.gonio.detector.target_floor(&base).unwrap_or(0.0);
            tracing::info!(floor, "reading: the targets' absolute floor");
            self.floor = Some(floor);
            if self.gonio.detector.family() != "sr830" {
                let m = format!(
                    "the plan's [reading] target is for a lock-in; the {} reads its fixed samples",
                    self.gonio.detector.family()
                );
                tracing::warn!("{m}");
                self.store.event("note", None, &m)?;
            }
        }
        Ok(Some(super::target_for_kind(
            &base,
            kind,
            self.floor.unwrap_or(0.0),
        )))
    }

    fn record(
        &self,
        s: &StoredStep,
        position: [f64; 4],
        r: &Reading,
        retried_before: u64,
        targeted: bool,
    ) -> ReadingRecord {
        let dirs = self.mech.layout.forward(position);
        let g = &self.mech.geometry;
        let c = r.columns();
        let mut bits = u32::from(c.status) & 0x0F;
        let sample_lit = matches!(
            s.step.kind,
            StepKind::Sample | StepKind::Reference | StepKind::Standard
        );
        if sample_lit && kinematics::arm_separation_deg(dirs) < g.min_arm_separation_deg {
            bits |= flags::SHADOWED;
        }
        if sample_lit && dirs.wi.z > 0.0 && g.beam_diameter_m / dirs.wi.z > g.sample_length_m {
            bits |= flags::OVERFILLED;
        }
        if c.capped {
            bits |= flags::CAPPED;
        }
        if targeted && r.lockin().is_some() {
            bits |= flags::TARGETED;
        }
        if let Some(l) = r.lockin().filter(|_| targeted) {
            if l.fitted {
                bits |= flags::FITTED;
            }
            match (l.sample_rate, l.snapshot_interval_s) {
                (Some(rate), _) => bits |= flags::buffered(rate.index()),
                (None, Some(s)) => bits |= flags::snap_interval(s),
                (None, None) => {}
            }
        }
        ReadingRecord {
            step_id: s.id,
            commanded: s.step.stages,
            position,
            read_pair: pair_deg(dirs),
            sensitivity: c.range,
            sensitivity_v: c.full_scale,
            time_constant: c.integration,
            time_constant_s: c.integration_s,
            slope_db: c.slope_db,
            r_mean: c.mean,
            r_std: c.std,
            x_mean: c.x,
            y_mean: c.y,
            n: c.n as u32,
            autorange_steps: c.autorange_steps as u32,
            lias: c.status,
            flags: bits,
            retries: self.retried() - retried_before,
            physical_s: self.physical_s(),
            wall_s: wall_now(),
        }
    }

    fn bench_failed(&mut self, id: i64, e: BenchError) -> Result<StepOutcome, StoreError> {
        let m = format!("bench: {e}");
        self.fault(Some(id), &m, false)?;
        Ok(StepOutcome::Stop(match e {
            BenchError::Declined(_) | BenchError::NoOperator(_) => Outcome::Interrupted,
            BenchError::UnknownChannel(_) => Outcome::Faulted(m),
        }))
    }

    fn spectral_failed(&mut self, id: i64, e: SpectralError) -> Result<StepOutcome, StoreError> {
        let m = format!("wavelength: {e}");
        self.fault(Some(id), &m, false)?;
        Ok(StepOutcome::Stop(Outcome::Faulted(m)))
    }

    fn motion_failed(&mut self, id: i64, e: MotionError) -> Result<StepOutcome, StoreError> {
        let m = e.to_string();
        let Some((axis, cause)) = axis_fault(&e) else {
            self.fault(Some(id), &m, false)?;
            return Ok(StepOutcome::Stop(Outcome::Faulted(m)));
        };
        let axis = axis.to_string();
        match cause {
            AxisError::Aborted => {
                self.store
                    .event("interrupt", Some(id), "stop requested; stages stopped")?;
                Ok(StepOutcome::Stop(Outcome::Interrupted))
            }
            AxisError::ControllerReset | AxisError::NotReferenced { .. } | AxisError::NotHomed => {
                self.fault(Some(id), &m, true)?;
                let _ = self.gonio.motion.stop_all();
                match self.rehome_lost() {
                    Ok(lost) if lost.is_empty() => {
                        self.store.event(
                            "home",
                            Some(id),
                            "every axis kept its reference; measuring the step again",
                        )?;
                        Ok(StepOutcome::Again(m))
                    }
                    Ok(lost) => {
                        self.store.event(
                            "home",
                            Some(id),
                            &format!("re-homed {}; measuring the step again", lost.join(", ")),
                        )?;
                        let _ = self.events.send(Event::Homed { axes: lost });
                        Ok(StepOutcome::Again(m))
                    }
                    Err(e2) => {
                        let m2 = format!("re-homing after the fault on {axis} failed: {e2}");
                        self.fault(Some(id), &m2, false)?;
                        Ok(StepOutcome::Stop(Outcome::Faulted(m2)))
                    }
                }
            }
            AxisError::OutOfLimits { .. } => Ok(StepOutcome::Skip(m)),
            _ => {
                self.fault(Some(id), &m, false)?;
                Ok(StepOutcome::Stop(Outcome::Faulted(m)))
            }
        }
    }

    /// Asks the bench for a change. When a person answers, that may take minutes: the
    /// instrument's lines are kept alive meanwhile.
    fn ask_bench<T: Send>(&mut self, f: impl FnOnce(&mut B) -> T + Send) -> T {
        if !self.bench.waits_for_a_person() {
            return f(&mut self.bench);
        }
        let bench = &mut self.bench;
        self.gonio.while_a_person_answers(move || f(bench))
    }

    /// After a controller reset or lost power: waits until every controller answers
    /// (a rebooting one is silent for a few seconds) and no stage is still stopping,
    /// then homes each axis that lost its reference. Every controller is asked, not
    /// only the axis the error named: a power loss's NUL byte arrives on the shared
    /// line in answer to whichever controller was being polled, so it does not say
    /// which one rebooted. Returns the axes homed.
    fn rehome_lost(&mut self) -> Result<Vec<String>, MotionError> {
        const BOOT: Duration = Duration::from_secs(10);
        let names: Vec<String> = self.gonio.motion.axis_names();
        let start = self.gonio.motion.clock().now();
        let mut lost = Vec::new();
        for name in &names {
            loop {
                let waiting = match self.gonio.motion.state(name) {
                    Ok(AxisState::Moving) => AxisError::Device {
                        command: "homing".into(),
                        reason: "the stage is still moving".into(),
                    },
                    Ok(s) => {
                        if s == AxisState::Unreferenced {
                            lost.push(name.clone());
                        }
                        break;
                    }
                    Err(MotionError::AtAxis {
                        source: e @ AxisError::Transport(TransportError::Timeout(_)),
                        ..
                    }) => e,
                    Err(e) => return Err(e),
                };
                if self.gonio.motion.clock().now().saturating_sub(start) > BOOT {
                    return Err(MotionError::AtAxis {
                        axis: name.clone(),
                        source: waiting,
                    });
                }
                let now = self.gonio.motion.clock().now();
                self.gonio.idle_until(now + Duration::from_millis(500));
            }
        }
        let refs: Vec<&str> = lost.iter().map(String::as_str).collect();
        self.gonio.motion.home(&refs)?;
        Ok(lost)
    }

    fn detector_failed(&mut self, id: i64, e: DetectorError) -> Result<StepOutcome, StoreError> {
        let m = e.to_string();
        match e.disposition() {
            Disposition::Skip => Ok(StepOutcome::Skip(m)),
            Disposition::Again => {
                // Survived the driver's own retries: measure the step again, within
                // the engine's attempts.
                self.fault(Some(id), &m, true)?;
                Ok(StepOutcome::Again(m))
            }
            Disposition::Stop => {
                self.fault(Some(id), &m, false)?;
                Ok(StepOutcome::Stop(Outcome::Faulted(m)))
            }
        }
    }

    /// Ends the session: stages stopped, outcome stored.
    pub(super) fn finish(
        &mut self,
        outcome: Outcome,
        measured: usize,
        skipped: usize,
    ) -> Result<SessionReport, StoreError> {
        let span = self.span.clone();
        let _entered = span.enter();
        // Whatever happened, nothing keeps moving.
        if let Err(e) = self.gonio.motion.stop_all() {
            self.store
                .event("fault", None, &format!("stopping the stages: {e}"))?;
        }
        let counts = self.store.state_counts()?;
        let total: u64 = counts.values().sum();
        let pending = counts.get("pending").copied().unwrap_or(0);
        let message = match &outcome {
            Outcome::Complete => "every step finished".to_string(),
            Outcome::Interrupted => "interrupted; resumable".to_string(),
            Outcome::Faulted(m) => format!("stopped by a fault; resumable: {m}"),
        };
        tracing::info!(outcome = outcome.status(), "session ended: {message}");
        self.store.event("stop", None, &message)?;
        self.store.end_session(outcome.status())?;
        let _ = self.events.send(Event::Finished {
            outcome: outcome.clone(),
        });
        Ok(SessionReport {
            outcome,
            measured,
            skipped,
            finished: (total - pending) as usize,
            total: total as usize,
            physical_s: self.physical_s(),
        })
    }
}
