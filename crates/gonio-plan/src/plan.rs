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

use gonio_core::dirfile::{self, PairDeg};
use gonio_core::limits::{Fault, Range, count_at, num};
use gonio_core::tomlfile::{self, FileError, Tagged};
use gonio_core::{Channels, DirPair, SphericalDeg};
use serde::de::{self, MapAccess, SeqAccess, Visitor};
use serde::{Deserialize, Serialize};

pub use gonio_core::goniometer::{Mechanics, MechanicsError, Rejection};

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

/// Values of one angle: a list, or an inclusive range with a step.
///
/// Written untagged (a list, a table or a number); read by hand, so that a value of
/// none of the three forms is refused with the forms listed rather than serde's
/// "data did not match any variant of untagged enum".
#[derive(Clone, Debug, PartialEq, Serialize)]
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

/// What an angle's value may be, for messages.
const VALUES_FORMS: &str = "a list of angles like [0, 30, 60], one angle like 45, or a range like { from = 0, to = 60, step = 30 }";

impl<'de> Deserialize<'de> for Values {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(ValuesVisitor(VALUES_FORMS))
    }
}

/// Reads [`Values`]; the text names the forms accepted, for messages.
struct ValuesVisitor(&'static str);

impl<'de> Visitor<'de> for ValuesVisitor {
    type Value = Values;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.0)
    }

    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Values, E> {
        Ok(Values::One(v))
    }

    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Values, E> {
        Ok(Values::One(v as f64))
    }

    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Values, E> {
        Ok(Values::One(v as f64))
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Values, A::Error> {
        let mut v = Vec::new();
        while let Some(x) = seq.next_element::<f64>()? {
            v.push(x);
        }
        Ok(Values::List(v))
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Values, A::Error> {
        let (mut from, mut to, mut step) = (None, None, None);
        while let Some(key) = map.next_key::<String>()? {
            let slot = match key.as_str() {
                "from" => &mut from,
                "to" => &mut to,
                "step" => &mut step,
                _ => {
                    return Err(de::Error::custom(format!(
                        "unknown key `{key}` in a range: a range is {}",
                        self.range_example()
                    )));
                }
            };
            *slot = Some(map.next_value::<f64>()?);
        }
        match (from, to, step) {
            (Some(from), Some(to), Some(step)) => Ok(Values::Range { from, to, step }),
            _ => {
                let missing: Vec<&str> = [("from", from), ("to", to), ("step", step)]
                    .iter()
                    .filter(|(_, v)| v.is_none())
                    .map(|(k, _)| *k)
                    .collect();
                Err(de::Error::custom(format!(
                    "a range needs from, to and step (missing {}): {}",
                    missing.join(", "),
                    self.range_example()
                )))
            }
        }
    }
}

impl ValuesVisitor {
    /// The range form of the values read, as an example.
    fn range_example(&self) -> &'static str {
        if self.0 == WAVELENGTH_FORMS {
            "{ from = 400, to = 700, step = 10 }"
        } else {
            "{ from = 0, to = 60, step = 30 }"
        }
    }
}

/// The wavelengths a plan measures at, nm: a list, one wavelength, or an inclusive
/// range with a step (see [`Wavelengths::expand`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(transparent)]
pub struct Wavelengths(pub Values);

/// What a plan's wavelengths may be, for messages.
const WAVELENGTH_FORMS: &str = "a list of wavelengths in nm like [450, 550, 650], one like 550, or a range like { from = 400, to = 700, step = 10 }";

/// Wavelengths a plan may name, nm: from 1 nm (soft X-rays) to 100 µm (far infrared),
/// well past any selector Gonio drives; outside it a number is a typo.
pub const WAVELENGTH: Range = Range::closed(1.0, 100_000.0, "nm");
/// The smallest step of a wavelength range, nm: a picometre is far below any
/// selector's bandwidth, and range values are rounded to 10⁻⁶ nm.
pub const WAVELENGTH_STEP: Range = Range::closed(0.001, 100_000.0, "nm");
/// Most wavelengths a plan may name (1 nm steps over 10 µm).
pub const MAX_WAVELENGTHS: usize = 10_000;

impl<'de> Deserialize<'de> for Wavelengths {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(ValuesVisitor(WAVELENGTH_FORMS))
            .map(Wavelengths)
    }
}

