//! Spectra onto the 1 nm working grid: Sprague (1880) interpolation of uniform data
//! (the method CIE 167:2005 recommends for uniformly spaced spectral data; section
//! **UNCONFIRMED**), or linear interpolation; the end values beyond the data's ends.

use super::tables::{GRID_FIRST_NM, GRID_LEN, linear_at};

/// The Sprague coefficients of the two points added before the first sample (each
/// row applied to the first six samples, divided by 209), as CIE 167:2005 tabulates
/// them (table number **UNCONFIRMED**).
const SPRAGUE_BEFORE: [[f64; 6]; 2] = [
    [884.0, -1960.0, 3033.0, -2648.0, 1080.0, -180.0],
    [508.0, -540.0, 488.0, -367.0, 144.0, -24.0],
];
/// The two points added after the last sample, from the last six (÷ 209).
const SPRAGUE_AFTER: [[f64; 6]; 2] = [
    [-24.0, 144.0, -367.0, 488.0, -540.0, 508.0],
    [-180.0, 1080.0, -2648.0, 3033.0, -1960.0, 884.0],
];

/// Fewest uniform samples Sprague interpolation takes (the end extensions use six).
pub(crate) const SPRAGUE_MIN_POINTS: usize = 6;

/// Uniform samples `v` at `first + i·step` nm, extended by two Sprague points at each
/// end: `ext[i + 2]` is `v[i]`.
fn extended(v: &[f64]) -> Vec<f64> {
    let n = v.len();
    let dot = |c: &[f64; 6], s: &[f64]| c.iter().zip(s).map(|(a, b)| a * b).sum::<f64>() / 209.0;
    let (lo, hi) = (&v[..6], &v[n - 6..]);
    let mut e = Vec::with_capacity(n + 4);
    e.push(dot(&SPRAGUE_BEFORE[0], lo));
    e.push(dot(&SPRAGUE_BEFORE[1], lo));
    e.extend_from_slice(v);
    e.push(dot(&SPRAGUE_AFTER[0], hi));
    e.push(dot(&SPRAGUE_AFTER[1], hi));
    e
}

/// The quintic of the segment from sample `i` to `i + 1`, from the six extended points
/// `p = r[i−2..=i+3]`: `f(t) = a0 + a1 t + … + a5 t⁵`, `t ∈ [0, 1]`.
fn sprague_coefficients(p: &[f64]) -> [f64; 6] {
    [
        p[2],
        (2.0 * p[0] - 16.0 * p[1] + 16.0 * p[3] - 2.0 * p[4]) / 24.0,
        (-p[0] + 16.0 * p[1] - 30.0 * p[2] + 16.0 * p[3] - p[4]) / 24.0,
        (-9.0 * p[0] + 39.0 * p[1] - 70.0 * p[2] + 66.0 * p[3] - 33.0 * p[4] + 7.0 * p[5]) / 24.0,
        (13.0 * p[0] - 64.0 * p[1] + 126.0 * p[2] - 124.0 * p[3] + 61.0 * p[4] - 12.0 * p[5])
            / 24.0,
        (-5.0 * p[0] + 25.0 * p[1] - 50.0 * p[2] + 50.0 * p[3] - 25.0 * p[4] + 5.0 * p[5]) / 24.0,
    ]
}

/// How a spectrum is read between its samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Interpolation {
    /// Sprague (1880) fifth-order interpolation of uniform samples (CIE 167:2005's
    /// recommendation for uniformly spaced data). It passes through every sample and
    /// reproduces polynomials up to degree 4 away from the two end intervals.
    #[default]
    Sprague,
    /// Straight lines between samples.
    Linear,
}

/// Calls `f(grid_index, value)` for every point of the 1 nm grid 360–830 nm, with the
/// uniform samples `v` (at `first + i·step` nm) interpolated there and the end value
/// beyond the data's ends. `v` has at least [`SPRAGUE_MIN_POINTS`] points for
/// [`Interpolation::Sprague`], two for linear.
pub(crate) fn uniform_onto_grid(
    first: f64,
    step: f64,
    v: &[f64],
    how: Interpolation,
    mut f: impl FnMut(usize, f64),
) {
    let n = v.len();
    let last = first + step * (n - 1) as f64;
    let ext = match how {
        Interpolation::Sprague => extended(v),
        Interpolation::Linear => Vec::new(),
    };
    let inv = 1.0 / step;
    let mut g = 0;
    // Before the first sample: its value.
    while g < GRID_LEN && (GRID_FIRST_NM + g) as f64 <= first {
        f(g, v[0]);
        g += 1;
    }
    // Between the samples, a segment at a time: the grid points of segment i are those
    // with first + i·step ≤ λ < first + (i + 1)·step.
    while g < GRID_LEN && ((GRID_FIRST_NM + g) as f64) < last {
        let lambda = (GRID_FIRST_NM + g) as f64;
        // λ ∈ (first, last): the segment index is below n − 1.
        let i = (((lambda - first) * inv).floor() as usize).min(n - 2);
        let start = first + step * i as f64;
        let end = first + step * (i + 1) as f64;
        let a = match how {
            Interpolation::Sprague => sprague_coefficients(&ext[i..i + 6]),
            Interpolation::Linear => [v[i], v[i + 1] - v[i], 0.0, 0.0, 0.0, 0.0],
        };
        loop {
            let lambda = (GRID_FIRST_NM + g) as f64;
            let t = (lambda - start) * inv;
            f(
                g,
                a[0] + t * (a[1] + t * (a[2] + t * (a[3] + t * (a[4] + t * a[5])))),
            );
            g += 1;
            if g >= GRID_LEN {
                break;
            }
            let next = (GRID_FIRST_NM + g) as f64;
            if next >= end || next >= last {
                break;
            }
        }
    }
    // From the last sample on: its value.
    while g < GRID_LEN {
        f(g, v[n - 1]);
        g += 1;
    }
}

/// As [`uniform_onto_grid`] for samples at any strictly increasing wavelengths:
/// linear interpolation.
pub(crate) fn scattered_onto_grid(w: &[f64], v: &[f64], mut f: impl FnMut(usize, f64)) {
    for g in 0..GRID_LEN {
        f(g, linear_at(w, v, (GRID_FIRST_NM + g) as f64));
    }
}
