//! The simulator's config file: the instrument's mechanics, optics, sample, lock-in
//! physics and faults. Strict TOML (unknown keys are errors); errors name the file,
//! line and field.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use gonio_brdf::{Brdf, Model};
use gonio_core::kinematics::Layout;
use serde::Deserialize;

use crate::apt::AptDeviceConfig;
use crate::controller::ControllerConfig;
use crate::faults::FaultConfig;
use crate::filterwheel::FilterWheelSim;
use crate::lockin::LockInConfig;
use crate::monochromator::MonochromatorSim;
use crate::optics::OpticsConfig;
use crate::picoammeter::PicoammeterConfig;

/// The embedded default: the blue paint of Lafortune et al. 1997 on a coplanar-arm
/// goniometer (`config/sim-example.toml`).
pub const DEFAULT_SIM: &str = include_str!("../../config/sim-example.toml");

/// The most bytes a table sample (`[sample] table`) may have: 1 GiB, a 5° × 5° full
/// 4-D RGB table with its uncertainties about twice over. The simulator holds the
/// whole table, and a run file keeps its text.
pub const MAX_TABLE_BYTES: u64 = 1 << 30;

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
    /// A measured or tabulated BRDF instead of a model: a table file of
    /// `docs/processing.md` (CSV with a grid header), interpolated quadrilinearly.
    pub table: Option<PathBuf>,
    /// A microgeometry sample instead of a model: its BRDF is tabulated by ray tracing
    /// (`gonio-micro`) when the sample is first prepared.
    pub micro: Option<MicroSampleConfig>,
}

/// What the sample is, as the config gives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleKind {
    /// A model file (or the embedded blue paint).
    Model,
    /// A table file.
    Table,
    /// A microgeometry surface, tabulated by ray tracing.
    Micro,
}

/// A microgeometry sample (`[sample.micro]`): a `gonio micro` surface file and how to
/// tabulate it. The table is traced once, by [`SimConfig::prepare_sample`] (or when
/// the simulator is built), and its text is what a run file keeps, so a resumed run
/// measures the same table without tracing again.
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
    /// An APT controller's time to answer, s (its USB line runs at 115 200 baud).
    pub apt_latency_s: f64,
}

impl Default for LinkConfig {
    fn default() -> Self {
        LinkConfig {
            motion_baud: 57_600,
            detector_baud: 9_600,
            // The figures `gonio plan check` estimates a run with.
            motion_latency_s: gonio_proto::smc100::timing::REPLY_LATENCY_S,
            detector_latency_s: gonio_proto::sr830::timing::REPLY_LATENCY_S,
            apt_latency_s: gonio_proto::apt::timing::REPLY_LATENCY_S,
        }
    }
}

/// What drives a role's stage in the simulator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RoleStage {
    /// The SMC100 at this address on the motion line.
    Smc100(u8),
    /// The APT controller of `[apt.ROLE]`, on its own line.
    Apt,
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
    /// Thorlabs APT controllers, by the role their stage plays (`[apt.sample_rot]`):
    /// each on its own line, instead of an SMC100 address for that role.
    #[serde(default)]
    pub apt: BTreeMap<String, AptDeviceConfig>,
    /// A Keithley 6485 picoammeter on a photodiode as the detector, instead of the
    /// SR830: its current is the optics' power (`signal / responsivity_v_per_w`) times
    /// its own `responsivity_a_per_w`.
    #[serde(default)]
    pub picoammeter: Option<PicoammeterConfig>,
    /// A Newport Cornerstone 130 monochromator between the lamp and the sample: the
    /// light is then its passband (`crate::spectral`), selected over its own line.
    #[serde(default)]
    pub monochromator: Option<MonochromatorSim>,
    /// A Thorlabs FW102C wheel of filters between the lamp and the sample, instead.
    #[serde(default)]
    pub filter_wheel: Option<FilterWheelSim>,
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

/// The ranges the simulator config's numbers must lie in (documented in
/// `docs/simulator.md`, "Limits"); lengths use `gonio_core::goniometer::LENGTH`, serial
/// lines `gonio_driver::config::limits`, the lock-in [`LockInConfig::validate`](crate::lockin::LockInConfig::validate).
pub mod limits {
    use gonio_core::limits::Range;

