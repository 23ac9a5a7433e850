//! Local search on an array path: 2-opt and Or-opt moves from a work queue, and the
//! iterated local search's kicks (module docs of `order`, steps 3 and 4).

use gonio_core::rng::{GOLDEN_GAMMA, splitmix64};

use super::END;
use super::problem::Problem;

/// Smallest gain (seconds) worth a move: below it rounding could make moves cycle.
const MIN_GAIN: f64 = 1e-10;
/// Longest run Or-opt moves.
const OR_MAX: usize = 3;

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
pub(super) struct Search<'a> {
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
    pub(super) fn new(pb: &'a Problem, order: &[usize]) -> Search<'a> {
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

    pub(super) fn order(&self) -> Vec<usize> {
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
    pub(super) fn improve(&mut self, timed_out: &impl Fn() -> bool) {
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
    pub(super) fn perturb(&mut self, timed_out: &impl Fn() -> bool) {
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
