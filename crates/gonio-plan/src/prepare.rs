//! A plan checked and scheduled on an instrument: what `gonio plan check` prints and
//! what a new run file records.

use std::collections::BTreeMap;

use gonio_core::dirfile::PairDeg;
use gonio_core::tomlfile::FileError;

use crate::adaptive::{self, Pool};
use crate::plan::{self, Checked, Mechanics, Plan, Points};
use crate::schedule::{self, Schedule, ScheduleError};

/// Why a plan cannot run on an instrument: bad input.
#[derive(Debug, thiserror::Error)]
pub enum PrepareError {
    /// A file the plan names.
    #[error("{0}")]
    File(#[from] FileError),
    /// The schedule.
    #[error("{path}: {source}")]
    Schedule {
        /// The plan's name.
        path: String,
        /// Why.
        #[source]
        source: ScheduleError,
    },
}

/// A plan checked and scheduled on an instrument.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// The instrument's mechanics.
    pub mech: Mechanics,
    /// The plan's pairs, plan order.
    pub pairs: Vec<PairDeg>,
    /// Accepted and rejected pairs.
    pub checked: Checked,
    /// The steps and estimates (of an adaptive plan: its coarse pass).
    pub schedule: Schedule,
    /// An adaptive plan's budget, coarse pass, batches and candidates.
    pub adaptive: Option<adaptive::Summary>,
}

/// Checks `plan` on the instrument `mech` and schedules it from the stages' home (0°,
/// or the nearest limit), each reading estimated at `reading_s` seconds.
pub fn prepare(mech: &Mechanics, reading_s: f64, plan: &Plan) -> Result<Prepared, PrepareError> {
    let name = || {
        plan.source
            .as_deref()
            .map_or("<plan>".into(), |p| p.display().to_string())
    };
    let adaptive_error = |m: String| {
        PrepareError::File(FileError {
            field: Some("points.budget".into()),
            ..FileError::whole("plan", plan.source.as_deref(), m)
        })
    };
    let (pairs, budget) = match &plan.points {
        Points::Adaptive(a) => {
            let budget =
                adaptive::budget_points(plan, a, mech, reading_s).map_err(adaptive_error)?;
            let pairs = a
                .coarse_per_incidence(budget)
                .and_then(|n| a.coarse_pairs(n))
                .map_err(adaptive_error)?;
            (pairs, Some((a, budget)))
        }
        _ => (plan.pairs()?, None),
    };
    let checked = plan::check(mech, &pairs);
    let start = mech.limits.map(|(lo, hi)| 0f64.clamp(lo, hi));
    let schedule = schedule::build(plan, mech, &checked, start, reading_s).map_err(|source| {
        PrepareError::Schedule {
            path: name(),
            source,
        }
    })?;
    if let Some((a, _)) = budget
        && let adaptive::Budget::Hours(h) = a.budget
        && schedule.duration_s() > h * 3600.0
    {
        return Err(adaptive_error(format!(
            "the coarse pass alone is estimated at {:.0} s, more than the budget of {h} h \
             ({:.0} s): raise the budget or lower `coarse`",
            schedule.duration_s(),
            h * 3600.0
        )));
    }
    let adaptive = match budget {
        None => None,
        Some((a, points)) => {
            let pool = Pool::new(a, mech).map_err(adaptive_error)?;
            let coarse = checked.accepted.len();
            let point_s = schedule.duration_s() / coarse.max(1) as f64;
            Some(adaptive::Summary {
                budget: a.budget,
                points,
                coarse,
                batch: a.batch_points(points),
                pool: pool.candidates.len(),
                refused: pool.refused,
                point_s,
                // With a budget in hours the batches are cut to the time left.
                estimate_s: match a.budget {
                    adaptive::Budget::Hours(h) => (h * 3600.0).min(
                        schedule.duration_s() + points.saturating_sub(coarse) as f64 * point_s,
                    ),
                    adaptive::Budget::Points(_) => {
                        schedule.duration_s() + points.saturating_sub(coarse) as f64 * point_s
                    }
                },
                method: a.method,
            })
        }
    };
    tracing::debug!(
        pairs = pairs.len(),
        accepted = checked.accepted.len(),
        rejected = checked.rejected.len(),
        steps = schedule.steps.len(),
        motion_s = schedule.motion_s,
        band_s = schedule.band_s,
        inner = schedule.spectral.as_ref().map(|d| d.inner.as_str()),
        "plan prepared"
    );
    Ok(Prepared {
        mech: mech.clone(),
        pairs,
        checked,
        schedule,
        adaptive,
    })
}

/// Counts of rejected pairs by reason.
pub fn rejection_counts(checked: &Checked) -> BTreeMap<&'static str, usize> {
    let mut m = BTreeMap::new();
    for r in &checked.rejected {
        *m.entry(r.reason.name()).or_insert(0) += 1;
    }
    m
}
