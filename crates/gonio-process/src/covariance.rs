//! The covariance of reduced samples: what is independent in each, and the errors
//! they share.
//!
//! A reduced sample's error is a sum of independent parts — its own noise and reply
//! rounding — and of errors shared with other samples: one dark vector subtracted
//! from every reading, one calibration scale, the drift references between which
//! its level is interpolated, the reference standard's certificate, a wavelength
//! scale. Each shared error is a standard normal draw `e_s` times a per-sample
//! coefficient `v_is` (1/sr, signed: a dark error moves a weak sample the other way
//! from the calibration), so for one channel
//!
//!   C = D + V Vᵀ,  D = diag(σ_ind,i²),  V_is = v_is,
//!
//! and the sample's stated σ² is `D_ii + Σ_s v_is²`. A user who knows the truth (a
//! simulated run, a standard) forms the full χ² = rᵀC⁻¹r by Woodbury's identity,
//! χ² = rᵀD⁻¹r − bᵀ(I + VᵀD⁻¹V)⁻¹b with b = VᵀD⁻¹r, which costs O(n k²) for k
//! shared sources; and the shift each shared source most likely took,
//! ê = (I + VᵀD⁻¹V)⁻¹b, in units of its own σ (it is a standard normal draw), says
//! which term moved the run.

use serde::{Deserialize, Serialize};

/// One shared error source: a standard normal draw that moves several samples.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Source {
    /// The budget term it belongs to (`dark`, `calibration`, `drift`, `standard`,
    /// `range accuracy`, `wavelength`).
    pub term: String,
    /// The channel it moves (its index in the samples' channels).
    pub channel: usize,
    /// What it is, e.g. `dark X`, `drift reference 3 (t = 812 s)`.
    pub label: String,
}

/// The covariance of a set of samples ([module docs](self)).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Covariance {
    /// Each row's directions, (θi, φi, θo, φo) in degrees: how a row finds its
    /// sample, or its node in a table of the samples' own grid.
    #[serde(default)]
    pub directions: Vec<[f64; 4]>,
    /// The shared sources.
    pub sources: Vec<Source>,
    /// Per sample, per channel: the independent standard uncertainty, 1/sr.
    pub independent: Vec<Vec<f64>>,
    /// Per sample: the coefficient of each source, 1/sr (0 for another channel's).
    pub coefficients: Vec<Vec<f64>>,
}

/// A comparison of samples with values known to be true, against the covariance.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Agreement {
    /// The channel.
    pub channel: usize,
    /// Samples compared.
    pub n: usize,
    /// χ²/n with each sample's own σ alone (correlations ignored).
    pub chi2_plain: f64,
    /// χ²/n against the full covariance, rᵀC⁻¹r/n.
    pub chi2_full: f64,
    /// The mean of the per-sample z = r/σ.
    pub mean_z: f64,
    /// The shared part of the samples' σ over the whole, root mean square over the
    /// samples: how far the mean z may wander (a run's mean z lies within a few times
    /// this of 0 when the shared terms are right).
    pub shared_fraction: f64,
    /// Each shared source's most likely shift given the residuals, in units of its
    /// own σ, largest first: (source index, shift).
    pub shifts: Vec<(usize, f64)>,
}

impl Covariance {
    /// The sample's total σ on `channel`: the independent part and every source's
    /// coefficient in quadrature.
    pub fn sigma(&self, sample: usize, channel: usize) -> f64 {
        let own = self.independent[sample][channel];
        self.sources
            .iter()
            .zip(&self.coefficients[sample])
            .filter(|(s, _)| s.channel == channel)
            .fold(own * own, |a, (_, v)| a + v * v)
            .sqrt()
    }

    /// The indices of `channel`'s sources.
    fn sources_of(&self, channel: usize) -> Vec<usize> {
        (0..self.sources.len())
            .filter(|&s| self.sources[s].channel == channel)
            .collect()
    }

