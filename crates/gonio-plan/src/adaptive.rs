//! Adaptive plans (`kind = "adaptive"`): a coarse pass over the outgoing hemisphere at
//! each incident direction, then batches of outgoing directions chosen during the run
//! where the reconstruction is least certain, until a budget of points or of
//! instrument time is spent.
//!
//! ```toml
//! [points]
//! kind = "adaptive"
//! phi_i = 0
//! theta_i = [30, 60]            # a list, or { from, to, step }
//! budget = { points = 1200 }    # or { hours = 2.5 } (the planner's estimate)
//! # coarse = 0.3                # share of the budget in the coarse pass
//! # batch = 0.1                 # share of the budget in each later batch
//! # candidates = 32768           # directions each batch chooses among, per incidence
//! # method = "residual"         # or "variation", "value"
//! # seed = 0                    # turns the direction lattices
//! ```
//!
//! This module is the geometry of it, pure like the rest of the crate: the
//! direction lattices, the coarse pass, the pool of measurable candidates, the
//! budget's arithmetic, and the schedule of one batch ([`schedule_batch`]). Which
//! candidates a batch takes is decided from the readings elsewhere (the scoring
//! lives with the interpolation in `gonio-process`, the glue that reads the run in
//! `gonio-reduce`).
//!
//! **Directions.** Both the coarse pass and the pool are spherical Fibonacci lattices
//! on the hemisphere: point k of n at cos θ = 1 − (k + ½)/n and φ = 2πk/Φ (Φ the
//! golden ratio) plus a turn drawn from the seed. Equal-area and without a pole
//! cluster, so that the coarse pass is the most uniform start a point count allows.
//! Each incidence's coarse pass also holds its mirror direction, where a specular
//! peak of any sharpness stands.

use gonio_core::dirfile::PairDeg;
use gonio_core::limits::Range;
use gonio_core::rng::splitmix64;
use gonio_core::{DirPair, SphericalDeg};
use serde::{Deserialize, Serialize};

