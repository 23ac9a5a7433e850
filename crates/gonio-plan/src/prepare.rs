//! A plan checked and scheduled on an instrument: what `gonio plan check` prints and
//! what a new run file records.

use std::collections::BTreeMap;

use gonio_core::dirfile::PairDeg;
use gonio_core::tomlfile::FileError;

use crate::plan::{self, Checked, Mechanics, Plan};
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
    /// The steps and estimates.
    pub schedule: Schedule,
}

/// Checks `plan` on the instrument `mech` and schedules it from the stages' home (0°,
/// or the nearest limit), each reading estimated at `reading_s` seconds.
pub fn prepare(mech: &Mechanics, reading_s: f64, plan: &Plan) -> Result<Prepared, PrepareError> {
    let pairs = plan.pairs()?;
    let checked = plan::check(mech, &pairs);
    let start = mech.limits.map(|(lo, hi)| 0f64.clamp(lo, hi));
    let schedule = schedule::build(plan, mech, &checked, start, reading_s).map_err(|source| {
        PrepareError::Schedule {
            path: plan
                .source
                .as_deref()
                .map_or("<plan>".into(), |p| p.display().to_string()),
            source,
        }
    })?;
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
