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

use std::time::{Duration, Instant};

use gonio_core::kdtree::{KdTree, Metric};
pub use gonio_core::motion::{AxisMotion, MotionModel};
use gonio_core::rng::{GOLDEN_GAMMA, splitmix64};

/// Length of each point's neighbour list (candidates for the local search and the
/// greedy construction).
pub const NEIGHBOURS: usize = 12;

/// Points per k-d tree leaf.
const LEAF: usize = 8;
/// Smallest gain (seconds) worth a move: below it rounding could make moves cycle.
const MIN_GAIN: f64 = 1e-10;
/// Longest run Or-opt moves.
const OR_MAX: usize = 3;

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

/// Step-time metric on a fixed node set: the points `0..n` and the start `n`.
struct Problem {
    /// The k-d tree over the node coordinates (the start last) under the step time.
    tree: KdTree<4, StepTime>,
    /// Neighbour lists, `NEIGHBOURS` per node, nearest first, and their step times.
    neigh: Vec<Vec<usize>>,
    neigh_d: Vec<Vec<f64>>,
}

impl Problem {
    fn new(model: &MotionModel, start: [f64; 4], points: &[[f64; 4]]) -> Option<Problem> {
        if !model.axes.iter().all(AxisMotion::is_valid) {
            return None;
        }
        let mut axes = [Profile::FREE; 4];
        for (p, ax) in axes.iter_mut().zip(&model.axes) {
            *p = Profile::new(*ax);
        }
        let mut nodes = points.to_vec();
        nodes.push(start);
        if nodes.iter().flatten().any(|c| !c.is_finite()) {
            return None;
        }
        let mut pb = Problem {
            tree: KdTree::with_leaf_size(nodes, StepTime { axes }, LEAF),
            neigh: Vec::new(),
            neigh_d: Vec::new(),
        };
        let neigh: Vec<Vec<usize>> = (0..pb.m())
            .map(|u| {
                pb.tree
                    .nearest_where(pb.node(u), NEIGHBOURS, |v| v != u)
                    .into_iter()
                    .map(|(_, v)| v)
                    .collect()
            })
            .collect();
        pb.neigh_d = neigh
            .iter()
            .enumerate()
            .map(|(u, l)| l.iter().map(|&v| pb.d(u, v)).collect())
            .collect();
        pb.neigh = neigh;
        Some(pb)
    }

    /// Number of nodes: the points and the start.
    fn m(&self) -> usize {
        self.tree.len()
    }

    /// Number of points (the start excluded).
    fn n(&self) -> usize {
        self.m() - 1
    }

    /// Coordinates of node `u`.
    #[inline]
    fn node(&self, u: usize) -> &[f64; 4] {
        &self.tree.points()[u]
    }

    fn start(&self) -> usize {
        self.n()
    }

    /// Step time between nodes; `END` (the free end of the open path) costs nothing.
    #[inline]
    fn d(&self, u: usize, v: usize) -> f64 {
        if u == END || v == END {
            0.0
        } else {
            self.tree.metric().distance(self.node(u), self.node(v))
        }
    }

    fn nearest_neighbour(&self) -> Vec<usize> {
        let n = self.n();
        let mut tree = self.tree.clone();
        tree.remove(self.start());
        let mut order = Vec::with_capacity(n);
        let mut at = self.start();
        while let Some((_, next)) = tree.nearest_one(self.node(at)) {
            tree.remove(next);
            order.push(next);
            at = next;
        }
        order
    }

