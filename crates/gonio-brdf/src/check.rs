//! Statistical checks of a model's sampler: a chi-square goodness-of-fit test of the
//! directions [`Brdf::sample`] draws against the density [`Brdf::pdf`] claims, as
//! renderers test their BSDF samplers.
//!
//! The hemisphere is cut into cells of equal solid angle (uniform in `cos θ` and `φ`).
//! Expected counts are the pdf integrated over each cell by adaptive cubature; cells
//! expecting fewer than `min_expected` samples are pooled; the statistic is compared to
//! the chi-square distribution. The same integrals give the pdf's total mass.

use std::f64::consts::TAU;

use gonio_core::Dir;
use gonio_core::quad::{Tolerance, integrate_2d};

use crate::{Brdf, IncidentSampler};

/// How to run a [`chi_square`] test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChiSquareConfig {
    /// Cells along `cos θ`.
    pub theta_cells: usize,
    /// Cells along `φ`.
    pub phi_cells: usize,
    /// Number of samples to draw.
    pub samples: usize,
    /// Cells expecting fewer samples than this are pooled.
    pub min_expected: f64,
}

impl Default for ChiSquareConfig {
    fn default() -> Self {
        ChiSquareConfig {
            theta_cells: 20,
            phi_cells: 40,
            samples: 200_000,
            min_expected: 5.0,
        }
    }
}

/// The outcome of a [`chi_square`] test.
#[derive(Clone, Debug, PartialEq)]
pub struct ChiSquareResult {
    /// The chi-square statistic over the (pooled) cells.
    pub statistic: f64,
    /// Degrees of freedom: pooled cells − 1.
    pub dof: usize,
    /// Probability of a statistic at least this large if the sampler matches the pdf.
    pub p_value: f64,
    /// ∫ pdf over the hemisphere (1 minus the probability of a mirror term), to the
    /// accuracy of the cell integrals (~1e-6: the folds of the pdf are kinks and steps
    /// the cubature chases).
    pub pdf_mass: f64,
    /// The probability of a mirror sample the sampler uses.
    pub mirror_probability: f64,
    /// Continuous samples drawn.
    pub continuous: usize,
    /// Delta (mirror) samples drawn.
    pub delta: usize,
    /// Calls that returned no sample.
    pub failed: usize,
    /// Samples whose reported pdf differed from [`Brdf::pdf`] by more than 1e-6 relative
    /// (can only happen for a model that overrides [`Brdf::sample`] or [`Brdf::pdf`]:
    /// the default implementations share one mixture).
    pub pdf_mismatches: usize,
}

/// Runs the test for incident direction `wi`, drawing uniform numbers in [0, 1) from
/// `uniform` (seed it for a reproducible test).
pub fn chi_square<B: Brdf + ?Sized>(
    brdf: &B,
    wi: Dir,
    cfg: &ChiSquareConfig,
    uniform: &mut dyn FnMut() -> f64,
) -> ChiSquareResult {
    let (nt, np) = (cfg.theta_cells, cfg.phi_cells);
    let mut observed = vec![0.0; nt * np];
    let (mut continuous, mut delta, mut failed, mut mismatches) = (0, 0, 0, 0);
    let sampler = IncidentSampler::new(brdf, wi);
    for i in 0..cfg.samples {
        let (uc, u0, u1) = (uniform(), uniform(), uniform());
        // The first draws go through the trait's own entry points as users call them.
        let drawn = if i < 1000 {
            brdf.sample(wi, uc, [u0, u1])
        } else {
            sampler.sample(uc, [u0, u1])
        };
        match drawn {
            None => failed += 1,
            Some(s) if s.delta => delta += 1,
            Some(s) => {
                continuous += 1;
                let p = if i < 1000 {
                    brdf.pdf(wi, s.wo)
                } else {
                    sampler.pdf(s.wo)
                };
                if (p - s.pdf).abs() > 1e-6 * p.max(s.pdf) {
                    mismatches += 1;
                }
                let it = ((s.wo.z * nt as f64) as usize).min(nt - 1);
                let ip = ((s.wo.phi() / TAU * np as f64) as usize).min(np - 1);
                observed[it * np + ip] += 1.0;
            }
        }
    }
    let mut expected = vec![0.0; nt * np];
    let n = cfg.samples as f64;
    for it in 0..nt {
        for ip in 0..np {
            let z = [it as f64 / nt as f64, (it + 1) as f64 / nt as f64];
            let p = [
                ip as f64 / np as f64 * TAU,
                (ip + 1) as f64 / np as f64 * TAU,
            ];
            let e = integrate_2d(
                |z, phi, out| {
                    let s = (1.0 - z * z).max(0.0).sqrt();
                    let (sp, cp) = phi.sin_cos();
                    out[0] = match Dir::new(gonio_core::Vec3::new(s * cp, s * sp, z)) {
                        Some(wo) => sampler.pdf(wo),
                        None => 0.0,
                    };
                },
                z,
                p,
                1,
                // An error of 1e-9 in a cell's probability is 2e-4 samples at 2e5 draws.
                Tolerance {
                    abs: 1e-9,
                    rel: 1e-7,
                    max_evals: 200_000,
                },
            );
            expected[it * np + ip] = e.values[0] * n;
        }
    }
    let pdf_mass = expected.iter().sum::<f64>() / n;
    let (statistic, dof) = pooled_statistic(&observed, &expected, cfg.min_expected);
    ChiSquareResult {
        statistic,
        dof,
        p_value: chi_square_sf(statistic, dof),
        pdf_mass,
        mirror_probability: sampler.mirror_probability(),
        continuous,
        delta,
        failed,
        pdf_mismatches: mismatches,
    }
}

