//! Measurement plans: which direction pairs, in which channels, how many times, with
//! which calibrations. A plan is a TOML file (`config/plan-*.toml`); it is expanded
//! into direction pairs, and every pair is taken through the instrument's inverse
//! kinematics and checked against the stages' limits and the optical geometry
//! ([`check`]) before anything moves.
//!
//! ```toml
//! name = "blue paint, in-plane"
//! channels = ["550nm"]          # optional: bands the bench switches between
//! repeats = 1                   # readings per point (consecutive, no motion between)
//!
//! [points]
//! kind = "in-plane"             # grid | isotropic | in-plane | list
//! theta_i = [0, 30, 60]         # a list, or a range { from = 0, to = 60, step = 30 }
//! theta_o = { from = -80, to = 80, step = 5 }   # signed: > 0 on the mirror side
//!
//! [drift]
//! every = 50                    # a reference point re-measured every 50 points
//!
//! [calibration]
//! dark = true
//! incident = { transmittance = 1e-3 }
//! ```
//!
//! Point kinds: `grid` (all combinations of `theta_i`, `phi_i`, `theta_o`, `phi_o`),
//! `isotropic` (fixed `phi_i`, `theta_i` × `theta_o` × `delta_phi`, φo = φi + Δφ),
//! `in-plane` (fixed `phi_i`; a signed `theta_o` > 0 lies on the mirror side,
//! φo = φi + 180°, < 0 on the source's side, φo = φi) and `list` (a directions CSV
//! file of `CONVENTIONS.md`, relative to the plan).

use std::path::{Path, PathBuf};

use gonio_core::dirfile::{self, PairDeg};
use gonio_core::kinematics::{self, KinematicsError, Layout};
use gonio_core::tomlfile::{self, FileError};
use gonio_core::{DirPair, SphericalDeg};
use gonio_driver::InstrumentConfig;
use serde::{Deserialize, Serialize};

use crate::order::{AxisMotion, MotionModel};

/// The kind of file, for errors about unnamed text.
const KIND: &str = "plan";
/// Most direction pairs a plan may expand to.
pub const MAX_POINTS: usize = 1_000_000;
/// Two direction pairs closer than this (component-wise, unit vectors) are the same.
const SAME_PAIR: f64 = 1e-9;
/// Stage velocity assumed when the instrument config leaves it to the controller,
/// deg/s (the SMC100PP's factory setting for the simulator's stages).
pub const ASSUMED_VELOCITY: f64 = 20.0;
/// Stage acceleration assumed likewise, deg/s².
pub const ASSUMED_ACCELERATION: f64 = 80.0;

/// Values of one angle: a list, or an inclusive range with a step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Values {
    /// Explicit values, degrees.
    List(Vec<f64>),
    /// `from`, `from + step`, … up to `to` (included when it falls on the grid).
    Range {
        /// First value, degrees.
        from: f64,
        /// Last value, degrees.
        to: f64,
        /// Step, degrees (> 0).
        step: f64,
    },
    /// A single value, degrees.
    One(f64),
}

impl Values {
    /// The values, or why there are none.
    pub fn expand(&self) -> Result<Vec<f64>, String> {
        let v = match self {
            Values::One(x) => vec![*x],
            Values::List(v) => v.clone(),
            Values::Range { from, to, step } => {
                if !(step.is_finite() && *step > 0.0) {
                    return Err(format!("step {step} must be positive"));
                }
                if !(from.is_finite() && to.is_finite() && from <= to) {
                    return Err(format!("range from {from} to {to} must have from ≤ to"));
                }
                // A point within 1e-9 steps of `to` counts as on the grid.
                let n = ((to - from) / step + 1e-9).floor();
                if n >= MAX_POINTS as f64 {
                    return Err(format!("more than {MAX_POINTS} values"));
                }
                (0..=n as usize).map(|k| from + k as f64 * step).collect()
            }
        };
        if v.is_empty() {
            return Err("no values".into());
        }
        if let Some(x) = v.iter().find(|x| !x.is_finite()) {
            return Err(format!("{x} is not a finite angle"));
        }
        Ok(v)
    }
}

