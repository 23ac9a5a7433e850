//! Where a segment's rays start, in spatial order, and each ray's own random stream.
//!
//! # Why an order
//! Primary rays start anywhere on the patch; traced in the order they are drawn,
//! each one's cells are far from the last one's, and waiting for memory was most of
//! a primary ray's time (issue 40). So a segment's rays are traced in the order of
//! a spatial tree over the patch: neighbouring rays start close together and share
//! the cached heights and block maxima.
//!
//! # The same rays as independent draws
//! The `n` start points of a segment are `n` independent uniform points of the patch,
//! listed by the leaf of a binary space partition they fall in. They are drawn that
//! way directly, without drawing and sorting: the number of the node's points in
//! the first half of its rectangle is `Binomial(n_node, 1/2)` (the halves have equal
//! areas), the rest go to the second half, and a leaf's points are independent and
//! uniform over it. That is exactly the law of `n` independent uniform points
//! grouped by leaf (conditionally on a node's count, its points are independent
//! and uniform over it; Devroye, *Non-Uniform Random Variate Generation*, 1986,
//! Ch. XI, on sampling multinomial counts by conditional binomials). The estimators
//! are sums over rays, blind to their order, so their law is unchanged.
//!
//! Every random number comes from a counter-based stream: a tree node's split from
//! the stream of (seed, purpose, incident node, segment, tree node), ray `k`'s start
//! in its leaf, its turn and every bounce from the stream of (seed, purpose,
//! incident node, `k`). So any block of a segment is traced alone — on any thread,
//! in any process — with the same numbers, and the sums are folded in ray order.

use rand::RngCore;
use rand_distr::{Binomial, Distribution};

/// SplitMix64's increment: the odd integer nearest `2⁶⁴/φ` (Steele, Lea & Flood,
/// "Fast splittable pseudorandom number generators", OOPSLA 2014).
const GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

/// SplitMix64's output function (Stafford's "Mix13" variant of MurmurHash3's
/// 64-bit finaliser, as in Steele, Lea & Flood 2014): a bijection of `u64` whose
/// every output bit depends on every input bit.
#[inline]
fn mix64(z: u64) -> u64 {
    let z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    let z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A counter-based random stream: SplitMix64 (Steele, Lea & Flood 2014) started at
/// a hash of a key. Its `i`-th output is `mix64(h + (i + 1)·γ)`, a function of the
/// key and `i` alone. Two keys' streams are stretches of one Weyl sequence of
/// period 2⁶⁴ at hashed offsets; a ray draws tens of numbers, so that two of a
/// run's ≤ 10¹⁰ streams overlap at all has a probability of the order of
/// 10² · 10²⁰ / 2⁶⁴ ≈ 10⁻³ (and would only repeat a few draws).
#[derive(Clone, Debug)]
pub(crate) struct KeyRng {
    state: u64,
}

impl KeyRng {
    /// The stream of `key`: the words are chained through [`mix64`], a bijection
    /// at each step, so keys that differ in one word start different streams.
    #[inline]
    pub(crate) fn new(key: &[u64]) -> KeyRng {
        KeyRng::START.then(key)
    }

    /// The chain before any word.
    const START: KeyRng = KeyRng {
        state: 0x6a09_e667_f3bc_c909, // √2's fraction, an arbitrary start
    };

    /// The stream of this stream's key followed by `key` (`KeyRng::new(&[a, b])`
    /// is `KeyRng::new(&[a]).then(&[b])`): a shared prefix is chained once.
    #[inline]
    pub(crate) fn then(&self, key: &[u64]) -> KeyRng {
        let mut h = self.state;
        for &k in key {
            h = mix64(h.wrapping_add(GAMMA) ^ k);
        }
        KeyRng { state: h }
    }
}

impl RngCore for KeyRng {
    #[inline]
    fn next_u32(&mut self) -> u32 {
        (self.next_u64() >> 32) as u32
    }

    #[inline]
    fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GAMMA);
        mix64(self.state)
    }

    fn fill_bytes(&mut self, dst: &mut [u8]) {
        for chunk in dst.chunks_mut(8) {
            let b = self.next_u64().to_le_bytes();
            chunk.copy_from_slice(&b[..chunk.len()]);
        }
    }
}

/// A leaf holds at most this many rays: its rectangle then spans about
/// `LEAF / density` cells, a few hundred at a table's default density, whose data
/// fit in the first-level cache, so the order within a leaf does not matter.
const LEAF: u64 = 64;

/// No node is split below this depth (a guard: at `LEAF` rays a leaf is reached
/// some 15 levels down for a segment; 48 halvings leave rectangles of 2⁻²⁴ of the
/// patch's sides).
const MAX_DEPTH: u32 = 48;

/// An axis-aligned rectangle `[x0, x0 + w) × [y0, y0 + h)` of the plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Rect {
    pub x0: f64,
    pub y0: f64,
    pub w: f64,
    pub h: f64,
}

impl Rect {
    /// The two halves across the longer side (x on a tie), first the lower.
    fn halves(&self) -> (Rect, Rect) {
        if self.w >= self.h {
            let w = 0.5 * self.w;
            (
                Rect { w, ..*self },
                Rect {
                    x0: self.x0 + w,
                    w,
                    ..*self
                },
            )
        } else {
            let h = 0.5 * self.h;
            (
                Rect { h, ..*self },
                Rect {
                    y0: self.y0 + h,
                    h,
                    ..*self
                },
            )
        }
    }

