//! A k-d tree over points of `D` coordinates for exact k-nearest queries under any
//! [`Metric`], with deletion.
//!
//! The answer to a query is defined without reference to the tree: the `k` points
//! nearest to the query by [`Metric::distance`], in `(distance, index)` order — ties go
//! to the lower index — exactly what a brute-force scan with a stable sort returns. The
//! tree only makes it fast: it prunes a subtree when the metric's lower bound to the
//! subtree's bounding box ([`Metric::box_bound`]) exceeds the k-th best distance, or
//! equals it while every index below is higher (so many duplicate points stay cheap).
//!
//! Two metrics use it in Gonio: [`SquaredEuclidean`] (the nearest-j kernel over
//! scattered BRDF samples) and the motion time of the goniometer's stages (the
//! ordering of a measurement plan, in `gonio-plan`), which also deletes points as a
//! path visits them.
//!
//! ```
//! use gonio_core::kdtree::{KdTree, SquaredEuclidean};
//! let pts = vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [5.0, 5.0]];
//! let mut tree = KdTree::new(pts, SquaredEuclidean);
//! // [1, 0] and [0, 1] tie at distance 1 from the origin: the lower index comes first.
//! assert_eq!(tree.nearest(&[0.1, 0.1], 3).iter().map(|n| n.1).collect::<Vec<_>>(), [0, 1, 2]);
//! tree.remove(0);
//! assert_eq!(tree.nearest_one(&[0.0, 0.0]), Some((1.0, 1)));
//! ```
//!
//! Construction is O(n log n): each node splits its points at the median of the axis
//! of widest [`Metric::spread`], by `(coordinate, index)`. Coordinates should be
//! finite; a point with a NaN coordinate may be returned or skipped, but nothing
//! panics.

/// A distance on `[f64; D]` the tree can prune with.
///
/// The tree is exact (returns what a brute-force scan would) as long as
/// [`box_bound`](Metric::box_bound) never exceeds [`distance`](Metric::distance) — in
/// floating point as computed, not only in exact arithmetic — for any point in the box.
/// The distance need not be a true metric: any non-negative value that orders points by
/// closeness works (the squared Euclidean distance is one).
pub trait Metric<const D: usize> {
    /// The distance from the query `q` to the point `p`.
    fn distance(&self, q: &[f64; D], p: &[f64; D]) -> f64;

    /// A lower bound on [`distance`](Metric::distance)`(q, p)` over every `p` with
    /// `lo[i] ≤ p[i] ≤ hi[i]` on each axis (zero when `q` is in the box).
    fn box_bound(&self, q: &[f64; D], lo: &[f64; D], hi: &[f64; D]) -> f64;

    /// How far apart points spread along `axis` when their coordinates there span
    /// `width ≥ 0`: the tree splits each node on the axis of widest spread (the first
    /// such axis on ties). The default is `width` itself.
    fn spread(&self, axis: usize, width: f64) -> f64 {
        let _ = axis;
        width
    }
}

/// The squared Euclidean distance `Σᵢ (qᵢ − pᵢ)²` (squared, so no square root is taken
/// per comparison: it orders points as the Euclidean distance does).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SquaredEuclidean;

impl<const D: usize> Metric<D> for SquaredEuclidean {
    #[inline]
    fn distance(&self, q: &[f64; D], p: &[f64; D]) -> f64 {
        (0..D).map(|i| (p[i] - q[i]).powi(2)).sum()
    }

    #[inline]
    fn box_bound(&self, q: &[f64; D], lo: &[f64; D], hi: &[f64; D]) -> f64 {
        (0..D)
            .map(|i| (lo[i] - q[i]).max(q[i] - hi[i]).max(0.0).powi(2))
            .sum()
    }
}

/// Marks "no node".
const NONE: usize = usize::MAX;

#[derive(Clone, Debug)]
struct Node<const D: usize> {
    /// The node's points are `idx[lo..hi]`.
    lo: usize,
    hi: usize,
    /// Bounding box of the node's points.
    min: [f64; D],
    max: [f64; D],
    /// Children, or `NONE` for a leaf.
    left: usize,
    right: usize,
    parent: usize,
    /// Active points below.
    count: usize,
    /// Lowest point index below (active or not): with the distance bound, it prunes
    /// the subtrees that could only tie, which keeps ties to the lower index cheap even
    /// for many duplicate points.
    min_idx: usize,
}

