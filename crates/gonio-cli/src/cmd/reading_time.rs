//! The detector's time over a plan, reading by reading, from the signal expected at
//! each step — from the simulated sample, or from a previous run's readings: for a
//! plan with a `[reading]` target, the time constant the driver will choose, its
//! settling and averaging; for the fixed reading, its cycles. Either way the range
//! changes autoranging makes on the way from one signal to the next, each costing a
//! reading more, by the sessions' own rules (`gonio_proto::sr830::ranging`) and
//! timings (`gonio_proto::sr830::timing`).

use std::collections::BTreeMap;
use std::path::Path;

use gonio_acquire::engine::{ReadTarget, read_target, setup_for, target_for_kind};
use gonio_driver::bench::Bench;
use gonio_driver::config::DetectorKind;
use gonio_driver::sr830::target::{NoiseDensity, choose_time_constant, estimate, floor_sigma};
use gonio_driver::sr830::{Sensitivity, Sr830Config, ranging, timing};
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

/// The estimate of a plan's detector time, reading by reading.
#[derive(Clone, Debug, Serialize)]
pub struct ReadingTime {
    /// Where the expected signals came from.
    pub source: String,
    /// True for readings to the plan's `[reading]` target; false for the fixed
    /// reading.
    pub targeted: bool,
    /// The target relative to the value (0 for the fixed reading).
    pub sigma_relative: f64,
    /// The absolute floor in force, V (0 for the fixed reading).
    pub sigma_absolute: f64,
    /// Readings estimated.
    pub readings: usize,
    /// From each move's (or range change's) end to the averaged window's first
    /// snapshot, s.
    pub settle_s: f64,
    /// The windows' snapshots, s.
    pub averaging_s: f64,
    /// The exchanges of each reading that are not its snapshots' spacing: status
    /// queries, time-constant and range changes, and (fixed) the snapshots'
    /// own exchanges, s.
    pub serial_s: f64,
    /// Their sum, s.
    pub detector_s: f64,
    /// Range changes autoranging is expected to make.
    pub range_changes: usize,
    /// The part of the detector's time those cost, s.
    pub ranging_s: f64,
    /// Readings expected to reach the cap.
    pub capped: usize,
    /// Readings per time constant chosen.
    pub time_constants: BTreeMap<String, usize>,
    /// Each step's reading, s, in schedule order.
    #[serde(skip)]
    pub per_step: Vec<f64>,
    /// The part of each step's reading its range changes cost, s.
    #[serde(skip)]
    pub per_step_ranging: Vec<f64>,
}

impl ReadingTime {
    fn new(source: String, readings: usize) -> Self {
        ReadingTime {
            source,
            targeted: false,
            sigma_relative: 0.0,
            sigma_absolute: 0.0,
            readings,
            settle_s: 0.0,
            averaging_s: 0.0,
            serial_s: 0.0,
            detector_s: 0.0,
            range_changes: 0,
            ranging_s: 0.0,
            capped: 0,
            time_constants: BTreeMap::new(),
            per_step: Vec::with_capacity(readings),
            per_step_ranging: Vec::with_capacity(readings),
        }
    }

    /// Adds one step's reading: its parts, the range changes in it and what they
    /// cost.
    fn add(&mut self, settle: f64, averaging: f64, serial: f64, changes: usize, ranging: f64) {
        self.settle_s += settle;
        self.averaging_s += averaging;
        self.serial_s += serial;
        self.range_changes += changes;
        self.ranging_s += ranging;
        self.per_step.push(settle + averaging + serial);
        self.per_step_ranging.push(ranging);
    }
}

/// The mean R a reading of a signal `s` V sees through noise of standard deviation
/// `sigma` V in each of X and Y: `sigma·√(π/2)` for no signal (Rayleigh), `s` for a
/// signal well above it, joined as √(s² + π σ²/2).
fn mean_r(s: f64, sigma: f64) -> f64 {
    (s * s + std::f64::consts::FRAC_PI_2 * sigma * sigma).sqrt()
}