    /// The point at fractions `(u, v)` of its sides.
    #[inline]
    pub(crate) fn at(&self, u: f64, v: f64) -> (f64, f64) {
        (self.x0 + u * self.w, self.y0 + v * self.h)
    }
}

/// The spatial order of one segment of `n` rays over `patch`: the leaf of every
/// ray of the segment, by its index in that order. `key` names the segment's
/// streams (seed, purpose, incident node, segment).
pub(crate) struct SegmentOrder {
    pub key: [u64; 4],
    pub n: u64,
    pub patch: Rect,
}

impl SegmentOrder {
    /// Calls `f(k, leaf)` for every index `k` in `range` (within `0..n`), in order:
    /// ray `k` starts uniformly in `leaf`. Only the tree nodes over `range` are
    /// drawn, so each block of a segment costs its own leaves and two root paths.
    pub(crate) fn visit(&self, range: std::ops::Range<u64>, f: &mut impl FnMut(u64, &Rect)) {
        self.node(1, 0, self.patch, 0, self.n, &range, f);
    }

    /// Node `id` (the root 1, children `2·id` and `2·id + 1`) at `depth`, over
    /// `rect`, holding the rays `first..first + n`.
    #[allow(clippy::too_many_arguments)]
    fn node(
        &self,
        id: u64,
        depth: u32,
        rect: Rect,
        first: u64,
        n: u64,
        range: &std::ops::Range<u64>,
        f: &mut impl FnMut(u64, &Rect),
    ) {
        let end = first + n;
        if n == 0 || end <= range.start || first >= range.end {
            return;
        }
        if n <= LEAF || depth >= MAX_DEPTH {
            for k in first.max(range.start)..end.min(range.end) {
                f(k, &rect);
            }
            return;
        }
        let [a, b, c, d] = self.key;
        let mut rng = KeyRng::new(&[a, b, c, d, id]);
        let left = match Binomial::new(n, 0.5) {
            Ok(bin) => bin.sample(&mut rng),
            // n > 0 and p = 1/2 are always valid; were they not, an even split is
            // still a split.
            Err(_) => n / 2,
        };
        let (r0, r1) = rect.halves();
        self.node(2 * id, depth + 1, r0, first, left, range, f);
        self.node(2 * id + 1, depth + 1, r1, first + left, n - left, range, f);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chained_prefix_is_the_whole_key() {
        let (a, b) = (
            KeyRng::new(&[7, 1, 3, 99]),
            KeyRng::new(&[7, 1, 3]).then(&[99]),
        );
        assert_eq!(a.state, b.state);
        assert_ne!(a.state, KeyRng::new(&[7, 1, 3, 98]).state);
    }

    fn order(n: u64) -> SegmentOrder {
        SegmentOrder {
            key: [1, 2, 3, 4],
            n,
            patch: Rect {
                x0: 0.0,
                y0: 0.0,
                w: 8.0,
                h: 4.0,
            },
        }
    }

    /// Every index once, in order, and the leaves the same whichever blocks ask.
    #[test]
    fn blocks_see_the_leaves_of_the_whole() {
        let o = order(5000);
        let mut whole = Vec::new();
        o.visit(0..5000, &mut |k, r| whole.push((k, *r)));
        assert_eq!(whole.len(), 5000);
        assert!(whole.iter().enumerate().all(|(i, (k, _))| i as u64 == *k));
        let mut parts = Vec::new();
        for b in 0..5 {
            o.visit(b * 1000..(b + 1) * 1000, &mut |k, r| parts.push((k, *r)));
        }
        assert_eq!(parts, whole);
    }

    /// The points are uniform over the patch: a χ² test over 8 × 4 unit squares
    /// (31 degrees of freedom; 70 is beyond its 0.9999 quantile, about 66).
    #[test]
    fn starts_are_uniform() {
        let n = 64_000u64;
        let o = order(n);
        let mut counts = [0u64; 32];
        o.visit(0..n, &mut |k, r| {
            let mut rng = KeyRng::new(&[9, k]);
            let (x, y) = r.at(
                crate::material::uniform(&mut rng),
                crate::material::uniform(&mut rng),
            );
            assert!((0.0..8.0).contains(&x) && (0.0..4.0).contains(&y));
            counts[(y as usize) * 8 + x as usize] += 1;
        });
        let e = n as f64 / 32.0;
        let chi2: f64 = counts.iter().map(|&c| (c as f64 - e).powi(2) / e).sum();
        assert!(chi2 < 70.0, "{chi2} {counts:?}");
    }

    /// The stream is SplitMix64: with state 0 its first outputs are the reference
    /// ones (Vigna's splitmix64.c, seeded with 0).
    #[test]
    fn splitmix_matches_the_reference() {
        let mut r = KeyRng { state: 0 };
        assert_eq!(r.next_u64(), 0xe220_a839_7b1d_cdaf);
        assert_eq!(r.next_u64(), 0x6e78_9e6a_a1b9_65f4);
        assert_eq!(r.next_u64(), 0x06c4_5d18_8009_454f);
    }
}
