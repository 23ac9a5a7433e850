//! What `plan check` says of a plan with a `[reading]` target: each step's expected
//! signal — from the simulated sample, or from a previous run's readings — the time
//! constant the driver will choose for it, its settling and averaging, and how the
//! detector's time splits.

use std::collections::BTreeMap;
use std::path::Path;

use gonio_acquire::engine::{ReadTarget, read_target, setup_for, target_for_kind};
use gonio_driver::bench::Bench;
use gonio_driver::config::DetectorKind;
use gonio_driver::sr830::target::{choose_time_constant, estimate, floor_sigma};
use gonio_plan::StepKind;
use serde::Serialize;

use crate::cmd::prepare::Loaded;
use crate::error::{CliError, CliResult};

/// Where the expected signals come from.
pub enum Source<'a> {
    /// The simulator's sample and light (a config, or the embedded default).
    Sim(Box<gonio_sim::SimConfig>),
    /// The readings of a previous run: each step takes the nearest reading of its
    /// kind.
    Run(&'a Path),
}

/// The estimate of a targeted plan's detector time.
#[derive(Clone, Debug, Serialize)]
pub struct ReadingTime {
    /// Where the expected signals came from.
    pub source: String,
    /// The target relative to the value, and the absolute floor in force, V.
    pub sigma_relative: f64,
    /// The floor, V.
    pub sigma_absolute: f64,
    /// Readings estimated.
    pub readings: usize,
    /// From each move's end to the averaged window's first snapshot, s.
    pub settle_s: f64,
    /// The windows' snapshots, s.
    pub averaging_s: f64,
    /// The time-constant and status exchanges around each reading, s.
    pub serial_s: f64,
    /// Their sum, s.
    pub detector_s: f64,
    /// Readings expected to reach the cap.
    pub capped: usize,
    /// Readings per time constant chosen.
    pub time_constants: BTreeMap<String, usize>,
}

/// The estimate for `loaded`'s plan, when it has a `[reading]` table and the
/// detector is a lock-in with a noise law; `None` otherwise.
pub fn estimate_plan(loaded: &Loaded, source: Source<'_>) -> CliResult<Option<ReadingTime>> {
    let Some(reading) = &loaded.plan.reading else {
        return Ok(None);
    };
    let inst = &loaded.instrument;
    let lockin = inst.detector.lockin.clone().with_baud(inst.detector.baud);
    let Some(noise) = lockin.noise else {
        return Ok(None);
    };
    if inst.detector.kind != DetectorKind::Sr830 {
        return Ok(None);
    }
    let base: ReadTarget = read_target(reading);
    let choices = lockin.time_constant_choices();
    let floor =
        floor_sigma(&base, &noise, lockin.slope, &choices, lockin.exchange_s).unwrap_or(0.0);
    let steps = &loaded.prepared.schedule.steps;
    let (signals, what) = match source {
        Source::Sim(cfg) => (
            sim_signals(loaded, &cfg)?,
            "the simulated sample".to_string(),
        ),
        Source::Run(path) => (run_signals(steps, path)?, path.display().to_string()),
    };
    let mut out = ReadingTime {
        source: what,
        sigma_relative: base.sigma_relative,
        sigma_absolute: if base.sigma_absolute > 0.0 {
            base.sigma_absolute
        } else {
            floor
        },
        readings: steps.len(),
        settle_s: 0.0,
        averaging_s: 0.0,
        serial_s: 0.0,
        detector_s: 0.0,
        capped: 0,
        time_constants: BTreeMap::new(),
    };
    // `OFLT` out and `LIAS?` with its answer: about 18 characters a reading.
    let serial = 0.5 * lockin.exchange_s;
    let mut previous: Option<f64> = None;
    for (step, r) in steps.iter().zip(&signals) {
        let target = target_for_kind(&base, step.kind, floor);
        // The driver chooses from the level the last reading had, then meets this one.
        let tc = match previous {
            Some(p) if p > 0.0 => choose_time_constant(
                p,
                &target,
                &noise,
                lockin.slope,
                choices.iter().copied(),
                lockin.exchange_s,
            )
            .map_or(lockin.time_constant, |e| e.time_constant),
            _ => lockin.time_constant,
        };
        let step_v = previous.map_or(*r, |p| (p - r).abs());
        let e = estimate(
            *r,
            step_v,
            &target,
            &noise,
            lockin.slope,
            tc,
            lockin.exchange_s,
        );
        let (settle, averaging) = if e.total_s() > target.max_s {
            out.capped += 1;
            let settle = e.settle_s.min(target.max_s);
            (settle, target.max_s - settle)
        } else {
            (e.settle_s, e.averaging_s)
        };
        out.settle_s += settle;
        out.averaging_s += averaging;
        out.serial_s += serial;
        *out.time_constants.entry(tc.to_string()).or_default() += 1;
        previous = Some(*r);
    }
    out.detector_s = out.settle_s + out.averaging_s + out.serial_s;
    Ok(Some(out))
}