/// The estimate for `loaded`'s plan on an SR830 (`None` for another detector, and for
/// a plan with a `[reading]` target on a lock-in without a noise law, which a
/// targeted reading needs to be estimated).
pub fn estimate_plan(loaded: &Loaded, source: Source<'_>) -> CliResult<Option<ReadingTime>> {
    let inst = &loaded.instrument;
    if inst.detector.kind != DetectorKind::Sr830 {
        return Ok(None);
    }
    let cfg = inst.lockin();
    if loaded.plan.reading.is_some() && cfg.noise.is_none() {
        return Ok(None);
    }
    let steps = &loaded.prepared.schedule.steps;
    let Some(Signals {
        values: signals,
        noise,
        what,
    }) = signals(loaded, source)?
    else {
        return Ok(None);
    };
    let lockin = Lockin {
        range_s: timing::range_change_s(cfg.baud),
        cfg: &cfg,
        noise,
    };
    let out = ReadingTime::new(what, steps.len());
    Ok(match &loaded.plan.reading {
        None => Some(lockin.fixed(out, &signals)),
        Some(reading) => lockin.targeted(out, steps, &signals, reading),
    })
}

/// The signals a plan's readings are estimated from.
struct Signals {
    /// The lock-in's R expected at each step, V.
    values: Vec<f64>,
    /// The noise they are read through: the simulator's own, or none to add to a
    /// run's readings, which hold theirs.
    noise: Option<NoiseDensity>,
    /// Where they come from.
    what: String,
}

/// The signals from `source`; `None` when the simulator cannot stand for the
/// instrument.
fn signals(loaded: &Loaded, source: Source<'_>) -> CliResult<Option<Signals>> {
    let steps = &loaded.prepared.schedule.steps;
    Ok(match source {
        Source::Sim(cfg) => {
            let noise = NoiseDensity {
                floor: cfg.lockin.amplifier_noise,
                shot: cfg.lockin.shot_noise,
            };
            let Some(signals) = sim_signals(loaded, &cfg)? else {
                return Ok(None);
            };
            Some(Signals {
                values: signals,
                noise: Some(noise),
                what: "the simulated sample".to_string(),
            })
        }
        Source::Run(path) => Some(Signals {
            values: run_signals(steps, path)?,
            noise: None,
            what: path.display().to_string(),
        }),
    })
}

/// The lock-in a plan's readings are estimated on: its set-up, the noise its
/// signals are read through, and the time a range change costs, s.
struct Lockin<'a> {
    cfg: &'a Sr830Config,
    noise: Option<NoiseDensity>,
    range_s: f64,
}

