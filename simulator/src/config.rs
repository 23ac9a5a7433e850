//! The simulator's config file: the instrument's mechanics, optics, sample, lock-in
//! physics and faults. Strict TOML (unknown keys are errors); errors name the file,
//! line and field.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

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
use crate::twin::{FieldError, ensure};

use gonio_core::limits::Range;
use limits::*;

mod sample;
pub use sample::{MAX_TABLE_BYTES, MicroSampleConfig, PreparedSample, SampleConfig, SampleKind};

/// The embedded default: the blue paint of Lafortune et al. 1997 on a coplanar-arm
/// goniometer (`config/sim-example.toml`).
pub const DEFAULT_SIM: &str = include_str!("../../config/sim-example.toml");

/// How the stages are arranged and which controller drives which role.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KinematicsConfig {
    /// The layout.
    pub layout: Layout,
    /// Controller address of each of the layout's four roles.
    pub addresses: BTreeMap<String, u8>,
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
pub(crate) const KIND: &str = "sim config";

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

    fn validate(&self) -> Result<(), Fault> {
        let roles = self.kinematics.layout.roles();
        let keys = self
            .kinematics
            .addresses
            .keys()
            .map(|k| ("kinematics.addresses", k));
        for (table, k) in keys.chain(self.apt.keys().map(|k| ("apt", k))) {
            let (ok, all) = (roles.contains(&k.as_str()), roles.join(", "));
            ensure!(ok; format!("{table}.{k}"), "not a role of this layout ({all})");
        }
        let stages = self.role_stages()?;
        let addrs = self.role_addresses()?;
        for (i, s) in stages.iter().enumerate() {
            let RoleStage::Smc100(a) = s else { continue };
            let f = format!("kinematics.addresses.{}", roles[i]);
            ensure!((1..=31).contains(a); f, "must be in 1..=31");
            ensure!(!stages[..i].contains(s); f, "repeats an address");
        }
        for (role, a) in &self.apt {
            validate_apt(role, a)?;
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
            validate_controller(i, c, &addrs)?;
        }
        validate_optics(&self.optics)?;
        self.lockin.validate().map_err(|e| e.under("lockin"))?;
        self.validate_sample()?;
        limits::TIME_SCALE.at("time_scale", self.time_scale)?;
        validate_faults(&self.faults)?;
        let l = &self.link;
        for (f, b) in [
            ("link.motion_baud", l.motion_baud),
            ("link.detector_baud", l.detector_baud),
        ] {
            use gonio_driver::config::limits::{MAX_BAUD, MIN_BAUD};
            gonio_core::limits::count_at(f, b.into(), MIN_BAUD, MAX_BAUD, "baud")?;
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
}

/// A field of the sim config and why its value is refused.
type Fault = (String, String);

/// Checks each row's value against its range ([`FieldError::ranges`]), naming the
/// field under `table`.
fn check_all(table: &str, rows: &[(&str, f64, Range)]) -> Result<(), Fault> {
    FieldError::ranges(rows).map_err(|e| e.under(table))
}

/// `[apt.ROLE]`.
fn validate_apt(role: &str, a: &AptDeviceConfig) -> Result<(), Fault> {
    let table = format!("apt.{role}");
    let f = |k: &str| format!("{table}.{k}");
    check_all(
        &table,
        &[
            ("start_position_deg", a.start_position_deg, POSITION),
            ("home_switch_deg", a.home_switch_deg, POSITION),
        ],
    )?;
    if let Some([lo, hi]) = a.limit_switches_deg {
        POSITION.at(f("limit_switches_deg"), lo)?;
        POSITION.at(f("limit_switches_deg"), hi)?;
        let m = "the reverse switch must be below the forward one";
        ensure!(lo < hi; f("limit_switches_deg"), "{m}");
    }
    check_all(
        &table,
        &[
            ("velocity", a.velocity, VELOCITY),
            ("acceleration", a.acceleration, ACCELERATION),
            ("update_period_s", a.update_period_s, TIME),
            ("keepalive_timeout_s", a.keepalive_timeout_s, TIME),
        ],
    )?;
    ensure!(a.update_period_s >= 1e-3; f("update_period_s"), "must be at least 0.001 s");
    let n = a.stepper_status_bytes;
    let m = "is neither 14 (a K10CR1) nor 28 (the manual)";
    ensure!(matches!(n, 14 | 28); f("stepper_status_bytes"), "{n} {m}");
    let m = "must be at most 1000000 (0: never stops)";
    ensure!(a.status_without_ack <= 1_000_000; f("status_without_ack"), "{m}");
    Ok(())
}

/// `[[controllers]]`, the `i`-th; `addrs` are the kinematics' SMC100 addresses.
fn validate_controller(i: usize, c: &ControllerConfig, addrs: &[u8]) -> Result<(), Fault> {
    let table = format!("controllers[{i}]");
    let f = |k: &str| format!("{table}.{k}");
    if !addrs.contains(&c.address) {
        let m = format!(
            "{} is not one of the kinematics addresses {addrs:?}",
            c.address
        );
        return Err((f("address"), m));
    }
    check_all(
        &table,
        &[
            ("velocity", c.velocity, VELOCITY),
            ("max_velocity", c.max_velocity, VELOCITY),
            ("home_velocity", c.home_velocity, VELOCITY),
            ("acceleration", c.acceleration, ACCELERATION),
            ("max_acceleration", c.max_acceleration, ACCELERATION),
            ("home_position", c.home_position, POSITION),
            ("home_switch", c.home_switch, POSITION),
            ("negative_limit", c.negative_limit, POSITION),
            ("positive_limit", c.positive_limit, POSITION),
            ("start_position", c.start_position, POSITION),
        ],
    )?;
    let ok = c.positive_limit > c.negative_limit;
    ensure!(ok; f("positive_limit"), "must be greater than `negative_limit`");
    check_all(
        &table,
        &[
            ("counts_per_unit", c.counts_per_unit, COUNTS_PER_UNIT),
            ("home_timeout_s", c.home_timeout_s, HOME_TIMEOUT),
            ("boot_time_s", c.boot_time_s, CONTROLLER_DELAY),
            ("following_error_s", c.following_error_s, CONTROLLER_DELAY),
            ("save_time_s", c.save_time_s, CONTROLLER_DELAY),
        ],
    )
}

/// `[optics]`.
fn validate_optics(o: &OpticsConfig) -> Result<(), Fault> {
    use gonio_core::goniometer::{ARM_SEPARATION, LENGTH};
    check_all(
        "optics",
        &[
            ("source_power_w", o.source_power_w, SOURCE_POWER),
            ("beam_diameter_m", o.beam_diameter_m, LENGTH),
            ("detector_radius_m", o.detector_radius_m, LENGTH),
            ("detector_distance_m", o.detector_distance_m, LENGTH),
            ("sample_length_m", o.sample_length_m, LENGTH),
            ("responsivity_v_per_w", o.responsivity_v_per_w, RESPONSIVITY),
            ("beam_divergence_deg", o.beam_divergence_deg, DIVERGENCE),
            (
                "min_arm_separation_deg",
                o.min_arm_separation_deg,
                ARM_SEPARATION,
            ),
        ],
    )?;
    let ok = o.min_arm_separation_deg < 180.0;
    ensure!(ok; "optics.min_arm_separation_deg", "must be less than 180 deg");
    check_all(
        "optics",
        &[
            ("drift_per_hour", o.drift_per_hour, DRIFT_PER_HOUR),
            ("drift_amplitude", o.drift_amplitude, DRIFT_AMPLITUDE),
            ("drift_period_s", o.drift_period_s, TIME),
            ("pickup_v", o.pickup_v, PICKUP),
            (
                "lamp_colour_temperature_k",
                o.lamp_colour_temperature_k,
                LAMP_TEMPERATURE,
            ),
            ("lamp_cut_on_nm", o.lamp_cut_on_nm, LAMP_CUT_ON),
        ],
    )
}

/// `[faults]`.
fn validate_faults(fl: &FaultConfig) -> Result<(), Fault> {
    check_all(
        "faults",
        &[
            ("drop_reply", fl.drop_reply, PROBABILITY),
            ("corrupt_reply", fl.corrupt_reply, PROBABILITY),
            ("reply_delay_s", fl.reply_delay_s, REPLY_DELAY),
        ],
    )?;
    for (i, p) in fl.power_loss.iter().enumerate() {
        TIME.at(format!("faults.power_loss[{i}].at_s"), p.at_s)?;
    }
    for (i, st) in fl.stall.iter().enumerate() {
        POSITION.at(format!("faults.stall[{i}].at"), st.at)?;
    }
    let overload = fl.overload.iter().enumerate();
    let overload = overload.map(|(i, w)| (format!("faults.overload[{i}]"), w));
    let unlock = fl.unlock.iter().enumerate();
    let unlock = unlock.map(|(i, w)| (format!("faults.unlock[{i}]"), w));
    let outage = fl.outage.iter().enumerate();
    let outage = outage.map(|(i, o)| (format!("faults.outage[{i}].window"), &o.window));
    for (f, w) in overload.chain(unlock).chain(outage) {
        TIME.at(format!("{f}.from_s"), w.from_s)?;
        TIME.at(format!("{f}.to_s"), w.to_s)?;
        ensure!(w.to_s >= w.from_s; format!("{f}.to_s"), "must not be before `from_s`");
    }
    Ok(())
}
