//! The whole run's estimate, as `plan check` prints it and `acquire` announces and
//! records it: the session's start-up (identification, set-up, homing), the
//! schedule's moves and band changes with their serial exchanges, and the detector's
//! readings — from the signals expected at each step when they are known (the
//! simulated sample, or a previous run), with the range changes autoranging makes
//! and, for a plan with a `[reading]` target, the targeted readings; else the
//! schedule's fixed reading per step.

use gonio_plan::StepKind;
use gonio_plan::adaptive::Budget;

use crate::cmd::prepare::Loaded;
use crate::cmd::reading_time::{ReadingTime, Source, estimate_plan};
use crate::error::{CliError, CliResult};

/// The estimate of a whole run, s.
#[derive(Clone, Debug)]
pub struct RunEstimate {
    /// Identification, set-up and homing before the first step.
    pub startup_s: f64,
    /// The schedule's moves, their exchanges included.
    pub motion_s: f64,
    /// The schedule's band changes.
    pub band_s: f64,
    /// The readings: from the expected signals when known, else the schedule's.
    pub detector_s: f64,
    /// All four.
    pub total_s: f64,
    /// The readings step by step, when the signals are known.
    pub reading: Option<ReadingTime>,
    /// An adaptive plan's whole run and its time per later point: the coarse pass
    /// above, and every point the budget leaves at the time per point of a trial
    /// batch ([`trial_batch_s`]).
    pub adaptive: Option<AdaptiveEstimate>,
}

/// An adaptive plan's whole run, s.
#[derive(Clone, Copy, Debug)]
pub struct AdaptiveEstimate {
    /// Per point after the coarse pass: its sample steps and drift references.
    pub point_s: f64,
    /// The whole run.
    pub whole_s: f64,
}

/// How long a simulated controller's home search takes at start-up: from where the
/// simulator's config stands it at power-up onto its switch, at its home velocity.
fn sim_search_s(sim: &gonio_sim::SimConfig, axis: &gonio_driver::smc100::AxisConfig) -> f64 {
    let c = sim.controller(axis.address);
    gonio_driver::smc100::timing::home_search_s(
        c.start_position,
        c.home_switch,
        c.home_velocity,
        c.acceleration.min(c.max_acceleration),
    )
}

/// The time per point of an adaptive run's later batches, s: a trial batch of
/// `batch` points taken evenly from the coarse pass's, scheduled as the planner
/// schedules a batch (`gonio_plan::adaptive::schedule_batch`: ordered from where the
/// coarse pass ends, the drift reference at its start, every `drift.every` points
/// and its end), each read in `reading_s`, the coarse pass's mean sample reading
/// without its range changes — the coarse pass has swept the hemisphere's signals,
/// and a batch measures among them. Which points a batch takes is decided from the
/// readings; the trial stands for their spread over the hemisphere.
fn trial_batch_s(loaded: &Loaded, batch: usize, reading_s: f64) -> CliResult<f64> {
    let p = &loaded.prepared;
    let accepted = &p.checked.accepted;
    let n = batch.clamp(1, accepted.len().max(1));
    let chosen: Vec<_> = (0..n)
        .filter_map(|k| accepted.get(k * accepted.len() / n))
        .map(|a| (a.pair, a.stages))
        .collect();
    let steps = &p.schedule.steps;
    let start = steps
        .iter()
        .rev()
        .find_map(|s| s.stages)
        .unwrap_or_else(|| p.mech.limits.map(|(lo, hi)| 0f64.clamp(lo, hi)));
    let reference = steps
        .iter()
        .find(|s| s.kind == StepKind::Reference)
        .and_then(|s| s.pair);
    let trial = gonio_plan::adaptive::schedule_batch(
        &loaded.plan,
        &p.mech,
        &chosen,
        accepted.len(),
        start,
        reference,
        reading_s,
    )
    .map_err(|e| CliError::Input(e.to_string()))?;
    Ok(trial.duration_s() / chosen.len().max(1) as f64)
}

impl RunEstimate {
    /// The estimate of `loaded`'s run, the readings from `signals` when given, the
    /// home searches from the simulator `sim` when the instrument is simulated (a
    /// real stage's distance from its switch is not known, and not counted).
    pub fn of(
        loaded: &Loaded,
        signals: Option<Source<'_>>,
        sim: Option<&gonio_sim::SimConfig>,
    ) -> CliResult<RunEstimate> {
        let s = &loaded.prepared.schedule;
        let startup_s = loaded
            .instrument
            .startup_seconds(&|axis| sim.map_or(0.0, |sim| sim_search_s(sim, axis)));
        let reading = match signals {
            Some(src) => estimate_plan(loaded, src)?,
            None => None,
        };
        let detector_s = reading.as_ref().map_or(s.detector_s, |r| r.detector_s);
        let total_s = startup_s + s.motion_s + s.band_s + detector_s;
        let fixed = s.detector_s / s.steps.len().max(1) as f64;
        let adaptive = match &loaded.prepared.adaptive {
            None => None,
            Some(a) => {
                let samples: Vec<f64> = s
                    .steps
                    .iter()
                    .enumerate()
                    .filter(|(_, st)| st.kind == StepKind::Sample)
                    .map(|(k, _)| {
                        reading.as_ref().map_or(fixed, |r| {
                            r.per_step.get(k).copied().unwrap_or(fixed)
                                - r.per_step_ranging.get(k).copied().unwrap_or(0.0)
                        })
                    })
                    .collect();
                let reading_s = samples.iter().sum::<f64>() / samples.len().max(1) as f64;
                let point_s = trial_batch_s(loaded, a.batch, reading_s)?;
                let whole = total_s + a.points.saturating_sub(a.coarse) as f64 * point_s;
                Some(AdaptiveEstimate {
                    point_s,
                    whole_s: match a.budget {
                        // The batches are cut to the time left.
                        Budget::Hours(h) => whole.min(h * 3600.0),
                        Budget::Points(_) => whole,
                    },
                })
            }
        };
        Ok(RunEstimate {
            startup_s,
            motion_s: s.motion_s,
            band_s: s.band_s,
            detector_s,
            total_s,
            reading,
            adaptive,
        })
    }

    /// The estimate a new run file records.
    pub fn record(&self, loaded: &Loaded) -> gonio_run::meta::Estimate {
        gonio_run::meta::Estimate {
            startup_s: self.startup_s,
            motion_s: self.motion_s,
            raster_motion_s: loaded.prepared.schedule.raster_motion_s,
            detector_s: self.detector_s,
            band_s: self.band_s,
        }
    }
}