    /// Compares `residuals` (value − truth per sample, on `channel`) with the
    /// covariance; `None` when a sample's independent σ is not positive (no D⁻¹).
    pub fn agreement(&self, channel: usize, residuals: &[f64]) -> Option<Agreement> {
        let n = residuals.len().min(self.independent.len());
        if n == 0 {
            return None;
        }
        let src = self.sources_of(channel);
        let k = src.len();
        // rᵀD⁻¹r, b = VᵀD⁻¹r and G = I + VᵀD⁻¹V.
        let (mut q, mut b, mut g) = (0.0, vec![0.0; k], vec![vec![0.0; k]; k]);
        let (mut plain, mut mean_z, mut shared2) = (0.0, 0.0, 0.0);
        for (i, &r) in residuals.iter().enumerate().take(n) {
            let d = self.independent[i][channel].powi(2);
            if d.is_nan() || d <= 0.0 {
                return None;
            }
            let v: Vec<f64> = src.iter().map(|&s| self.coefficients[i][s]).collect();
            let vv: f64 = v.iter().map(|x| x * x).sum();
            let total = d + vv;
            plain += r * r / total;
            mean_z += r / total.sqrt();
            shared2 += vv / total;
            q += r * r / d;
            for a in 0..k {
                b[a] += v[a] * r / d;
                for c in 0..k {
                    g[a][c] += v[a] * v[c] / d;
                }
            }
        }
        for (a, row) in g.iter_mut().enumerate() {
            row[a] += 1.0;
        }
        let e = solve_spd(g, &b)?;
        let chi2 = q - b.iter().zip(&e).map(|(b, e)| b * e).sum::<f64>();
        let mut shifts: Vec<(usize, f64)> = src.iter().copied().zip(e).collect();
        shifts.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
        let nf = n as f64;
        Some(Agreement {
            channel,
            n,
            chi2_plain: plain / nf,
            chi2_full: chi2 / nf,
            mean_z: mean_z / nf,
            shared_fraction: (shared2 / nf).sqrt(),
            shifts,
        })
    }

    /// The residuals on `channel` whitened by the full covariance: L⁻¹r with
    /// C = LLᵀ (Cholesky, in the samples' order), independent standard normals when
    /// the covariance is right. Dense, O(n³): for tables of a few hundred samples
    /// (the demo's); `None` when C is not positive definite.
    pub fn whiten(&self, channel: usize, residuals: &[f64]) -> Option<Vec<f64>> {
        let n = residuals.len().min(self.independent.len());
        let src = self.sources_of(channel);
        let c: Vec<Vec<f64>> = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| {
                        let shared: f64 = src
                            .iter()
                            .map(|&s| self.coefficients[i][s] * self.coefficients[j][s])
                            .sum();
                        let own = if i == j {
                            self.independent[i][channel].powi(2)
                        } else {
                            0.0
                        };
                        if j <= i { shared + own } else { 0.0 }
                    })
                    .collect()
            })
            .collect();
        let l = cholesky(c)?;
        // Forward substitution: L z = r.
        let mut z = vec![0.0; n];
        for i in 0..n {
            let s: f64 = (0..i).map(|j| l[i][j] * z[j]).sum();
            z[i] = (residuals[i] - s) / l[i][i];
        }
        Some(z)
    }
}

/// The lower Cholesky factor of a symmetric positive definite matrix given by its
/// lower triangle; `None` when it is not positive definite.
fn cholesky(mut a: Vec<Vec<f64>>) -> Option<Vec<Vec<f64>>> {
    let n = a.len();
    for j in 0..n {
        let d = a[j][j] - (0..j).map(|k| a[j][k] * a[j][k]).sum::<f64>();
        if d.is_nan() || d <= 0.0 {
            return None;
        }
        let d = d.sqrt();
        a[j][j] = d;
        for i in (j + 1)..n {
            let s = a[i][j] - (0..j).map(|k| a[i][k] * a[j][k]).sum::<f64>();
            a[i][j] = s / d;
        }
        for x in a[j].iter_mut().skip(j + 1) {
            *x = 0.0;
        }
    }
    Some(a)
}