    /// Greedy-matching construction (module docs, step 2).
    fn greedy(&self) -> Vec<usize> {
        let m = self.m();
        let start = self.start();
        let mut edges: Vec<(f64, usize, usize)> = Vec::with_capacity(m * NEIGHBOURS);
        for u in 0..m {
            for &v in &self.neigh[u] {
                if u < v || !self.neigh[v].contains(&u) {
                    edges.push((self.d(u, v), u.min(v), u.max(v)));
                }
            }
        }
        edges.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        edges.dedup_by(|a, b| a.1 == b.1 && a.2 == b.2);

        let mut adj = vec![[NONE; 2]; m];
        let mut deg = vec![0usize; m];
        let cap = |u: usize| if u == start { 1 } else { 2 };
        let mut uf = UnionFind::new(m);
        for &(_, u, v) in &edges {
            if deg[u] < cap(u) && deg[v] < cap(v) && uf.union(u, v) {
                adj[u][deg[u]] = v;
                adj[v][deg[v]] = u;
                deg[u] += 1;
                deg[v] += 1;
            }
        }

        // Chain the fragments: from the current end, to the nearest free fragment end.
        let mut tree = self.tree.clone();
        for (u, &du) in deg.iter().enumerate() {
            if du == 2 {
                tree.remove(u);
            }
        }
        let mut order = Vec::with_capacity(m - 1);
        let mut at = start;
        tree.remove(start);
        // Walk the fragment that begins at `from`, appending it to `order`.
        let walk = |from: usize, order: &mut Vec<usize>, tree: &mut KdTree<4, StepTime>| -> usize {
            let (mut prev, mut cur) = (NONE, from);
            loop {
                let next = adj[cur].iter().copied().find(|&x| x != NONE && x != prev);
                match next {
                    Some(x) => {
                        order.push(x);
                        prev = cur;
                        cur = x;
                    }
                    None => break,
                }
            }
            tree.remove(cur);
            cur
        };
        at = walk(at, &mut order, &mut tree);
        while let Some((_, next)) = tree.nearest_one(self.node(at)) {
            tree.remove(next);
            order.push(next);
            at = walk(next, &mut order, &mut tree);
        }
        order
    }
}

/// An axis' trapezoid profile with the divisions of [`trapezoid_time`](gonio_core::motion::trapezoid_time) done once: the
/// search evaluates it millions of times. (It may differ from `trapezoid_time` in the
/// last bit; every comparison [`optimise`] promises is made with
/// [`MotionModel::path_time`].)
#[derive(Clone, Copy)]
struct Profile {
    /// Distance of the full acceleration and deceleration ramps, `v²/a`.
    ramp: f64,
    /// Their time, `2v/a`.
    t_ramp: f64,
    inv_v: f64,
    /// `4/a`: a triangular move of `d` lasts `2√(d/a) = √(4d/a)`.
    four_over_a: f64,
}

impl Profile {
    /// An axis that never costs time.
    const FREE: Profile = Profile {
        ramp: f64::INFINITY,
        t_ramp: 0.0,
        inv_v: 0.0,
        four_over_a: 0.0,
    };

    fn new(ax: AxisMotion) -> Profile {
        let (v, a) = (ax.velocity, ax.acceleration);
        Profile {
            ramp: v * v / a,
            t_ramp: 2.0 * v / a,
            inv_v: 1.0 / v,
            four_over_a: 4.0 / a,
        }
    }

    /// Time of a move of `d ≥ 0`.
    #[inline(always)]
    fn time(&self, d: f64) -> f64 {
        if d >= self.ramp {
            self.t_ramp + (d - self.ramp) * self.inv_v
        } else {
            (d * self.four_over_a).sqrt()
        }
    }
}

/// The step time `maxᵢ tᵢ(|pᵢ − qᵢ|)` as the k-d tree's metric: its box bound is
/// `maxᵢ tᵢ(gapᵢ)`, and nodes split on the axis of widest extent *in time*.
#[derive(Clone, Copy)]
struct StepTime {
    /// The four axes' profiles (a missing axis moves for free).
    axes: [Profile; 4],
}

impl Metric<4> for StepTime {
    #[inline]
    fn distance(&self, q: &[f64; 4], p: &[f64; 4]) -> f64 {
        let t = |k: usize| self.axes[k].time((q[k] - p[k]).abs());
        t(0).max(t(1)).max(t(2).max(t(3)))
    }

    #[inline]
    fn box_bound(&self, q: &[f64; 4], lo: &[f64; 4], hi: &[f64; 4]) -> f64 {
        let mut m = 0.0f64;
        for (k, ax) in self.axes.iter().enumerate() {
            let gap = (lo[k] - q[k]).max(q[k] - hi[k]).max(0.0);
            m = m.max(ax.time(gap));
        }
        m
    }