/// Which direction pairs the plan measures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Points {
    /// Every combination of the four angles.
    Grid {
        /// Incident polar angles, degrees.
        theta_i: Values,
        /// Incident azimuths, degrees.
        phi_i: Values,
        /// Outgoing polar angles, degrees.
        theta_o: Values,
        /// Outgoing azimuths, degrees.
        phi_o: Values,
    },
    /// An isotropic sample: one incident azimuth, outgoing azimuths relative to it.
    Isotropic {
        /// Incident azimuth, degrees.
        #[serde(default)]
        phi_i: f64,
        /// Incident polar angles, degrees.
        theta_i: Values,
        /// Outgoing polar angles, degrees.
        theta_o: Values,
        /// φo − φi, degrees.
        delta_phi: Values,
    },
    /// Scans in the plane of incidence.
    InPlane {
        /// Incident azimuth, degrees.
        #[serde(default)]
        phi_i: f64,
        /// Incident polar angles, degrees.
        theta_i: Values,
        /// Signed outgoing polar angles, degrees: > 0 on the mirror side.
        theta_o: Values,
    },
    /// A directions file (CSV, `CONVENTIONS.md`), relative to the plan file.
    List {
        /// The file.
        file: PathBuf,
    },
}

/// Re-measuring a reference point to follow the source's and detector's drift.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriftConfig {
    /// A reference reading after every this many points (at least 1).
    pub every: usize,
    /// The reference pair `[θi, φi, θo, φo]`, degrees; the plan's first measurable
    /// pair if absent.
    #[serde(default)]
    pub at: Option<[f64; 4]>,
}

/// The incident-beam calibration: the sample removed, the detector facing the source.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IncidentConfig {
    /// Transmittance of the neutral density filter in the beam during this reading,
    /// (0, 1] (the full beam would overload the detector).
    #[serde(default = "one")]
    pub transmittance: f64,
    /// Stage positions for the reading, in the layout's role order; for coplanar arms
    /// the default is the source at −90° and the detector at +90°.
    #[serde(default)]
    pub stages: Option<[f64; 4]>,
}

fn one() -> f64 {
    1.0
}

/// A reference standard of known BRDF measured in place of the sample.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StandardConfig {
    /// Its model file (`CONVENTIONS.md` model TOML), relative to the plan file.
    pub model: PathBuf,
    /// Direction pairs `[θi, φi, θo, φo]` at which it is measured, degrees.
    pub at: Vec<[f64; 4]>,
}

/// Calibration readings around the sample's.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CalibrationConfig {
    /// A dark reading (source blocked).
    pub dark: bool,
    /// An incident-beam reading.
    pub incident: Option<IncidentConfig>,
    /// A reference standard.
    pub standard: Option<StandardConfig>,
    /// Repeat the calibrations after the sample's last point, so that the reduction
    /// can interpolate between the two.
    pub repeat_at_end: bool,
}

/// How the points are ordered.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OrderConfig {
    /// Minimise the motion time (`false`: the plan's own order).
    pub optimise: bool,
    /// Wall-time cap on the optimisation, s.
    pub budget_s: f64,
}

impl Default for OrderConfig {
    fn default() -> Self {
        OrderConfig {
            optimise: true,
            budget_s: 5.0,
        }
    }
}

/// A measurement plan, as read from its file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Plan {
    /// A name for reports.
    #[serde(default)]
    pub name: Option<String>,
    /// Bands the bench selects in turn (filter wheel, monochromator); absent: one
    /// pass in whatever band the detector sees.
    #[serde(default)]
    pub channels: Option<Vec<String>>,
    /// Readings per point, taken one after another without moving.
    #[serde(default = "one_repeat")]
    pub repeats: u32,
    /// The direction pairs.
    pub points: Points,
    /// Drift reference.
    #[serde(default)]
    pub drift: Option<DriftConfig>,
    /// Calibrations.
    #[serde(default)]
    pub calibration: CalibrationConfig,
    /// Ordering.
    #[serde(default)]
    pub order: OrderConfig,
    /// The file it was read from (anchors relative paths).
    #[serde(skip)]
    pub source: Option<PathBuf>,
}

