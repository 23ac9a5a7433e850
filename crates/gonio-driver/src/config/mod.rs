//! The instrument config file: which ports, which axes with which limits, which
//! detector settings. Read strictly (unknown keys are errors) and validated whole
//! before any port is opened; errors name the file, line and field.

use std::path::Path;
use std::time::Duration;

use serde::Deserialize;

pub use gonio_core::goniometer::{GeometryConfig, KinematicsConfig};
use gonio_core::goniometer::{Mechanics, MechanicsError, Stage};
use gonio_core::motion::MoveExchanges;
use gonio_core::spectral_timing::WavelengthTiming;

use crate::smc100::{AxisConfig, ChainPolicy};
use crate::spectral::{FilterWheelConfig, MonochromatorConfig};
use crate::sr830::Sr830Config;
use crate::transport::{FlowControl, Framing, SerialSettings};
use gonio_proto::apt::{AptAxisConfig, StageKind};
use gonio_proto::k6485::K6485Config;

mod validate;

/// A goniometer: its motion chain and its detector.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InstrumentConfig {
    /// A name for reports and run files.
    #[serde(default)]
    pub name: Option<String>,
    /// The SMC100 chain.
    pub motion: MotionConfig,
    /// The SR830 detector.
    pub detector: DetectorConfig,
    /// How the stages map to directions (needed to acquire).
    #[serde(default)]
    pub kinematics: Option<KinematicsConfig>,
    /// The optical geometry (needed to plan and to reduce readings).
    #[serde(default)]
    pub geometry: GeometryConfig,
    /// A monochromator that selects the wavelength channels (`[monochromator]`).
    #[serde(default)]
    pub monochromator: Option<MonochromatorConfig>,
    /// A wheel of band-pass filters that selects them instead (`[filter_wheel]`).
    #[serde(default)]
    pub filter_wheel: Option<FilterWheelConfig>,
}

/// The motion axes, their controllers and the timing and retry policy they share.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionConfig {
    /// The port of the axes that name none (`/dev/ttyUSB0`, `usb:SERIAL`, a udev
    /// name, or a pseudo-terminal); may be left out when every axis names its own.
    #[serde(default)]
    pub port: String,
    /// Baud rate: the SMC100's is fixed at 57600.
    #[serde(default = "default_motion_baud")]
    pub baud: u32,
    /// Flow control: the SMC100 uses Xon/Xoff (`software`).
    #[serde(default = "default_motion_flow")]
    pub flow: FlowControl,
    /// Reply timeout per command, ms.
    #[serde(default = "default_reply_timeout_ms")]
    pub reply_timeout_ms: u64,
    /// Status polling interval while stages move, ms.
    #[serde(default = "default_poll_ms")]
    pub poll_interval_ms: u64,
    /// Re-sends of an idempotent command after a lost reply.
    #[serde(default = "default_retries")]
    pub retries: usize,
    /// Attempts to reopen a vanished port.
    #[serde(default = "default_reconnects")]
    pub reconnect_attempts: usize,
    /// Pause between reconnection attempts, ms.
    #[serde(default = "default_reconnect_delay_ms")]
    pub reconnect_delay_ms: u64,
    /// The stages.
    pub axes: Vec<AxisSpec>,
}

/// The controller family an axis is driven by.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ControllerKind {
    /// A Newport SMC100 on an RS-485 chain (addresses 1–31) behind one serial line.
    #[default]
    Smc100,
    /// A Thorlabs KDC101 K-Cube DC servo controller (APT protocol), with the stage
    /// `stage` names (default `prm1z8`), on its own USB serial line.
    Kdc101,
    /// A Thorlabs K10CR1 rotation mount (APT protocol, built-in stepper controller), on
    /// its own USB serial line.
    K10cr1,
}

impl ControllerKind {
    /// The name configs use.
    pub fn as_str(self) -> &'static str {
        match self {
            ControllerKind::Smc100 => "smc100",
            ControllerKind::Kdc101 => "kdc101",
            ControllerKind::K10cr1 => "k10cr1",
        }
    }
}