impl Lockin<'_> {
    /// The range changes autoranging makes from `at` to read `r` V (its snapshots'
    /// spread `spread` V for a targeted reading), and the range it ends on.
    fn changes(
        &self,
        at: Sensitivity,
        r: f64,
        spread: f64,
        targeted: bool,
    ) -> (usize, Sensitivity) {
        let lockin = self.cfg;
        if !lockin.autorange {
            (0, at)
        } else if targeted {
            ranging::targeted_changes(at, r, spread, lockin.min_fraction)
        } else {
            ranging::fixed_changes(at, r, lockin.min_fraction)
        }
    }

    /// The fixed reading: a cycle at the configured time constant, and a cycle
    /// more after each range change.
    fn fixed(&self, mut out: ReadingTime, signals: &[f64]) -> ReadingTime {
        let (lockin, range_s) = (self.cfg, self.range_s);
        let tc = lockin.time_constant;
        let sigma = |r: f64| {
            self.noise.map_or(0.0, |n| {
                n.snapshot_variance(r, lockin.slope, tc).max(0.0).sqrt()
            })
        };
        let mut at: Sensitivity = lockin.sensitivity;
        let settle = lockin.settle_seconds(lockin.slope, tc);
        let snapshots = lockin.samples.max(1);
        let averaging = (snapshots - 1) as f64 * tc.seconds();
        let serial = lockin.cycle_s(tc) - settle - averaging;
        for r in signals {
            let (n, next) = self.changes(at, mean_r(*r, sigma(*r)), 0.0, false);
            at = next;
            let k = (n + 1) as f64;
            out.add(
                k * settle,
                k * averaging,
                k * serial + n as f64 * range_s,
                n,
                n as f64 * (lockin.cycle_s(tc) + range_s),
            );
        }
        *out.time_constants.entry(tc.to_string()).or_default() += out.readings;
        out.detector_s = out.settle_s + out.averaging_s + out.serial_s;
        out
    }

    /// Readings to the plan's `[reading]` target: the time constant the driver will
    /// choose from the level the last reading had, the settling and averaging it
    /// needs (capped at the target's longest), and the readings again after a range
    /// change. `None` without a noise law.
    fn targeted(
        &self,
        mut out: ReadingTime,
        steps: &[gonio_plan::Step],
        signals: &[f64],
        reading: &gonio_plan::ReadingConfig,
    ) -> Option<ReadingTime> {
        let (lockin, range_s) = (self.cfg, self.range_s);
        let noise_law = lockin.noise?;
        let base: ReadTarget = read_target(reading);
        let choices = lockin.time_constant_choices();
        let floor = floor_sigma(&base, &noise_law, lockin.slope, &choices, lockin.exchange_s)
            .unwrap_or(0.0);
        out.targeted = true;
        out.sigma_relative = base.sigma_relative;
        out.sigma_absolute = if base.sigma_absolute > 0.0 {
            base.sigma_absolute
        } else {
            floor
        };
        let mut at: Sensitivity = lockin.sensitivity;
        // Each reading sends its time constant (`OFLT`) and ends with `LIAS?`; its
        // snapshots go back to back, one exchange apart, inside the averaging.
        let serial =
            timing::time_constant_change_s(lockin.baud) + timing::lia_status_s(lockin.baud);
        let mut previous: Option<f64> = None;
        for (step, r) in steps.iter().zip(signals) {
            let target = target_for_kind(&base, step.kind, floor);
            // The driver chooses from the level the last reading had, then meets this one.
            let tc = match previous {
                Some(p) if p > 0.0 => choose_time_constant(
                    p,
                    &target,
                    &noise_law,
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
                &noise_law,
                lockin.slope,
                tc,
                lockin.exchange_s,
            );
            let capped = e.total_s() > target.max_s;
            let (settle, averaging) = if capped {
                out.capped += 1;
                let settle = e.settle_s.min(target.max_s);
                (settle, target.max_s - settle)
            } else {
                (e.settle_s, e.averaging_s)
            };
            // A capped reading keeps its range; another reads again at the range its
            // value calls for, from the range change on: the same light, no step to
            // settle from.
            let spread = self.noise.map_or(0.0, |n| {
                n.snapshot_variance(*r, lockin.slope, tc).max(0.0).sqrt()
            });
            let (n, next) = if capped {
                (0, at)
            } else {
                self.changes(at, mean_r(*r, spread), spread, true)
            };
            at = next;
            let (again_settle, again_averaging) = if n > 0 {
                let e = estimate(
                    *r,
                    0.0,
                    &target,
                    &noise_law,
                    lockin.slope,
                    tc,
                    lockin.exchange_s,
                );
                let settle = e.settle_s.min(target.max_s);
                (settle, e.averaging_s.min(target.max_s - settle))
            } else {
                (0.0, 0.0)
            };
            let n_f = n as f64;
            out.add(
                settle + n_f * again_settle,
                averaging + n_f * again_averaging,
                serial + n_f * range_s,
                n,
                n_f * (again_settle + again_averaging + range_s),
            );
            *out.time_constants.entry(tc.to_string()).or_default() += 1;
            previous = Some(*r);
        }
        out.detector_s = out.settle_s + out.averaging_s + out.serial_s;
        Some(out)
    }
}