fn one_repeat() -> u32 {
    1
}

/// The four angles of a pair, checked: θ in [0, 90], everything finite.
fn check_pair(p: &[f64; 4]) -> Result<(), String> {
    if p.iter().any(|x| !x.is_finite()) {
        return Err("angles must be finite".into());
    }
    for (name, t) in [("theta_i", p[0]), ("theta_o", p[2])] {
        if !(0.0..=90.0).contains(&t) {
            return Err(format!("{name} = {t} is outside [0, 90]"));
        }
    }
    Ok(())
}

impl Plan {
    /// Parses and validates a plan's text; `path` labels errors and anchors the
    /// relative paths it names.
    pub fn from_toml(text: &str, path: Option<&Path>) -> Result<Plan, FileError> {
        let mut plan: Plan = tomlfile::parse(KIND, text, path, Plan::validate)?;
        plan.source = path.map(Path::to_path_buf);
        Ok(plan)
    }

    /// Reads a plan file; also returns its text (run files keep it verbatim).
    pub fn load(path: &Path) -> Result<(Plan, String), FileError> {
        let (mut plan, text): (Plan, String) = tomlfile::load(KIND, path, Plan::validate)?;
        plan.source = Some(path.to_path_buf());
        Ok((plan, text))
    }

    /// A path the plan names, relative to the plan's directory.
    pub fn resolve(&self, p: &Path) -> PathBuf {
        match self.source.as_deref().and_then(Path::parent) {
            Some(dir) if p.is_relative() => dir.join(p),
            _ => p.to_path_buf(),
        }
    }

    fn validate(&self) -> Result<(), (String, String)> {
        let bad = |f: &str, m: String| Err((f.to_string(), m));
        if self.repeats == 0 || self.repeats > 10_000 {
            return bad("repeats", format!("{} is not in 1..=10000", self.repeats));
        }
        if let Some(ch) = &self.channels {
            if ch.is_empty() {
                return bad(
                    "channels",
                    "name at least one channel, or leave it out".into(),
                );
            }
            for (i, c) in ch.iter().enumerate() {
                if c.trim().is_empty() || ch[..i].contains(c) {
                    return bad(
                        &format!("channels[{i}]"),
                        format!("{c:?} is empty or repeated"),
                    );
                }
            }
        }
        let fields: Vec<(&str, &Values)> = match &self.points {
            Points::Grid {
                theta_i,
                phi_i,
                theta_o,
                phi_o,
            } => vec![
                ("theta_i", theta_i),
                ("phi_i", phi_i),
                ("theta_o", theta_o),
                ("phi_o", phi_o),
            ],
            Points::Isotropic {
                theta_i,
                theta_o,
                delta_phi,
                ..
            } => vec![
                ("theta_i", theta_i),
                ("theta_o", theta_o),
                ("delta_phi", delta_phi),
            ],
            Points::InPlane {
                theta_i, theta_o, ..
            } => vec![("theta_i", theta_i), ("theta_o", theta_o)],
            Points::List { .. } => vec![],
        };
        let mut total = 1usize;
        for (name, v) in fields {
            let values = v.expand().map_err(|m| (format!("points.{name}"), m))?;
            let (lo, hi) = match name {
                "theta_i" => (0.0, 90.0),
                "theta_o" if matches!(self.points, Points::InPlane { .. }) => (-90.0, 90.0),
                "theta_o" => (0.0, 90.0),
                _ => (f64::NEG_INFINITY, f64::INFINITY),
            };
            if let Some(x) = values.iter().find(|x| !(lo..=hi).contains(*x)) {
                return bad(
                    &format!("points.{name}"),
                    format!("{x} is outside [{lo}, {hi}]"),
                );
            }
            total = total.saturating_mul(values.len());
        }
        if total > MAX_POINTS {
            return bad(
                "points",
                format!("expands to {total} pairs, more than {MAX_POINTS}"),
            );
        }
        if let Some(d) = &self.drift {
            if d.every == 0 {
                return bad("drift.every", "must be at least 1".into());
            }
            if let Some(at) = &d.at {
                check_pair(at).map_err(|m| ("drift.at".to_string(), m))?;
            }
        }
        let c = &self.calibration;
        if let Some(i) = &c.incident {
            if !(i.transmittance > 0.0 && i.transmittance <= 1.0) {
                return bad(
                    "calibration.incident.transmittance",
                    format!("{} is not in (0, 1]", i.transmittance),
                );
            }
            if let Some(s) = &i.stages
                && s.iter().any(|x| !x.is_finite())
            {
                return bad(
                    "calibration.incident.stages",
                    "positions must be finite".into(),
                );
            }
        }
        if let Some(s) = &c.standard {
            if s.at.is_empty() {
                return bad("calibration.standard.at", "name at least one pair".into());
            }
            for (k, p) in s.at.iter().enumerate() {
                check_pair(p).map_err(|m| (format!("calibration.standard.at[{k}]"), m))?;
            }
        }
        if !(self.order.budget_s.is_finite() && self.order.budget_s >= 0.0) {
            return bad("order.budget_s", "must be ≥ 0".into());
        }
        Ok(())
    }

