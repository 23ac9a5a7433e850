//! Ordering the points of a measurement plan to minimise the physical motion time.
//!
//! The stages move concurrently, each with a trapezoidal velocity profile
//! ([`gonio_core::motion::trapezoid_time`]), so a step costs the time of its slowest
//! axis: `d(p, q) = maxᵢ tᵢ(|pᵢ − qᵢ|)`. Each `tᵢ` is increasing and concave with
//! `tᵢ(0) = 0`, hence subadditive, and a maximum of metrics is a metric: `d` is
//! symmetric and obeys the triangle inequality. [`optimise`] solves the resulting
//! open-path travelling-salesman problem from a fixed start (the stages' current
//! position): exactly by Held–Karp dynamic programming up to [`EXACT_MAX`] points
//! (O(2ⁿ n²)), heuristically beyond:
//!
//! 1. **Neighbour lists.** A k-d tree over the points (and the start), split on the axis
//!    of widest extent *in time*, prunes with the exact lower bound
//!    `maxᵢ tᵢ(gapᵢ)` to a box; it gives each point its [`NEIGHBOURS`] nearest by step
//!    time. O(n log n) to build, about O(k log n) per query.
//! 2. **Construction.** Greedy matching: candidate edges (from the lists) by increasing
//!    time are kept while no point gets three edges, the start more than one, or a
//!    cycle closes (union-find); the fragments are then chained from the start, each
//!    time to the nearest free fragment end (k-d tree with deletion). A plain
//!    nearest-neighbour path and the raster order are built too, and local search
//!    starts from the cheapest of the three. O(n k log n).
//! 3. **Local search** on an array path with a position index: 2-opt (segment
//!    reversal, valid since `d` is symmetric; reversing a tail is the open-path move
//!    that changes the last point) and Or-opt (moving a run of 1–3 points, possibly
//!    reversed, next to a neighbour), each point trying only its neighbour-list
//!    candidates under the gain criterion; a FIFO work queue of points whose edges
//!    changed replaces full passes. Each applied move costs O(n) for the array update
//!    (a memmove, fast in practice); evaluation is O(k) per point.
//! 4. **Perturbation** (iterated local search): `2n` kicks, each swapping two
//!    adjacent segments of ≤ 30 points (`A B C D → A C B D`, a 3-opt move 2-opt and
//!    Or-opt cannot undo) and re-running the queued search from the six touched
//!    points; a kick is kept only if the path got shorter, otherwise the positions it
//!    touched are restored. O(n) kicks of near-constant work plus array updates:
//!    about a second for 10⁴ points.
//!
//! Everything is deterministic: ties break on point index, the queue is FIFO, kicks
//! are placed by a hash of their counter (SplitMix64), and the amount of work is a
//! fixed function of the input (caps on moves and kicks). The wall-time `budget` of
//! [`optimise`] is only a safety cap on the local search: 10⁴ points take about 2 s in
//! all, so a budget of 5 s or more never binds there; if it does bind, the result
//! (still a valid order, no slower than raster or nearest neighbour) depends on
//! machine speed.

mod metric;
mod problem;
mod search;

use std::time::{Duration, Instant};

pub use gonio_core::motion::{AxisMotion, MotionModel};

use problem::Problem;
use search::Search;

/// Length of each point's neighbour list (candidates for the local search and the
/// greedy construction).
pub const NEIGHBOURS: usize = 12;

/// The raster order (0, 1, 2, …): the baseline.
pub fn raster(n: usize) -> Vec<usize> {
    (0..n).collect()
}

/// The nearest-neighbour order: from `start`, always to the closest (by step time)
/// point not yet visited, ties to the lower index. A baseline and one of the
/// constructions [`optimise`] starts from. O(n log n) typical with a k-d tree.
///
/// Returns the raster order when the model or a point is not finite and positive.
pub fn nearest_neighbour(model: &MotionModel, start: [f64; 4], points: &[[f64; 4]]) -> Vec<usize> {
    match Problem::new(model, start, points) {
        Some(pb) => pb.nearest_neighbour(),
        None => raster(points.len()),
    }
}