/// A k-d tree over a point set, answering k-nearest queries among its *active* points
/// (all of them until some are [removed](KdTree::remove)); indices are those of the
/// points given to [`new`](KdTree::new). See the [module docs](self).
#[derive(Clone, Debug)]
pub struct KdTree<const D: usize, M> {
    points: Vec<[f64; D]>,
    metric: M,
    /// Permutation of point indices; each node is a range of it.
    idx: Vec<usize>,
    nodes: Vec<Node<D>>,
    /// The leaf holding each point.
    leaf_of: Vec<usize>,
    active: Vec<bool>,
}

impl<const D: usize, M: Metric<D>> KdTree<D, M> {
    /// Points per leaf that [`new`](KdTree::new) uses.
    pub const DEFAULT_LEAF: usize = 8;

    /// A tree over `points` with [`DEFAULT_LEAF`](KdTree::DEFAULT_LEAF) points per leaf.
    pub fn new(points: Vec<[f64; D]>, metric: M) -> KdTree<D, M> {
        KdTree::with_leaf_size(points, metric, Self::DEFAULT_LEAF)
    }

    /// A tree over `points` whose leaves hold at most `leaf` points (at least one).
    /// Identical points are split like any others, so leaves stay small.
    pub fn with_leaf_size(points: Vec<[f64; D]>, metric: M, leaf: usize) -> KdTree<D, M> {
        let m = points.len();
        let mut t = KdTree {
            points,
            metric,
            idx: (0..m).collect(),
            nodes: Vec::new(),
            leaf_of: vec![NONE; m],
            active: vec![true; m],
        };
        if m > 0 {
            t.build_node(0, m, NONE, leaf.max(1));
        }
        t
    }

    fn build_node(&mut self, lo: usize, hi: usize, parent: usize, leaf: usize) -> usize {
        let pts = &self.points;
        let mut min = [f64::INFINITY; D];
        let mut max = [f64::NEG_INFINITY; D];
        for &i in &self.idx[lo..hi] {
            for k in 0..D {
                min[k] = min[k].min(pts[i][k]);
                max[k] = max[k].max(pts[i][k]);
            }
        }
        let id = self.nodes.len();
        self.nodes.push(Node {
            lo,
            hi,
            min,
            max,
            left: NONE,
            right: NONE,
            parent,
            count: hi - lo,
            min_idx: self.idx[lo..hi].iter().copied().min().unwrap_or(NONE),
        });
        if hi - lo <= leaf {
            for &i in &self.idx[lo..hi] {
                self.leaf_of[i] = id;
            }
            return id;
        }
        let (axis, _) = (0..D)
            .map(|k| (k, self.metric.spread(k, max[k] - min[k])))
            .fold((0, -1.0), |b, c| if c.1 > b.1 { c } else { b });
        // Median by (coordinate, index): a total order, so the halves are a function
        // of the points alone.
        let mid = lo + (hi - lo) / 2;
        self.idx[lo..hi].select_nth_unstable_by(mid - lo, |&a, &b| {
            pts[a][axis].total_cmp(&pts[b][axis]).then(a.cmp(&b))
        });
        let left = self.build_node(lo, mid, id, leaf);
        let right = self.build_node(mid, hi, id, leaf);
        self.nodes[id].left = left;
        self.nodes[id].right = right;
        id
    }

    /// Number of points (active or not).
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the tree holds no point.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The points, in the order given.
    pub fn points(&self) -> &[[f64; D]] {
        &self.points
    }

    /// The metric.
    pub fn metric(&self) -> &M {
        &self.metric
    }

    /// Number of active points.
    pub fn active_len(&self) -> usize {
        self.nodes.first().map_or(0, |root| root.count)
    }

    /// Whether point `i` is active (false for an index out of range).
    pub fn is_active(&self, i: usize) -> bool {
        self.active.get(i).copied().unwrap_or(false)
    }

