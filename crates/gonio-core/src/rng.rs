//! SplitMix64: the one deterministic hash and counter-based generator Gonio uses where
//! it needs well-spread numbers without a random source (the simulator's fault draws,
//! the ordering's perturbation kicks, test and bench data).
//!
//! The algorithm and its constants are those of Steele, Lea & Flood, "Fast splittable
//! pseudorandom number generators", OOPSLA 2014, as published by Sebastiano Vigna in
//! `splitmix64.c` (the golden-ratio increment `0x9e3779b97f4a7c15` and the mixing
//! multipliers `0xbf58476d1ce4e5b9`, `0x94d049bb133111eb` with shifts 30, 27, 31).
//! Nothing here is cryptographic.
//!
//! ```
//! use gonio_core::rng::{SplitMix64, splitmix64};
//! let mut g = SplitMix64::new(7);
//! assert_eq!(g.next_u64(), splitmix64(7));
//! ```

/// SplitMix64's state increment: 2⁶⁴ divided by the golden ratio, rounded to odd.
pub const GOLDEN_GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

/// One step of SplitMix64 from `state`: the state advanced by [`GOLDEN_GAMMA`], then
/// mixed (a bijection of 64-bit words). As a hash of a counter `k`,
/// `splitmix64(k.wrapping_mul(GOLDEN_GAMMA))` is the (k + 1)-th output of the
/// generator seeded with 0.
#[inline]
pub fn splitmix64(state: u64) -> u64 {
    let mut z = state.wrapping_add(GOLDEN_GAMMA);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The SplitMix64 generator: a seeded, reproducible stream of 64-bit words.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// A generator whose first output is [`splitmix64`]`(seed)`.
    pub fn new(seed: u64) -> SplitMix64 {
        SplitMix64 { state: seed }
    }

    /// The next word of the stream.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        let z = splitmix64(self.state);
        self.state = self.state.wrapping_add(GOLDEN_GAMMA);
        z
    }

    /// A uniform number in the open interval (0, 1): the word's top 53 bits, centred
    /// in their cell, so that neither end occurs (a logarithm of it is finite).
    #[inline]
    pub fn next_open01(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// A standard normal number by the Box–Muller transform (Box & Muller, Ann. Math.
    /// Statist. 29, 1958), √(−2 ln u)·cos 2πv, of two uniforms; the sine branch is not
    /// kept.
    #[inline]
    pub fn next_normal(&mut self) -> f64 {
        let (u, v) = (self.next_open01(), self.next_open01());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_values() {
        // The first outputs of Vigna's splitmix64.c seeded with 0 and with 1234567.
        let mut g = SplitMix64::new(0);
        assert_eq!(g.next_u64(), 0xe220_a839_7b1d_cdaf);
        assert_eq!(g.next_u64(), 0x6e78_9e6a_a1b9_65f4);
        let mut g = SplitMix64::new(1_234_567);
        assert_eq!(g.next_u64(), 6_457_827_717_110_365_317);
        assert_eq!(g.next_u64(), 3_203_168_211_198_807_973);
    }

    #[test]
    fn normals_have_the_moments_of_a_standard_normal() {
        let mut g = SplitMix64::new(42);
        let n = 200_000;
        let v: Vec<f64> = (0..n).map(|_| g.next_normal()).collect();
        let mean = v.iter().sum::<f64>() / n as f64;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        let kurt = v.iter().map(|x| (x - mean).powi(4)).sum::<f64>() / n as f64 / (var * var);
        // Standard errors at n = 2e5: 0.0022 (mean), 0.0032 (variance), 0.011 (kurtosis).
        assert!(mean.abs() < 0.01, "{mean}");
        assert!((var - 1.0).abs() < 0.015, "{var}");
        assert!((kurt - 3.0).abs() < 0.05, "{kurt}");
        let below = v.iter().filter(|x| **x < -1.0).count() as f64 / n as f64;
        // Φ(−1) = 0.158655.
        assert!((below - 0.158_655).abs() < 0.004, "{below}");
    }

    #[test]
    fn counter_hash_is_the_stream() {
        let mut g = SplitMix64::new(0);
        for k in 0..100u64 {
            assert_eq!(splitmix64(k.wrapping_mul(GOLDEN_GAMMA)), g.next_u64());
        }
    }
}
