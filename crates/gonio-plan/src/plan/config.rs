//! The plan's other tables: spectral order, reading time, drift, calibrations and
//! ordering.

use std::path::PathBuf;

use gonio_core::limits::{Fault, Range, count_at};
use serde::{Deserialize, Serialize};

/// Which loop of a spectral run is inside.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Inner {
    /// The faster of the two, from the estimated times.
    #[default]
    Auto,
    /// Every wavelength at each geometry point.
    Wavelength,
    /// A pass over the geometry per wavelength.
    Geometry,
}

impl Inner {
    /// The name a plan writes.
    pub fn as_str(self) -> &'static str {
        match self {
            Inner::Auto => "auto",
            Inner::Wavelength => "wavelength",
            Inner::Geometry => "geometry",
        }
    }
}

/// How a run with several bands is ordered.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SpectralConfig {
    /// Which loop is inside (default `auto`).
    pub inner: Inner,
}

/// The target relative uncertainty of a reading (`reading.sigma_relative`): from
/// 1e-7 to 10 %.
pub const READING_SIGMA_RELATIVE: Range = Range::closed(1e-7, 0.1, "");
/// The absolute floor of a reading's target (`reading.sigma_absolute`), in the
/// reading's unit (V, A): positive, at most 1.
pub const READING_SIGMA_ABSOLUTE: Range = Range::positive(1.0, "");
/// The time cap of one reading (`reading.max_s`), s: positive, at most an hour.
pub const READING_MAX_S: Range = Range::positive(3600.0, "s");
/// The fewest and most snapshots a reading may be asked to average at least
/// (`reading.min_samples`).
pub const READING_MIN_SAMPLES: (u64, u64) = (1, 10_000);

/// Reading time: each reading averages snapshots until the standard uncertainty of
/// its mean reaches a target, or its time cap. Absent from a plan, every reading
/// takes the detector's fixed number of snapshots.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReadingConfig {
    /// Target standard uncertainty of a reading's mean, relative to its magnitude
    /// (dimensionless), in [1e-7, 0.1].
    pub sigma_relative: f64,
    /// Floor of the target in the reading's unit (V for a lock-in, A for a
    /// picoammeter): the target is max(`sigma_relative`·|value|, `sigma_absolute`),
    /// so that a reading near zero does not chase a vanishing target. In (0, 1].
    #[serde(default)]
    pub sigma_absolute: Option<f64>,
    /// Cap on one reading's time, s, in (0, 3600]; a reading that reaches it before
    /// its target is kept and flagged `capped`. 30 s unless given.
    #[serde(default = "reading_max_s")]
    pub max_s: f64,
    /// Fewest snapshots a reading averages, in 1..=10000 (2 unless given: two are
    /// the fewest that show their own scatter).
    #[serde(default = "reading_min_samples")]
    pub min_samples: u32,
}

fn reading_max_s() -> f64 {
    30.0
}

fn reading_min_samples() -> u32 {
    2
}

impl ReadingConfig {
    /// Checks each field against its range: the fault's field and message.
    pub(super) fn validate(&self) -> Result<(), Fault> {
        READING_SIGMA_RELATIVE.at("reading.sigma_relative", self.sigma_relative)?;
        if let Some(a) = self.sigma_absolute {
            READING_SIGMA_ABSOLUTE.at("reading.sigma_absolute", a)?;
        }
        READING_MAX_S.at("reading.max_s", self.max_s)?;
        let (lo, hi) = READING_MIN_SAMPLES;
        count_at(
            "reading.min_samples",
            u64::from(self.min_samples),
            lo,
            hi,
            "",
        )?;
        Ok(())
    }
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
    /// Its model file (`docs/CONVENTIONS.md` model TOML), relative to the plan file.
    pub model: PathBuf,
    /// Direction pairs `[θi, φi, θo, φo]` at which it is measured, degrees.
    pub at: Vec<[f64; 4]>,
}

/// The dark readings a plan takes each time the calibrations are taken when it
/// does not say: four, so that the dark's shared error is half of one reading's
/// noise at the floor (a quarter of its variance), no longer the largest term of a
/// weak sample's budget, for a few seconds of detector time per calibration.
pub const DEFAULT_DARK_READINGS: u32 = 4;

impl CalibrationConfig {
    /// The dark readings taken each time the calibrations are (0 without `dark`),
    /// with `repeats` readings of every other step.
    pub fn dark_count(&self, repeats: u32) -> u32 {
        if self.dark {
            self.dark_readings
                .unwrap_or(DEFAULT_DARK_READINGS)
                .max(repeats)
        } else {
            0
        }
    }
}

/// Calibration readings around the sample's.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CalibrationConfig {
    /// Dark readings (source blocked).
    pub dark: bool,
    /// How many dark readings each time the calibrations are taken (at least the
    /// plan's `repeats`); [`DEFAULT_DARK_READINGS`] when not given. The dark is
    /// subtracted from every reading, so its error is shared by every sample: with
    /// one reading it is as large as a sample's own noise at the floor, and it moves
    /// the whole run (`gonio plan check` says what it contributes).
    pub dark_readings: Option<u32>,
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
