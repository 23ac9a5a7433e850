//! The adaptive planner's next batch, decided from the run file alone.
//!
//! An adaptive run (`kind = "adaptive"`, `gonio_plan::adaptive`) is created with its
//! coarse pass. Whenever no step is pending, the run engine asks [`Planner::next`]
//! for the next batch: the run is reduced as `gonio reduce` would reduce it, the
//! candidates are scored on the reconstruction (`gonio_process::adapt`), the best
//! are scheduled like any plan's points, and the engine appends them to the run file
//! with the decision in one transaction.
//!
//! The decision depends on nothing but the plan, the instrument's mechanics and the
//! values of the readings committed (none is pending when it is asked; their times
//! are not used): a run killed at any instant and resumed makes the same choices as
//! one never interrupted. Each
//! decision's `detail` records the budget's state, the data it was made from and,
//! per point, its score, the reconstruction there, its uncertainty and its gap.

use gonio_core::dirfile::PairDeg;
use gonio_plan::adaptive::{self, Adaptive, Budget, MIN_BATCH, MIN_SPACING_DEG, Pool};
use gonio_plan::plan::Points;
use gonio_plan::{Mechanics, Plan, StepKind};
use gonio_process::adapt::{self, Aim};
use gonio_run::{Batch, Decision, RunStore};

use crate::{Drift, Options, ReduceError, reduce};