/// One axis of `[[motion.axes]]`: its name, controller, port, limits and speeds.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisSpec {
    /// The axis' name in plans and configs (`source`, `detector`, `sample_rot`).
    pub name: String,
    /// Its controller family (default `smc100`).
    #[serde(default)]
    pub kind: ControllerKind,
    /// Its port, when not `motion.port`. SMC100 axes on one port form a chain.
    #[serde(default)]
    pub port: Option<String>,
    /// SMC100 address on the chain, 1–31 (SMC100 axes only).
    #[serde(default)]
    pub address: u8,
    /// Position units (`deg` for rotation stages; the only units of the APT stages).
    #[serde(default = "default_units")]
    pub units: String,
    /// Lowest position the driver will ever command, units.
    pub min: f64,
    /// Highest position the driver will ever command, units.
    pub max: f64,
    /// Velocity applied after homing, units/s; the controller's own otherwise.
    #[serde(default)]
    pub velocity: Option<f64>,
    /// Acceleration applied after homing, units/s².
    #[serde(default)]
    pub acceleration: Option<f64>,
    /// Largest |position − target| accepted at the end of a move, units.
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// Longest a home search may take, s.
    #[serde(default = "default_home_timeout")]
    pub home_timeout_s: f64,
    /// The stage on an APT controller (`prm1z8` on a KDC101; a K10CR1 is its own).
    #[serde(default)]
    pub stage: Option<StageKind>,
    /// An APT controller's serial number: start-up refuses any other controller on the
    /// port (a swapped cable).
    #[serde(default)]
    pub serial_number: Option<u32>,
    /// Backlash distance an APT controller is set to, deg; its own when absent.
    #[serde(default)]
    pub backlash_deg: Option<f64>,
    /// An APT controller gets the server-alive message every 0.5 s for the whole
    /// session (the protocol manual requires one at least once a second on USB,
    /// p. 130). `false` only to see what a controller does without it.
    #[serde(default = "default_keepalive")]
    pub keepalive: bool,
}

fn default_keepalive() -> bool {
    true
}

fn default_units() -> String {
    "deg".into()
}
fn default_tolerance() -> f64 {
    0.01
}
fn default_home_timeout() -> f64 {
    120.0
}

impl AxisSpec {
    /// The APT stage of an APT axis (`None` for other families).
    pub fn apt_stage(&self) -> Option<StageKind> {
        match self.kind {
            ControllerKind::Smc100 => None,
            ControllerKind::Kdc101 => Some(self.stage.unwrap_or(StageKind::Prm1Z8)),
            ControllerKind::K10cr1 => Some(StageKind::K10cr1),
        }
    }

    /// The axis as an APT session takes it (for an APT axis).
    pub fn apt(&self, stage: StageKind) -> AptAxisConfig {
        AptAxisConfig {
            velocity: self.velocity,
            acceleration: self.acceleration,
            tolerance: self.tolerance,
            home_timeout_s: self.home_timeout_s,
            backlash_deg: self.backlash_deg,
            keepalive: self.keepalive,
            ..AptAxisConfig::new(&self.name, stage, self.min, self.max)
        }
    }

    /// The axis as an SMC100 chain's session takes it.
    pub fn smc100(&self) -> AxisConfig {
        AxisConfig {
            name: self.name.clone(),
            address: self.address,
            units: self.units.clone(),
            min: self.min,
            max: self.max,
            velocity: self.velocity,
            acceleration: self.acceleration,
            tolerance: self.tolerance,
            home_timeout_s: self.home_timeout_s,
        }
    }
}

/// One serial line of the motion system, and what is on it.
#[derive(Clone, Debug, PartialEq)]
pub struct MotionLine {
    /// The configured port name.
    pub port: String,
    /// The controllers on it.
    pub kind: LineKind,
}

/// What a motion line carries.
#[derive(Clone, Debug, PartialEq)]
pub enum LineKind {
    /// A chain of SMC100 controllers, in config order.
    Smc100(Vec<AxisConfig>),
    /// One APT controller, and the serial number it must have.
    Apt(AptAxisConfig, Option<u32>),
}