    /// Wall seconds per simulated second: 0 (as fast as possible) up to 1000 (a
    /// thousand times slower than real time).
    pub const TIME_SCALE: Range = Range::closed(0.0, 1000.0, "");
    /// Stage positions, limits, home switch and stalls, in the stage's units.
    pub const POSITION: Range = Range::closed(-1e6, 1e6, "units");
    /// Stage velocities (power-up, largest, home search), units/s.
    pub const VELOCITY: Range = Range::closed(1e-6, 1e6, "units/s");
    /// Stage accelerations, units/s².
    pub const ACCELERATION: Range = Range::closed(1e-6, 1e8, "units/s²");
    /// Motor steps per unit.
    pub const COUNTS_PER_UNIT: Range = Range::closed(1e-3, 1e9, "");
    /// Longest home search, s.
    pub const HOME_TIMEOUT: Range = Range::positive(3600.0, "s");
    /// A controller's boot time and following-error delay, s.
    pub const CONTROLLER_DELAY: Range = Range::closed(0.0, 600.0, "s");
    /// Source power on the sample, W.
    pub const SOURCE_POWER: Range = Range::positive(1e3, "W");
    /// Detector responsivity times gain, V/W.
    pub const RESPONSIVITY: Range = Range::positive(1e12, "V/W");
    /// Beam divergence half-angle, degrees.
    pub const DIVERGENCE: Range = Range::closed(0.0, 45.0, "deg");
    /// Relative source drift per hour.
    pub const DRIFT_PER_HOUR: Range = Range::closed(-1.0, 1.0, "");
    /// Relative amplitude of the periodic drift.
    pub const DRIFT_AMPLITUDE: Range = Range::closed(0.0, 1.0, "");
    /// Chopper-frequency pickup, V.
    pub const PICKUP: Range = Range::closed(0.0, 100.0, "V");
    /// A lamp's colour temperature, K: from a candle's to above the sun's.
    pub const LAMP_TEMPERATURE: Range = Range::closed(1000.0, 10000.0, "K");
    /// The lamp's and optics' short-wavelength cut-on, nm.
    pub const LAMP_CUT_ON: Range = Range::closed(0.0, 5000.0, "nm");
    /// Times on the simulated clock (drift period, fault times and windows), s: up to
    /// about 30 years.
    pub const TIME: Range = Range::closed(0.0, 1e9, "s");
    /// A probability.
    pub const PROBABILITY: Range = Range::closed(0.0, 1.0, "");
    /// Extra delay of every reply, s.
    pub const REPLY_DELAY: Range = Range::closed(0.0, 3600.0, "s");
    /// A controller's or the lock-in's time to answer, s.
    pub const LATENCY: Range = Range::closed(0.0, 60.0, "s");
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

    /// Reads a config file: a regular file of at most
    /// [`MAX_CONFIG_BYTES`](gonio_core::input::MAX_CONFIG_BYTES).
    pub fn load(path: &Path) -> Result<SimConfig, SimConfigError> {
        let text = gonio_core::tomlfile::read(KIND, path)?;
        Self::from_toml(&text, Some(path))
    }

    /// What drives each role's stage, in the layout's order: an SMC100 address, or
    /// the APT controller of `[apt.ROLE]`.
    pub fn role_stages(&self) -> Result<[RoleStage; 4], (String, String)> {
        let roles = self.kinematics.layout.roles();
        let mut out = [RoleStage::Apt; 4];
        for (i, r) in roles.iter().enumerate() {
            out[i] = match (self.kinematics.addresses.get(*r), self.apt.contains_key(*r)) {
                (Some(a), false) => RoleStage::Smc100(*a),
                (None, true) => RoleStage::Apt,
                (Some(_), true) => {
                    return Err((
                        format!("apt.{r}"),
                        format!("role {r} also has an SMC100 address in kinematics.addresses"),
                    ));
                }
                (None, false) => {
                    return Err((
                        format!("kinematics.addresses.{r}"),
                        format!(
                            "missing: the {:?} layout needs {} (an SMC100 address or an [apt.{r}] table)",
                            self.kinematics.layout,
                            roles.join(", ")
                        ),
                    ));
                }
            };
        }
        Ok(out)
    }

    /// The SMC100 addresses of the roles on SMC100s, in the layout's order.
    pub fn role_addresses(&self) -> Result<Vec<u8>, (String, String)> {
        Ok(self
            .role_stages()?
            .iter()
            .filter_map(|s| match s {
                RoleStage::Smc100(a) => Some(*a),
                RoleStage::Apt => None,
            })
            .collect())
    }