/// The lock-in's R at each step, V: the simulator's light on the simulator's sample
/// (or standard, in the plan's light path for the step's kind), the noise aside, at
/// the step's band; `None` when the simulator cannot stand for the instrument (a
/// band selector it lacks, a filter wheel, whose bands it does not select here, a
/// band its sample has no value for).
fn sim_signals(loaded: &Loaded, cfg: &gonio_sim::SimConfig) -> CliResult<Option<Vec<f64>>> {
    let input = |e: &dyn std::fmt::Display| CliError::Input(e.to_string());
    let inst = &loaded.instrument;
    if gonio_sim::check_compatible(inst, cfg).is_err() || inst.filter_wheel.is_some() {
        return Ok(None);
    }
    let plan = &loaded.plan;
    let standard = match &plan.calibration.standard {
        Some(s) => {
            let path = plan.resolve(&s.model);
            let text = gonio_core::input::read_text(&path, gonio_core::input::MAX_CONFIG_BYTES)
                .map_err(|e| input(&e))?;
            // Named as acquire names it: this estimate now runs before every simulated run.
            let m = gonio_brdf::Model::from_toml(&text, Some(&path))
                .map_err(|e| CliError::Input(format!("reference standard model: {e}")))?;
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
    let mut band = None;
    for step in &loaded.prepared.schedule.steps {
        bench
            .set_up(setup_for(step.kind, transmittance))
            .map_err(|e| input(&e))?;
        if let Some(ch) = &step.channel
            && band.as_ref() != Some(ch)
        {
            match &inst.monochromator {
                Some(m) => select_wavelength(&shared, &m.cs130, ch)?,
                // A band the simulated sample has no value for: no signal to expect.
                None if bench.select_channel(ch).is_err() => return Ok(None),
                None => {}
            }
            band = Some(ch.clone());
        }
        let v = match (&step.pair, step.kind) {
            (_, StepKind::Dark) | (None, _) => 0.0,
            (Some(p), _) => gonio_sim::lock(&shared).optics().signal(0.0, p.to_dirs()),
        };
        out.push(gain * v.abs());
    }
    Ok(Some(out))
}

/// Sets the simulated monochromator to the band `channel` as its session would (the
/// grating and order-sorting filter its config chooses, then the wavelength), its
/// shutter open (a dark reading's light path is the bench's here), and lets the
/// drive arrive.
fn select_wavelength(
    sim: &gonio_sim::SharedSim,
    cs130: &gonio_driver::cs130::Cs130Config,
    channel: &str,
) -> CliResult<()> {
    use gonio_driver::cs130::Command;
    let input = |e: &dyn std::fmt::Display| CliError::Input(e.to_string());
    let nm = gonio_driver::spectral::channel_nm(channel).map_err(|e| input(&e))?;
    let mut statements = vec![Command::Grat(
        cs130.grating_for(nm).map_err(|e| input(&e))?.index,
    )];
    if cs130.auto_order_filter && cs130.filter_wheel {
        statements.push(Command::Filter(
            cs130.order_filter_for(nm).map_err(|e| input(&e))?,
        ));
    }
    statements.push(Command::GoWave(nm));
    statements.push(Command::Shutter(true));
    let mut s = gonio_sim::lock(sim);
    for c in statements {
        s.port_bytes(gonio_sim::Port::Monochromator, &c.to_bytes());
    }
    // Long enough for any change of grating, filter and wavelength to end.
    let clock = s.clock().clone();
    clock.advance(std::time::Duration::from_secs(600));
    s.port_bytes(gonio_sim::Port::Monochromator, &Command::Wave.to_bytes());
    Ok(())
}

/// The R of the nearest reading of the same kind (and band) in a previous run, V.
fn run_signals(steps: &[gonio_plan::Step], path: &Path) -> CliResult<Vec<f64>> {
    let store = gonio_run::RunStore::open(path)?;
    let stored = store.steps()?;
    type Kind = (StepKind, Option<String>);
    let kinds: BTreeMap<i64, Kind> = stored
        .iter()
        .map(|s| (s.id, (s.step.kind, s.step.channel.clone())))
        .collect();
    let readings: Vec<(Kind, gonio_core::dirfile::PairDeg, f64)> = store
        .readings()?
        .into_iter()
        .filter(|r| r.r_mean.is_finite())
        .filter_map(|r| {
            kinds
                .get(&r.step_id)
                .map(|k| (k.clone(), r.read_pair, r.r_mean))
        })
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
            let same = readings
                .iter()
                .filter(|(k, _, _)| k.0 == s.kind && k.1 == s.channel);
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
