//! Special functions the models need and `std` lacks.

use std::f64::consts::PI;
use std::sync::OnceLock;

/// The complementary error function `erfc(x) = 1 − erf(x)`, to a relative accuracy of
/// 4e-15 for all `x` (no cancellation in the tail, where it matters):
/// `1 − erf x` below 0.75 (erfc > 0.28 there, so little is lost), `e^{−x²} erfcx(x)`
/// above.
pub fn erfc(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x < 0.0 {
        return 2.0 - erfc(-x);
    }
    if x < SERIES_END {
        return 1.0 - erf_series(x);
    }
    (-x * x).exp() * erfcx(x)
}

/// The scaled complementary error function `erfcx(x) = e^{x²} erfc(x)`, which stays
/// representable where `erfc` underflows (≈ `1/(x√π)` for large `x`); relative
/// accuracy 4e-15.
///
/// Below 0.75 from the series; on [0.75, 4] from three 16-term Chebyshev expansions
/// whose coefficients are computed once, at first use, from the continued fraction
/// `erfcx x = 1/√π · 1/(x + (1/2)/(x + 1/(x + (3/2)/(x + …))))`
/// (Abramowitz & Stegun 7.1.14); above 4 from the continued fraction itself, which
/// converges there within 24 terms.
pub fn erfcx(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x < SERIES_END {
        return (x * x).exp() * erfc(x);
    }
    if x < CHEB_END {
        let i = CHEB_BREAKS[1..3].iter().filter(|b| x >= **b).count();
        return erfcx_pieces()[i].eval(x);
    }
    // Depth 24 is exact to the last bit from x = 4 on, 16 from x = 5 on.
    erfcx_continued_fraction(x, if x < 5.0 { 24 } else { 16 })
}

/// Where `erfc` switches from `1 − erf` to `e^{−x²} erfcx`.
const SERIES_END: f64 = 0.75;
/// Where `erfcx` switches from the Chebyshev expansion to the continued fraction.
const CHEB_END: f64 = 4.0;

/// The continued fraction for `erfcx`, evaluated from the bottom up at a fixed `depth`:
/// backward evaluation does not accumulate rounding as the forward (Lentz) product
/// does, and is accurate to the last bit for `x ≥ 0.75` at depth 500 and for `x ≥ 4`
/// at depth 24.
fn erfcx_continued_fraction(x: f64, depth: usize) -> f64 {
    let mut t = x;
    for k in (1..=depth).rev() {
        t = x + 0.5 * k as f64 / t;
    }
    1.0 / (PI.sqrt() * t)
}

/// A Chebyshev expansion on `[a, b]`.
struct Chebyshev {
    a: f64,
    b: f64,
    c: Vec<f64>,
}

impl Chebyshev {
    /// Interpolates `f` at the `n` Chebyshev nodes of `[a, b]`.
    fn fit(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> Self {
        let values: Vec<f64> = (0..n)
            .map(|j| {
                let t = (PI * (j as f64 + 0.5) / n as f64).cos();
                f(0.5 * (a + b) + 0.5 * (b - a) * t)
            })
            .collect();
        let c = (0..n)
            .map(|k| {
                let s: f64 = values
                    .iter()
                    .enumerate()
                    .map(|(j, v)| v * (PI * k as f64 * (j as f64 + 0.5) / n as f64).cos())
                    .sum();
                2.0 * s / n as f64
            })
            .collect();
        Chebyshev { a, b, c }
    }

    /// Clenshaw's recurrence.
    fn eval(&self, x: f64) -> f64 {
        let t = (2.0 * x - self.a - self.b) / (self.b - self.a);
        let (mut b1, mut b2) = (0.0, 0.0);
        for ck in self.c.iter().skip(1).rev() {
            let b0 = 2.0 * t * b1 - b2 + ck;
            b2 = b1;
            b1 = b0;
        }
        t * b1 - b2 + 0.5 * self.c[0]
    }
}

/// Where the three Chebyshev pieces of `erfcx` on [0.75, 4] meet.
const CHEB_BREAKS: [f64; 4] = [SERIES_END, 1.5, 2.5, CHEB_END];

fn erfcx_pieces() -> &'static [Chebyshev; 3] {
    static TABLE: OnceLock<[Chebyshev; 3]> = OnceLock::new();
    // erfcx is entire, so each expansion converges faster than geometrically: 16 of
    // 32 interpolation coefficients reach rounding level on pieces this short (fewer,
    // shorter pieces keep Clenshaw's rounding near the ends small).
    TABLE.get_or_init(|| {
        std::array::from_fn(|i| {
            let (a, b) = (CHEB_BREAKS[i], CHEB_BREAKS[i + 1]);
            let mut c = Chebyshev::fit(|x| erfcx_continued_fraction(x, 2000), a, b, 32);
            c.c.truncate(16);
            c
        })
    })
}