use crate::plan::{Accepted, Checked, Mechanics, Plan, Values};
use crate::schedule::{self, Schedule, ScheduleError};

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
/// Fewest points a batch takes (a smaller remainder of the budget is left unspent).
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
pub(crate) mod defaults {
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
pub(crate) struct AdaptiveFields {
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
    pub(crate) fn into_adaptive(self) -> Adaptive {
        Adaptive {
            phi_i: self.phi_i,
            theta_i: self.theta_i,
            budget: self.budget,
            coarse: self.coarse.unwrap_or(defaults::COARSE),
            batch: self.batch.unwrap_or(defaults::BATCH),
            candidates: self.candidates.unwrap_or(defaults::CANDIDATES),
            method: self.method,
            seed: self.seed,
        }
    }
}

impl Adaptive {
    /// Checks the fields other than the angles: the fault's field and message.
    pub(crate) fn validate(&self) -> Result<(), (String, String)> {
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

    /// The incident directions, degrees, in the plan's order.
    pub fn incidences(&self) -> Result<Vec<SphericalDeg>, String> {
        Ok(self
            .theta_i
            .expand()?
            .into_iter()
            .map(|t| SphericalDeg::new(t, self.phi_i))
            .collect())
    }

    /// The lattice turn of incidence `k` for a purpose (`0` the coarse pass, `1` the
    /// pool): a fraction of a turn, from the seed.
    fn turn(&self, k: usize, purpose: u64) -> f64 {
        let h = splitmix64(
            self.seed ^ splitmix64((k as u64).wrapping_mul(0x9e37_79b9) ^ purpose.rotate_left(32)),
        );
        (h >> 11) as f64 / (1u64 << 53) as f64
    }

    /// The coarse pass: per incidence, a lattice of `per_incidence` outgoing
    /// directions and the mirror direction, in the plan's order of incidences.
    pub fn coarse_pairs(&self, per_incidence: usize) -> Result<Vec<PairDeg>, String> {
        let mut out = Vec::new();
        for (k, inc) in self.incidences()?.into_iter().enumerate() {
            out.push(PairDeg {
                incident: inc,
                outgoing: SphericalDeg::new(inc.theta_deg, inc.phi_deg + 180.0),
            });
            out.extend(
                lattice(per_incidence, self.turn(k, 0))
                    .into_iter()
                    .map(|o| PairDeg {
                        incident: inc,
                        outgoing: o,
                    }),
            );
        }
        Ok(out)
    }

    /// The coarse pass's lattice size per incidence for a budget of `points`.
    pub fn coarse_per_incidence(&self, points: usize) -> Result<usize, String> {
        let n = self.incidences()?.len().max(1);
        Ok(((points as f64 * self.coarse / n as f64).round() as usize).max(1))
    }

    /// Points in each batch after the coarse pass, for a budget of `points`.
    pub fn batch_points(&self, points: usize) -> usize {
        ((points as f64 * self.batch).round() as usize).max(MIN_BATCH)
    }
}

/// `n` directions of the upper hemisphere on a spherical Fibonacci lattice turned by
/// `turn` (a fraction of a full turn), degrees; equal-area: cos θ = 1 − (k + ½)/n.
pub fn lattice(n: usize, turn: f64) -> Vec<SphericalDeg> {
    let golden = (1.0 + 5f64.sqrt()) / 2.0;
    (0..n)
        .map(|k| {
            let z = 1.0 - (k as f64 + 0.5) / n as f64;
            let phi = ((k as f64 / golden + turn).fract()) * 360.0;
            SphericalDeg::new(z.clamp(-1.0, 1.0).acos().to_degrees(), phi)
        })
        .collect()
}

/// The measurable candidates of a run: per incidence, the pool lattice's directions
/// that the instrument accepts, with their stage positions.
#[derive(Clone, Debug, PartialEq)]
pub struct Pool {
    /// The candidates, incidence by incidence.
    pub candidates: Vec<Accepted>,
    /// How many lattice directions the instrument refused.
    pub refused: usize,
}

impl Pool {
    /// The pool of `spec` on the instrument `mech`.
    pub fn new(spec: &Adaptive, mech: &Mechanics) -> Result<Pool, String> {
        let mut pairs = Vec::new();
        for (k, inc) in spec.incidences()?.into_iter().enumerate() {
            pairs.extend(
                lattice(spec.candidates, spec.turn(k, 1))
                    .into_iter()
                    .map(|o| PairDeg {
                        incident: inc,
                        outgoing: o,
                    }),
            );
        }
        let checked = crate::plan::check(mech, &pairs);
        Ok(Pool {
            refused: checked.rejected.len(),
            candidates: checked.accepted,
        })
    }
}

/// The schedule of one batch: `chosen` (measurable pairs with their stage positions)
/// ordered for least motion from `start`, with the plan's channels and repeats and
/// its drift reference at `reference` (the coarse pass's, so that every batch is
/// tied to the same point) at the batch's start, every `drift.every` points and at
/// its end; no calibrations (the coarse pass took them). `first_index` numbers the
/// points in the plan's order (`Step::plan_index`), after those already taken.
pub fn schedule_batch(
    plan: &Plan,
    mech: &Mechanics,
    chosen: &[(PairDeg, [f64; 4])],
    first_index: usize,
    start: [f64; 4],
    reference: Option<PairDeg>,
    reading_s: f64,
) -> Result<Schedule, ScheduleError> {
    let mut p = plan.clone();
    p.calibration = Default::default();
    if let (Some(d), Some(r)) = (p.drift.as_mut(), reference) {
        d.at = Some([
            r.incident.theta_deg,
            r.incident.phi_deg,
            r.outgoing.theta_deg,
            r.outgoing.phi_deg,
        ]);
    }
    let checked = Checked {
        accepted: chosen
            .iter()
            .enumerate()
            .map(|(i, (pair, stages))| Accepted {
                index: first_index + i,
                pair: *pair,
                stages: *stages,
            })
            .collect(),
        rejected: Vec::new(),
    };
    schedule::build(&p, mech, &checked, start, reading_s)
}

/// What `gonio plan check` says of an adaptive plan on an instrument.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// The budget as written.
    pub budget: Budget,
    /// The budget in points (for a budget in hours, the points the estimated time
    /// per point allows).
    pub points: usize,
    /// Measurable pairs of the coarse pass.
    pub coarse: usize,
    /// Points per later batch.
    pub batch: usize,
    /// Measurable candidates (all incidences).
    pub pool: usize,
    /// Candidates the instrument refused.
    pub refused: usize,
    /// Estimated instrument time per point, s (the coarse pass's, calibrations
    /// spread over its points).
    pub point_s: f64,
    /// Estimated time of the whole run, s: the coarse pass and the points left.
    pub estimate_s: f64,
    /// What a batch looks for.
    pub method: Method,
}

/// The coarse pass's lattice per incidence on which a time estimate is based.
const TRIAL_PER_INCIDENCE: usize = 32;

/// The budget in points: as written, or the points `hours` allow at the time per
/// point of a trial coarse pass scheduled on `mech` (calibrations included, so the
/// estimate errs short).
pub fn budget_points(
    plan: &Plan,
    spec: &Adaptive,
    mech: &Mechanics,
    reading_s: f64,
) -> Result<usize, String> {
    match spec.budget {
        Budget::Points(p) => Ok(p),
        Budget::Hours(h) => {
            let pairs = spec.coarse_pairs(TRIAL_PER_INCIDENCE)?;
            let checked = crate::plan::check(mech, &pairs);
            let n = checked.accepted.len();
            let start = mech.limits.map(|(lo, hi)| 0f64.clamp(lo, hi));
            let s = schedule::build(plan, mech, &checked, start, reading_s)
                .map_err(|e| e.to_string())?;
            let per = s.duration_s() / n.max(1) as f64;
            let points = (h * 3600.0 / per.max(1e-3)).floor();
            Ok((points as usize).clamp(1, MAX_BUDGET_POINTS))
        }
    }
}

/// The chord between two pairs' outgoing directions, as the minimum spacing is
/// measured (same incidence assumed).
pub fn outgoing_chord(a: &PairDeg, b: &PairDeg) -> f64 {
    let (x, y) = (a.to_dirs(), b.to_dirs());
    (x.wo.vec() - y.wo.vec()).norm()
}

/// Whether a pair is the same direction pair as another (component-wise within
/// 1e-9 on the unit vectors).
pub fn same_pair(a: DirPair, b: DirPair) -> bool {
    (a.wi.vec() - b.wi.vec()).norm() < 1e-9 && (a.wo.vec() - b.wo.vec()).norm() < 1e-9
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lattice_is_equal_area_on_the_hemisphere() {
        let n = 4000;
        let l = lattice(n, 0.25);
        assert_eq!(l.len(), n);
        // Equal area: the share of points with θ below 60° is the share of the
        // hemisphere's area there, 1 − cos 60° = 0.5, to one point.
        let below = l.iter().filter(|d| d.theta_deg < 60.0).count();
        assert!((below as f64 - n as f64 * 0.5).abs() <= 1.0, "{below}");
        // And the azimuths fill the turn evenly: each quadrant holds a quarter.
        for q in 0..4 {
            let c = l
                .iter()
                .filter(|d| (d.phi_deg / 90.0).floor() as usize == q)
                .count();
            assert!((c as f64 - 1000.0).abs() < 15.0, "quadrant {q}: {c}");
        }
        assert!(l.iter().all(|d| d.theta_deg > 0.0 && d.theta_deg < 90.0));
    }

    #[test]
    fn the_turn_depends_on_the_seed_and_the_incidence_only() {
        let spec = |seed| Adaptive {
            phi_i: 0.0,
            theta_i: Values::List(vec![30.0, 60.0]),
            budget: Budget::Points(100),
            coarse: 0.3,
            batch: 0.1,
            candidates: 1024,
            method: Method::Variation,
            seed,
        };
        let (a, b) = (spec(1), spec(2));
        assert_eq!(a.turn(0, 0), spec(1).turn(0, 0));
        assert_ne!(a.turn(0, 0), b.turn(0, 0));
        assert_ne!(a.turn(0, 0), a.turn(1, 0));
        assert_ne!(a.turn(0, 0), a.turn(0, 1));
        let c = a.coarse_pairs(15).expect("pairs");
        // 15 lattice points and the mirror direction per incidence.
        assert_eq!(c.len(), 32);
        assert_eq!(c[0].outgoing, SphericalDeg::new(30.0, 180.0));
        assert_eq!(c[16].outgoing, SphericalDeg::new(60.0, 180.0));
        assert_eq!(a.coarse_per_incidence(100), Ok(15));
        assert_eq!(a.batch_points(100), 10);
        assert_eq!(a.batch_points(10), MIN_BATCH);
    }
}
