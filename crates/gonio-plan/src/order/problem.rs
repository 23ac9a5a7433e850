//! The step-time problem on a fixed node set (the points and the start): the k-d
//! tree, the neighbour lists, and the constructions local search starts from
//! (nearest neighbour, greedy matching).

use gonio_core::kdtree::{KdTree, Metric};

use super::metric::{Profile, StepTime};
use super::{AxisMotion, END, MotionModel, NEIGHBOURS, NONE};

/// Points per k-d tree leaf.
const LEAF: usize = 8;

/// Step-time metric on a fixed node set: the points `0..n` and the start `n`.
pub(super) struct Problem {
    /// The k-d tree over the node coordinates (the start last) under the step time.
    tree: KdTree<4, StepTime>,
    /// Neighbour lists, `NEIGHBOURS` per node, nearest first, and their step times.
    pub(super) neigh: Vec<Vec<usize>>,
    pub(super) neigh_d: Vec<Vec<f64>>,
}

impl Problem {
    pub(super) fn new(
        model: &MotionModel,
        start: [f64; 4],
        points: &[[f64; 4]],
    ) -> Option<Problem> {
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
    pub(super) fn m(&self) -> usize {
        self.tree.len()
    }

    /// Number of points (the start excluded).
    pub(super) fn n(&self) -> usize {
        self.m() - 1
    }

    /// Coordinates of node `u`.
    #[inline]
    pub(super) fn node(&self, u: usize) -> &[f64; 4] {
        &self.tree.points()[u]
    }

    pub(super) fn start(&self) -> usize {
        self.n()
    }

    /// Step time between nodes; `END` (the free end of the open path) costs nothing.
    #[inline]
    pub(super) fn d(&self, u: usize, v: usize) -> f64 {
        if u == END || v == END {
            0.0
        } else {
            self.tree.metric().distance(self.node(u), self.node(v))
        }
    }

    pub(super) fn nearest_neighbour(&self) -> Vec<usize> {
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
    pub(super) fn greedy(&self) -> Vec<usize> {
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