/// The error function: `|x| < 2` by the series
/// `erf x = (2/√π) e^{−x²} Σ 2ⁿ x^{2n+1} / (2n+1)!!`, whose terms are all positive;
/// beyond, `1 − erfc x`.
pub fn erf(x: f64) -> f64 {
    if x.abs() < 2.0 {
        erf_series(x)
    } else {
        1.0 - erfc(x)
    }
}

fn erf_series(x: f64) -> f64 {
    let x2 = x * x;
    let mut term = x;
    let mut sum = x;
    let mut n = 0.0;
    while term.abs() > 1e-17 * sum.abs() {
        n += 1.0;
        term *= 2.0 * x2 / (2.0 * n + 1.0);
        sum += term;
    }
    2.0 / PI.sqrt() * (-x2).exp() * sum
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference values from mpmath at 30 digits, kept as printed.
    #[test]
    fn matches_high_precision_values() {
        let cases = [
            (
                0.1,
                0.112462916018284898404712251014,
                0.887537083981715101595287748986,
            ),
            (
                0.5,
                0.520499877813046537682746653892,
                0.479500122186953462317253346108,
            ),
            (
                1.0,
                0.842700792949714869341220635083,
                0.157299207050285130658779364917,
            ),
            (
                1.9999,
                0.995320197907029391692092902482,
                0.00467980209297060830790709751806,
            ),
            (
                2.0,
                0.995322265018952734162069256367,
                0.00467773498104726583793074363275,
            ),
            (
                3.0,
                0.99997790950300141455862722387,
                0.0000220904969985854413727761295823,
            ),
            (
                5.0,
                0.99999999999846254020557196515,
                1.53745979442803485018834348538e-12,
            ),
            (10.0, 1.0, 2.08848758376254475700078629496e-45),
            (26.0, 1.0, 5.66319240885614284647572789693e-296),
        ];
        for (x, e, ec) in cases {
            assert!((erf(x) - e).abs() < 4e-16, "erf({x}) = {} vs {e}", erf(x));
            assert!(
                (erfc(x) - ec).abs() < 3e-15 * ec,
                "erfc({x}) = {} vs {ec}",
                erfc(x)
            );
            assert!((erf(-x) + e).abs() < 4e-16);
            assert!((erfc(-x) - (2.0 - ec)).abs() < 4e-16);
        }
    }

    /// erfcx across the three regimes, against mpmath's `erfc(x)·exp(x²)` at 30 digits.
    #[test]
    fn erfcx_matches_high_precision_values() {
        let cases = [
            (0.5, 0.615690344192925874870793422684),
            (0.75, 0.506937650293144805791431821539),
            (1.0, 0.427583576155807004410750344491),
            (2.5, 0.210806364061143580647112048407),
            (3.999, 0.137031848598271205260763404742),
            (4.0, 0.1369994576250613898894451714),
            (20.0, 0.0281743487410513193186491545345),
            (1e6, 5.6418958354747419215630599656e-7),
        ];
        for (x, want) in cases {
            let got = erfcx(x);
            assert!(
                (got - want).abs() < 4e-15 * want,
                "erfcx({x}) = {got} vs {want}"
            );
        }
        // The Chebyshev pieces are as good as the continued fraction they were fit to.
        for k in 0..=650 {
            let x = 0.75 + 3.25 * k as f64 / 650.0;
            let (a, b) = (erfcx(x), erfcx_continued_fraction(x, 2000));
            assert!((a - b).abs() < 4e-15 * b, "x={x}: {a} vs {b}");
        }
    }
}
