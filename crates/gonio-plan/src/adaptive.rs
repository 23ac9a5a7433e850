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

use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use gonio_core::rng::splitmix64;
use serde::Serialize;

use crate::plan::{Accepted, Checked, Mechanics, Plan};
pub use crate::plan::{
    Adaptive, BATCH_SHARE, BUDGET_HOURS, Budget, CANDIDATES, COARSE_SHARE, MAX_BUDGET_POINTS,
    MIN_BATCH, MIN_SPACING_DEG, Method,
};
use crate::schedule::{self, Schedule, ScheduleError};

impl Adaptive {
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
    /// Capped so that the lattices and the mirror directions never pass the budget;
    /// refused below two points per incidence (one direction and the mirror).
    pub fn coarse_per_incidence(&self, points: usize) -> Result<usize, String> {
        let n = self.incidences()?.len().max(1);
        let most = (points / n).saturating_sub(1);
        if most == 0 {
            return Err(format!(
                "a budget of {points} points cannot hold a coarse pass at {n} incidences: \
                 it takes at least two points per incidence (a direction and the mirror)"
            ));
        }
        Ok(((points as f64 * self.coarse / n as f64).round() as usize).clamp(1, most))
    }

    /// Points in each batch after the coarse pass, for a budget of `points`.
    pub fn batch_points(&self, points: usize) -> usize {
        ((points as f64 * self.batch).round() as usize).max(MIN_BATCH)
    }
}

/// `n` directions of the upper hemisphere on a spherical Fibonacci lattice turned by
/// `turn` (a fraction of a full turn), degrees
/// ([`SphericalDeg::fibonacci_hemisphere`]).
pub fn lattice(n: usize, turn: f64) -> Vec<SphericalDeg> {
    SphericalDeg::fibonacci_hemisphere(n, turn)
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
            // At least the smallest coarse pass (a direction and the mirror per
            // incidence), whose time is then held to the budget.
            let least = 2 * spec.incidences()?.len().max(1);
            Ok((points as usize).clamp(least, MAX_BUDGET_POINTS))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::Values;

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