    /// Deletes point `i` from later answers; false if it was not active (or out of
    /// range). O(log n).
    pub fn remove(&mut self, i: usize) -> bool {
        if !self.is_active(i) {
            return false;
        }
        self.active[i] = false;
        let mut id = self.leaf_of[i];
        while id != NONE {
            self.nodes[id].count -= 1;
            id = self.nodes[id].parent;
        }
        true
    }

    /// The `k` active points nearest to `q` as `(distance, index)`, nearest first,
    /// ties to the lower index (fewer when fewer are active).
    pub fn nearest(&self, q: &[f64; D], k: usize) -> Vec<(f64, usize)> {
        self.nearest_where(q, k, |_| true)
    }

    /// The active point nearest to `q` as `(distance, index)`, ties to the lower index.
    pub fn nearest_one(&self, q: &[f64; D]) -> Option<(f64, usize)> {
        self.nearest(q, 1).first().copied()
    }

    /// As [`nearest`](KdTree::nearest), among the active points whose index `keep`
    /// accepts (e.g. all but the query's own point).
    pub fn nearest_where(
        &self,
        q: &[f64; D],
        k: usize,
        keep: impl Fn(usize) -> bool,
    ) -> Vec<(f64, usize)> {
        let mut best: Vec<(f64, usize)> = Vec::with_capacity(k + 1);
        if k == 0 || self.nodes.is_empty() {
            return best;
        }
        // Depth-first, the nearer child first; each entry carries its box bound.
        let mut stack: Vec<(usize, f64)> = Vec::with_capacity(64);
        stack.push((0, self.bound(0, q)));
        while let Some((id, b)) = stack.pop() {
            let nd = &self.nodes[id];
            if nd.count == 0 {
                continue;
            }
            if best.len() == k {
                let worst = best[k - 1];
                if b > worst.0 || (b == worst.0 && nd.min_idx > worst.1) {
                    continue;
                }
            }
            if nd.left == NONE {
                for &i in &self.idx[nd.lo..nd.hi] {
                    if !self.active[i] || !keep(i) {
                        continue;
                    }
                    let c = (self.metric.distance(q, &self.points[i]), i);
                    if best.len() < k || less(c, best[k - 1]) {
                        let at = best.partition_point(|&e| less(e, c));
                        best.insert(at, c);
                        best.truncate(k);
                    }
                }
            } else {
                let (bl, br) = (self.bound(nd.left, q), self.bound(nd.right, q));
                // The nearer child is pushed last, so visited first.
                if bl <= br {
                    stack.push((nd.right, br));
                    stack.push((nd.left, bl));
                } else {
                    stack.push((nd.left, bl));
                    stack.push((nd.right, br));
                }
            }
        }
        best
    }

    /// The metric's lower bound from `q` to node `id`'s box.
    #[inline]
    fn bound(&self, id: usize, q: &[f64; D]) -> f64 {
        let nd = &self.nodes[id];
        self.metric.box_bound(q, &nd.min, &nd.max)
    }
}

