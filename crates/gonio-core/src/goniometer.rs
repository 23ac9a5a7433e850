//! The goniometer as planning and reduction see it: which stage plays which role in
//! the kinematics, each stage's limits and speeds, and the optical geometry that
//! decides which configurations can be measured (shadowing, overfilling) and turns
//! detector signals into BRDF values (the detector's solid angle).
//!
//! Nothing here talks to an instrument: the instrument config that names ports and
//! controllers lives with the drivers, and hands its stages over as [`Stage`]s.

use crate::DirPair;
use crate::kinematics::{self, KinematicsError, Layout};
use crate::limits::{Fault, Range};
use crate::motion::{AxisMotion, MotionModel, MoveExchanges};
use crate::spectral_timing::WavelengthTiming;

/// Stage velocity assumed when the instrument config leaves it to the controller,
/// deg/s (the SMC100PP's factory setting for the simulator's stages).
pub const ASSUMED_VELOCITY: f64 = 20.0;
/// Stage acceleration assumed likewise, deg/s².
pub const ASSUMED_ACCELERATION: f64 = 80.0;
/// Time of a band change on an instrument with no wavelength timing
/// ([`Mechanics::wavelength`] is `None`), s: an operator turns a filter wheel or a
/// monochromator's dial and confirms, which takes about a minute. A guess for
/// planning, not a measurement: it only has to make the planner keep band changes
/// few when a person makes them.
pub const OPERATOR_BAND_CHANGE_S: f64 = 60.0;

/// One stage as planning sees it: its name, its soft limits and its speeds.
#[derive(Clone, Debug, PartialEq)]
pub struct Stage {
    /// The axis' name in configs (`source`, `detector`, `sample_rot`).
    pub name: String,
    /// Lowest position ever commanded, degrees.
    pub min: f64,
    /// Highest position ever commanded, degrees.
    pub max: f64,
    /// Top speed, deg/s, when configured.
    pub velocity: Option<f64>,
    /// Acceleration, deg/s², when configured.
    pub acceleration: Option<f64>,
}

/// Which layout the stages form and which axis plays each role.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct KinematicsConfig {
    /// The layout (`spherical` or `coplanar-arms`, see `gonio_core::kinematics`).
    pub layout: Layout,
    /// Axis name of each role (`source = "arm1"`); a role not listed is played by the
    /// axis of the same name.
    #[serde(default)]
    pub axes: std::collections::BTreeMap<String, String>,
}

impl KinematicsConfig {
    /// The axis name of each of the layout's four roles, in role order.
    pub fn role_axes(&self) -> [String; 4] {
        self.layout
            .roles()
            .map(|r| self.axes.get(r).cloned().unwrap_or_else(|| r.to_string()))
    }
}

/// The geometry of the light path: what limits which configurations can be measured,
/// and what turns detector signals into BRDF values.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct GeometryConfig {
    /// Closest the source and detector may come, as seen from the sample, before the
    /// detector arm blocks the beam, degrees.
    pub min_arm_separation_deg: f64,
    /// Beam diameter at the sample, m.
    pub beam_diameter_m: f64,
    /// Sample length along the plane of incidence, m.
    pub sample_length_m: f64,
    /// Detector aperture radius, m.
    pub detector_radius_m: f64,
    /// Sample-to-aperture distance, m.
    pub detector_distance_m: f64,
}

/// The range of every length of the light path (beam, sample, aperture, distance):
/// from a nanometre to 100 m. Outside it, solid angles and footprints leave the range
/// where the radiometry means anything.
pub const LENGTH: Range = Range::closed(1e-9, 100.0, "m");

/// The range of the closest arm separation, degrees: `[0, 180)` in effect (180 is
/// refused separately, since no pair could then be measured).
pub const ARM_SEPARATION: Range = Range::closed(0.0, 180.0, "deg");

impl GeometryConfig {
    /// Checks every length against [`LENGTH`] and the arm separation against
    /// [`ARM_SEPARATION`]; a fault names the field under `prefix` (`geometry`).
    pub fn validate(&self, prefix: &str) -> Result<(), Fault> {
        for (f, v) in [
            ("beam_diameter_m", self.beam_diameter_m),
            ("sample_length_m", self.sample_length_m),
            ("detector_radius_m", self.detector_radius_m),
            ("detector_distance_m", self.detector_distance_m),
        ] {
            LENGTH.at(format!("{prefix}.{f}"), v)?;
        }
        let f = format!("{prefix}.min_arm_separation_deg");
        ARM_SEPARATION.at(f.clone(), self.min_arm_separation_deg)?;
        if self.min_arm_separation_deg >= 180.0 {
            return Err((f, "must be less than 180 deg".into()));
        }
        Ok(())
    }
}