/// The chi-square statistic after pooling cells that expect fewer than `min_expected`.
fn pooled_statistic(observed: &[f64], expected: &[f64], min_expected: f64) -> (f64, usize) {
    let mut idx: Vec<usize> = (0..expected.len()).collect();
    idx.sort_by(|a, b| expected[*a].total_cmp(&expected[*b]));
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    let mut stat = 0.0;
    let mut cells = 0;
    for i in idx {
        if expected[i] < min_expected || pool_e > 0.0 && pool_e < min_expected {
            pool_o += observed[i];
            pool_e += expected[i];
            continue;
        }
        stat += (observed[i] - expected[i]).powi(2) / expected[i];
        cells += 1;
    }
    if pool_e > 0.0 {
        stat += (pool_o - pool_e).powi(2) / pool_e;
        cells += 1;
    } else if pool_o > 0.0 {
        // Samples where the pdf says none can land: certain failure.
        return (f64::INFINITY, cells.max(1));
    }
    (stat, cells.saturating_sub(1).max(1))
}

/// The survival function `P(X ≥ x)` of the chi-square distribution with `dof` degrees
/// of freedom: the regularized upper incomplete gamma `Q(dof/2, x/2)`.
///
/// Series for `x < a + 1`, Lentz's continued fraction otherwise (the classical pair);
/// `ln Γ(a)` is exact by recursion because `a = dof/2` is a whole or half integer.
pub fn chi_square_sf(x: f64, dof: usize) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 1.0;
    }
    if x.is_infinite() {
        return 0.0;
    }
    let a = 0.5 * dof as f64;
    let y = 0.5 * x;
    let ln_pre = a * y.ln() - y - ln_gamma_half_integer(dof);
    if y < a + 1.0 {
        // P(a, y) = e^{−y} y^a / Γ(a+1) Σ y^k / ((a+1)…(a+k)).
        let (mut term, mut sum, mut ap) = (1.0 / a, 1.0 / a, a);
        for _ in 0..10_000 {
            ap += 1.0;
            term *= y / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-17 {
                break;
            }
        }
        (1.0 - sum * ln_pre.exp()).max(0.0)
    } else {
        let tiny = 1e-300;
        let mut b = y + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (ln_pre.exp() * h).min(1.0)
    }
}

/// `ln Γ(dof/2)`, exactly by `Γ(a+1) = a Γ(a)` from `Γ(1) = 1` or `Γ(1/2) = √π`.
fn ln_gamma_half_integer(dof: usize) -> f64 {
    let (mut a, mut acc) = if dof.is_multiple_of(2) {
        (1.0, 0.0)
    } else {
        (0.5, 0.5 * std::f64::consts::PI.ln())
    };
    let target = 0.5 * dof as f64;
    while a < target {
        acc += a.ln();
        a += 1.0;
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference values from mpmath's regularized incomplete gamma (20 digits).
    #[test]
    fn survival_function_matches_reference() {
        let cases = [
            (3.841458820694124, 1, 0.050000000000000057435),
            (18.307038053275146, 10, 0.050000000000000006706),
            (100.0, 80, 0.064570368921132975762),
            (1000.0, 1100, 0.98559027211008652829),
            (0.5, 3, 0.91889141165467585936),
            (50.0, 2, 1.3887943864964020595e-11),
        ];
        for (x, k, p) in cases {
            let got = chi_square_sf(x, k);
            assert!(
                (got - p).abs() < 1e-12 * p.max(1e-3),
                "sf({x}, {k}) = {got}, want {p}"
            );
        }
    }

    #[test]
    fn pooling_merges_small_cells() {
        // Two tiny cells pooled into one of expectation 6, against observed 6: no penalty.
        let (s, dof) = pooled_statistic(&[3.0, 3.0, 10.0, 20.0], &[3.0, 3.0, 10.0, 20.0], 5.0);
        assert_eq!(s, 0.0);
        assert_eq!(dof, 2);
        // A sample in a cell of zero expectation is an immediate failure.
        let (s, _) = pooled_statistic(&[1.0, 10.0], &[0.0, 10.0], 5.0);
        assert!(s.is_infinite() || s > 1e3);
    }
}
