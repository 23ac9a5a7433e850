//! Creating a run file for a prepared plan, with every input kept verbatim so that
//! the run can be resumed and reprocessed from the file alone.

use std::path::{Path, PathBuf};

use gonio_plan::plan::{self, Plan};
use gonio_plan::{Prepared, rejection_counts};

use crate::meta::{Estimate, RunMeta};
use crate::store::{RunStore, StoreError};
use crate::time::wall_now;

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
    /// Simulator config text and its sample's text, when simulated.
    pub sim: Option<(String, String)>,
    /// Seed.
    pub seed: Option<u64>,
    /// Operator notes.
    pub notes: Option<String>,
    /// Software name and version.
    pub software: String,
}

/// Why a run file could not be created.
#[derive(Debug, thiserror::Error)]
pub enum CreateError {
    /// A file the plan names could not be read (missing, not a regular file, too
    /// large, not UTF-8).
    #[error("{0}")]
    Read(#[from] gonio_core::input::InputError),
    /// The run file.
    #[error("{0}")]
    Store(#[from] StoreError),
}

/// The metadata of a new run of `plan`, prepared as `prepared`, from `inputs`: reads
/// the files the plan names (a list plan's directions, the standard's model).
pub fn meta_for(plan: &Plan, prepared: &Prepared, inputs: &Inputs) -> Result<RunMeta, CreateError> {
    let read = |p: &Path, max: u64| gonio_core::input::read_text(&plan.resolve(p), max);
    let plan_pairs = match &plan.points {
        plan::Points::List { file } => Some(read(file, gonio_core::dirfile::MAX_BYTES)?),
        _ => None,
    };
    let standard_model = match &plan.calibration.standard {
        Some(s) => Some(read(&s.model, gonio_core::input::MAX_CONFIG_BYTES)?),
        None => None,
    };
    let m = &prepared.mech;
    let s = &prepared.schedule;
    Ok(RunMeta {
        instrument: inputs.instrument_text.clone(),
        instrument_path: inputs
            .instrument_path
            .as_ref()
            .map(|p| p.display().to_string()),
        plan: inputs.plan_text.clone(),
        plan_path: inputs.plan_path.as_ref().map(|p| p.display().to_string()),
        plan_pairs,
        standard_model,
        sim: inputs.sim.as_ref().map(|(s, _)| s.clone()),
        sim_sample: inputs.sim.as_ref().map(|(_, t)| t.clone()),
        seed: inputs.seed,
        software: Some(inputs.software.clone()),
        created_s: Some(wall_now()),
        notes: inputs.notes.clone(),
        name: plan.name.clone(),
        kinematics: Some(
            serde_json::json!({ "layout": m.layout, "axes": m.axes, "limits": m.limits }),
        ),
        geometry: m.geometry.clone(),
        transmittance: plan
            .calibration
            .incident
            .as_ref()
            .map_or(1.0, |i| i.transmittance),
        estimate: Some(Estimate {
            startup_s: 0.0,
            motion_s: s.motion_s,
            raster_motion_s: s.raster_motion_s,
            detector_s: s.detector_s,
            band_s: s.band_s,
        }),
        check: Some({
            let mut check = serde_json::json!({
                "pairs": prepared.pairs.len(),
                "accepted": prepared.checked.accepted.len(),
                "rejected": rejection_counts(&prepared.checked),
            });
            // With several bands: which loop is inside, both estimates, the reason.
            if let Some(d) = &s.spectral {
                check["spectral"] = serde_json::json!(d);
            }
            check
        }),
        ..RunMeta::default()
    })
}

/// Creates the run file `out` for a prepared plan, keeping every input verbatim.
pub fn create(
    out: &Path,
    plan: &Plan,
    prepared: &Prepared,
    inputs: &Inputs,
) -> Result<RunStore, CreateError> {
    let meta = meta_for(plan, prepared, inputs)?;
    Ok(RunStore::create(
        out,
        &meta.to_map(),
        &prepared.schedule.steps,
    )?)
}