impl Default for GeometryConfig {
    fn default() -> Self {
        GeometryConfig {
            min_arm_separation_deg: 8.0,
            beam_diameter_m: 0.005,
            sample_length_m: 0.05,
            detector_radius_m: 0.005,
            detector_distance_m: 0.3,
        }
    }
}

/// Why a pair is not measured.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
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
/// the serial exchanges of a move, and the optical geometry.
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
    /// The serial exchanges of a move, role order; `None`: none counted. Set with
    /// [`with_exchanges`](Mechanics::with_exchanges).
    pub exchanges: Option<MoveExchanges>,
    /// The optical geometry.
    pub geometry: GeometryConfig,
    /// How long the bench takes to change wavelength; `None`: an operator changes
    /// bands, [`OPERATOR_BAND_CHANGE_S`] a change. Set with
    /// [`with_wavelength`](Mechanics::with_wavelength).
    pub wavelength: Option<WavelengthTiming>,
}

/// Why an instrument cannot plan.
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
    /// The mechanics of an instrument whose stages are `stages`, arranged as
    /// `kinematics` says, with the optical geometry `geometry`. A stage without a
    /// velocity or acceleration of its own is assumed to move at
    /// [`ASSUMED_VELOCITY`] and [`ASSUMED_ACCELERATION`].
    pub fn new(
        kinematics: Option<&KinematicsConfig>,
        stages: &[Stage],
        geometry: &GeometryConfig,
    ) -> Result<Mechanics, MechanicsError> {
        let k = kinematics.ok_or(MechanicsError::NoKinematics)?;
        let axes = k.role_axes();
        let roles = k.layout.roles();
        let mut limits = [(0.0, 0.0); 4];
        let mut motion = Vec::with_capacity(4);
        for (i, name) in axes.iter().enumerate() {
            let a = stages.iter().find(|a| &a.name == name).ok_or_else(|| {
                MechanicsError::UnknownAxis {
                    role: roles[i].to_string(),
                    axis: name.clone(),
                }
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
            exchanges: None,
            geometry: geometry.clone(),
            wavelength: None,
        })
    }

    /// The same mechanics with a wavelength selector of timing `timing`.
    pub fn with_wavelength(mut self, timing: WavelengthTiming) -> Mechanics {
        self.wavelength = Some(timing);
        self
    }

    /// The same mechanics with the serial exchanges `exchanges` around each move.
    pub fn with_exchanges(mut self, exchanges: MoveExchanges) -> Mechanics {
        self.exchanges = Some(exchanges);
        self
    }

    /// The time of a step's motion, s, from the stages at `from` to `to` (role order;
    /// `None`: the stages stay where they are and only their positions are read): the
    /// slowest stage's trapezoid, or with [`exchanges`](Mechanics::exchanges) the
    /// whole move as the controllers' sessions make it
    /// ([`MoveExchanges::move_s`]).
    pub fn move_s(&self, from: &[f64; 4], to: Option<&[f64; 4]>) -> f64 {
        match (to, &self.exchanges) {
            (Some(to), None) => self.motion.step_time(from, to),
            (None, None) => 0.0,
            (None, Some(x)) => x.positions_s(),
            (Some(to), Some(x)) => {
                let each: Vec<f64> = self
                    .motion
                    .axes
                    .iter()
                    .zip(from.iter().zip(to))
                    .map(|(ax, (a, b))| ax.move_time(b - a))
                    .collect();
                x.move_s(&each)
            }
        }
    }

    /// Time to change from the band at `from_nm` (`None`: unknown, as at the start)
    /// to the band at `to_nm`, s: the wavelength timing's, or
    /// [`OPERATOR_BAND_CHANGE_S`] for any change without one.
    pub fn wavelength_move_s(&self, from_nm: Option<f64>, to_nm: f64) -> f64 {
        match &self.wavelength {
            Some(t) => t.move_s(from_nm, to_nm),
            None if from_nm == Some(to_nm) => 0.0,
            None => OPERATOR_BAND_CHANGE_S,
        }
    }

    /// Time of a change between two different bands that are not wavelengths
    /// (`R`, `G`, `B`, named filters), s: a per-change selector's constant, else
    /// [`OPERATOR_BAND_CHANGE_S`] (a monochromator's model needs wavelengths).
    pub fn named_band_change_s(&self) -> f64 {
        match &self.wavelength {
            Some(WavelengthTiming::PerChange { change_s }) => *change_s,
            _ => OPERATOR_BAND_CHANGE_S,
        }
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