impl Wavelengths {
    /// The wavelengths, nm, or the fault (field under `wavelengths`, message).
    ///
    /// A range gives `from + k·step` for k = 0, 1, … up to `to` (included when it
    /// lies within 10⁻⁹ steps of the grid), each rounded to 10⁻⁶ nm: 400 to 700 by
    /// 10 is exactly 31 wavelengths, and 400 to 401 by 0.1 names its channels
    /// `400.1nm`, not `400.09999999999997nm`. A list is kept as written. Every
    /// wavelength lies in [`WAVELENGTH`], they strictly increase, and there are at
    /// most [`MAX_WAVELENGTHS`].
    pub fn expand(&self) -> Result<Vec<f64>, Fault> {
        const F: &str = "wavelengths";
        let v = match &self.0 {
            Values::One(x) => vec![*x],
            Values::List(v) => v.clone(),
            Values::Range { from, to, step } => {
                WAVELENGTH.at(format!("{F}.from"), *from)?;
                WAVELENGTH.at(format!("{F}.to"), *to)?;
                WAVELENGTH_STEP.at(format!("{F}.step"), *step)?;
                if from > to {
                    return Err((
                        F.into(),
                        format!("range from {from} to {to} must have from ≤ to"),
                    ));
                }
                let n = ((to - from) / step + 1e-9).floor();
                if n + 1.0 > MAX_WAVELENGTHS as f64 {
                    return Err((
                        format!("{F}.step"),
                        format!(
                            "{from} to {to} by {step} nm is more than {MAX_WAVELENGTHS} wavelengths"
                        ),
                    ));
                }
                // Below MAX_WAVELENGTHS: the cast is exact.
                (0..=n as usize)
                    .map(|k| ((from + k as f64 * step) * 1e6).round() / 1e6)
                    .collect()
            }
        };
        if v.is_empty() {
            return Err((F.into(), "name at least one wavelength".into()));
        }
        if v.len() > MAX_WAVELENGTHS {
            return Err((
                F.into(),
                format!("{} wavelengths, more than {MAX_WAVELENGTHS}", v.len()),
            ));
        }
        for (k, x) in v.iter().enumerate() {
            let field = if matches!(self.0, Values::List(_)) {
                format!("{F}[{k}]")
            } else {
                F.to_string()
            };
            WAVELENGTH.at(field.clone(), *x)?;
            if k > 0 && *x <= v[k - 1] {
                return Err((
                    field,
                    format!(
                        "{} nm does not follow {} nm: wavelengths must be strictly increasing",
                        num(*x),
                        num(v[k - 1])
                    ),
                ));
            }
        }
        Ok(v)
    }

    /// The channel names of the wavelengths, as `gonio_core::Channels` writes them
    /// (`550nm`, `412.5nm`), which read back to the same numbers.
    pub fn names(&self) -> Result<Vec<String>, Fault> {
        let v = self.expand()?;
        Channels::wavelengths(&v)
            .map(|c| c.names())
            .map_err(|e| ("wavelengths".to_string(), e.to_string()))
    }
}

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
///
/// Written with `kind` as its tag; read through [`Tagged`], so that an error in one of
/// the table's fields names that field and its line.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
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
    /// A directions file (CSV, `docs/CONVENTIONS.md`), relative to the plan file.
    List {
        /// The file.
        file: PathBuf,
    },
    /// A coarse pass, then outgoing directions chosen during the run where the
    /// reconstruction is least certain, within a budget (the `adaptive` module).
    Adaptive(Adaptive),
}