    /// The plan's direction pairs in its own order (duplicates included), degrees.
    /// Reads the directions file of a `list` plan.
    pub fn pairs(&self) -> Result<Vec<PairDeg>, FileError> {
        let pair = |ti: f64, pi: f64, to: f64, po: f64| PairDeg {
            incident: SphericalDeg::new(ti, pi),
            outgoing: SphericalDeg::new(to, po),
        };
        // Validated by `validate`: expansion cannot fail here; an error is reported
        // anyway rather than unwrapped.
        let ex = |name: &str, v: &Values| {
            v.expand().map_err(|m| FileError {
                field: Some(format!("points.{name}")),
                ..FileError::whole(KIND, self.source.as_deref(), m)
            })
        };
        let mut out = Vec::new();
        match &self.points {
            Points::Grid {
                theta_i,
                phi_i,
                theta_o,
                phi_o,
            } => {
                let (a, b, c, d) = (
                    ex("theta_i", theta_i)?,
                    ex("phi_i", phi_i)?,
                    ex("theta_o", theta_o)?,
                    ex("phi_o", phi_o)?,
                );
                for &ti in &a {
                    for &pi in &b {
                        for &to in &c {
                            for &po in &d {
                                out.push(pair(ti, pi, to, po));
                            }
                        }
                    }
                }
            }
            Points::Isotropic {
                phi_i,
                theta_i,
                theta_o,
                delta_phi,
            } => {
                let (a, c, d) = (
                    ex("theta_i", theta_i)?,
                    ex("theta_o", theta_o)?,
                    ex("delta_phi", delta_phi)?,
                );
                for &ti in &a {
                    for &to in &c {
                        for &dp in &d {
                            out.push(pair(ti, *phi_i, to, phi_i + dp));
                        }
                    }
                }
            }
            Points::InPlane {
                phi_i,
                theta_i,
                theta_o,
            } => {
                let (a, c) = (ex("theta_i", theta_i)?, ex("theta_o", theta_o)?);
                for &ti in &a {
                    for &to in &c {
                        let po = if to > 0.0 { phi_i + 180.0 } else { *phi_i };
                        out.push(pair(ti, *phi_i, to.abs(), po));
                    }
                }
            }
            Points::List { file } => {
                let path = self.resolve(file);
                let text = std::fs::read_to_string(&path).map_err(|e| FileError {
                    field: Some("points.file".into()),
                    ..FileError::whole(
                        KIND,
                        self.source.as_deref(),
                        format!("{}: {e}", path.display()),
                    )
                })?;
                out = dirfile::read_pairs(&text).map_err(|e| FileError {
                    line: Some(e.line),
                    field: e.column.clone(),
                    ..FileError::whole("directions file", Some(&path), e.message.clone())
                })?;
                if out.len() > MAX_POINTS {
                    return Err(FileError::whole(
                        "directions file",
                        Some(&path),
                        format!("{} pairs, more than {MAX_POINTS}", out.len()),
                    ));
                }
            }
        }
        Ok(out)
    }
}