impl MotionLine {
    /// The names of the axes on the line.
    pub fn axis_names(&self) -> Vec<String> {
        match &self.kind {
            LineKind::Smc100(axes) => axes.iter().map(|a| a.name.clone()).collect(),
            LineKind::Apt(a, _) => vec![a.name.clone()],
        }
    }
}

fn default_motion_baud() -> u32 {
    57_600
}
fn default_motion_flow() -> FlowControl {
    FlowControl::Software
}
fn default_reply_timeout_ms() -> u64 {
    100
}
fn default_poll_ms() -> u64 {
    50
}
fn default_retries() -> usize {
    2
}
fn default_reconnects() -> usize {
    5
}
fn default_reconnect_delay_ms() -> u64 {
    500
}

/// The detector family.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DetectorKind {
    /// A Stanford Research SR830 lock-in amplifier (`[detector.lockin]`).
    #[default]
    Sr830,
    /// A Keithley 6485 picoammeter on a photodiode (`[detector.picoammeter]`).
    K6485,
}

/// The detector's serial line and its settings.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DetectorConfig {
    /// The detector family (default `sr830`).
    #[serde(default)]
    pub kind: DetectorKind,
    /// Port path, or `usb:SERIAL`.
    pub port: String,
    /// Baud rate, as set on the SR830's front panel (default 9600).
    #[serde(default = "default_detector_baud")]
    pub baud: u32,
    /// Flow control (`none`, or `hardware` for CTS/DTR).
    #[serde(default = "default_detector_flow")]
    pub flow: FlowControl,
    /// Lock-in settings (`[detector.lockin]`, for `kind = "sr830"`).
    #[serde(default)]
    pub lockin: Sr830Config,
    /// Picoammeter settings (`[detector.picoammeter]`, for `kind = "k6485"`).
    #[serde(default)]
    pub picoammeter: Option<K6485Config>,
}

impl DetectorConfig {
    /// The picoammeter settings in force: the section's, else the defaults.
    pub fn picoammeter(&self) -> K6485Config {
        self.picoammeter.clone().unwrap_or_default()
    }
}

fn default_detector_baud() -> u32 {
    9_600
}
fn default_detector_flow() -> FlowControl {
    FlowControl::None
}

impl MotionConfig {
    /// The port an axis is on: its own, else `motion.port`.
    pub fn port_of<'a>(&'a self, axis: &'a AxisSpec) -> &'a str {
        axis.port.as_deref().unwrap_or(&self.port)
    }

    /// The serial lines and what each carries, in the order their first axis appears.
    pub fn lines(&self) -> Vec<MotionLine> {
        let mut lines: Vec<MotionLine> = Vec::new();
        for a in &self.axes {
            let port = self.port_of(a);
            match a.kind {
                ControllerKind::Smc100 => {
                    if let Some(LineKind::Smc100(axes)) = lines
                        .iter_mut()
                        .find(|l| l.port == port && matches!(l.kind, LineKind::Smc100(_)))
                        .map(|l| &mut l.kind)
                    {
                        axes.push(a.smc100());
                    } else {
                        lines.push(MotionLine {
                            port: port.to_string(),
                            kind: LineKind::Smc100(vec![a.smc100()]),
                        });
                    }
                }
                ControllerKind::Kdc101 | ControllerKind::K10cr1 => {
                    let stage = a.apt_stage().unwrap_or(StageKind::Prm1Z8);
                    lines.push(MotionLine {
                        port: port.to_string(),
                        kind: LineKind::Apt(a.apt(stage), a.serial_number),
                    });
                }
            }
        }
        lines
    }

    /// Every port the axes use, each once.
    pub fn ports(&self) -> Vec<&str> {
        let mut out: Vec<&str> = Vec::new();
        for a in &self.axes {
            let p = self.port_of(a);
            if !out.contains(&p) {
                out.push(p);
            }
        }
        out
    }

    /// The SMC100 axes, as one chain's session takes them (the config of an
    /// instrument whose axes are all SMC100s on one line).
    pub fn smc100_axes(&self) -> Vec<AxisConfig> {
        self.axes
            .iter()
            .filter(|a| a.kind == ControllerKind::Smc100)
            .map(AxisSpec::smc100)
            .collect()
    }