/// Why the planner cannot decide.
#[derive(Debug, thiserror::Error)]
pub enum AdaptError {
    /// The run's stored plan.
    #[error("the run's plan: {0}")]
    Plan(String),
    /// The run file.
    #[error(transparent)]
    Store(#[from] gonio_run::StoreError),
    /// The reduction of the readings so far.
    #[error("reducing the readings so far: {0}")]
    Reduce(#[from] ReduceError),
    /// The scores.
    #[error("scoring the candidates: {0}")]
    Score(#[from] gonio_process::ProcessError),
    /// The batch's schedule.
    #[error("scheduling the batch: {0}")]
    Schedule(#[from] gonio_plan::schedule::ScheduleError),
}

/// Decides an adaptive run's batches.
#[derive(Clone, Debug)]
pub struct Planner {
    plan: Plan,
    spec: Adaptive,
    mech: Mechanics,
    reading_s: f64,
    pool: Pool,
    points: usize,
}

impl Planner {
    /// The planner of the run in `store`, on the instrument `mech` whose readings take
    /// `reading_s`; `None` when the run's plan is not adaptive.
    pub fn for_run(
        store: &RunStore,
        mech: &Mechanics,
        reading_s: f64,
    ) -> Result<Option<Planner>, AdaptError> {
        let text = store
            .meta_value("plan")?
            .ok_or_else(|| AdaptError::Plan("the run file records no plan".into()))?;
        let plan = Plan::from_toml(&text, None).map_err(|e| AdaptError::Plan(e.to_string()))?;
        Self::new(plan, mech, reading_s)
    }

    /// The planner of `plan`; `None` when it is not adaptive.
    pub fn new(
        plan: Plan,
        mech: &Mechanics,
        reading_s: f64,
    ) -> Result<Option<Planner>, AdaptError> {
        let Points::Adaptive(spec) = &plan.points else {
            return Ok(None);
        };
        let spec = spec.clone();
        let points =
            adaptive::budget_points(&plan, &spec, mech, reading_s).map_err(AdaptError::Plan)?;
        let pool = Pool::new(&spec, mech).map_err(AdaptError::Plan)?;
        Ok(Some(Planner {
            plan,
            spec,
            mech: mech.clone(),
            reading_s,
            pool,
            points,
        }))
    }

    /// The budget in points.
    pub fn budget_points(&self) -> usize {
        self.points
    }

    /// The next batch, or `None` when the budget is spent (or no candidate is worth
    /// a point). Call only when no step of the run is pending.
    pub fn next(&mut self, store: &RunStore) -> Result<Option<Batch>, AdaptError> {
        let steps = store.steps()?;
        let sample_points: std::collections::BTreeSet<usize> = steps
            .iter()
            .filter(|s| s.step.kind == StepKind::Sample)
            .filter_map(|s| s.step.plan_index)
            .collect();
        let taken = sample_points.len();
        let left = self.points.saturating_sub(taken);
        let mut n = self.spec.batch_points(self.points).min(left);
        if left == 0 {
            tracing::info!(taken, budget = self.points, "adaptive budget spent");
            return Ok(None);
        }
        let decisions = store.decisions()?;
        let batch_no = decisions.len() + 1;
        // Without drift correction: the level would be interpolated in instrument
        // time, which a resumed session does not continue exactly (its clock starts
        // again), and the choice must depend on the readings' values alone. The
        // source's drift over a run is a fraction of a percent, far below the
        // contrasts a batch is chosen by.
        let options = Options {
            drift: Drift::None,
            ..Options::default()
        };
        let red = reduce(store, &options)?;
        let aim = match self.spec.method {
            adaptive::Method::Residual => Aim::Residual,
            adaptive::Method::Variation => Aim::Variation,
            adaptive::Method::Value => Aim::Value,
        };
        let pairs: Vec<PairDeg> = self.pool.candidates.iter().map(|c| c.pair).collect();
        let span = tracing::info_span!("adaptive batch", batch = batch_no, points = n);
        let _g = span.enter();
        let t0 = std::time::Instant::now();
        let mut picks = adapt::choose(&red.samples, &pairs, n, aim, MIN_SPACING_DEG)?;
        if picks.is_empty() {
            tracing::info!("no candidate left worth a point");
            return Ok(None);
        }
        let start = steps
            .iter()
            .rev()
            .find_map(|s| s.step.stages)
            .unwrap_or_else(|| self.mech.limits.map(|(lo, hi)| 0f64.clamp(lo, hi)));
        let reference = steps
            .iter()
            .find(|s| s.step.kind == StepKind::Reference)
            .and_then(|s| s.step.pair);
        let first_index = steps
            .iter()
            .filter_map(|s| s.step.plan_index)
            .max()
            .map_or(0, |m| m + 1);
        let schedule_of = |picks: &[adapt::Pick]| {
            let chosen: Vec<(PairDeg, [f64; 4])> = picks
                .iter()
                .map(|p| {
                    let c = &self.pool.candidates[p.candidate];
                    (c.pair, c.stages)
                })
                .collect();
            adaptive::schedule_batch(
                &self.plan,
                &self.mech,
                &chosen,
                first_index,
                start,
                reference,
                self.reading_s,
            )
        };
        let mut schedule = schedule_of(&picks)?;
        let spent_s = planned_s(store, &decisions)?;
        if let Budget::Hours(h) = self.spec.budget {
            // A time budget: the batch is cut to what the time left allows, by its
            // own time per point, and given up below the smallest batch.
            let left_s = h * 3600.0 - spent_s;
            if schedule.duration_s() > left_s {
                let per = schedule.duration_s() / picks.len() as f64;
                n = ((left_s / per).floor().max(0.0) as usize).min(picks.len());
                while n >= MIN_BATCH {
                    picks.truncate(n);
                    schedule = schedule_of(&picks)?;
                    if schedule.duration_s() <= left_s {
                        break;
                    }
                    n -= 1;
                }
                if n < MIN_BATCH {
                    tracing::info!(spent_s, left_s, "adaptive time budget spent");
                    return Ok(None);
                }
            }
        }
        let detail = serde_json::json!({
            "batch": batch_no,
            "method": self.spec.method.as_str(),
            "budget_points": self.points,
            "points_before": taken,
            "samples": red.samples.samples.len(),
            "estimate_s": schedule.duration_s(),
            "planned_s": spent_s + schedule.duration_s(),
            "columns": ["theta_i", "phi_i", "theta_o", "phi_o", "score", "value", "uncertainty", "gap_deg"],
            "picks": picks.iter().map(|p| {
                let c = &self.pool.candidates[p.candidate].pair;
                [c.incident.theta_deg, c.incident.phi_deg, c.outgoing.theta_deg,
                 c.outgoing.phi_deg, p.score, p.value, p.uncertainty, p.gap_deg]
            }).collect::<Vec<_>>(),
        });
        tracing::info!(
            points = picks.len(),
            steps = schedule.steps.len(),
            estimate_s = schedule.duration_s(),
            ms = t0.elapsed().as_secs_f64() * 1e3,
            "adaptive batch chosen"
        );
        Ok(Some(Batch {
            decision: Decision {
                method: self.spec.method.as_str().into(),
                points: picks.len() as u32,
                detail: detail.to_string(),
            },
            steps: schedule.steps,
        }))
    }
}

/// The planned instrument time so far, s: the coarse pass's estimate as the run file
/// records it, and each batch's.
fn planned_s(store: &RunStore, decisions: &[gonio_run::DecisionRecord]) -> Result<f64, AdaptError> {
    let meta = store.run_meta()?;
    let coarse = meta.estimate.map_or(0.0, |e| e.total_s());
    let batches: f64 = decisions
        .iter()
        .filter_map(|d| {
            serde_json::from_str::<serde_json::Value>(&d.detail)
                .ok()?
                .get("estimate_s")?
                .as_f64()
        })
        .sum();
    Ok(coarse + batches)
}

/// The sample points of a run's decisions, incidence by incidence: what the report
/// shows of where an adaptive run's points went. Each entry is `(batch, pair)`,
/// batch 0 for the coarse pass.
pub fn points_by_batch(store: &RunStore) -> Result<Vec<(usize, PairDeg)>, AdaptError> {
    let decisions = store.decisions()?;
    let steps = store.steps()?;
    let mut out = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    for s in &steps {
        if s.step.kind != StepKind::Sample {
            continue;
        }
        let (Some(pair), Some(index)) = (s.step.pair, s.step.plan_index) else {
            continue;
        };
        if !seen.insert(index) {
            continue;
        }
        let batch = decisions
            .iter()
            .rposition(|d| s.id >= d.first_step)
            .map_or(0, |k| k + 1);
        out.push((batch, pair));
    }
    Ok(out)
}