/// A visiting order (a permutation of `0..points.len()`) that minimises the path time
/// from `start`: exact up to [`EXACT_MAX`] points; beyond, the best of a greedy, a
/// nearest-neighbour and the raster construction, improved by 2-opt and Or-opt local
/// search and deterministic perturbations (see the [module docs](self)).
///
/// Deterministic: the work done is a fixed function of the input; `budget` is only a
/// safety cap on the local search's wall time (checked between moves and kicks; the
/// O(n log n) constructions and the exact solver are not interrupted), which 5 s never
/// reach for plans up to ~10⁴ points. The result is never slower than the raster or the
/// nearest-neighbour order. When the model has a non-finite or non-positive velocity
/// or acceleration, or a point is not finite, the raster order is returned.
pub fn optimise(
    model: &MotionModel,
    start: [f64; 4],
    points: &[[f64; 4]],
    budget: Duration,
) -> Vec<usize> {
    let n = points.len();
    if n < 2 {
        return raster(n);
    }
    let Some(pb) = Problem::new(model, start, points) else {
        return raster(n);
    };
    let deadline = Instant::now().checked_add(budget);
    let timed_out = move || deadline.is_some_and(|d| Instant::now() >= d);

    let raster_order = raster(n);
    let nn = pb.nearest_neighbour();
    let baseline = |o: &[usize]| model.path_time(&start, points, o);
    let (t_raster, t_nn) = (baseline(&raster_order), baseline(&nn));

    let mut best = if n <= EXACT_MAX {
        held_karp(model, start, points)
    } else {
        let greedy = pb.greedy();
        let t_greedy = baseline(&greedy);
        let first = if t_greedy <= t_nn && t_greedy <= t_raster {
            greedy
        } else if t_nn <= t_raster {
            nn.clone()
        } else {
            raster_order.clone()
        };
        let mut search = Search::new(&pb, &first);
        search.improve(&timed_out);
        search.perturb(&timed_out);
        search.order()
    };
    let mut t_best = baseline(&best);

    // Local search only improves its start, but from the greedy start it could, on
    // odd inputs, end above another construction: the promise "never slower than
    // raster or nearest neighbour" is kept by searching from that one too.
    for (alt, t_alt) in [(nn, t_nn), (raster_order, t_raster)] {
        if t_alt < t_best {
            let mut s = Search::new(&pb, &alt);
            s.improve(&timed_out);
            let o = s.order();
            let t = baseline(&o);
            // Local search never worsens its start; the comparison guards rounding.
            let (o, t) = if t <= t_alt { (o, t) } else { (alt, t_alt) };
            if t < t_best {
                best = o;
                t_best = t;
            }
        }
    }
    best
}

/// Plans up to this many points are solved exactly (Held–Karp).
pub const EXACT_MAX: usize = 12;

/// The optimal order by Held–Karp dynamic programming over subsets, O(2ⁿ n²) time and
/// O(2ⁿ n) memory: `best[S][j]` is the least time from `start` through the set `S`
/// ending at `j`. The sums run in path order with [`MotionModel::step_time`], so the
/// value is exactly [`MotionModel::path_time`] of the order returned, and no order
/// (raster included) sums lower. Ties go to the first found (lower indices).
fn held_karp(model: &MotionModel, start: [f64; 4], points: &[[f64; 4]]) -> Vec<usize> {
    let n = points.len();
    let full = (1usize << n) - 1;
    let d: Vec<Vec<f64>> = points
        .iter()
        .map(|p| points.iter().map(|q| model.step_time(p, q)).collect())
        .collect();
    let mut best = vec![f64::INFINITY; (full + 1) * n];
    let mut from = vec![NONE; (full + 1) * n];
    for (j, p) in points.iter().enumerate() {
        best[(1 << j) * n + j] = model.step_time(&start, p);
    }
    for set in 1..=full {
        for j in 0..n {
            let here = best[set * n + j];
            if set & (1 << j) == 0 || !here.is_finite() {
                continue;
            }
            for (k, dk) in d[j].iter().enumerate() {
                if set & (1 << k) != 0 {
                    continue;
                }
                let (next, t) = (set | (1 << k), here + dk);
                if t < best[next * n + k] {
                    best[next * n + k] = t;
                    from[next * n + k] = j;
                }
            }
        }
    }
    let mut last = 0;
    for j in 1..n {
        if best[full * n + j] < best[full * n + last] {
            last = j;
        }
    }
    let mut order = Vec::with_capacity(n);
    let (mut set, mut j) = (full, last);
    while j != NONE {
        order.push(j);
        let prev = from[set * n + j];
        set &= !(1 << j);
        j = prev;
    }
    order.reverse();
    order
}

/// Marks "no node".
const NONE: usize = usize::MAX;
/// The free end of the open path: a virtual node at zero time from everything.
const END: usize = usize::MAX - 1;