    #[inline]
    fn spread(&self, axis: usize, width: f64) -> f64 {
        self.axes[axis].time(width)
    }
}

/// Marks "no node".
const NONE: usize = usize::MAX;
/// The free end of the open path: a virtual node at zero time from everything.
const END: usize = usize::MAX - 1;

struct UnionFind {
    parent: Vec<usize>,
}

impl UnionFind {
    fn new(n: usize) -> Self {
        UnionFind {
            parent: (0..n).collect(),
        }
    }

    fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] != x {
            self.parent[x] = self.parent[self.parent[x]];
            x = self.parent[x];
        }
        x
    }

    /// Joins the sets of `a` and `b`; false if they were already one.
    fn union(&mut self, a: usize, b: usize) -> bool {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra == rb {
            return false;
        }
        self.parent[ra.max(rb)] = ra.min(rb);
        true
    }
}

/// Cap on applied local-search moves per point (a deterministic bound on the work;
/// real plans converge after a few moves per point).
const MOVES_PER_POINT: usize = 50;
/// Perturbation kicks per point (deterministic work of the iterated local search).
const KICKS_PER_POINT: usize = 2;
/// Checks of the wall-time safety cap happen every this many queue pops.
const CLOCK_EVERY: usize = 256;

/// An improving move found for a point.
#[derive(Clone, Copy)]
enum Move {
    /// Reverse `path[i + 1 ..= j]`.
    TwoOpt { i: usize, j: usize },
    /// Move `path[i .. i + len]` to between positions `t` and `t + 1`, reversed or not.
    OrOpt {
        i: usize,
        len: usize,
        t: usize,
        rev: bool,
    },
}

/// Local search state: the path (start first) and each node's position in it.
struct Search<'a> {
    pb: &'a Problem,
    path: Vec<usize>,
    pos: Vec<usize>,
    queue: std::collections::VecDeque<usize>,
    queued: Vec<bool>,
    moves_left: usize,
    /// Gain (seconds) accumulated since the last kick, and the range of positions
    /// changed since then (for undoing a rejected kick).
    gain: f64,
    lo: usize,
    hi: usize,
}