/// The kinds of [`Points`], as a plan names them.
const POINT_KINDS: &[&str] = &["grid", "isotropic", "in-plane", "list", "adaptive"];

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GridFields {
    theta_i: Values,
    phi_i: Values,
    theta_o: Values,
    phi_o: Values,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct IsotropicFields {
    #[serde(default)]
    phi_i: f64,
    theta_i: Values,
    theta_o: Values,
    delta_phi: Values,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InPlaneFields {
    #[serde(default)]
    phi_i: f64,
    theta_i: Values,
    theta_o: Values,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ListFields {
    file: PathBuf,
}

impl<'de> Deserialize<'de> for Points {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let t = Tagged::read(d, POINT_KINDS)?;
        Ok(match t.kind() {
            "grid" => {
                let f: GridFields = t.fields()?;
                Points::Grid {
                    theta_i: f.theta_i,
                    phi_i: f.phi_i,
                    theta_o: f.theta_o,
                    phi_o: f.phi_o,
                }
            }
            "isotropic" => {
                let f: IsotropicFields = t.fields()?;
                Points::Isotropic {
                    phi_i: f.phi_i,
                    theta_i: f.theta_i,
                    theta_o: f.theta_o,
                    delta_phi: f.delta_phi,
                }
            }
            "in-plane" => {
                let f: InPlaneFields = t.fields()?;
                Points::InPlane {
                    phi_i: f.phi_i,
                    theta_i: f.theta_i,
                    theta_o: f.theta_o,
                }
            }
            "list" => Points::List {
                file: t.fields::<ListFields, _>()?.file,
            },
            "adaptive" => Points::Adaptive(t.fields::<AdaptiveFields, _>()?.into_adaptive()),
            _ => return Err(t.unknown_kind()),
        })
    }
}

// The `adaptive` kind's table: read and checked here with the other kinds; its
// geometry (lattices, pool, batches) is the `adaptive` module's.

/// Most points an adaptive budget may name.
pub const MAX_BUDGET_POINTS: usize = 1_000_000;
/// An adaptive budget in hours: up to a month of instrument time.
pub const BUDGET_HOURS: Range = Range::closed(1e-3, 744.0, "h");
/// The coarse pass's share of the budget (`coarse`).
pub const COARSE_SHARE: Range = Range::closed(0.01, 1.0, "");
/// A batch's share of the budget (`batch`).
pub const BATCH_SHARE: Range = Range::closed(0.001, 1.0, "");
/// Candidate directions per incidence (`candidates`).
pub const CANDIDATES: (usize, usize) = (64, 262_144);
/// Fewest points a batch is written for, and cut to under a budget in hours (below
/// it the time counts as spent); a budget in points takes its last few points in
/// a batch of what is left.
pub const MIN_BATCH: usize = 4;
/// Two directions closer than this, degrees, are one: a candidate nearer a measured
/// point is not taken (far below any detector's aperture).
pub const MIN_SPACING_DEG: f64 = 0.1;

/// How many points, or how much time, an adaptive run may spend.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", try_from = "BudgetFields")]
pub enum Budget {
    /// Sample points (geometry points, every incidence; channels and repeats of a
    /// point count once), the coarse pass included.
    Points(usize),
    /// Instrument hours as the planner estimates them (motion, band changes,
    /// readings; calibrations and drift references included).
    Hours(f64),
}

/// What a batch looks for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Where the kernel reconstruction mispredicts the measured neighbours of a
    /// direction when each is left out (leave-one-out residuals), weighted by the area
    /// a point would cover and by cos θo.
    #[default]
    Residual,
    /// Where the measured neighbours of a direction disagree most with the kernel
    /// reconstruction there (local variation), weighted by the area a point would
    /// cover and by cos θo.
    Variation,
    /// Where the reconstructed BRDF is largest (a warp by the lobe the coarse pass
    /// found, as Dupuy & Jakob 2018 warp by the microfacet distribution), weighted
    /// the same way.
    Value,
}

impl Method {
    /// The name a plan writes.
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Residual => "residual",
            Method::Variation => "variation",
            Method::Value => "value",
        }
    }
}

/// The `[points]` table of an adaptive plan.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Adaptive {
    /// Incident azimuth, degrees.
    pub phi_i: f64,
    /// Incident polar angles, degrees.
    pub theta_i: Values,
    /// The budget.
    pub budget: Budget,
    /// Share of the budget's points measured in the coarse pass.
    pub coarse: f64,
    /// Share of the budget's points in each later batch.
    pub batch: f64,
    /// Candidate directions per incidence.
    pub candidates: usize,
    /// What a batch looks for.
    pub method: Method,
    /// Turns the lattices (and so which directions exist to choose from).
    pub seed: u64,
}

/// Defaults of the optional fields.
mod adaptive_defaults {
    /// `coarse`.
    pub const COARSE: f64 = 0.3;
    /// `batch`.
    pub const BATCH: f64 = 0.1;
    /// `candidates`: 1.1° apart on the hemisphere, about the simulated detector's
    /// aperture (0.95° in half-angle), below which a sharper choice means little;
    /// 8192 (2.2° apart) left the error of an n = 500 lobe no better at 1200 points
    /// than at 600 (BENCHMARKS.md, "Adaptive acquisition").
    pub const CANDIDATES: usize = 32768;
}