    /// The serial settings of a line: the family's framing, `motion.baud` and
    /// `motion.flow` for SMC100 chains.
    pub fn line_serial(&self, line: &MotionLine) -> SerialSettings {
        match line.kind {
            LineKind::Smc100(_) => SerialSettings {
                path: line.port.clone(),
                ..self.serial()
            },
            LineKind::Apt(..) => SerialSettings {
                path: line.port.clone(),
                baud: crate::apt::BAUD,
                flow: FlowControl::Hardware,
                framing: Framing::Apt,
            },
        }
    }

    /// The chain's timing and retry policy.
    pub fn policy(&self) -> ChainPolicy {
        ChainPolicy {
            reply_timeout: Duration::from_millis(self.reply_timeout_ms),
            poll_interval: Duration::from_millis(self.poll_interval_ms),
            retries: self.retries,
            reconnect_attempts: self.reconnect_attempts,
            reconnect_delay: Duration::from_millis(self.reconnect_delay_ms),
            ..ChainPolicy::default()
        }
    }

    /// How to open the port.
    pub fn serial(&self) -> SerialSettings {
        SerialSettings {
            path: self.port.clone(),
            baud: self.baud,
            flow: self.flow,
            framing: Framing::Lines {
                terminator: b'\n',
                max_line: gonio_proto::smc100::MAX_LINE,
            },
        }
    }
}

impl DetectorConfig {
    /// How to open the port.
    pub fn serial(&self) -> SerialSettings {
        SerialSettings {
            path: self.port.clone(),
            baud: self.baud,
            flow: self.flow,
            framing: match self.kind {
                DetectorKind::Sr830 => Framing::Sr830 {
                    max_line: gonio_proto::sr830::MAX_LINE,
                },
                DetectorKind::K6485 => Framing::Lines {
                    terminator: gonio_proto::k6485::REPLY_TERMINATOR,
                    max_line: gonio_proto::k6485::MAX_LINE,
                },
            },
        }
    }
}

/// True for a port that names the in-process simulator (`"sim"`): every line of an
/// instrument may be `"sim"`, each standing for its own simulated line.
pub fn is_sim_port(port: &str) -> bool {
    port == "sim"
}

/// The ranges the instrument config's numbers must lie in (documented in
/// `docs/hardware.md`, "Limits"). The lock-in's own are checked by
/// [`Sr830Config::validate`], the geometry's by [`GeometryConfig::validate`].
pub mod limits {
    use gonio_core::limits::Range;

    /// Slowest serial line accepted, baud.
    pub const MIN_BAUD: u64 = 50;
    /// Fastest serial line accepted, baud (USB adapters reach a few Mbaud).
    pub const MAX_BAUD: u64 = 4_000_000;
    /// Longest reply timeout, polling interval or reconnection delay, ms: a minute.
    pub const MAX_WAIT_MS: u64 = 60_000;
    /// Most re-sends of a command after a lost reply.
    pub const MAX_RETRIES: u64 = 10;
    /// Most attempts to reopen a vanished port.
    pub const MAX_RECONNECTS: u64 = 100;
    /// Stage limits `min`, `max`, in the stage's units (degrees for rotation stages).
    pub const POSITION: Range = Range::closed(-1e6, 1e6, "units");
    /// Stage velocity, units/s.
    pub const VELOCITY: Range = Range::closed(1e-6, 1e6, "units/s");
    /// Stage acceleration, units/s².
    pub const ACCELERATION: Range = Range::closed(1e-6, 1e8, "units/s²");
    /// End-of-move tolerance, units.
    pub const TOLERANCE: Range = Range::positive(1e3, "units");
    /// Longest home search, s: an hour.
    pub const HOME_TIMEOUT: Range = Range::positive(3600.0, "s");
}

/// An instrument config that could not be used, with where and why.
pub type ConfigFileError = gonio_core::tomlfile::FileError;

/// The kind of file, for errors about unnamed text.
const KIND: &str = "instrument config";

