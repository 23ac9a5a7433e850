//! Runs as wholes: preparing a plan on an instrument, creating the run file with
//! everything needed to resume and reprocess it, reading it back, and summarising it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use gonio_core::dirfile::PairDeg;
use gonio_core::tomlfile::FileError;
use gonio_driver::InstrumentConfig;
use serde::Serialize;

use crate::plan::{self, Checked, Mechanics, MechanicsError, Plan};
use crate::schedule::{self, Schedule, ScheduleError, StepKind};
use crate::store::{RunStore, StoreError, utc};

/// Metadata keys of a run file (see `docs/run-file.md`).
pub mod keys {
    /// Instrument config, verbatim TOML.
    pub const INSTRUMENT: &str = "instrument";
    /// Where it was read from.
    pub const INSTRUMENT_PATH: &str = "instrument_path";
    /// Plan, verbatim TOML.
    pub const PLAN: &str = "plan";
    /// Where it was read from.
    pub const PLAN_PATH: &str = "plan_path";
    /// A `list` plan's directions file, verbatim.
    pub const PLAN_PAIRS: &str = "plan_pairs";
    /// The reference standard's model file, verbatim.
    pub const STANDARD_MODEL: &str = "standard_model";
    /// The simulator config, verbatim, when the run is simulated.
    pub const SIM: &str = "sim";
    /// The simulated sample's model file, verbatim.
    pub const SIM_SAMPLE: &str = "sim_sample";
    /// The seed of every random draw.
    pub const SEED: &str = "seed";
    /// Software that created the run.
    pub const SOFTWARE: &str = "software";
    /// Creation time, Unix seconds.
    pub const CREATED: &str = "created_s";
    /// Operator notes.
    pub const NOTES: &str = "notes";
    /// Run name (the plan's).
    pub const NAME: &str = "name";
    /// Layout and role axes (JSON).
    pub const KINEMATICS: &str = "kinematics";
    /// Optical geometry (JSON).
    pub const GEOMETRY: &str = "geometry";
    /// The incident-beam filter's transmittance.
    pub const TRANSMITTANCE: &str = "incident_transmittance";
    /// Estimated motion, raster motion and detector seconds (JSON).
    pub const ESTIMATE: &str = "estimate";
    /// The plan check: accepted and rejected counts by reason (JSON).
    pub const CHECK: &str = "check";
    /// Run status: `created`, `running`, `complete`, `interrupted`, `faulted`.
    pub const STATUS: &str = "status";
}