/// The adaptive fields as read, before defaults.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct AdaptiveFields {
    #[serde(default)]
    phi_i: f64,
    theta_i: Values,
    budget: Budget,
    #[serde(default)]
    coarse: Option<f64>,
    #[serde(default)]
    batch: Option<f64>,
    #[serde(default)]
    candidates: Option<usize>,
    #[serde(default)]
    method: Method,
    #[serde(default)]
    seed: u64,
}

/// `budget = { points = N }` or `{ hours = H }`, as read.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BudgetFields {
    #[serde(default)]
    points: Option<usize>,
    #[serde(default)]
    hours: Option<f64>,
}

impl TryFrom<BudgetFields> for Budget {
    type Error = String;

    fn try_from(b: BudgetFields) -> Result<Budget, String> {
        match (b.points, b.hours) {
            (Some(p), None) => Ok(Budget::Points(p)),
            (None, Some(h)) => Ok(Budget::Hours(h)),
            _ => Err(
                "`budget` takes one of `points` and `hours`: { points = 1200 } or \
                 { hours = 2.5 }"
                    .into(),
            ),
        }
    }
}

impl AdaptiveFields {
    /// The table with its defaults.
    fn into_adaptive(self) -> Adaptive {
        Adaptive {
            phi_i: self.phi_i,
            theta_i: self.theta_i,
            budget: self.budget,
            coarse: self.coarse.unwrap_or(adaptive_defaults::COARSE),
            batch: self.batch.unwrap_or(adaptive_defaults::BATCH),
            candidates: self.candidates.unwrap_or(adaptive_defaults::CANDIDATES),
            method: self.method,
            seed: self.seed,
        }
    }
}

