//! The simulator's config file: the instrument's mechanics, optics, sample, lock-in
//! physics and faults. Strict TOML (unknown keys are errors); errors name the file,
//! line and field.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use gonio_brdf::{Brdf, Model};
use gonio_core::kinematics::Layout;
use serde::Deserialize;

use crate::controller::ControllerConfig;
use crate::faults::FaultConfig;
use crate::lockin::LockInConfig;
use crate::optics::OpticsConfig;

/// The embedded default: the blue paint of Lafortune et al. 1997 on a coplanar-arm
/// goniometer (`config/sim-example.toml`).
pub const DEFAULT_SIM: &str = include_str!("../../config/sim-example.toml");

/// The embedded default sample.
const BLUE_PAINT: &str = include_str!("../../config/models/blue-paint-550nm.toml");

/// How the stages are arranged and which controller drives which role.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KinematicsConfig {
    /// The layout.
    pub layout: Layout,
    /// Controller address of each of the layout's four roles.
    pub addresses: BTreeMap<String, u8>,
}

/// The sample on the stage.
#[derive(Clone, Debug, PartialEq, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct SampleConfig {
    /// A model file (relative to the config file's directory).
    pub model: Option<PathBuf>,
    /// The channel the detector sees (a name like `G` or `550nm`); the first if absent.
    pub channel: Option<String>,
}

/// Serial line timing, for the physical time of each exchange.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LinkConfig {
    /// Baud rate of the SMC100 line.
    pub motion_baud: u32,
    /// Baud rate of the SR830 line.
    pub detector_baud: u32,
    /// The SMC100's time to answer a query, s (10–16 ms in the manual).
    pub motion_latency_s: f64,
    /// The SR830's time to answer a query, s.
    pub detector_latency_s: f64,
}

impl Default for LinkConfig {
    fn default() -> Self {
        LinkConfig {
            motion_baud: 57_600,
            detector_baud: 9_600,
            motion_latency_s: 0.010,
            detector_latency_s: 0.005,
        }
    }
}

/// A simulated goniometer.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimConfig {
    /// Seed of every random draw (noise, faults): one seed, the same bytes.
    #[serde(default)]
    pub seed: u64,
    /// Wall seconds per physical second: 0 = as fast as possible (in-process), 1 = real time.
    #[serde(default)]
    pub time_scale: f64,
    /// Mechanics.
    pub kinematics: KinematicsConfig,
    /// Controller settings by address; addresses not listed get the defaults.
    #[serde(default)]
    pub controllers: Vec<ControllerConfig>,
    /// Optics.
    #[serde(default)]
    pub optics: OpticsConfig,
    /// Sample.
    #[serde(default)]
    pub sample: SampleConfig,
    /// Lock-in physics.
    #[serde(default)]
    pub lockin: LockInConfig,
    /// Faults.
    #[serde(default)]
    pub faults: FaultConfig,
    /// Serial timing.
    #[serde(default)]
    pub link: LinkConfig,
    /// The file it was read from (names it in errors; anchors relative paths).
    #[serde(skip)]
    pub source: Option<PathBuf>,
    /// The sample model's text, when it comes from elsewhere than `sample.model`
    /// (a run file, which keeps it verbatim).
    #[serde(skip)]
    pub sample_text: Option<String>,
}

/// A sim config that could not be used, with where and why.
pub type SimConfigError = gonio_core::tomlfile::FileError;

/// The kind of file, for errors about unnamed text.
const KIND: &str = "sim config";

impl SimConfig {
    /// The embedded default (`config/sim-example.toml`).
    pub fn default_config() -> Result<SimConfig, SimConfigError> {
        Self::from_toml(DEFAULT_SIM, None)
    }

    /// Parses a config's text; `path` labels errors and anchors relative paths.
    pub fn from_toml(text: &str, path: Option<&Path>) -> Result<SimConfig, SimConfigError> {
        let mut cfg: SimConfig = gonio_core::tomlfile::parse(KIND, text, path, Self::validate)?;
        cfg.source = path.map(Path::to_path_buf);
        Ok(cfg)
    }