/// Why a plan cannot run on an instrument: bad input, exit status 2.
#[derive(Debug, thiserror::Error)]
pub enum PrepareError {
    /// The instrument config cannot plan.
    #[error("{path}: {source}")]
    Mechanics {
        /// The instrument config's name.
        path: String,
        /// Why.
        #[source]
        source: MechanicsError,
    },
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

/// Checks `plan` on `instrument` and schedules it from the stages' home (0°, or the
/// nearest limit).
pub fn prepare(
    instrument: &InstrumentConfig,
    instrument_name: &str,
    plan: &Plan,
) -> Result<Prepared, PrepareError> {
    let mech = Mechanics::of(instrument).map_err(|source| PrepareError::Mechanics {
        path: instrument_name.to_string(),
        source,
    })?;
    let pairs = plan.pairs()?;
    let checked = plan::check(&mech, &pairs);
    let start = mech.limits.map(|(lo, hi)| 0f64.clamp(lo, hi));
    let reading = schedule::reading_seconds(instrument);
    let schedule = schedule::build(plan, &mech, &checked, start, reading).map_err(|source| {
        PrepareError::Schedule {
            path: plan
                .source
                .as_deref()
                .map_or("<plan>".into(), |p| p.display().to_string()),
            source,
        }
    })?;
    Ok(Prepared {
        mech,
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

/// The verbatim inputs of a new run.
#[derive(Clone, Debug, Default)]
pub struct Inputs {
    /// Instrument config text.
    pub instrument_text: String,
    /// Its path.
    pub instrument_path: Option<PathBuf>,
    /// Plan text.
    pub plan_text: String,
    /// Its path.
    pub plan_path: Option<PathBuf>,
    /// Simulator config text and its sample's model text, when simulated.
    pub sim: Option<(String, String)>,
    /// Seed.
    pub seed: Option<u64>,
    /// Operator notes.
    pub notes: Option<String>,
    /// Software name and version.
    pub software: String,
}

/// Creates the run file `out` for a prepared plan, keeping every input verbatim.
pub fn create(
    out: &Path,
    plan: &Plan,
    prepared: &Prepared,
    inputs: &Inputs,
) -> Result<RunStore, CreateError> {
    let mut meta = BTreeMap::new();
    let mut put = |k: &str, v: String| {
        meta.insert(k.to_string(), v);
    };
    put(keys::INSTRUMENT, inputs.instrument_text.clone());
    put(keys::PLAN, inputs.plan_text.clone());
    if let Some(p) = &inputs.instrument_path {
        put(keys::INSTRUMENT_PATH, p.display().to_string());
    }
    if let Some(p) = &inputs.plan_path {
        put(keys::PLAN_PATH, p.display().to_string());
    }
    if let plan::Points::List { file } = &plan.points {
        let path = plan.resolve(file);
        let text =
            std::fs::read_to_string(&path).map_err(|e| CreateError::Read(path.clone(), e))?;
        put(keys::PLAN_PAIRS, text);
    }
    if let Some(s) = &plan.calibration.standard {
        let path = plan.resolve(&s.model);
        let text =
            std::fs::read_to_string(&path).map_err(|e| CreateError::Read(path.clone(), e))?;
        put(keys::STANDARD_MODEL, text);
    }
    if let Some((sim, sample)) = &inputs.sim {
        put(keys::SIM, sim.clone());
        put(keys::SIM_SAMPLE, sample.clone());
    }
    if let Some(seed) = inputs.seed {
        put(keys::SEED, seed.to_string());
    }
    if let Some(n) = &inputs.notes {
        put(keys::NOTES, n.clone());
    }
    if let Some(n) = &plan.name {
        put(keys::NAME, n.clone());
    }
    put(keys::SOFTWARE, inputs.software.clone());
    put(keys::CREATED, crate::store::wall_now().to_string());
    let m = &prepared.mech;
    put(
        keys::KINEMATICS,
        serde_json::json!({ "layout": m.layout, "axes": m.axes, "limits": m.limits }).to_string(),
    );
    put(
        keys::GEOMETRY,
        serde_json::to_string(&m.geometry).unwrap_or_default(),
    );
    put(
        keys::TRANSMITTANCE,
        plan.calibration
            .incident
            .as_ref()
            .map_or(1.0, |i| i.transmittance)
            .to_string(),
    );
    let s = &prepared.schedule;
    put(
        keys::ESTIMATE,
        serde_json::json!({
            "motion_s": s.motion_s,
            "raster_motion_s": s.raster_motion_s,
            "detector_s": s.detector_s,
        })
        .to_string(),
    );
    put(
        keys::CHECK,
        serde_json::json!({
            "pairs": prepared.pairs.len(),
            "accepted": prepared.checked.accepted.len(),
            "rejected": rejection_counts(&prepared.checked),
        })
        .to_string(),
    );
    Ok(RunStore::create(out, &meta, &s.steps)?)
}

/// Why a run file could not be created.
#[derive(Debug, thiserror::Error)]
pub enum CreateError {
    /// A file the plan names could not be read.
    #[error("{0}: {1}")]
    Read(PathBuf, #[source] std::io::Error),
    /// The run file.
    #[error("{0}")]
    Store(#[from] StoreError),
}

/// What a stored run needs to go on: its instrument and, when simulated, its
/// simulator, rebuilt from the texts the run file keeps.
#[derive(Clone, Debug)]
pub struct Stored {
    /// The instrument config.
    pub instrument: InstrumentConfig,
    /// Simulator config and sample model texts.
    pub sim: Option<(String, String)>,
    /// The seed.
    pub seed: Option<u64>,
    /// The reference standard's model text.
    pub standard_model: Option<String>,
    /// The incident filter's transmittance.
    pub transmittance: f64,
}

/// Reads back what [`create`] stored.
pub fn stored(store: &RunStore) -> Result<Stored, StoreError> {
    let meta = store.meta()?;
    let corrupt = |why: String| StoreError::Corrupt {
        path: store.path().to_path_buf(),
        why,
    };
    let text = meta
        .get(keys::INSTRUMENT)
        .ok_or_else(|| corrupt("no instrument config".into()))?;
    let instrument = InstrumentConfig::from_toml(text, None)
        .map_err(|e| corrupt(format!("stored instrument config: {e}")))?;
    let sim = match (meta.get(keys::SIM), meta.get(keys::SIM_SAMPLE)) {
        (Some(a), Some(b)) => Some((a.clone(), b.clone())),
        _ => None,
    };
    Ok(Stored {
        instrument,
        sim,
        seed: meta.get(keys::SEED).and_then(|s| s.parse().ok()),
        standard_model: meta.get(keys::STANDARD_MODEL).cloned(),
        transmittance: meta
            .get(keys::TRANSMITTANCE)
            .and_then(|s| s.parse().ok())
            .unwrap_or(1.0),
    })
}

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

/// What `gonio show` prints.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// The file.
    pub path: String,
    /// Run name.
    pub name: Option<String>,
    /// Status.
    pub status: String,
    /// Steps in the schedule.
    pub steps: usize,
    /// Steps by state.
    pub states: BTreeMap<String, u64>,
    /// Done steps by kind.
    pub done_by_kind: BTreeMap<String, usize>,
    /// Readings with a flag.
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
}

/// Summarises a run file.
pub fn summary(store: &RunStore) -> Result<Summary, StoreError> {
    let meta = store.meta()?;
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
    let mut events = BTreeMap::new();
    for e in store.events()? {
        *events.entry(e.kind).or_insert(0) += 1;
    }
    let json = |k: &str| {
        meta.get(k)
            .and_then(|v| serde_json::from_str(v).ok())
            .unwrap_or(serde_json::Value::Null)
    };
    Ok(Summary {
        path: store.path().display().to_string(),
        name: meta.get(keys::NAME).cloned(),
        status: meta.get(keys::STATUS).cloned().unwrap_or_default(),
        steps: steps.len(),
        states: store.state_counts()?,
        done_by_kind,
        flagged: readings.iter().filter(|r| r.flags != 0).count(),
        retries: readings.iter().map(|r| r.retries).sum(),
        sessions,
        estimate: json(keys::ESTIMATE),
        check: json(keys::CHECK),
        events,
        created: meta
            .get(keys::CREATED)
            .and_then(|v| v.parse::<f64>().ok())
            .map(utc),
        software: meta.get(keys::SOFTWARE).cloned(),
        seed: meta.get(keys::SEED).cloned(),
        notes: meta.get(keys::NOTES).cloned(),
        instrument: meta.get(keys::INSTRUMENT).cloned().unwrap_or_default(),
        plan: meta.get(keys::PLAN).cloned().unwrap_or_default(),
        sim: meta.get(keys::SIM).cloned(),
    })
}