impl Adaptive {
    /// Checks the fields other than the angles: the fault's field and message.
    fn validate(&self) -> Result<(), (String, String)> {
        match self.budget {
            Budget::Points(p) if !(1..=MAX_BUDGET_POINTS).contains(&p) => {
                return Err((
                    "points.budget.points".into(),
                    format!("{p} is not in 1..={MAX_BUDGET_POINTS}"),
                ));
            }
            Budget::Hours(h) => {
                BUDGET_HOURS.at("points.budget.hours", h)?;
            }
            Budget::Points(_) => {}
        }
        COARSE_SHARE.at("points.coarse", self.coarse)?;
        BATCH_SHARE.at("points.batch", self.batch)?;
        if !(CANDIDATES.0..=CANDIDATES.1).contains(&self.candidates) {
            return Err((
                "points.candidates".into(),
                format!(
                    "{} is not in {}..={}",
                    self.candidates, CANDIDATES.0, CANDIDATES.1
                ),
            ));
        }
        Ok(())
    }
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
    fn validate(&self) -> Result<(), Fault> {
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

/// The four angles of a pair, checked: θ in [0, 90], φ in [`PHI`], everything finite.
fn check_pair(p: &[f64; 4]) -> Result<(), String> {
    if p.iter().any(|x| !x.is_finite()) {
        return Err("angles must be finite".into());
    }
    for (name, t) in [("theta_i", p[0]), ("theta_o", p[2])] {
        if !(0.0..=90.0).contains(&t) {
            return Err(format!("{name} = {t} is outside [0, 90]"));
        }
    }
    for (name, f) in [("phi_i", p[1]), ("phi_o", p[3])] {
        PHI.check(f).map_err(|m| format!("{name} {m}"))?;
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
        if let Some(w) = &self.wavelengths {
            if self.channels.is_some() {
                return bad(
                    "wavelengths",
                    "`wavelengths` and `channels` both name the bands; give one of them".into(),
                );
            }
            w.names()?;
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
            Points::Adaptive(a) => {
                a.validate()?;
                vec![("theta_i", &a.theta_i)]
            }
        };
        let mut total = 1usize;
        for (name, v) in fields {
            let values = v.expand().map_err(|m| (format!("points.{name}"), m))?;
            let (lo, hi) = match name {
                "theta_i" => (0.0, 90.0),
                "theta_o" if matches!(self.points, Points::InPlane { .. }) => (-90.0, 90.0),
                "theta_o" => (0.0, 90.0),
                _ => (PHI.min, PHI.max),
            };
            if let Some(x) = values.iter().find(|x| !(lo..=hi).contains(*x)) {
                let num = gonio_core::limits::num;
                return bad(
                    &format!("points.{name}"),
                    format!("{} is outside [{}, {}]", num(*x), num(lo), num(hi)),
                );
            }
            total = total.saturating_mul(values.len());
        }
        if let Points::Isotropic { phi_i, .. }
        | Points::InPlane { phi_i, .. }
        | Points::Adaptive(Adaptive { phi_i, .. }) = &self.points
        {
            PHI.at("points.phi_i", *phi_i)?;
        }
        if let Points::Adaptive(a) = &self.points {
            if let Budget::Points(p) = a.budget {
                total = p;
            }
            if self.calibration.incident.is_none() && self.calibration.standard.is_none() {
                return bad(
                    "calibration",
                    "an adaptive plan chooses its points from the reduced BRDF: it needs \
                     `calibration.incident` or `calibration.standard`"
                        .into(),
                );
            }
            if self.calibration.repeat_at_end {
                return bad(
                    "calibration.repeat_at_end",
                    "an adaptive run's end is decided during the run: its calibrations are \
                     taken once, before the coarse pass"
                        .into(),
                );
            }
        }
        if total > MAX_POINTS {
            return bad(
                "points",
                format!("expands to {total} pairs, more than {MAX_POINTS}"),
            );
        }
        // A list plan's pairs are counted when its file is read (`pairs`).
        if !matches!(self.points, Points::List { .. }) {
            self.check_readings(total)?;
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
            if let Some(s) = &i.stages {
                for (k, x) in s.iter().enumerate() {
                    STAGE_POSITION.at(format!("calibration.incident.stages[{k}]"), *x)?;
                }
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
        BUDGET.at("order.budget_s", self.order.budget_s)?;
        if let Some(r) = &self.reading {
            r.validate()?;
        }
        Ok(())
    }

    /// Checks that `pairs` pairs, with the calibrations, repeats and channels, stay
    /// within [`MAX_READINGS`]; the fault names the field that multiplies them.
    fn check_readings(&self, pairs: usize) -> Result<(), (String, String)> {
        let passes = self.band_count();
        let standards = self.calibration.standard.as_ref().map_or(0, |s| s.at.len());
        // Dark and incident readings, the standard's pairs, and the pairs themselves.
        let per_pass = pairs.saturating_add(standards).saturating_add(2);
        let n = per_pass
            .saturating_mul(self.repeats as usize)
            .saturating_mul(passes);
        if n <= MAX_READINGS {
            return Ok(());
        }
        let field = if self.repeats > 1 {
            "repeats"
        } else if passes > 1 && self.wavelengths.is_some() {
            "wavelengths"
        } else if passes > 1 {
            "channels"
        } else {
            "points"
        };
        Err((
            field.into(),
            format!(
                "{pairs} pairs and {standards} standard pairs × {} repeats × {passes} channels \
                 is about {n} readings, more than the {MAX_READINGS} a plan may take",
                self.repeats
            ),
        ))
    }

    /// How many bands the plan measures in (1 without `channels` or `wavelengths`).
    fn band_count(&self) -> usize {
        match (&self.channels, &self.wavelengths) {
            (Some(c), _) => c.len().max(1),
            (None, Some(w)) => w.expand().map_or(1, |v| v.len()),
            (None, None) => 1,
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
            Points::Adaptive(a) => {
                let at = |m: String| FileError {
                    field: Some("points".into()),
                    ..FileError::whole(KIND, self.source.as_deref(), m)
                };
                match a.budget {
                    Budget::Points(p) => {
                        out = a
                            .coarse_per_incidence(p)
                            .and_then(|n| a.coarse_pairs(n))
                            .map_err(at)?;
                    }
                    Budget::Hours(_) => {
                        return Err(at(
                            "an adaptive plan with a budget in hours is expanded on an \
                             instrument (its coarse pass depends on the time a point takes)"
                                .into(),
                        ));
                    }
                }
            }
            Points::List { file } => {
                let path = self.resolve(file);
                // A regular file of bounded size: a FIFO or a device named here is
                // refused without being read.
                let text =
                    gonio_core::input::read_text(&path, dirfile::MAX_BYTES).map_err(|e| {
                        FileError {
                            field: Some("points.file".into()),
                            ..FileError::whole(KIND, self.source.as_deref(), e.to_string())
                        }
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
                self.check_readings(out.len())
                    .map_err(|(field, m)| FileError {
                        field: Some(field),
                        ..FileError::whole(KIND, self.source.as_deref(), m)
                    })?;
            }
        }
        Ok(out)
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