/// Why a pair is not measured.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "reason", rename_all = "kebab-case")]
pub enum Rejection {
    /// A direction at or below the sample's horizon.
    BelowHorizon {
        /// `wi` or `wo`.
        which: String,
    },
    /// No stage solution within every axis' limits.
    OutOfLimits {
        /// The axis of the best solution that is out.
        axis: String,
        /// Its position there, degrees.
        position: f64,
        /// The axis' lower limit.
        min: f64,
        /// The axis' upper limit.
        max: f64,
    },
    /// The detector arm would block the source.
    Shadowed {
        /// Angle between source and detector seen from the sample, degrees.
        separation_deg: f64,
        /// The instrument's minimum.
        min_deg: f64,
    },
    /// The beam's footprint is longer than the sample.
    Overfilled {
        /// Footprint length along the plane of incidence, m.
        footprint_m: f64,
        /// Sample length, m.
        sample_m: f64,
    },
    /// The same configuration as an earlier pair (e.g. φ at the pole).
    Duplicate {
        /// Index (in plan order) of the pair kept.
        of: usize,
    },
}

impl std::fmt::Display for Rejection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Rejection::BelowHorizon { which } => write!(f, "{which} at or below the horizon"),
            Rejection::OutOfLimits {
                axis,
                position,
                min,
                max,
            } => write!(
                f,
                "out of limits: axis {axis} at {position:.3}° outside [{min}, {max}]"
            ),
            Rejection::Shadowed {
                separation_deg,
                min_deg,
            } => write!(
                f,
                "shadowed: source and detector {separation_deg:.2}° apart, under {min_deg}°"
            ),
            Rejection::Overfilled {
                footprint_m,
                sample_m,
            } => write!(
                f,
                "overfilled: beam footprint {:.1} mm on a {:.1} mm sample",
                footprint_m * 1e3,
                sample_m * 1e3
            ),
            Rejection::Duplicate { of } => write!(f, "duplicate of pair {of}"),
        }
    }
}

impl Rejection {
    /// A short name of the reason, for counts.
    pub fn name(&self) -> &'static str {
        match self {
            Rejection::BelowHorizon { .. } => "below-horizon",
            Rejection::OutOfLimits { .. } => "out-of-limits",
            Rejection::Shadowed { .. } => "shadowed",
            Rejection::Overfilled { .. } => "overfilled",
            Rejection::Duplicate { .. } => "duplicate",
        }
    }
}

/// The instrument as planning sees it: layout, axis limits and speeds in role order,
/// and the optical geometry.
#[derive(Clone, Debug, PartialEq)]
pub struct Mechanics {
    /// The layout.
    pub layout: Layout,
    /// Axis name of each role.
    pub axes: [String; 4],
    /// `(min, max)` of each role's axis, degrees.
    pub limits: [(f64, f64); 4],
    /// Speeds of each role's axis.
    pub motion: MotionModel,
    /// The optical geometry.
    pub geometry: gonio_driver::config::GeometryConfig,
}