impl InstrumentConfig {
    /// The stages as planning sees them: names, limits, speeds.
    pub fn stages(&self) -> Vec<Stage> {
        self.motion
            .axes
            .iter()
            .map(|a| Stage {
                name: a.name.clone(),
                min: a.min,
                max: a.max,
                velocity: a.velocity,
                acceleration: a.acceleration,
            })
            .collect()
    }

    /// The instrument as planning sees it (layout, role axes, limits, speeds, the
    /// serial exchanges of a move, geometry); fails without a `[kinematics]` section.
    pub fn mechanics(&self) -> Result<Mechanics, MechanicsError> {
        let mech = Mechanics::new(self.kinematics.as_ref(), &self.stages(), &self.geometry)?;
        let exchanges = self.move_exchanges(&mech.axes);
        let mech = mech.with_exchanges(exchanges);
        Ok(match self.wavelength_timing() {
            Some(t) => mech.with_wavelength(t),
            None => mech,
        })
    }

    /// The line (an index into [`MotionConfig::lines`]) the axis `name` is on.
    fn line_of(&self, lines: &[MotionLine], name: &str) -> Option<usize> {
        lines
            .iter()
            .position(|l| l.axis_names().iter().any(|n| n == name))
    }

    /// The serial exchanges of a move of the axes `names` (in the order a move
    /// commands them), each as its family's session makes them at its line's baud
    /// rate and the chain's polling interval.
    pub fn move_exchanges(&self, names: &[String]) -> MoveExchanges {
        let lines = self.motion.lines();
        let poll = self.motion.policy().poll_interval;
        let axes = names
            .iter()
            .filter_map(|name| {
                let line = self.line_of(&lines, name)?;
                Some(match &lines[line].kind {
                    LineKind::Smc100(axes) => {
                        let a = axes.iter().find(|a| &a.name == name)?;
                        gonio_proto::smc100::timing::move_exchanges(a, line, self.motion.baud, poll)
                    }
                    LineKind::Apt(a, _) => {
                        gonio_proto::apt::timing::move_exchanges(a.stage, line, poll)
                    }
                })
            })
            .collect();
        MoveExchanges { axes }
    }

    /// The session's start-up before its first step, s (the engine's: every
    /// controller identified, the detector set up, the band selector taken over, and
    /// every axis homed), with each SMC100 axis' home search taking `search_s(axis)`
    /// (0 where the stage is not known to stand away from its switch). An APT line's
    /// identification and homing are not counted.
    pub fn startup_seconds(&self, search_s: &dyn Fn(&AxisConfig) -> f64) -> f64 {
        let poll = self.motion.policy().poll_interval;
        let baud = self.motion.baud;
        let mut t = 0.0;
        for (line, l) in self.motion.lines().iter().enumerate() {
            if let LineKind::Smc100(axes) = &l.kind {
                t += gonio_proto::smc100::timing::identify_s(axes, baud);
                let home = MoveExchanges {
                    axes: axes
                        .iter()
                        .map(|a| gonio_proto::smc100::timing::home_exchanges(a, line, baud, poll))
                        .collect(),
                };
                let searches: Vec<f64> = axes.iter().map(search_s).collect();
                t += home.move_s(&searches);
            }
        }
        if self.detector.kind == DetectorKind::Sr830 {
            t += self.lockin().setup_s();
        }
        if let Some(m) = &self.monochromator {
            t += m.cs130.init_s(m.baud);
        }
        t
    }

    /// The lock-in's settings with the detector line's baud rate, as its session
    /// takes them.
    pub fn lockin(&self) -> Sr830Config {
        self.detector.lockin.clone().with_baud(self.detector.baud)
    }

    /// Checks that the band selector can serve every one of `wavelengths_nm` (a
    /// grating range and an order filter on a monochromator, a band-pass filter on a
    /// wheel): what a plan must pass before its run file is created. Without a band
    /// selector every wavelength passes (an operator changes the bands).
    pub fn check_bands(&self, wavelengths_nm: &[f64]) -> Result<(), String> {
        for &nm in wavelengths_nm {
            if let Some(m) = &self.monochromator {
                let c = &m.cs130;
                c.grating_for(nm)
                    .map_err(|e| format!("monochromator: {e}"))?;
                if c.auto_order_filter {
                    c.order_filter_for(nm)
                        .map_err(|e| format!("monochromator: {e}"))?;
                }
            }
            if let Some(w) = &self.filter_wheel
                && w.fw102c.position_for_band(nm).is_none()
            {
                return Err(format!(
                    "filter_wheel: no band-pass filter is centred within {} nm of {nm} nm",
                    w.fw102c.band_tolerance_nm
                ));
            }
        }
        Ok(())
    }

