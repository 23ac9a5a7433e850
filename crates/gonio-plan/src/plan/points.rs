//! The `[points]` table: which direction pairs a plan measures, by kind, and the
//! adaptive kind's budget and defaults.

use std::path::PathBuf;

use gonio_core::limits::Range;
use gonio_core::tomlfile::Tagged;
use serde::{Deserialize, Serialize};

use super::Values;

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
    pub(super) fn validate(&self) -> Result<(), (String, String)> {
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