/// `(distance, index)` order: by distance, ties to the lower index.
#[inline]
fn less(a: (f64, usize), b: (f64, usize)) -> bool {
    a.0 < b.0 || (a.0 == b.0 && a.1 < b.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fixed pseudo-random stream (xorshift), so the tests are reproducible.
    struct XorShift(u64);

    impl XorShift {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// A Chebyshev-like metric with per-axis costs: the maximum over axes of a concave
    /// increasing time, as the stages' motion time is (a trapezoid profile).
    struct MaxTime([(f64, f64); 3]);

    impl MaxTime {
        fn time(&self, k: usize, d: f64) -> f64 {
            let (v, a) = self.0[k];
            let ramp = v * v / a;
            if d >= ramp {
                2.0 * v / a + (d - ramp) / v
            } else {
                (4.0 * d / a).sqrt()
            }
        }
    }

    impl Metric<3> for MaxTime {
        fn distance(&self, q: &[f64; 3], p: &[f64; 3]) -> f64 {
            (0..3).fold(0.0, |m, k| m.max(self.time(k, (q[k] - p[k]).abs())))
        }
        fn box_bound(&self, q: &[f64; 3], lo: &[f64; 3], hi: &[f64; 3]) -> f64 {
            (0..3).fold(0.0, |m, k| {
                m.max(self.time(k, (lo[k] - q[k]).max(q[k] - hi[k]).max(0.0)))
            })
        }
        fn spread(&self, axis: usize, width: f64) -> f64 {
            self.time(axis, width)
        }
    }

    /// The brute-force answer: every kept active point, stably sorted by distance.
    fn brute<M: Metric<3>>(
        t: &KdTree<3, M>,
        q: &[f64; 3],
        k: usize,
        keep: impl Fn(usize) -> bool,
    ) -> Vec<(f64, usize)> {
        let mut all: Vec<(f64, usize)> = (0..t.len())
            .filter(|&i| t.is_active(i) && keep(i))
            .map(|i| (t.metric().distance(q, &t.points()[i]), i))
            .collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0));
        all.truncate(k);
        all
    }

    /// A cloud with many exact ties: coordinates on a coarse lattice, every point
    /// repeated, and queries on the lattice and between.
    fn cloud(r: &mut XorShift, n: usize, coarse: bool) -> Vec<[f64; 3]> {
        let c = |r: &mut XorShift| {
            let x = 4.0 * r.next();
            if coarse { x.round() } else { x }
        };
        let mut pts: Vec<[f64; 3]> = (0..n).map(|_| [c(r), c(r), c(r)]).collect();
        if coarse {
            let again = pts[..n / 3].to_vec();
            pts.extend(again);
        }
        pts
    }

    fn check<M: Metric<3>>(metric: impl Fn() -> M) {
        let mut r = XorShift(0x2545_f491_4f6c_dd1d);
        for (n, coarse, leaf) in [
            (500, false, 8),
            (600, true, 8),
            (300, true, 1),
            (7, true, 12),
        ] {
            let pts = cloud(&mut r, n, coarse);
            let mut t = KdTree::with_leaf_size(pts.clone(), metric(), leaf);
            for round in 0..4 {
                for _ in 0..40 {
                    let q = if round % 2 == 0 {
                        [4.0 * r.next(), 4.0 * r.next(), 4.0 * r.next()]
                    } else {
                        pts[(r.next() * pts.len() as f64) as usize]
                    };
                    for k in [1, 2, 7, 20, pts.len() + 3] {
                        assert_eq!(t.nearest(&q, k), brute(&t, &q, k, |_| true));
                    }
                    let skip = (r.next() * pts.len() as f64) as usize;
                    assert_eq!(
                        t.nearest_where(&q, 5, |i| i != skip),
                        brute(&t, &q, 5, |i| i != skip)
                    );
                    assert_eq!(
                        t.nearest_one(&q),
                        brute(&t, &q, 1, |_| true).first().copied()
                    );
                }
                // Delete a quarter of the points (some twice) and ask again.
                for _ in 0..pts.len() / 4 {
                    let i = (r.next() * pts.len() as f64) as usize;
                    let was = t.is_active(i);
                    assert_eq!(t.remove(i), was);
                    assert!(!t.is_active(i));
                }
                let active = (0..pts.len()).filter(|&i| t.is_active(i)).count();
                assert_eq!(t.active_len(), active);
            }
        }
    }

    #[test]
    fn squared_euclidean_matches_brute_force() {
        check(|| SquaredEuclidean);
    }

    #[test]
    fn max_time_metric_matches_brute_force() {
        check(|| MaxTime([(20.0, 80.0), (30.0, 120.0), (10.0, 40.0)]));
    }

    #[test]
    fn empty_and_exhausted() {
        let mut t = KdTree::<2, _>::new(Vec::new(), SquaredEuclidean);
        assert!(t.is_empty());
        assert_eq!(t.nearest(&[0.0, 0.0], 3), []);
        assert_eq!(t.nearest_one(&[0.0, 0.0]), None);
        assert!(!t.remove(0));

        t = KdTree::new(vec![[1.0, 1.0]; 3], SquaredEuclidean);
        assert_eq!(t.nearest(&[0.0, 0.0], 0), []);
        assert_eq!(t.nearest(&[1.0, 1.0], 5), [(0.0, 0), (0.0, 1), (0.0, 2)]);
        for i in 0..3 {
            assert!(t.remove(i));
        }
        assert_eq!(t.active_len(), 0);
        assert_eq!(t.nearest_one(&[1.0, 1.0]), None);
    }
}
