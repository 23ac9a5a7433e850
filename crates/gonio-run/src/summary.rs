//! What `gonio show` prints: a run's status, counts, sessions and inputs.

use std::collections::BTreeMap;

use gonio_plan::StepKind;
use serde::Serialize;

use crate::store::{RunStore, StoreError};
use crate::time::utc;

/// A session of a run, for reports.
#[derive(Clone, Debug, Serialize)]
pub struct SessionSummary {
    /// Start, UTC.
    pub started: String,
    /// End, UTC (none: killed or still running).
    pub ended: Option<String>,
    /// How it ended.
    pub outcome: Option<String>,
    /// Wall seconds.
    pub wall_s: Option<f64>,
    /// Readings taken.
    pub readings: usize,
    /// Instrument seconds (to its last reading).
    pub physical_s: f64,
}

/// An adaptive run's batches, for reports.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct BatchesSummary {
    /// Batches decided during the run.
    pub decided: usize,
    /// Sample points they chose.
    pub points: u64,
    /// Steps they added.
    pub steps: u64,
}

/// What `gonio show` prints.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// The file.
    pub path: String,
    /// Run name.
    pub name: Option<String>,
    /// Status: the stored one, except that a run stored as `running` which no
    /// process measures (none holds its lock) is `stale` ([`status_now`]).
    pub status: String,
    /// What the status means and what to do, for `stale` (absent otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub status_note: Option<String>,
    /// Steps in the schedule.
    pub steps: usize,
    /// Steps by state.
    pub states: BTreeMap<String, u64>,
    /// Done steps by kind.
    pub done_by_kind: BTreeMap<String, usize>,
    /// Readings with a flag that questions them (not how they were read).
    pub flagged: usize,
    /// Exchanges retried.
    pub retries: u64,
    /// Sessions.
    pub sessions: Vec<SessionSummary>,
    /// Estimated motion, raster motion and detector seconds.
    pub estimate: serde_json::Value,
    /// The plan check.
    pub check: serde_json::Value,
    /// Events by kind.
    pub events: BTreeMap<String, usize>,
    /// Creation time, UTC.
    pub created: Option<String>,
    /// Software that created it.
    pub software: Option<String>,
    /// Seed.
    pub seed: Option<String>,
    /// Notes.
    pub notes: Option<String>,
    /// Instrument config, verbatim.
    pub instrument: String,
    /// Plan, verbatim.
    pub plan: String,
    /// Simulator config, verbatim.
    pub sim: Option<String>,
    /// An adaptive run's batches (absent for other runs, and from their JSON).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub batches: Option<BatchesSummary>,
}

/// What a `stale` run is: stored as running, but nobody measures it.
pub const STALE_NOTE: &str = "no process measures the run: its last session ended without \
                              a clean stop (killed, or its status could not be written); \
                              `gonio resume` continues it";

/// A run's status as it is now, from the `stored` one: `running` stays so only
/// while a process holds the run's lock (the measuring process, which cannot die
/// and keep it: `lock.rs`); otherwise the last session ended without writing its
/// end — killed, or a full disk refused the write — and the run is `stale`.
pub fn status_now(store: &RunStore, stored: &str) -> (String, Option<String>) {
    if stored == "running" && store.measured_by().is_none() {
        ("stale".into(), Some(STALE_NOTE.into()))
    } else {
        (stored.into(), None)
    }
}

/// Summarises a run file.
pub fn summary(store: &RunStore) -> Result<Summary, StoreError> {
    let meta = store.run_meta()?;
    let steps = store.steps()?;
    let readings = store.readings()?;
    let kinds: BTreeMap<i64, StepKind> = steps.iter().map(|s| (s.id, s.step.kind)).collect();
    let mut done_by_kind = BTreeMap::new();
    for r in &readings {
        if let Some(k) = kinds.get(&r.step_id) {
            *done_by_kind.entry(k.as_str().to_string()).or_insert(0) += 1;
        }
    }
    let per_session = store.session_readings()?;
    let sessions = store
        .sessions()?
        .into_iter()
        .map(|s| {
            let (readings, physical_s) = per_session.get(&s.id).copied().unwrap_or((0, 0.0));
            SessionSummary {
                started: utc(s.started_s),
                ended: s.ended_s.map(utc),
                outcome: s.outcome,
                wall_s: s.ended_s.map(|e| e - s.started_s),
                readings,
                physical_s,
            }
        })
        .collect();
    let decisions = store.decisions()?;
    let batches = (!decisions.is_empty()).then(|| BatchesSummary {
        decided: decisions.len(),
        points: decisions.iter().map(|d| u64::from(d.points)).sum(),
        steps: decisions.iter().map(|d| u64::from(d.steps)).sum(),
    });
    let mut events = BTreeMap::new();
    for e in store.events()? {
        *events.entry(e.kind).or_insert(0) += 1;
    }
    let (status, status_note) = status_now(store, meta.status.as_str());
    Ok(Summary {
        path: store.path().display().to_string(),
        name: meta.name,
        status,
        status_note,
        steps: steps.len(),
        states: store.state_counts()?,
        done_by_kind,
        flagged: readings
            .iter()
            .filter(|r| crate::flags::questioned(r.flags))
            .count(),
        retries: readings.iter().map(|r| r.retries).sum(),
        sessions,
        estimate: meta
            .estimate
            .and_then(|e| serde_json::to_value(e).ok())
            .unwrap_or(serde_json::Value::Null),
        check: meta.check.unwrap_or(serde_json::Value::Null),
        events,
        created: meta.created_s.map(utc),
        software: meta.software,
        seed: meta.seed.map(|s| s.to_string()),
        notes: meta.notes,
        instrument: meta.instrument,
        plan: meta.plan,
        sim: meta.sim,
        batches,
    })
}