    /// True when a monochromator or filter wheel selects the wavelengths.
    pub fn has_band_selector(&self) -> bool {
        self.monochromator.is_some() || self.filter_wheel.is_some()
    }

    /// How long the band selector takes to change wavelength, for the planner: a
    /// monochromator's slew, settling, and its order-filter and grating changes at
    /// the wavelengths where its config changes them, with its session's statements
    /// around each change; a filter wheel's change time.
    /// `None` without either (an operator changes bands).
    pub fn wavelength_timing(&self) -> Option<WavelengthTiming> {
        if let Some(w) = &self.filter_wheel {
            return Some(WavelengthTiming::per_change(w.change_s));
        }
        let m = self.monochromator.as_ref()?;
        let c = &m.cs130;
        let t = &m.timing;
        let lo = c
            .gratings
            .iter()
            .map(|g| g.min_nm)
            .fold(f64::INFINITY, f64::min);
        let hi = c.gratings.iter().map(|g| g.max_nm).fold(0.0, f64::max);
        let (mut filters, mut gratings) = (Vec::new(), Vec::new());
        if lo.is_finite() && hi > lo {
            // Half-nanometre steps find each crossover to within 0.5 nm: a planning
            // estimate needs no better.
            let steps = ((hi - lo) / 0.5) as usize;
            let (mut filter, mut grating) = (None, None);
            for k in 0..=steps {
                let nm = lo + k as f64 * 0.5;
                let f = c.order_filter_for(nm).ok();
                if k > 0 && f != filter && f.is_some() {
                    filters.push(nm);
                }
                filter = f.or(filter);
                let g = c.grating_for(nm).ok().map(|g| g.index);
                if k > 0 && g != grating && g.is_some() {
                    gratings.push(nm);
                }
                grating = g.or(grating);
            }
        }
        let mut timing = WavelengthTiming::monochromator(t.slew_nm_per_s, t.settle_s)
            .with_backlash(c.approach_nm)
            .with_exchanges(c.change_exchanges(m.baud));
        if c.auto_order_filter && !filters.is_empty() {
            timing = timing.with_order_filter(t.filter_change_s, &filters);
        }
        if !gratings.is_empty() {
            timing = timing.with_grating(t.grating_change_s, &gratings);
        }
        Some(timing)
    }

    /// Estimated seconds per reading on the detector, as its session reads after a
    /// move: the lock-in's settling, snapshots and their exchanges
    /// ([`Sr830Config::read_s`]), or the picoammeter's integrations and `READ?`s;
    /// range changes aside (they depend on the signal).
    pub fn reading_seconds(&self) -> f64 {
        if self.detector.kind == DetectorKind::K6485 {
            // One `READ?` (about 8 characters) and its reply (about 40) a sample.
            let p = self.detector.picoammeter();
            let wire = gonio_proto::timing::wire_s(p.samples * 48, self.detector.baud);
            return p.reading_seconds() + wire;
        }
        self.lockin().read_s()
    }

    /// Parses and validates a config's text; `path` only labels errors.
    pub fn from_toml(text: &str, path: Option<&Path>) -> Result<Self, ConfigFileError> {
        gonio_core::tomlfile::parse(KIND, text, path, Self::validate)
    }

    /// Reads and validates a config file.
    pub fn load(path: &Path) -> Result<Self, ConfigFileError> {
        Ok(Self::load_with_text(path)?.0)
    }

    /// Reads and validates a config file; also returns its text, which run files keep
    /// verbatim.
    pub fn load_with_text(path: &Path) -> Result<(Self, String), ConfigFileError> {
        gonio_core::tomlfile::load(KIND, path, Self::validate)
    }
}
