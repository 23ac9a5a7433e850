//! A run file's metadata as a typed value: the verbatim inputs that make it
//! resumable and reprocessable, and what Gonio recorded when it created the run.
//!
//! In the file the metadata is a key–value table (`meta`), text values only, so
//! that any SQLite client can read it; [`RunMeta`] is that table read and checked.
//! Keys this build does not know are kept in [`RunMeta::other`].

use std::collections::BTreeMap;
use std::path::Path;

use gonio_core::goniometer::GeometryConfig;
use serde::Serialize;

use crate::error::StoreError;

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
    /// Steps in the schedule (written by the store, checked on open).
    pub const STEP_COUNT: &str = "step_count";
    /// Digest of the `meta` rows fixed at creation (hexadecimal).
    pub const INTEGRITY_META: &str = "integrity_meta";
    /// Readings committed and their digest, `COUNT:DIGEST`.
    pub const INTEGRITY_READINGS: &str = "integrity_readings";
}

/// A run's status.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RunStatus {
    /// Created; no session has started.
    #[default]
    Created,
    /// A session is working on it (or was killed while it did).
    Running,
    /// Every step is done or failed.
    Complete,
    /// Stopped on request; resumable.
    Interrupted,
    /// Stopped by a fault; resumable once it is fixed.
    Faulted,
}

impl RunStatus {
    /// The name stored in the file.
    pub fn as_str(self) -> &'static str {
        match self {
            RunStatus::Created => "created",
            RunStatus::Running => "running",
            RunStatus::Complete => "complete",
            RunStatus::Interrupted => "interrupted",
            RunStatus::Faulted => "faulted",
        }
    }

    /// The status a stored name means.
    pub fn parse(s: &str) -> Option<RunStatus> {
        Some(match s {
            "created" => RunStatus::Created,
            "running" => RunStatus::Running,
            "complete" => RunStatus::Complete,
            "interrupted" => RunStatus::Interrupted,
            "faulted" => RunStatus::Faulted,
            _ => return None,
        })
    }
}

impl std::fmt::Display for RunStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Estimated durations recorded at creation, s.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct Estimate {
    /// The session's start-up: identification, set-up, homing (absent from run files
    /// written before it was estimated).
    #[serde(default)]
    pub startup_s: f64,
    /// Motion in the optimised order.
    pub motion_s: f64,
    /// Motion in plan order.
    pub raster_motion_s: f64,
    /// Detector time.
    pub detector_s: f64,
    /// Band changes (absent from run files written before bands were estimated).
    #[serde(default)]
    pub band_s: f64,
}

impl Estimate {
    /// The whole estimate, s: start-up, motion, band changes and detector.
    pub fn total_s(&self) -> f64 {
        self.startup_s + self.motion_s + self.band_s + self.detector_s
    }
}

/// The metadata of a run file, typed.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RunMeta {
    /// Instrument config, verbatim TOML.
    pub instrument: String,
    /// Where it was read from.
    pub instrument_path: Option<String>,
    /// Plan, verbatim TOML.
    pub plan: String,
    /// Where it was read from.
    pub plan_path: Option<String>,
    /// A `list` plan's directions file, verbatim.
    pub plan_pairs: Option<String>,
    /// The reference standard's model file, verbatim.
    pub standard_model: Option<String>,
    /// The simulator config, verbatim, when the run is simulated.
    pub sim: Option<String>,
    /// The simulated sample's model file (or table), verbatim.
    pub sim_sample: Option<String>,
    /// The seed of every random draw.
    pub seed: Option<u64>,
    /// Software that created the run.
    pub software: Option<String>,
    /// Creation time, Unix seconds.
    pub created_s: Option<f64>,
    /// Operator notes.
    pub notes: Option<String>,
    /// Run name (the plan's).
    pub name: Option<String>,
    /// Layout, role axes and limits, as recorded.
    pub kinematics: Option<serde_json::Value>,
    /// The optical geometry.
    pub geometry: GeometryConfig,
    /// The incident-beam filter's transmittance.
    pub transmittance: f64,
    /// Estimated durations.
    pub estimate: Option<Estimate>,
    /// The plan check: pairs, accepted, rejected by reason.
    pub check: Option<serde_json::Value>,
    /// The run's status.
    pub status: RunStatus,
    /// Steps in the schedule.
    pub step_count: Option<usize>,
    /// Keys this build does not know, verbatim.
    pub other: BTreeMap<String, String>,
}