/// Solves G x = b for a symmetric positive definite G (Cholesky).
fn solve_spd(g: Vec<Vec<f64>>, b: &[f64]) -> Option<Vec<f64>> {
    let n = b.len();
    let l = cholesky(g)?;
    let mut y = vec![0.0; n];
    for i in 0..n {
        let s: f64 = (0..i).map(|j| l[i][j] * y[j]).sum();
        y[i] = (b[i] - s) / l[i][i];
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let s: f64 = ((i + 1)..n).map(|j| l[j][i] * x[j]).sum();
        x[i] = (y[i] - s) / l[i][i];
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// n samples on one channel: independent σ 1 + i/n, one common source of
    /// coefficient 0.8 and one of alternating sign 0.5.
    fn two_sources(n: usize) -> Covariance {
        let src = |term: &str| Source {
            term: term.into(),
            channel: 0,
            label: term.into(),
        };
        Covariance {
            directions: Vec::new(),
            sources: vec![src("calibration"), src("dark")],
            independent: (0..n).map(|i| vec![1.0 + i as f64 / n as f64]).collect(),
            coefficients: (0..n)
                .map(|i| vec![0.8, if i % 2 == 0 { 0.5 } else { -0.5 }])
                .collect(),
        }
    }

    fn normal(rng: &mut rand_chacha::ChaCha8Rng) -> f64 {
        rng.sample(rand_distr::StandardNormal)
    }

    #[test]
    fn woodbury_equals_the_dense_inverse_and_whitening() {
        let c = two_sources(7);
        let r: Vec<f64> = (0..7).map(|i| (i as f64 * 0.7).sin() * 2.0).collect();
        let a = c.agreement(0, &r).expect("positive definite");
        // χ² from the whitened residuals: |L⁻¹r|² = rᵀC⁻¹r.
        let z = c.whiten(0, &r).expect("positive definite");
        let dense: f64 = z.iter().map(|x| x * x).sum::<f64>() / 7.0;
        assert!(
            (a.chi2_full - dense).abs() < 1e-12,
            "{} vs {dense}",
            a.chi2_full
        );
        // The plain χ² uses each total σ.
        let plain: f64 = r
            .iter()
            .enumerate()
            .map(|(i, r)| (r / c.sigma(i, 0)).powi(2))
            .sum::<f64>()
            / 7.0;
        assert!((a.chi2_plain - plain).abs() < 1e-12);
    }

    #[test]
    fn draws_from_the_model_give_chi2_near_one_and_find_the_shift() {
        let n = 400;
        let c = two_sources(n);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (mut full, mut plain) = (0.0, 0.0);
        let runs = 40;
        for _ in 0..runs {
            let e = [normal(&mut rng), normal(&mut rng)];
            let r: Vec<f64> = (0..n)
                .map(|i| {
                    c.independent[i][0] * normal(&mut rng)
                        + c.coefficients[i][0] * e[0]
                        + c.coefficients[i][1] * e[1]
                })
                .collect();
            let a = c.agreement(0, &r).expect("agreement");
            full += a.chi2_full;
            plain += a.chi2_plain;
            // With 400 samples each source's shift is pinned to about ±0.1 σ.
            for (s, shift) in &a.shifts {
                assert!((shift - e[*s]).abs() < 0.35, "{s}: {shift} vs {}", e[*s]);
            }
        }
        let (full, plain) = (full / runs as f64, plain / runs as f64);
        // rᵀC⁻¹r/n has mean 1 and, over 40 runs of 400, a standard error of 0.011.
        assert!((full - 1.0).abs() < 0.05, "{full}");
        assert!((plain - 1.0).abs() < 0.2, "{plain}");
    }

    #[test]
    fn a_shift_the_covariance_does_not_know_shows() {
        let n = 200;
        let c = two_sources(n);
        // A common offset of 3 (the known common source has σ 0.8: 3.75 σ).
        let r = vec![3.0; n];
        let a = c.agreement(0, &r).expect("agreement");
        assert_eq!(a.shifts[0].0, 0, "the calibration source moved the run");
        assert!(a.shifts[0].1 > 3.0, "{:?}", a.shifts);
        assert!(a.mean_z > 1.0);
    }

    #[test]
    fn nothing_positive_no_agreement() {
        let mut c = two_sources(3);
        c.independent[1][0] = 0.0;
        assert!(c.agreement(0, &[0.1, 0.2, 0.3]).is_none());
        assert!(Covariance::default().agreement(0, &[]).is_none());
    }
}