    /// The APT controllers' roles, in the layout's order: the index of a role here is
    /// its line's in [`Port::Apt`](crate::Port::Apt).
    pub fn apt_roles(&self) -> Vec<&'static str> {
        self.kinematics
            .layout
            .roles()
            .iter()
            .copied()
            .filter(|r| self.apt.contains_key(*r))
            .collect()
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
        for k in self.apt.keys() {
            if !roles.contains(&k.as_str()) {
                return Err((
                    format!("apt.{k}"),
                    format!("not a role of this layout ({})", roles.join(", ")),
                ));
            }
        }
        let stages = self.role_stages()?;
        let addrs = self.role_addresses()?;
        for (i, s) in stages.iter().enumerate() {
            let RoleStage::Smc100(a) = s else { continue };
            if !(1..=31).contains(a) {
                return Err((
                    format!("kinematics.addresses.{}", roles[i]),
                    "must be in 1..=31".into(),
                ));
            }
            if stages[..i].contains(s) {
                return Err((
                    format!("kinematics.addresses.{}", roles[i]),
                    "repeats an address".into(),
                ));
            }
        }
        for (role, a) in &self.apt {
            let f = |k: &str| format!("apt.{role}.{k}");
            limits::POSITION.at(f("start_position_deg"), a.start_position_deg)?;
            limits::POSITION.at(f("home_switch_deg"), a.home_switch_deg)?;
            if let Some([lo, hi]) = a.limit_switches_deg {
                limits::POSITION.at(f("limit_switches_deg"), lo)?;
                limits::POSITION.at(f("limit_switches_deg"), hi)?;
                if lo >= hi {
                    return Err((
                        f("limit_switches_deg"),
                        "the reverse switch must be below the forward one".into(),
                    ));
                }
            }
            limits::VELOCITY.at(f("velocity"), a.velocity)?;
            limits::ACCELERATION.at(f("acceleration"), a.acceleration)?;
            limits::TIME.at(f("update_period_s"), a.update_period_s)?;
            limits::TIME.at(f("keepalive_timeout_s"), a.keepalive_timeout_s)?;
            if a.update_period_s < 1e-3 {
                return Err((f("update_period_s"), "must be at least 0.001 s".into()));
            }
            if !matches!(a.stepper_status_bytes, 14 | 28) {
                return Err((
                    f("stepper_status_bytes"),
                    format!(
                        "{} is neither 14 (a K10CR1) nor 28 (the manual)",
                        a.stepper_status_bytes
                    ),
                ));
            }
            if a.status_without_ack > 1_000_000 {
                return Err((
                    f("status_without_ack"),
                    "must be at most 1000000 (0: never stops)".into(),
                ));
            }
        }
        if self.monochromator.is_some() && self.filter_wheel.is_some() {
            return Err((
                "filter_wheel".into(),
                "the simulator has one band selector: [monochromator] or [filter_wheel]".into(),
            ));
        }
        if let Some(m) = &self.monochromator {
            m.validate().map_err(|e| e.under("monochromator"))?;
        }
        if let Some(w) = &self.filter_wheel {
            w.validate().map_err(|e| e.under("filter_wheel"))?;
        }
        if let Some(p) = &self.picoammeter {
            p.validate().map_err(|e| e.under("picoammeter"))?;
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
            let f = |k: &str| format!("controllers[{i}].{k}");
            for (k, v) in [
                ("velocity", c.velocity),
                ("max_velocity", c.max_velocity),
                ("home_velocity", c.home_velocity),
            ] {
                limits::VELOCITY.at(f(k), v)?;
            }
            for (k, v) in [
                ("acceleration", c.acceleration),
                ("max_acceleration", c.max_acceleration),
            ] {
                limits::ACCELERATION.at(f(k), v)?;
            }
            for (k, v) in [
                ("home_position", c.home_position),
                ("home_switch", c.home_switch),
                ("negative_limit", c.negative_limit),
                ("positive_limit", c.positive_limit),
                ("start_position", c.start_position),
            ] {
                limits::POSITION.at(f(k), v)?;
            }
            if c.positive_limit <= c.negative_limit {
                return Err((
                    f("positive_limit"),
                    "must be greater than `negative_limit`".into(),
                ));
            }
            limits::COUNTS_PER_UNIT.at(f("counts_per_unit"), c.counts_per_unit)?;
            limits::HOME_TIMEOUT.at(f("home_timeout_s"), c.home_timeout_s)?;
            limits::CONTROLLER_DELAY.at(f("boot_time_s"), c.boot_time_s)?;
            limits::CONTROLLER_DELAY.at(f("following_error_s"), c.following_error_s)?;
            limits::CONTROLLER_DELAY.at(f("save_time_s"), c.save_time_s)?;
        }
        let o = &self.optics;
        limits::SOURCE_POWER.at("optics.source_power_w", o.source_power_w)?;
        for (f, v) in [
            ("optics.beam_diameter_m", o.beam_diameter_m),
            ("optics.detector_radius_m", o.detector_radius_m),
            ("optics.detector_distance_m", o.detector_distance_m),
            ("optics.sample_length_m", o.sample_length_m),
        ] {
            gonio_core::goniometer::LENGTH.at(f, v)?;
        }
        limits::RESPONSIVITY.at("optics.responsivity_v_per_w", o.responsivity_v_per_w)?;
        limits::DIVERGENCE.at("optics.beam_divergence_deg", o.beam_divergence_deg)?;
        gonio_core::goniometer::ARM_SEPARATION
            .at("optics.min_arm_separation_deg", o.min_arm_separation_deg)?;
        if o.min_arm_separation_deg >= 180.0 {
            return Err((
                "optics.min_arm_separation_deg".into(),
                "must be less than 180 deg".into(),
            ));
        }
        limits::DRIFT_PER_HOUR.at("optics.drift_per_hour", o.drift_per_hour)?;
        limits::DRIFT_AMPLITUDE.at("optics.drift_amplitude", o.drift_amplitude)?;
        limits::TIME.at("optics.drift_period_s", o.drift_period_s)?;
        limits::PICKUP.at("optics.pickup_v", o.pickup_v)?;
        limits::LAMP_TEMPERATURE.at(
            "optics.lamp_colour_temperature_k",
            o.lamp_colour_temperature_k,
        )?;
        limits::LAMP_CUT_ON.at("optics.lamp_cut_on_nm", o.lamp_cut_on_nm)?;
        self.lockin.validate().map_err(|e| e.under("lockin"))?;
        if self.sample.table.is_some() && self.sample.model.is_some() {
            return Err((
                "sample.table".into(),
                "a sample is a model or a table, not both (remove sample.model)".into(),
            ));
        }
        if let Some(m) = &self.sample.micro {
            if self.sample.model.is_some() || self.sample.table.is_some() {
                return Err((
                    "sample.micro".into(),
                    "a sample is a model, a table or a microgeometry, not more than one \
                     (remove sample.model or sample.table)"
                        .into(),
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
            // The node cap of a grid (gonio_process::MAX_GRID_NODES).
            gonio_process::GridStep::new(dt, dp).map_err(|e| ("sample.micro.grid".into(), e))?;
            gonio_core::limits::count_at(
                "sample.micro.rays",
                m.rays as u64,
                2,
                gonio_micro::MAX_RAYS as u64,
                "rays",
            )?;
        }
        limits::TIME_SCALE.at("time_scale", self.time_scale)?;
        let fl = &self.faults;
        for (f, p) in [
            ("faults.drop_reply", fl.drop_reply),
            ("faults.corrupt_reply", fl.corrupt_reply),
        ] {
            limits::PROBABILITY.at(f, p)?;
        }
        limits::REPLY_DELAY.at("faults.reply_delay_s", fl.reply_delay_s)?;
        for (i, p) in fl.power_loss.iter().enumerate() {
            limits::TIME.at(format!("faults.power_loss[{i}].at_s"), p.at_s)?;
        }
        for (i, st) in fl.stall.iter().enumerate() {
            limits::POSITION.at(format!("faults.stall[{i}].at"), st.at)?;
        }
        let windows = fl
            .overload
            .iter()
            .enumerate()
            .map(|(i, w)| (format!("faults.overload[{i}]"), w))
            .chain(
                fl.unlock
                    .iter()
                    .enumerate()
                    .map(|(i, w)| (format!("faults.unlock[{i}]"), w)),
            )
            .chain(
                fl.outage
                    .iter()
                    .enumerate()
                    .map(|(i, o)| (format!("faults.outage[{i}].window"), &o.window)),
            );
        for (f, w) in windows {
            limits::TIME.at(format!("{f}.from_s"), w.from_s)?;
            limits::TIME.at(format!("{f}.to_s"), w.to_s)?;
            if w.to_s < w.from_s {
                return Err((format!("{f}.to_s"), "must not be before `from_s`".into()));
            }
        }
        let l = &self.link;
        for (f, b) in [
            ("link.motion_baud", l.motion_baud),
            ("link.detector_baud", l.detector_baud),
        ] {
            gonio_core::limits::count_at(
                f,
                b.into(),
                gonio_driver::config::limits::MIN_BAUD,
                gonio_driver::config::limits::MAX_BAUD,
                "baud",
            )?;
        }
        limits::LATENCY.at("link.motion_latency_s", l.motion_latency_s)?;
        limits::LATENCY.at("link.detector_latency_s", l.detector_latency_s)?;
        limits::LATENCY.at("link.apt_latency_s", l.apt_latency_s)?;
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

    /// What the sample is: a model, a table or a microgeometry.
    pub fn sample_kind(&self) -> SampleKind {
        if self.sample.micro.is_some() {
            SampleKind::Micro
        } else if self.sample.table.is_some() {
            SampleKind::Table
        } else {
            SampleKind::Model
        }
    }

    fn sample_error(&self, field: &str, message: String) -> SimConfigError {
        SimConfigError {
            field: Some(field.into()),
            ..SimConfigError::whole(KIND, self.source.as_deref(), message)
        }
    }

    /// A path from the config, resolved against the config file's directory.
    fn resolve(&self, p: &Path) -> PathBuf {
        match self.source.as_deref().and_then(Path::parent) {
            Some(b) if p.is_relative() => b.join(p),
            _ => p.to_path_buf(),
        }
    }

    /// The sample as text, as a run file keeps it: [`sample_text`](Self::sample_text)
    /// when set; else the model file `sample.model` names (the embedded blue paint
    /// without one), the table file `sample.table` names, or the table a
    /// `[sample.micro]` surface traces to (tracing it: prefer
    /// [`prepare_sample`](Self::prepare_sample), which keeps the result).
    pub fn sample_model_text(&self) -> Result<String, SimConfigError> {
        if let Some(t) = &self.sample_text {
            return Ok(t.clone());
        }
        match self.sample_kind() {
            SampleKind::Micro => Ok(self.trace_micro()?.1),
            SampleKind::Table => {
                let p = self.sample.table.as_deref().unwrap_or(Path::new(""));
                let path = self.resolve(p);
                let text = gonio_core::input::read_text(&path, MAX_TABLE_BYTES)
                    .map_err(|e| self.sample_error("sample.table", e.to_string()))?;
                // A table file of format 2 keeps its grid in a sidecar; the run file
                // keeps one text, so the grid is written into it.
                let side = gonio_process::file::sidecar_path(&path);
                if !side.exists() {
                    return Ok(text);
                }
                let err =
                    |e: &dyn std::fmt::Display| self.sample_error("sample.table", e.to_string());
                let meta_text =
                    gonio_core::input::read_text(&side, gonio_core::input::MAX_CONFIG_BYTES)
                        .map_err(|e| err(&e))?;
                let meta = gonio_process::file::Meta::from_json(&meta_text, Some(&side))
                    .map_err(|e| err(&e))?;
                match gonio_process::file::read_from(
                    text.as_bytes(),
                    text.len() as u64,
                    Some(&meta),
                    Some(&path),
                )
                .map_err(|e| err(&e))?
                {
                    gonio_process::file::Content::Table(t) => {
                        Ok(gonio_process::file::write_table_self_contained(&t))
                    }
                    gonio_process::file::Content::Samples(_) => Ok(text),
                }
            }
            SampleKind::Model => match &self.sample.model {
                Some(p) => {
                    let path = self.resolve(p);
                    gonio_core::input::read_text(&path, gonio_core::input::MAX_CONFIG_BYTES)
                        .map_err(|e| self.sample_error("sample.model", e.to_string()))
                }
                None => Ok(BLUE_PAINT.to_string()),
            },
        }
    }

    /// Traces a `[sample.micro]` surface into its table: the BRDF and its text.
    fn trace_micro(&self) -> Result<(std::sync::Arc<dyn Brdf>, String), SimConfigError> {
        let Some(m) = &self.sample.micro else {
            return Err(self.sample_error("sample.micro", "no microgeometry sample".into()));
        };
        let surface = m.surface_path(self.source.as_deref());
        let err = |e: &dyn std::fmt::Display| {
            let msg = e.to_string();
            // Surface-file errors already start with the file's name.
            if msg.starts_with(&surface.display().to_string()) {
                self.sample_error("sample.micro.surface", msg)
            } else {
                self.sample_error(
                    "sample.micro.surface",
                    format!("{}: {msg}", surface.display()),
                )
            }
        };
        let sample = gonio_micro::Sample::load(&surface).map_err(|e| err(&e))?;
        let sim = gonio_micro::Simulation::new(sample, gonio_micro::SimOptions::default())
            .map_err(|e| err(&e))?;
        let step = gonio_process::GridStep::new(m.grid[0], m.grid[1])
            .map_err(|e| self.sample_error("sample.micro.grid", e))?;
        let grid = if m.isotropic {
            step.isotropic_grid()
        } else {
            step.grid()
        };
        tracing::info!(
            surface = %surface.display(),
            rays = m.rays,
            seed = m.seed,
            "tracing the microgeometry sample"
        );
        let r = sim.to_table(&grid, m.rays, m.seed).map_err(|e| err(&e))?;
        // The run file keeps this text alone, with no sidecar: the grid goes in it.
        let text = gonio_process::file::write_table_self_contained(&r.table);
        Ok((std::sync::Arc::new(r.table), text))
    }

    /// Reads a table sample's text: a table (its grid line), or rows that form a
    /// complete uniform grid.
    fn table_of(&self, text: &str, field: &str) -> Result<gonio_process::Table, SimConfigError> {
        match gonio_process::file::read(text, None) {
            Ok(gonio_process::file::Content::Table(t)) => Ok(t),
            Ok(gonio_process::file::Content::Samples(s)) => s.to_table().ok_or_else(|| {
                self.sample_error(
                    field,
                    "the sample's text holds scattered samples, not a table".into(),
                )
            }),
            Err(e) => Err(self.sample_error(field, format!("sample table: {e}"))),
        }
    }

    /// Loads (or traces) the sample once and keeps it with its text, so that every
    /// simulator built from this config, and the run file, share it. Nothing to do
    /// when it is already prepared.
    pub fn prepare_sample(&mut self) -> Result<(), SimConfigError> {
        if self.prepared.is_some() {
            return Ok(());
        }
        let (brdf, text): (std::sync::Arc<dyn Brdf>, String) = match self.sample_kind() {
            SampleKind::Micro if self.sample_text.is_none() => self.trace_micro()?,
            SampleKind::Micro | SampleKind::Table => {
                let field = if self.sample_kind() == SampleKind::Micro {
                    "sample.micro"
                } else {
                    "sample.table"
                };
                let text = self.sample_model_text()?;
                (std::sync::Arc::new(self.table_of(&text, field)?), text)
            }
            SampleKind::Model => {
                let text = self.sample_model_text()?;
                let m = Model::from_toml(&text, self.sample.model.as_deref())
                    .map_err(|e| self.sample_error("sample.model", e.to_string()))?;
                (std::sync::Arc::new(m), text)
            }
        };
        self.set_sample(brdf, text);
        Ok(())
    }

    /// Hands over a sample prepared outside the simulator (any `Brdf`) and the text a
    /// run file keeps for it.
    pub fn set_sample(&mut self, brdf: std::sync::Arc<dyn Brdf>, text: String) {
        self.prepared = Some(PreparedSample(brdf));
        self.sample_text = Some(text);
    }

    /// Loads the sample (preparing it if needed) and finds the measured channel.
    pub fn load_sample(&self) -> Result<(Box<dyn Brdf>, usize), SimConfigError> {
        let model: Box<dyn Brdf> = match &self.prepared {
            Some(p) => Box::new(Shared(p.0.clone())),
            None => {
                let mut c = self.clone();
                c.prepare_sample()?;
                match c.prepared {
                    Some(p) => Box::new(Shared(p.0)),
                    None => {
                        return Err(self.sample_error("sample", "not prepared".into()));
                    }
                }
            }
        };
        let channel = match &self.sample.channel {
            None => 0,
            Some(name) => model.channels().index_of(name).ok_or_else(|| {
                self.sample_error(
                    "sample.channel",
                    format!("the sample has channels {}, not {name:?}", model.channels()),
                )
            })?,
        };
        Ok((model, channel))
    }
}
