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
//! Several bands: `channels = ["R", "G", "B"]` names them, or
//! `wavelengths = [450, 550, 650]` / `wavelengths = { from = 400, to = 700, step = 10 }`
//! gives them in nm ([`Wavelengths`]; the bands are then named `450nm`, …). With
//! several, `[spectral] inner = "auto" | "wavelength" | "geometry"` says which loop is
//! inside ([`Inner`]; the schedule decides `auto` from the estimated times).
//!
//! Point kinds: `grid` (all combinations of `theta_i`, `phi_i`, `theta_o`, `phi_o`),
//! `isotropic` (fixed `phi_i`, `theta_i` × `theta_o` × `delta_phi`, φo = φi + Δφ),
//! `adaptive` (fixed `phi_i`, `theta_i`, a `budget`; outgoing directions chosen
//! during the run: see the `adaptive` module),
//! `in-plane` (fixed `phi_i`; a signed `theta_o` > 0 lies on the mirror side,
//! φo = φi + 180°, < 0 on the source's side, φo = φi) and `list` (a directions CSV
//! file of `docs/CONVENTIONS.md`, relative to the plan).

use std::path::{Path, PathBuf};

use gonio_core::Channels;
use gonio_core::limits::Range;
use gonio_core::tomlfile::{self, FileError};
use serde::{Deserialize, Serialize};

pub use gonio_core::goniometer::{Mechanics, MechanicsError, Rejection};

mod check;
mod config;
mod pairs;
mod points;
mod validate;
mod values;

pub use check::{Accepted, Checked, Rejected, check};
pub use config::{
    CalibrationConfig, DEFAULT_DARK_READINGS, DriftConfig, IncidentConfig, Inner, OrderConfig,
    READING_MAX_S, READING_MIN_SAMPLES, READING_SIGMA_ABSOLUTE, READING_SIGMA_RELATIVE,
    ReadingConfig, SpectralConfig, StandardConfig,
};
pub use points::{
    Adaptive, BATCH_SHARE, BUDGET_HOURS, Budget, CANDIDATES, COARSE_SHARE, MAX_BUDGET_POINTS,
    MIN_BATCH, MIN_SPACING_DEG, Method, Points,
};
pub use values::{MAX_WAVELENGTHS, Values, WAVELENGTH, WAVELENGTH_STEP, Wavelengths};

/// The kind of file, for errors about unnamed text.
const KIND: &str = "plan";
/// Most direction pairs a plan may expand to.
pub const MAX_POINTS: usize = 1_000_000;
/// Most readings a plan may ask for: its pairs and calibrations, times its repeats,
/// times its channels. Two million readings are weeks of instrument time at the
/// fastest the lock-in settles, and keep the schedule (and the run file's steps)
/// within a few hundred megabytes.
pub const MAX_READINGS: usize = 2_000_000;
/// Azimuths (`phi_i`, `phi_o`, `delta_phi`, the φ of `drift.at` and
/// `calibration.standard.at`), degrees: a turn either way.
pub const PHI: Range = Range::closed(-360.0, 360.0, "deg");
/// Incident-beam stage positions (`calibration.incident.stages`), degrees.
pub const STAGE_POSITION: Range = Range::closed(-1e6, 1e6, "deg");
/// The ordering's wall-time budget (`order.budget_s`): at most an hour.
pub const BUDGET: Range = Range::closed(0.0, 3600.0, "s");
/// Two direction pairs closer than this (component-wise, unit vectors) are the same.
const SAME_PAIR: f64 = 1e-9;
pub use gonio_core::goniometer::{ASSUMED_ACCELERATION, ASSUMED_VELOCITY};

/// A measurement plan, as read from its file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Plan {
    /// A name for reports.
    #[serde(default)]
    pub name: Option<String>,
    /// Bands the bench selects in turn (filter wheel, monochromator); absent: one
    /// pass in whatever band the detector sees. Not with `wavelengths`.
    #[serde(default)]
    pub channels: Option<Vec<String>>,
    /// Wavelengths the bench selects, nm: the bands named as `gonio_core::Channels`
    /// names wavelengths (`550nm`). Not with `channels`.
    #[serde(default)]
    pub wavelengths: Option<Wavelengths>,
    /// Which loop is inside when there are several bands.
    #[serde(default)]
    pub spectral: SpectralConfig,
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
    /// Reading time: each reading averages until its target precision (absent:
    /// a fixed number of snapshots per reading).
    #[serde(default)]
    pub reading: Option<ReadingConfig>,
    /// The file it was read from (anchors relative paths).
    #[serde(skip)]
    pub source: Option<PathBuf>,
}

fn one_repeat() -> u32 {
    1
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

    /// The bands the plan measures in, in its order: the `channels`, or the
    /// `wavelengths`' channel names; `None` for one unnamed band.
    pub fn channel_names(&self) -> Result<Option<Vec<String>>, FileError> {
        match (&self.channels, &self.wavelengths) {
            (Some(c), _) => Ok(Some(c.clone())),
            (None, Some(w)) => w.names().map(Some).map_err(|(field, m)| FileError {
                field: Some(field),
                ..FileError::whole(KIND, self.source.as_deref(), m)
            }),
            (None, None) => Ok(None),
        }
    }

    /// The wavelength of each band, nm, when every band is one: the `wavelengths`,
    /// or `channels` that all name wavelengths (`["450nm", "550nm"]`).
    pub fn band_wavelengths(&self) -> Option<Vec<f64>> {
        match (&self.channels, &self.wavelengths) {
            (Some(c), _) => match Channels::from_names(c) {
                Ok(Channels::Wavelengths(w)) => Some(w.to_vec()),
                _ => None,
            },
            (None, Some(w)) => w.expand().ok(),
            (None, None) => None,
        }
    }
}
