//! Adaptive Gauss–Kronrod quadrature in one and two dimensions.
//!
//! Every integral Gonio reports (directional albedo, expected counts of a sampling
//! test, the projected solid angle of an aperture that crosses the horizon) goes
//! through here. Both integrators are *globally* adaptive: they keep the pieces of the
//! domain in a heap ordered by their error estimate and split the worst one until the
//! summed error meets the tolerance, so effort goes where the integrand has kinks or
//! peaks. The error estimate of a piece is `|K15 − G7|`, the difference between the
//! 15-point Kronrod rule and its embedded 7-point Gauss rule: the error of the 7-point
//! rule, so a pessimistic bound for the 15-point value that is returned.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Kronrod 15-point abscissae on [-1, 1], non-negative half (QUADPACK `qk15`).
const XGK: [f64; 8] = [
    0.991_455_371_120_812_639_206_854_697_526_329,
    0.949_107_912_342_758_524_526_189_684_047_851,
    0.864_864_423_359_769_072_789_712_788_640_926,
    0.741_531_185_599_394_439_863_864_773_280_788,
    0.586_087_235_467_691_130_294_144_845_693_013,
    0.405_845_151_377_397_166_906_606_412_076_961,
    0.207_784_955_007_898_467_600_689_403_773_245,
    0.0,
];
/// Kronrod 15-point weights, matching [`XGK`].
const WGK: [f64; 8] = [
    0.022_935_322_010_529_224_963_732_008_058_970,
    0.063_092_092_629_978_553_290_700_663_189_204,
    0.104_790_010_322_250_183_839_876_322_541_518,
    0.140_653_259_715_525_918_745_189_590_510_238,
    0.169_004_726_639_267_902_826_583_426_598_550,
    0.190_350_578_064_785_409_913_256_402_421_014,
    0.204_432_940_075_298_892_414_161_999_234_649,
    0.209_482_141_084_727_828_012_999_174_891_714,
];
/// Gauss 7-point weights for the abscissae `XGK[1], XGK[3], XGK[5], XGK[7]`.
const WG: [f64; 4] = [
    0.129_484_966_168_869_693_270_611_432_679_082,
    0.279_705_391_489_276_667_901_467_771_423_780,
    0.381_830_050_505_118_944_950_369_775_488_975,
    0.417_959_183_673_469_387_755_102_040_816_327,
];

/// The 15 nodes on [-1, 1] in increasing order with Kronrod and Gauss weights (the
/// Gauss weight is zero on the 8 nodes that only the Kronrod rule uses).
fn rule15() -> [(f64, f64, f64); 15] {
    let mut r = [(0.0, 0.0, 0.0); 15];
    for k in 0..8 {
        let g = if k % 2 == 1 { WG[k / 2] } else { 0.0 };
        r[k] = (-XGK[k], WGK[k], g);
        r[14 - k] = (XGK[k], WGK[k], g);
    }
    r
}

/// When to stop refining.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerance {
    /// Absolute error goal.
    pub abs: f64,
    /// Relative error goal (of the largest channel for vector integrands).
    pub rel: f64,
    /// Give up after this many integrand evaluations (the result says it did not converge).
    pub max_evals: usize,
}

impl Tolerance {
    /// A tolerance with the given absolute and relative goals and a generous budget.
    pub fn new(abs: f64, rel: f64) -> Self {
        Tolerance {
            abs,
            rel,
            max_evals: 2_000_000,
        }
    }
}

/// A scalar integral with its error estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// The integral.
    pub value: f64,
    /// Estimated absolute error (a bound in practice, not a guarantee).
    pub error: f64,
    /// Integrand evaluations used.
    pub evals: usize,
    /// False when the evaluation budget ran out before the tolerance was met.
    pub converged: bool,
}

struct Piece1 {
    a: f64,
    b: f64,
    value: f64,
    error: f64,
}

