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
    /// A microgeometry sample instead of a model: its BRDF is tabulated by ray tracing
    /// when the simulator starts.
    pub micro: Option<MicroSampleConfig>,
}

/// A microgeometry sample (`[sample.micro]`): a `gonio micro` surface file and how to
/// tabulate it. The simulator does not trace rays itself (it depends on no processing
/// crate): whoever starts it — `gonio acquire`, the tests — tabulates the surface with
/// `gonio-micro` and hands the table over with [`SimConfig::set_sample`].
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MicroSampleConfig {
    /// The surface file (relative to the config file's directory).
    pub surface: PathBuf,
    /// The table's grid, [DTHETA, DPHI] degrees (polar band midpoints, a full turn).
    #[serde(default = "default_micro_grid")]
    pub grid: [f64; 2],
    /// Tabulate the isotropic form (θi, φo − φi, θo): right for isotropic surfaces,
    /// and far cheaper.
    #[serde(default = "default_true")]
    pub isotropic: bool,
    /// Rays per incident direction of the grid.
    #[serde(default = "default_micro_rays")]
    pub rays: usize,
    /// Seed of the ray tracer (the same seed, the same table).
    #[serde(default)]
    pub seed: u64,
}

fn default_micro_grid() -> [f64; 2] {
    [10.0, 15.0]
}

fn default_true() -> bool {
    true
}

fn default_micro_rays() -> usize {
    50_000
}

impl MicroSampleConfig {
    /// The surface file's path, resolved against the config file's directory.
    pub fn surface_path(&self, config: Option<&Path>) -> PathBuf {
        match config.and_then(Path::parent) {
            Some(b) if self.surface.is_relative() => b.join(&self.surface),
            _ => self.surface.clone(),
        }
    }
}

/// A sample BRDF prepared outside the simulator (a tabulated microgeometry), shared
/// by every simulator built from the config.
#[derive(Clone)]
pub struct PreparedSample(pub std::sync::Arc<dyn Brdf>);

impl std::fmt::Debug for PreparedSample {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "PreparedSample({})", self.0.channels())
    }
}

impl PartialEq for PreparedSample {
    fn eq(&self, o: &Self) -> bool {
        std::sync::Arc::ptr_eq(&self.0, &o.0)
    }
}

/// A [`PreparedSample`] as the `Box<dyn Brdf>` the optics hold.
struct Shared(std::sync::Arc<dyn Brdf>);

impl Brdf for Shared {
    fn channels(&self) -> &gonio_core::Channels {
        self.0.channels()
    }
    fn eval(&self, wi: gonio_core::Dir, wo: gonio_core::Dir, out: &mut [f64]) {
        self.0.eval(wi, wo, out)
    }
    fn proposals(&self, wi: gonio_core::Dir, out: &mut Vec<gonio_brdf::Weighted>) {
        self.0.proposals(wi, out)
    }
    fn mirror(&self, wi: gonio_core::Dir, out: &mut [f64]) -> bool {
        self.0.mirror(wi, out)
    }
    fn is_reciprocal(&self) -> bool {
        self.0.is_reciprocal()
    }
    fn albedo(&self, wi: gonio_core::Dir, out: &mut [f64]) {
        self.0.albedo(wi, out)
    }
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
    /// The sample's BRDF when it was prepared outside (see [`MicroSampleConfig`]);
    /// it takes precedence over the model.
    #[serde(skip)]
    pub prepared: Option<PreparedSample>,
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
        if let Some(m) = &self.sample.micro {
            if self.sample.model.is_some() {
                return Err((
                    "sample.micro".into(),
                    "a sample is a model or a microgeometry, not both (remove sample.model)".into(),
                ));
            }
            let [dt, dp] = m.grid;
            if !(dt > 0.0
                && dp > 0.0
                && (90.0 / dt).fract().abs() < 1e-9
                && (360.0 / dp).fract().abs() < 1e-9)
            {
                return Err((
                    "sample.micro.grid".into(),
                    format!("[DTHETA, DPHI] must divide 90° and 360°, got {:?}", m.grid),
                ));
            }
            if m.rays < 2 {
                return Err(("sample.micro.rays".into(), "need at least 2 rays".into()));
            }
        }
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
        if self.sample.micro.is_some() {
            return Err(SimConfigError {
                field: Some("sample.micro".into()),
                ..SimConfigError::whole(
                    KIND,
                    self.source.as_deref(),
                    "a microgeometry sample has no model text until it is tabulated \
                     (SimConfig::set_sample)"
                        .to_string(),
                )
            });
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

    /// Hands over a sample prepared outside the simulator (a tabulated microgeometry)
    /// and the text a run file keeps for it.
    pub fn set_sample(&mut self, brdf: std::sync::Arc<dyn Brdf>, text: String) {
        self.prepared = Some(PreparedSample(brdf));
        self.sample_text = Some(text);
    }

    /// Loads the sample and finds the measured channel.
    pub fn load_sample(&self) -> Result<(Box<dyn Brdf>, usize), SimConfigError> {
        let model: Box<dyn Brdf> = match &self.prepared {
            Some(p) => Box::new(Shared(p.0.clone())),
            None => {
                if self.sample.micro.is_some() && self.sample_text.is_none() {
                    return Err(SimConfigError {
                        field: Some("sample.micro".into()),
                        ..SimConfigError::whole(
                            KIND,
                            self.source.as_deref(),
                            "a microgeometry sample is tabulated by `gonio` (gonio-micro) when \
                             it starts the simulator; the standalone simulator takes model \
                             samples only"
                                .to_string(),
                        )
                    });
                }
                let text = self.sample_model_text()?;
                Box::new(
                    Model::from_toml(&text, self.sample.model.as_deref()).map_err(|e| {
                        SimConfigError {
                            field: Some("sample.model".into()),
                            ..SimConfigError::whole(KIND, self.source.as_deref(), e.to_string())
                        }
                    })?,
                )
            }
        };
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
        Ok((model, channel))
    }
}