impl RunMeta {
    /// Reads the `meta` table of the run file `path`. A value this build relies on
    /// that does not parse makes the file corrupt; unknown keys are kept.
    pub fn from_map(map: &BTreeMap<String, String>, path: &Path) -> Result<RunMeta, StoreError> {
        let corrupt = |why: String| StoreError::Corrupt {
            path: path.to_path_buf(),
            why,
        };
        let mut rest = map.clone();
        let mut take = |k: &str| rest.remove(k);
        let missing = |key: &str| StoreError::MissingMeta {
            path: path.to_path_buf(),
            key: key.to_string(),
        };
        let instrument = take(keys::INSTRUMENT).ok_or_else(|| missing(keys::INSTRUMENT))?;
        let plan = take(keys::PLAN).ok_or_else(|| missing(keys::PLAN))?;
        // The store's own record, not the run's description.
        take(keys::INTEGRITY_META);
        take(keys::INTEGRITY_READINGS);
        let num = |k: &str, v: Option<String>| -> Result<Option<f64>, StoreError> {
            v.map(|v| {
                v.parse::<f64>()
                    .map_err(|_| corrupt(format!("meta `{k}` = {v:?} is not a number")))
            })
            .transpose()
        };
        let json = |k: &str, v: Option<String>| -> Result<Option<serde_json::Value>, StoreError> {
            v.map(|v| serde_json::from_str(&v).map_err(|e| corrupt(format!("meta `{k}`: {e}"))))
                .transpose()
        };
        let seed = take(keys::SEED)
            .map(|v| {
                v.parse::<u64>()
                    .map_err(|_| corrupt(format!("meta `seed` = {v:?} is not a seed")))
            })
            .transpose()?;
        let created_s = num(keys::CREATED, take(keys::CREATED))?;
        let transmittance = num(keys::TRANSMITTANCE, take(keys::TRANSMITTANCE))?.unwrap_or(1.0);
        let geometry = match take(keys::GEOMETRY) {
            Some(v) => {
                serde_json::from_str(&v).map_err(|e| corrupt(format!("meta `geometry`: {e}")))?
            }
            None => geometry_of_instrument(&instrument),
        };
        let estimate = match take(keys::ESTIMATE) {
            Some(v) => Some(
                serde_json::from_str(&v).map_err(|e| corrupt(format!("meta `estimate`: {e}")))?,
            ),
            None => None,
        };
        let kinematics = json(keys::KINEMATICS, take(keys::KINEMATICS))?;
        let check = json(keys::CHECK, take(keys::CHECK))?;
        let status = match take(keys::STATUS) {
            Some(v) => RunStatus::parse(&v)
                .ok_or_else(|| corrupt(format!("meta `status` = {v:?} is not a run status")))?,
            None => RunStatus::Created,
        };
        let step_count = take(keys::STEP_COUNT)
            .map(|v| {
                v.parse::<usize>()
                    .map_err(|_| corrupt(format!("meta `step_count` = {v:?} is not a count")))
            })
            .transpose()?;
        let mut meta = RunMeta {
            instrument,
            instrument_path: take(keys::INSTRUMENT_PATH),
            plan,
            plan_path: take(keys::PLAN_PATH),
            plan_pairs: take(keys::PLAN_PAIRS),
            standard_model: take(keys::STANDARD_MODEL),
            sim: take(keys::SIM),
            sim_sample: take(keys::SIM_SAMPLE),
            seed,
            software: take(keys::SOFTWARE),
            created_s,
            notes: take(keys::NOTES),
            name: take(keys::NAME),
            kinematics,
            geometry,
            transmittance,
            estimate,
            check,
            status,
            step_count,
            other: BTreeMap::new(),
        };
        meta.other = rest;
        Ok(meta)
    }