/// Why an instrument config cannot plan.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MechanicsError {
    /// No `[kinematics]` section.
    #[error("field `kinematics`: missing; acquisition needs the stages' layout")]
    NoKinematics,
    /// A role's axis is not in `motion.axes`.
    #[error("field `kinematics.axes.{role}`: no axis named {axis:?} in motion.axes")]
    UnknownAxis {
        /// The role.
        role: String,
        /// The axis name it maps to.
        axis: String,
    },
}

impl Mechanics {
    /// The mechanics of an instrument config.
    pub fn of(cfg: &InstrumentConfig) -> Result<Mechanics, MechanicsError> {
        let k = cfg
            .kinematics
            .as_ref()
            .ok_or(MechanicsError::NoKinematics)?;
        let axes = k.role_axes();
        let roles = k.layout.roles();
        let mut limits = [(0.0, 0.0); 4];
        let mut motion = Vec::with_capacity(4);
        for (i, name) in axes.iter().enumerate() {
            let a = cfg
                .motion
                .axes
                .iter()
                .find(|a| &a.name == name)
                .ok_or_else(|| MechanicsError::UnknownAxis {
                    role: roles[i].to_string(),
                    axis: name.clone(),
                })?;
            limits[i] = (a.min, a.max);
            motion.push(AxisMotion {
                velocity: a.velocity.unwrap_or(ASSUMED_VELOCITY),
                acceleration: a.acceleration.unwrap_or(ASSUMED_ACCELERATION),
            });
        }
        Ok(Mechanics {
            layout: k.layout,
            axes,
            limits,
            motion: MotionModel { axes: motion },
            geometry: cfg.geometry.clone(),
        })
    }

    /// The first axis (role index) of `stages` outside its limits.
    fn out_of_limits(&self, stages: &[f64; 4]) -> Option<usize> {
        (0..4).find(|&i| !(self.limits[i].0..=self.limits[i].1).contains(&stages[i]))
    }

    /// The stage positions that put the instrument at `pair`, within every limit, or
    /// why there are none. Among the equivalent solutions (the arms' mirror set-up,
    /// whole turns of each stage) the one nearest the canonical inverse is taken.
    pub fn stages_for(&self, pair: DirPair) -> Result<[f64; 4], Rejection> {
        let base = self.layout.inverse(pair, None).map_err(|e| match e {
            KinematicsError::BelowHorizon { which, .. }
            | KinematicsError::NonFiniteDirection { which } => Rejection::BelowHorizon {
                which: which.to_string(),
            },
            // Not reachable for finite directions above the horizon: reported as the
            // arms' plane axis being out of reach.
            KinematicsError::OutOfArmPlane { .. } | KinematicsError::NonFiniteHint { .. } => {
                Rejection::OutOfLimits {
                    axis: self.axes[3].clone(),
                    position: f64::NAN,
                    min: self.limits[3].0,
                    max: self.limits[3].1,
                }
            }
        })?;
        let mut seeds = vec![base];
        if self.layout == Layout::CoplanarArms {
            seeds.push([-base[0], -base[1], base[2] + 180.0, -base[3]]);
        }
        let mut best: Option<([f64; 4], f64)> = None;
        for s in &seeds {
            // Each stage independently: the in-limit turn closest to the seed.
            let mut c = *s;
            let mut ok = true;
            for i in 0..4 {
                let (lo, hi) = self.limits[i];
                let turns = [0.0, 360.0, -360.0, 720.0, -720.0];
                match turns
                    .iter()
                    .map(|t| s[i] + t)
                    .find(|v| (lo..=hi).contains(v))
                {
                    Some(v) => c[i] = v,
                    None => ok = false,
                }
            }
            if ok {
                let cost: f64 = (0..4).map(|i| (c[i] - base[i]).abs()).sum();
                if best.is_none_or(|(_, b)| cost < b) {
                    best = Some((c, cost));
                }
            }
        }
        match best {
            Some((c, _)) => Ok(c),
            None => {
                let i = self.out_of_limits(&base).unwrap_or(0);
                Err(Rejection::OutOfLimits {
                    axis: self.axes[i].clone(),
                    position: base[i],
                    min: self.limits[i].0,
                    max: self.limits[i].1,
                })
            }
        }
    }

