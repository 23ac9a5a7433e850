//! A static k-d tree for nearest-j queries among points of a fixed dimension.

/// A point set with a tree over it; queries return indices into the original points.
pub(crate) struct KdTree<const D: usize> {
    points: Vec<[f64; D]>,
    /// Permutation of point indices; each node is a range of it.
    perm: Vec<usize>,
    nodes: Vec<Node>,
}

struct Node {
    lo: usize,
    hi: usize,
    /// Split dimension and value, and children; none for a leaf.
    split: Option<(usize, f64, usize, usize)>,
}

const LEAF: usize = 12;

impl<const D: usize> KdTree<D> {
    pub(crate) fn build(points: Vec<[f64; D]>) -> KdTree<D> {
        let perm: Vec<usize> = (0..points.len()).collect();
        let mut t = KdTree {
            points,
            perm,
            nodes: Vec::new(),
        };
        if !t.points.is_empty() {
            t.build_node(0, t.points.len());
        }
        t
    }

    fn build_node(&mut self, lo: usize, hi: usize) -> usize {
        let id = self.nodes.len();
        self.nodes.push(Node {
            lo,
            hi,
            split: None,
        });
        if hi - lo <= LEAF {
            return id;
        }
        // Split the widest dimension at the median: balanced depth whatever the data.
        let mut dim = 0;
        let mut widest = -1.0;
        for d in 0..D {
            let (mut a, mut b) = (f64::INFINITY, f64::NEG_INFINITY);
            for &p in &self.perm[lo..hi] {
                a = a.min(self.points[p][d]);
                b = b.max(self.points[p][d]);
            }
            if b - a > widest {
                widest = b - a;
                dim = d;
            }
        }
        if widest <= 0.0 {
            return id;
        }
        let mid = (lo + hi) / 2;
        let pts = &self.points;
        self.perm[lo..hi]
            .select_nth_unstable_by(mid - lo, |&a, &b| pts[a][dim].total_cmp(&pts[b][dim]));
        let value = self.points[self.perm[mid]][dim];
        let left = self.build_node(lo, mid);
        let right = self.build_node(mid, hi);
        self.nodes[id].split = Some((dim, value, left, right));
        id
    }

    /// The `j` nearest points to `q` as (squared distance, index), nearest first.
    pub(crate) fn nearest(&self, q: &[f64; D], j: usize) -> Vec<(f64, usize)> {
        let mut best: Vec<(f64, usize)> = Vec::with_capacity(j + 1);
        if !self.nodes.is_empty() && j > 0 {
            self.search(0, q, j, &mut best);
        }
        best
    }

    fn search(&self, id: usize, q: &[f64; D], j: usize, best: &mut Vec<(f64, usize)>) {
        let node = &self.nodes[id];
        match node.split {
            None => {
                for &p in &self.perm[node.lo..node.hi] {
                    let d2: f64 = (0..D).map(|d| (self.points[p][d] - q[d]).powi(2)).sum();
                    if best.len() < j || d2 < best[best.len() - 1].0 {
                        let at = best.partition_point(|e| e.0 <= d2);
                        best.insert(at, (d2, p));
                        best.truncate(j);
                    }
                }
            }
            Some((dim, value, left, right)) => {
                let diff = q[dim] - value;
                let (near, far) = if diff < 0.0 {
                    (left, right)
                } else {
                    (right, left)
                };
                self.search(near, q, j, best);
                if best.len() < j || diff * diff < best[best.len() - 1].0 {
                    self.search(far, q, j, best);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_brute_force() {
        // A fixed pseudo-random cloud (xorshift), so the test is reproducible.
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let pts: Vec<[f64; 3]> = (0..500).map(|_| [next(), next(), next()]).collect();
        let tree = KdTree::build(pts.clone());
        for _ in 0..50 {
            let q = [next(), next(), next()];
            let got = tree.nearest(&q, 7);
            let mut all: Vec<(f64, usize)> = pts
                .iter()
                .enumerate()
                .map(|(i, p)| ((0..3).map(|d| (p[d] - q[d]).powi(2)).sum(), i))
                .collect();
            all.sort_by(|a, b| a.0.total_cmp(&b.0));
            assert_eq!(got, all[..7].to_vec());
        }
    }
}