/// The lock-in's R at each step, V: the simulator's light on the simulator's sample
/// (or standard, in the plan's light path for the step's kind).
fn sim_signals(loaded: &Loaded, cfg: &gonio_sim::SimConfig) -> CliResult<Vec<f64>> {
    let input = |e: &dyn std::fmt::Display| CliError::Input(e.to_string());
    let plan = &loaded.plan;
    let standard = match &plan.calibration.standard {
        Some(s) => {
            let path = plan.resolve(&s.model);
            let text = gonio_core::input::read_text(&path, gonio_core::input::MAX_CONFIG_BYTES)
                .map_err(|e| input(&e))?;
            let m = gonio_brdf::Model::from_toml(&text, Some(&path)).map_err(|e| input(&e))?;
            Some((Box::new(m) as Box<dyn gonio_brdf::Brdf>, 0))
        }
        None => None,
    };
    let transmittance = plan
        .calibration
        .incident
        .as_ref()
        .map_or(1.0, |i| i.transmittance);
    let sim = gonio_sim::SimInstrument::new(cfg, gonio_sim::SimClock::driven(0.0))
        .map_err(|e| input(&e))?;
    let shared: gonio_sim::SharedSim = std::sync::Arc::new(std::sync::Mutex::new(sim));
    let mut bench = gonio_sim::SimBench::new(shared.clone(), standard);
    let gain = cfg.lockin.chop_gain;
    let mut out = Vec::with_capacity(loaded.prepared.schedule.steps.len());
    for step in &loaded.prepared.schedule.steps {
        bench
            .set_up(setup_for(step.kind, transmittance))
            .map_err(|e| input(&e))?;
        if let Some(ch) = &step.channel {
            bench.select_channel(ch).map_err(|e| input(&e))?;
        }
        let v = match (&step.pair, step.kind) {
            (_, StepKind::Dark) | (None, _) => 0.0,
            (Some(p), _) => gonio_sim::lock(&shared).optics().signal(0.0, p.to_dirs()),
        };
        out.push(gain * v.abs());
    }
    Ok(out)
}

/// The R of the nearest reading of the same kind in a previous run, V.
fn run_signals(steps: &[gonio_plan::Step], path: &Path) -> CliResult<Vec<f64>> {
    let store = gonio_run::RunStore::open(path)?;
    let stored = store.steps()?;
    let kinds: BTreeMap<i64, StepKind> = stored.iter().map(|s| (s.id, s.step.kind)).collect();
    let readings: Vec<(StepKind, gonio_core::dirfile::PairDeg, f64)> = store
        .readings()?
        .into_iter()
        .filter(|r| r.r_mean.is_finite())
        .filter_map(|r| kinds.get(&r.step_id).map(|k| (*k, r.read_pair, r.r_mean)))
        .collect();
    if readings.is_empty() {
        return Err(CliError::Input(format!(
            "{}: the run has no readings",
            path.display()
        )));
    }
    // The squared chord between two pairs' directions, incident and outgoing.
    let chord = |a: &gonio_core::dirfile::PairDeg, b: &gonio_core::dirfile::PairDeg| {
        let (da, db) = (a.to_dirs(), b.to_dirs());
        let d = |x: gonio_core::Dir, y: gonio_core::Dir| {
            (x.x - y.x).powi(2) + (x.y - y.y).powi(2) + (x.z - y.z).powi(2)
        };
        d(da.wi, db.wi) + d(da.wo, db.wo)
    };
    Ok(steps
        .iter()
        .map(|s| {
            let same = readings.iter().filter(|(k, _, _)| *k == s.kind);
            let best = match &s.pair {
                Some(p) => same
                    .map(|(_, q, r)| (chord(p, q), *r))
                    .min_by(|a, b| a.0.total_cmp(&b.0))
                    .map(|x| x.1),
                None => same.map(|x| x.2).next(),
            };
            best.unwrap_or(0.0)
        })
        .collect())
}