impl PartialEq for Piece1 {
    fn eq(&self, o: &Self) -> bool {
        self.error == o.error
    }
}
impl Eq for Piece1 {}
impl PartialOrd for Piece1 {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Piece1 {
    fn cmp(&self, o: &Self) -> Ordering {
        self.error.total_cmp(&o.error)
    }
}

fn gk15<F: FnMut(f64) -> f64>(f: &mut F, a: f64, b: f64) -> (f64, f64) {
    let c = 0.5 * (a + b);
    let h = 0.5 * (b - a);
    let (mut k, mut g) = (0.0, 0.0);
    for (x, wk, wg) in rule15() {
        let y = f(c + h * x);
        k += wk * y;
        g += wg * y;
    }
    (k * h, ((k - g) * h).abs())
}

/// ∫ f over [a, b] by adaptive Gauss–Kronrod.
pub fn integrate<F: FnMut(f64) -> f64>(f: F, a: f64, b: f64, tol: Tolerance) -> Estimate {
    integrate_pieces(f, &[a, b], tol)
}

/// ∫ f over `[breaks[0], breaks.last()]`, starting from the pieces between consecutive
/// break points: put breaks where the integrand has kinks or singular derivatives so
/// that no rule straddles them. Breaks must be non-decreasing; empty pieces are skipped.
pub fn integrate_pieces<F: FnMut(f64) -> f64>(
    mut f: F,
    breaks: &[f64],
    tol: Tolerance,
) -> Estimate {
    let mut heap = BinaryHeap::new();
    let mut evals = 0;
    for w in breaks.windows(2) {
        if w[1] > w[0] {
            let (value, error) = gk15(&mut f, w[0], w[1]);
            evals += 15;
            heap.push(Piece1 {
                a: w[0],
                b: w[1],
                value,
                error,
            });
        }
    }
    loop {
        let value: f64 = heap.iter().map(|p| p.value).sum();
        let error: f64 = heap.iter().map(|p| p.error).sum();
        let goal = tol.abs.max(tol.rel * value.abs());
        let done = error <= goal;
        if done || evals >= tol.max_evals {
            return Estimate {
                value,
                error,
                evals,
                converged: done,
            };
        }
        let Some(worst) = heap.pop() else {
            return Estimate {
                value: 0.0,
                error: 0.0,
                evals,
                converged: true,
            };
        };
        let m = 0.5 * (worst.a + worst.b);
        if !(m > worst.a && m < worst.b) {
            // The piece cannot be split further in floating point: keep it as is.
            heap.push(Piece1 {
                error: 0.0,
                ..worst
            });
            continue;
        }
        for (a, b) in [(worst.a, m), (m, worst.b)] {
            let (value, error) = gk15(&mut f, a, b);
            heap.push(Piece1 { a, b, value, error });
        }
        evals += 30;
    }
}

/// A vector-valued integral with its per-component error estimates.
#[derive(Clone, Debug, PartialEq)]
pub struct VecEstimate {
    /// The integral of each component.
    pub values: Vec<f64>,
    /// Estimated absolute error of each component.
    pub errors: Vec<f64>,
    /// Integrand evaluations used.
    pub evals: usize,
    /// False when the evaluation budget ran out before the tolerance was met.
    pub converged: bool,
}

struct Piece2 {
    lo: [f64; 2],
    hi: [f64; 2],
    values: Vec<f64>,
    errors: Vec<f64>,
    /// Which axis to split next (the one whose refinement changes the estimate most).
    split_axis: usize,
    key: f64,
}

impl PartialEq for Piece2 {
    fn eq(&self, o: &Self) -> bool {
        self.key == o.key
    }
}
impl Eq for Piece2 {}
impl PartialOrd for Piece2 {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Piece2 {
    fn cmp(&self, o: &Self) -> Ordering {
        self.key.total_cmp(&o.key)
    }
}

/// Tensor-product G7–K15 on one rectangle: 225 evaluations.
fn gk15_2d<F: FnMut(f64, f64, &mut [f64])>(
    f: &mut F,
    lo: [f64; 2],
    hi: [f64; 2],
    m: usize,
    buf: &mut [f64],
) -> Piece2 {
    let r = rule15();
    let c = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
    let h = [0.5 * (hi[0] - lo[0]), 0.5 * (hi[1] - lo[1])];
    let area = h[0] * h[1];
    let mut kk = vec![0.0; m];
    let mut gg = vec![0.0; m];
    // Kronrod in one axis, Gauss in the other: tells which axis is under-resolved.
    let mut kg = vec![0.0; m];
    let mut gk = vec![0.0; m];
    for (x, wkx, wgx) in r {
        for (y, wky, wgy) in r {
            f(c[0] + h[0] * x, c[1] + h[1] * y, buf);
            for j in 0..m {
                let v = buf[j];
                kk[j] += wkx * wky * v;
                gg[j] += wgx * wgy * v;
                kg[j] += wkx * wgy * v;
                gk[j] += wgx * wky * v;
            }
        }
    }
    let values: Vec<f64> = kk.iter().map(|k| k * area).collect();
    let errors: Vec<f64> = kk
        .iter()
        .zip(&gg)
        .map(|(k, g)| ((k - g) * area).abs())
        .collect();
    // |K⊗K − G⊗K| measures the error along x, |K⊗K − K⊗G| along y.
    let ex: f64 = (0..m).map(|j| (kk[j] - gk[j]).abs()).sum();
    let ey: f64 = (0..m).map(|j| (kk[j] - kg[j]).abs()).sum();
    let key = errors.iter().cloned().fold(0.0, f64::max);
    Piece2 {
        lo,
        hi,
        values,
        errors,
        split_axis: if ex >= ey { 0 } else { 1 },
        key,
    }
}

/// ∫∫ f over the rectangle `[x0, x1] × [y0, y1]` for an integrand with `m` components,
/// which `f(x, y, out)` writes into `out[..m]`.
///
/// Adaptive tensor-product Gauss–Kronrod: the worst rectangle is halved along the axis
/// where the Kronrod and Gauss rules disagree most. The tolerance applies to every
/// component: stop when each component's error is within `max(abs, rel · max|value|)`.
pub fn integrate_2d<F: FnMut(f64, f64, &mut [f64])>(
    mut f: F,
    x: [f64; 2],
    y: [f64; 2],
    m: usize,
    tol: Tolerance,
) -> VecEstimate {
    let mut buf = vec![0.0; m];
    let mut heap = BinaryHeap::new();
    heap.push(gk15_2d(&mut f, [x[0], y[0]], [x[1], y[1]], m, &mut buf));
    let mut evals = 225;
    loop {
        let mut values = vec![0.0; m];
        let mut errors = vec![0.0; m];
        for p in heap.iter() {
            for j in 0..m {
                values[j] += p.values[j];
                errors[j] += p.errors[j];
            }
        }
        let scale = values.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let goal = tol.abs.max(tol.rel * scale);
        let done = errors.iter().all(|e| *e <= goal);
        if done || evals >= tol.max_evals {
            return VecEstimate {
                values,
                errors,
                evals,
                converged: done,
            };
        }
        let Some(worst) = heap.pop() else {
            return VecEstimate {
                values,
                errors,
                evals,
                converged: true,
            };
        };
        let ax = worst.split_axis;
        let mid = 0.5 * (worst.lo[ax] + worst.hi[ax]);
        if !(mid > worst.lo[ax] && mid < worst.hi[ax]) {
            heap.push(Piece2 {
                key: 0.0,
                errors: vec![0.0; m],
                ..worst
            });
            continue;
        }
        let mut hi_a = worst.hi;
        hi_a[ax] = mid;
        let mut lo_b = worst.lo;
        lo_b[ax] = mid;
        heap.push(gk15_2d(&mut f, worst.lo, hi_a, m, &mut buf));
        heap.push(gk15_2d(&mut f, lo_b, worst.hi, m, &mut buf));
        evals += 450;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn polynomials_up_to_degree_22_are_exact() {
        // The 15-point Kronrod extension of the 7-point Gauss rule is exact to degree 22.
        let (k, _) = gk15(&mut |x: f64| x.powi(22), -1.0, 1.0);
        assert!((k - 2.0 / 23.0).abs() < 1e-15);
        // …and the embedded 7-point Gauss rule to degree 13, so the error estimate
        // of a degree-13 polynomial vanishes.
        let (k, e) = gk15(&mut |x: f64| x.powi(12) + x.powi(13), -1.0, 1.0);
        assert!((k - 2.0 / 13.0).abs() < 1e-15 && e < 1e-15);
    }

    #[test]
    fn sqrt_endpoint_singularity_converges() {
        // ∫0^1 sqrt(1 - x²) dx = π/4, with a square-root singularity at 1.
        let e = integrate(
            |x| (1.0 - x * x).max(0.0).sqrt(),
            0.0,
            1.0,
            Tolerance::new(1e-13, 0.0),
        );
        assert!(e.converged);
        assert!((e.value - PI / 4.0).abs() < 1e-12, "{e:?}");
    }

    #[test]
    fn breaks_handle_kinks() {
        let e = integrate_pieces(
            |x| (x - 0.3).abs(),
            &[0.0, 0.3, 1.0],
            Tolerance::new(0.0, 1e-14),
        );
        assert!((e.value - (0.045 + 0.245)).abs() < 1e-15);
        assert_eq!(e.evals, 30);
    }

    #[test]
    fn cubature_of_a_sharp_peak() {
        // ∫∫ over the unit square of a narrow Gaussian at (0.3, 0.7): σ = 0.01.
        let s = 0.01;
        let e = integrate_2d(
            |x, y, out| {
                let r2 = (x - 0.3).powi(2) + (y - 0.7).powi(2);
                out[0] = (-r2 / (2.0 * s * s)).exp();
                out[1] = 1.0;
            },
            [0.0, 1.0],
            [0.0, 1.0],
            2,
            Tolerance::new(0.0, 1e-10),
        );
        assert!(e.converged);
        let exact = 2.0 * PI * s * s;
        assert!(
            (e.values[0] - exact).abs() < 1e-10 * exact.max(1.0),
            "{e:?}"
        );
        assert!((e.values[1] - 1.0).abs() < 1e-14);
    }

    #[test]
    fn cubature_with_a_kink_along_a_curve() {
        // ∫∫ max(0, 1 - x² - y²) over [0,1]² = ∫ over the quarter disc = π/8.
        let e = integrate_2d(
            |x, y, out| out[0] = (1.0 - x * x - y * y).max(0.0),
            [0.0, 1.0],
            [0.0, 1.0],
            1,
            Tolerance::new(1e-9, 0.0),
        );
        assert!(e.converged, "{e:?}");
        assert!((e.values[0] - PI / 8.0).abs() < 1e-9, "{e:?}");
    }
}