    /// The `meta` table this value is stored as (without `status` and `step_count`,
    /// which the store writes itself).
    pub fn to_map(&self) -> BTreeMap<String, String> {
        let mut m = self.other.clone();
        let mut put = |k: &str, v: Option<String>| {
            if let Some(v) = v {
                m.insert(k.to_string(), v);
            }
        };
        put(keys::INSTRUMENT, Some(self.instrument.clone()));
        put(keys::INSTRUMENT_PATH, self.instrument_path.clone());
        put(keys::PLAN, Some(self.plan.clone()));
        put(keys::PLAN_PATH, self.plan_path.clone());
        put(keys::PLAN_PAIRS, self.plan_pairs.clone());
        put(keys::STANDARD_MODEL, self.standard_model.clone());
        put(keys::SIM, self.sim.clone());
        put(keys::SIM_SAMPLE, self.sim_sample.clone());
        put(keys::SEED, self.seed.map(|s| s.to_string()));
        put(keys::SOFTWARE, self.software.clone());
        put(keys::CREATED, self.created_s.map(|s| s.to_string()));
        put(keys::NOTES, self.notes.clone());
        put(keys::NAME, self.name.clone());
        put(
            keys::KINEMATICS,
            self.kinematics.as_ref().map(serde_json::Value::to_string),
        );
        put(keys::GEOMETRY, serde_json::to_string(&self.geometry).ok());
        put(keys::TRANSMITTANCE, Some(self.transmittance.to_string()));
        put(
            keys::ESTIMATE,
            self.estimate.and_then(|e| serde_json::to_string(&e).ok()),
        );
        put(
            keys::CHECK,
            self.check.as_ref().map(serde_json::Value::to_string),
        );
        m
    }
}

/// The `[geometry]` table of an instrument config's text (its defaults when the
/// table is absent or unreadable): for run files that did not record it apart.
fn geometry_of_instrument(text: &str) -> GeometryConfig {
    #[derive(serde::Deserialize)]
    struct Only {
        #[serde(default)]
        geometry: Option<toml::Value>,
    }
    toml::from_str::<Only>(text)
        .ok()
        .and_then(|o| o.geometry)
        .and_then(|g| g.try_into().ok())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(pairs: &[(&str, &str)]) -> BTreeMap<String, String> {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    }

    #[test]
    fn round_trips_and_keeps_unknown_keys() {
        let m = map(&[
            ("instrument", "[geometry]\ndetector_radius_m = 0.01\n"),
            ("plan", "[points]\n"),
            ("seed", "42"),
            ("created_s", "1800000000.5"),
            ("incident_transmittance", "0.001"),
            (
                "estimate",
                r#"{"motion_s":1.5,"raster_motion_s":2.0,"detector_s":3.0}"#,
            ),
            ("status", "interrupted"),
            ("step_count", "7"),
            ("from_a_newer_build", "kept"),
        ]);
        let meta = RunMeta::from_map(&m, Path::new("r.gonio")).expect("reads");
        assert_eq!(meta.seed, Some(42));
        assert_eq!(meta.created_s, Some(1_800_000_000.5));
        assert_eq!(meta.transmittance, 0.001);
        assert_eq!(meta.status, RunStatus::Interrupted);
        assert_eq!(meta.step_count, Some(7));
        assert_eq!(meta.estimate.map(|e| e.detector_s), Some(3.0));
        // Written before band changes were estimated: none.
        assert_eq!(meta.estimate.map(|e| e.band_s), Some(0.0));
        assert_eq!(meta.other["from_a_newer_build"], "kept");
        // Without a recorded geometry, the instrument config's own table.
        assert_eq!(meta.geometry.detector_radius_m, 0.01);
        assert_eq!(
            meta.geometry.detector_distance_m,
            GeometryConfig::default().detector_distance_m
        );
        // What the store writes back reads to the same value (status and step count
        // are the store's own).
        let mut back = meta.to_map();
        back.insert("status".into(), "interrupted".into());
        back.insert("step_count".into(), "7".into());
        assert_eq!(
            RunMeta::from_map(&back, Path::new("r.gonio")).expect("reads"),
            meta
        );
    }

    #[test]
    fn a_bad_value_makes_the_file_corrupt_naming_the_key() {
        let base = [("instrument", ""), ("plan", "")];
        for (k, v) in [
            ("status", "half-done"),
            ("seed", "-1"),
            ("created_s", "yesterday"),
            ("geometry", "{"),
        ] {
            let mut m = map(&base);
            m.insert(k.into(), v.into());
            let e = RunMeta::from_map(&m, Path::new("r.gonio")).expect_err(k);
            assert!(matches!(e, StoreError::Corrupt { .. }), "{k}: {e}");
            assert!(e.to_string().contains(&format!("`{k}`")), "{e}");
            assert!(e.to_string().starts_with("r.gonio: corrupted"), "{e}");
        }
        let e = RunMeta::from_map(&map(&[("plan", "")]), Path::new("r.gonio"))
            .expect_err("no instrument");
        assert!(matches!(e, StoreError::MissingMeta { ref key, .. } if key == "instrument"));
        assert!(
            e.to_string()
                .starts_with("r.gonio: the run's meta row `instrument` is missing"),
            "{e}"
        );
        assert!(
            !e.is_bad_input(),
            "a damaged run is a runtime fault (exit 1)"
        );
    }
}