    /// Reads a config file.
    pub fn load(path: &Path) -> Result<SimConfig, SimConfigError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| SimConfigError::whole(KIND, Some(path), e.to_string()))?;
        Self::from_toml(&text, Some(path))
    }

    /// The controller address of each role, in the layout's order.
    pub fn role_addresses(&self) -> Result<[u8; 4], (String, String)> {
        let roles = self.kinematics.layout.roles();
        let mut out = [0u8; 4];
        for (i, r) in roles.iter().enumerate() {
            out[i] = *self.kinematics.addresses.get(*r).ok_or_else(|| {
                (
                    format!("kinematics.addresses.{r}"),
                    format!(
                        "missing: the {:?} layout needs {}",
                        self.kinematics.layout,
                        roles.join(", ")
                    ),
                )
            })?;
        }
        Ok(out)
    }

    fn validate(&self) -> Result<(), (String, String)> {
        let roles = self.kinematics.layout.roles();
        for k in self.kinematics.addresses.keys() {
            if !roles.contains(&k.as_str()) {
                return Err((
                    format!("kinematics.addresses.{k}"),
                    format!("not a role of this layout ({})", roles.join(", ")),
                ));
            }
        }
        let addrs = self.role_addresses()?;
        for (i, a) in addrs.iter().enumerate() {
            if !(1..=31).contains(a) {
                return Err((
                    format!("kinematics.addresses.{}", roles[i]),
                    "must be in 1..=31".into(),
                ));
            }
            if addrs[..i].contains(a) {
                return Err((
                    format!("kinematics.addresses.{}", roles[i]),
                    "repeats an address".into(),
                ));
            }
        }
        for (i, c) in self.controllers.iter().enumerate() {
            if !addrs.contains(&c.address) {
                return Err((
                    format!("controllers[{i}].address"),
                    format!(
                        "{} is not one of the kinematics addresses {addrs:?}",
                        c.address
                    ),
                ));
            }
            if !(c.velocity > 0.0
                && c.acceleration > 0.0
                && c.home_velocity > 0.0
                && c.counts_per_unit > 0.0)
            {
                return Err((
                    format!("controllers[{i}]"),
                    "velocities, accelerations and counts_per_unit must be positive".into(),
                ));
            }
        }
        let o = &self.optics;
        for (f, v) in [
            ("optics.source_power_w", o.source_power_w),
            ("optics.beam_diameter_m", o.beam_diameter_m),
            ("optics.detector_radius_m", o.detector_radius_m),
            ("optics.detector_distance_m", o.detector_distance_m),
            ("optics.responsivity_v_per_w", o.responsivity_v_per_w),
            ("optics.sample_length_m", o.sample_length_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err((f.into(), "must be positive".into()));
            }
        }
        if !(o.pickup_v.is_finite() && o.pickup_v >= 0.0) {
            return Err(("optics.pickup_v".into(), "must be ≥ 0".into()));
        }
        self.lockin
            .validate()
            .map_err(|e| (format!("lockin.{}", e.field), e.reason))?;
        if !(self.time_scale.is_finite() && self.time_scale >= 0.0) {
            return Err(("time_scale".into(), "must be ≥ 0".into()));
        }
        for (f, p) in [
            ("faults.drop_reply", self.faults.drop_reply),
            ("faults.corrupt_reply", self.faults.corrupt_reply),
        ] {
            if !(0.0..=1.0).contains(&p) {
                return Err((f.into(), "a probability must be in [0, 1]".into()));
            }
        }
        Ok(())
    }

    /// The controller configuration of `address` (the listed one, or the defaults).
    pub fn controller(&self, address: u8) -> ControllerConfig {
        self.controllers
            .iter()
            .find(|c| c.address == address)
            .cloned()
            .unwrap_or(ControllerConfig {
                address,
                ..ControllerConfig::default()
            })
    }

    /// The sample's model file, as text: [`sample_text`](Self::sample_text) when
    /// set, else the file `sample.model` names, else the embedded blue paint.
    pub fn sample_model_text(&self) -> Result<String, SimConfigError> {
        if let Some(t) = &self.sample_text {
            return Ok(t.clone());
        }
        match &self.sample.model {
            Some(p) => {
                let path = match self.source.as_deref().and_then(Path::parent) {
                    Some(b) if p.is_relative() => b.join(p),
                    _ => p.clone(),
                };
                std::fs::read_to_string(&path).map_err(|e| SimConfigError {
                    field: Some("sample.model".into()),
                    ..SimConfigError::whole(
                        KIND,
                        self.source.as_deref(),
                        format!("{}: {e}", path.display()),
                    )
                })
            }
            None => Ok(BLUE_PAINT.to_string()),
        }
    }

    /// Loads the sample and finds the measured channel.
    pub fn load_sample(&self) -> Result<(Box<dyn Brdf>, usize), SimConfigError> {
        let text = self.sample_model_text()?;
        let model =
            Model::from_toml(&text, self.sample.model.as_deref()).map_err(|e| SimConfigError {
                field: Some("sample.model".into()),
                ..SimConfigError::whole(KIND, self.source.as_deref(), e.to_string())
            })?;
        let channel = match &self.sample.channel {
            None => 0,
            Some(name) => model
                .channels()
                .index_of(name)
                .ok_or_else(|| SimConfigError {
                    field: Some("sample.channel".into()),
                    ..SimConfigError::whole(
                        KIND,
                        self.source.as_deref(),
                        format!("the sample has channels {}, not {name:?}", model.channels()),
                    )
                })?,
        };
        Ok((Box::new(model), channel))
    }
}