    /// Checks a pair against the optical geometry, then finds its stages.
    pub fn accept(&self, pair: DirPair) -> Result<[f64; 4], Rejection> {
        for (which, d) in [("wi", pair.wi), ("wo", pair.wo)] {
            if !(d.vec().is_finite() && d.z > 0.0) {
                return Err(Rejection::BelowHorizon {
                    which: which.into(),
                });
            }
        }
        let g = &self.geometry;
        let sep = kinematics::arm_separation_deg(pair);
        if sep < g.min_arm_separation_deg {
            return Err(Rejection::Shadowed {
                separation_deg: sep,
                min_deg: g.min_arm_separation_deg,
            });
        }
        let footprint = g.beam_diameter_m / pair.wi.z;
        if footprint > g.sample_length_m {
            return Err(Rejection::Overfilled {
                footprint_m: footprint,
                sample_m: g.sample_length_m,
            });
        }
        self.stages_for(pair)
    }
}

/// A pair the plan measures, with its stage positions.
#[derive(Clone, Debug, PartialEq)]
pub struct Accepted {
    /// Index in the plan's own order.
    pub index: usize,
    /// The pair, degrees, as the plan gave it.
    pub pair: PairDeg,
    /// Stage positions, degrees, role order.
    pub stages: [f64; 4],
}

/// A pair the plan does not measure, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct Rejected {
    /// Index in the plan's own order.
    pub index: usize,
    /// The pair, degrees.
    pub pair: PairDeg,
    /// Why.
    pub reason: Rejection,
}

/// The outcome of checking a plan against an instrument.
#[derive(Clone, Debug, PartialEq)]
pub struct Checked {
    /// Pairs to measure, plan order.
    pub accepted: Vec<Accepted>,
    /// Pairs left out, plan order.
    pub rejected: Vec<Rejected>,
}

/// True when two pairs are the same configuration.
fn same(a: DirPair, b: DirPair) -> bool {
    let close = |u: gonio_core::Vec3, v: gonio_core::Vec3| {
        (u.x - v.x).abs() <= SAME_PAIR
            && (u.y - v.y).abs() <= SAME_PAIR
            && (u.z - v.z).abs() <= SAME_PAIR
    };
    close(a.wi.vec(), b.wi.vec()) && close(a.wo.vec(), b.wo.vec())
}

/// Checks every pair of `pairs` (plan order) on `mech`.
pub fn check(mech: &Mechanics, pairs: &[PairDeg]) -> Checked {
    let mut accepted: Vec<Accepted> = Vec::new();
    let mut rejected = Vec::new();
    // Duplicates are found by hashing a quantised key, not by an O(n²) scan.
    let mut seen: std::collections::HashMap<[i64; 6], usize> = std::collections::HashMap::new();
    let key = |d: DirPair| {
        let q = |x: f64| (x * 1e8).round() as i64;
        [
            q(d.wi.x),
            q(d.wi.y),
            q(d.wi.z),
            q(d.wo.x),
            q(d.wo.y),
            q(d.wo.z),
        ]
    };
    for (index, pair) in pairs.iter().enumerate() {
        let dirs = pair.to_dirs();
        if let Some(&of) = seen.get(&key(dirs))
            && same(pairs[of].to_dirs(), dirs)
        {
            rejected.push(Rejected {
                index,
                pair: *pair,
                reason: Rejection::Duplicate { of },
            });
            continue;
        }
        match mech.accept(dirs) {
            Ok(stages) => {
                seen.insert(key(dirs), index);
                accepted.push(Accepted {
                    index,
                    pair: *pair,
                    stages,
                });
            }
            Err(reason) => rejected.push(Rejected {
                index,
                pair: *pair,
                reason,
            }),
        }
    }
    Checked { accepted, rejected }
}