impl<'a> Search<'a> {
    fn new(pb: &'a Problem, order: &[usize]) -> Search<'a> {
        let m = pb.m();
        let mut path = Vec::with_capacity(m);
        path.push(pb.start());
        path.extend_from_slice(order);
        let mut pos = vec![0; m];
        for (p, &u) in path.iter().enumerate() {
            pos[u] = p;
        }
        Search {
            pb,
            path,
            pos,
            queue: std::collections::VecDeque::new(),
            queued: vec![false; m],
            moves_left: MOVES_PER_POINT.saturating_mul(m),
            gain: 0.0,
            lo: usize::MAX,
            hi: 0,
        }
    }

    fn order(&self) -> Vec<usize> {
        self.path[1..].to_vec()
    }

    /// Node at position `p`, or `END` past the last.
    #[inline]
    fn at(&self, p: usize) -> usize {
        self.path.get(p).copied().unwrap_or(END)
    }

    fn push(&mut self, u: usize) {
        if u < self.queued.len() && !self.queued[u] {
            self.queued[u] = true;
            self.queue.push_back(u);
        }
    }

    /// Runs the queued local search from every point, in path order.
    fn improve(&mut self, timed_out: &impl Fn() -> bool) {
        for p in 0..self.path.len() {
            let u = self.path[p];
            self.push(u);
        }
        self.drain(timed_out);
    }

    /// Processes the work queue to a local optimum (or the caps).
    fn drain(&mut self, timed_out: &impl Fn() -> bool) -> bool {
        let mut pops = 0usize;
        while let Some(u) = self.queue.pop_front() {
            self.queued[u] = false;
            pops += 1;
            if self.moves_left == 0 || (pops.is_multiple_of(CLOCK_EVERY) && timed_out()) {
                self.clear_queue();
                return false;
            }
            if let Some((gain, mv)) = self.best_move(u) {
                self.moves_left -= 1;
                self.gain += gain;
                self.apply(mv);
                self.push(u);
            }
        }
        true
    }

    fn clear_queue(&mut self) {
        while let Some(u) = self.queue.pop_front() {
            self.queued[u] = false;
        }
    }

    /// The best improving 2-opt or Or-opt move involving node `u`.
    fn best_move(&self, u: usize) -> Option<(f64, Move)> {
        let pb = self.pb;
        let n = self.path.len() - 1; // last position
        let i = self.pos[u];
        let mut best: Option<(f64, Move)> = None;
        let mut offer = |gain: f64, mv: Move| {
            if gain > MIN_GAIN && best.is_none_or(|(g, _)| gain > g) {
                best = Some((gain, mv));
            }
        };

        // 2-opt, successor side: drop (u, succ u) and (c, succ c), add (u, c) and
        // (succ u, succ c).
        let su = self.at(i + 1);
        let d_su = pb.d(u, su);
        for (&c, &d_uc) in pb.neigh[u].iter().zip(&pb.neigh_d[u]) {
            if d_uc >= d_su {
                break;
            }
            let j = self.pos[c];
            let sc = self.at(j + 1);
            let gain = d_su + pb.d(c, sc) - d_uc - pb.d(su, sc);
            offer(
                gain,
                Move::TwoOpt {
                    i: i.min(j),
                    j: i.max(j),
                },
            );
        }
        // 2-opt, predecessor side: drop (pred u, u) and (pred c, c), add (u, c) and
        // (pred u, pred c). The start has no predecessor.
        if i > 0 {
            let pu = self.path[i - 1];
            let d_pu = pb.d(pu, u);
            for (&c, &d_uc) in pb.neigh[u].iter().zip(&pb.neigh_d[u]) {
                if d_uc >= d_pu {
                    break;
                }
                let j = self.pos[c];
                if j == 0 {
                    continue;
                }
                let pc = self.path[j - 1];
                let gain = d_pu + pb.d(pc, c) - d_uc - pb.d(pu, pc);
                offer(
                    gain,
                    Move::TwoOpt {
                        i: i.min(j) - 1,
                        j: i.max(j) - 1,
                    },
                );
            }
        }
        // Or-opt: runs of 1..=OR_MAX points that begin or end at u.
        if i > 0 {
            for len in 1..=OR_MAX {
                for first in [i, (i + 1).saturating_sub(len)] {
                    if first == 0 || first + len - 1 > n {
                        continue;
                    }
                    if let Some((g, mv)) = self.best_insertion(first, len) {
                        offer(g, mv);
                    }
                    if len == 1 {
                        break;
                    }
                }
            }
        }
        best
    }

    /// Best place for the run `path[i .. i + len]` next to a neighbour of its ends.
    fn best_insertion(&self, i: usize, len: usize) -> Option<(f64, Move)> {
        let pb = self.pb;
        let last = i + len - 1;
        let (a, f, l, b) = (
            self.path[i - 1],
            self.path[i],
            self.path[last],
            self.at(last + 1),
        );
        let removal = pb.d(a, f) + pb.d(l, b) - pb.d(a, b);
        if removal <= MIN_GAIN {
            return None;
        }
        let mut best: Option<(f64, Move)> = None;
        for end in [f, l] {
            for (&c, &d_ec) in pb.neigh[end].iter().zip(&pb.neigh_d[end]) {
                if d_ec >= removal {
                    break;
                }
                let j = self.pos[c];
                // The edges (c, succ c) and (pred c, c) as target positions t.
                for t in [Some(j), j.checked_sub(1)].into_iter().flatten() {
                    if t + 1 >= i && t <= last {
                        continue; // an edge touching the run
                    }
                    let (x, y) = (self.path[t], self.at(t + 1));
                    let base = removal + pb.d(x, y);
                    let fwd = base - pb.d(x, f) - pb.d(l, y);
                    let rev = base - pb.d(x, l) - pb.d(f, y);
                    let (gain, reversed) = if rev > fwd && len > 1 {
                        (rev, true)
                    } else {
                        (fwd, false)
                    };
                    if gain > MIN_GAIN && best.is_none_or(|(g, _)| gain > g) {
                        best = Some((
                            gain,
                            Move::OrOpt {
                                i,
                                len,
                                t,
                                rev: reversed,
                            },
                        ));
                    }
                }
            }
        }
        best
    }

    fn apply(&mut self, mv: Move) {
        match mv {
            Move::TwoOpt { i, j } => {
                for p in [i, i + 1, j, j + 1] {
                    if let Some(&u) = self.path.get(p) {
                        self.push(u);
                    }
                }
                self.path[i + 1..=j].reverse();
                self.reindex(i + 1, j);
                self.touch(i + 1, j);
            }
            Move::OrOpt { i, len, t, rev } => {
                let last = i + len - 1;
                for p in [i - 1, i, last, last + 1, t, t + 1] {
                    if let Some(&u) = self.path.get(p) {
                        self.push(u);
                    }
                }
                if t > last {
                    self.path[i..=t].rotate_left(len);
                    if rev {
                        self.path[t + 1 - len..=t].reverse();
                    }
                    self.reindex(i, t);
                    self.touch(i, t);
                } else {
                    self.path[t + 1..=last].rotate_right(len);
                    if rev {
                        self.path[t + 1..t + 1 + len].reverse();
                    }
                    self.reindex(t + 1, last);
                    self.touch(t + 1, last);
                }
            }
        }
    }

    fn touch(&mut self, lo: usize, hi: usize) {
        self.lo = self.lo.min(lo);
        self.hi = self.hi.max(hi);
    }

    fn reindex(&mut self, lo: usize, hi: usize) {
        for p in lo..=hi {
            self.pos[self.path[p]] = p;
        }
    }

    /// Iterated local search: [`KICKS_PER_POINT`]` × n` deterministic kicks (a
    /// segment swap `A B C D → A C B D`, the sequential 3-opt move that 2-opt and
    /// Or-opt cannot undo for long segments), each followed by the queued local
    /// search from the touched points and kept only if the path got shorter; a
    /// rejected kick is undone by restoring the range of positions it touched.
    fn perturb(&mut self, timed_out: &impl Fn() -> bool) {
        let n = self.path.len() - 1; // last position
        if n < 4 {
            return;
        }
        let mut saved = self.path.clone();
        let kicks = KICKS_PER_POINT.saturating_mul(n);
        for k in 0..kicks {
            if timed_out() {
                break;
            }
            // The (k + 1)-th output of SplitMix64 seeded with 0.
            let h = splitmix64((k as u64).wrapping_mul(GOLDEN_GAMMA));
            let max_len = KICK_SEGMENT.min((n - 1) / 2).max(1);
            let l1 = 1 + (h % max_len as u64) as usize;
            let l2 = 1 + ((h >> 16) % max_len as u64) as usize;
            // Position of the point before B: any, leaving room for B and C.
            let p = ((h >> 32) % (n + 1 - l1 - l2) as u64) as usize;
            let (x, b0, b1) = (self.path[p], self.path[p + 1], self.path[p + l1]);
            let (c0, c1, y) = (
                self.path[p + l1 + 1],
                self.path[p + l1 + l2],
                self.at(p + l1 + l2 + 1),
            );
            let pb = self.pb;
            let kick_gain =
                pb.d(x, b0) + pb.d(b1, c0) + pb.d(c1, y) - pb.d(x, c0) - pb.d(c1, b0) - pb.d(b1, y);
            self.gain = kick_gain;
            self.lo = p + 1;
            self.hi = p + l1 + l2;
            self.path[p + 1..=p + l1 + l2].rotate_left(l1);
            self.reindex(p + 1, p + l1 + l2);
            for u in [x, b0, b1, c0, c1, y] {
                self.push(u);
            }
            self.moves_left = MOVES_PER_KICK;
            let finished = self.drain(timed_out);
            let (lo, hi) = (self.lo, self.hi);
            if finished && self.gain > MIN_GAIN {
                saved[lo..=hi].copy_from_slice(&self.path[lo..=hi]);
            } else {
                self.path[lo..=hi].copy_from_slice(&saved[lo..=hi]);
                self.reindex(lo, hi);
            }
        }
    }
}

/// Cap on the local-search moves that repair one kick (a rejected kick beyond it).
const MOVES_PER_KICK: usize = 1000;
/// Longest segment a kick moves.
const KICK_SEGMENT: usize = 30;
