//! The spherical-harmonic estimator: the symmetric coefficient matrix estimated
//! directly from rays, without a table in between.

use std::f64::consts::{PI, TAU};

use gonio_core::Dir;
use gonio_process::sh::{ShBrdf, basis, eval_basis, taper};

use super::{
    BLOCK, End, PURPOSE_SH, ShEstimate, Simulation, TraceStats, mean_and_error, run_ordered,
};
use crate::MicroError;
use crate::material::{Scratch, uniform};

impl Simulation {
    /// Estimates the symmetric spherical-harmonic matrix of the BRDF directly from
    /// rays (Westin et al. 1992, Sec. 3, Eq. 8–10), with the taper of their Sec. 2.5
    /// above `l_filter` (`None`: no taper).
    ///
    /// # Estimator
    /// In the hemisphere-even basis of [`gonio_process::sh`] the coefficients are
    /// `M_jk = 4 ∫_H ∫_H f_r(wi, wo) Y_j(wi) Y_k(wo) dωi dωo`. Each ray draws its own
    /// `wi` uniformly over the hemisphere (pdf `1/2π`) and a start point; its exit
    /// `(wo, e)` then has `E[e·g(wo)] = ∫ f_r cos θo g(wo) dωo` for any `g`: the pair
    /// (wi, wo) comes with density `f_r cos θo / 2π`. For a reciprocal surface the
    /// pair in the other order is as likely, so the ray stands for the symmetric
    /// density `f_r (cos θi + cos θo) / 4π`, and
    ///
    /// `M̂_jk = (1/N) Σ_rays 16π e · ½ (Y_j(wi) Y_k(wo) + Y_k(wi) Y_j(wo)) / (cos θi + cos θo)`
    ///
    /// (rays that do not leave contribute 0) is unbiased for M, symmetric by
    /// construction and exactly reciprocal in evaluation. Westin et al.'s
    /// `Y_k(V)/cos θr` weighting (`8π e … / cos θo`) is unbiased too, but its
    /// variance is infinite: `∫ f_r / cos θo dωo` diverges at the horizon, so its
    /// standard error was not a valid σ. Here the weight's square integrates to
    /// `∫∫ f_r cos θo / (cos θi + cos θo)² ≤ ∫∫ f_r / (cos θi + cos θo)`, which is
    /// finite (`∫₀¹∫₀¹ dμ dμ' / (μ + μ') = 2 ln 2`) for a bounded f_r: `sigma`, the
    /// standard error over the rays (before the taper), is an honest σ. The price
    /// is the assumption of reciprocity, which light transport through a
    /// microgeometry of reciprocal materials satisfies.
    pub fn estimate_sh(
        &self,
        l_max: usize,
        l_filter: Option<usize>,
        rays: usize,
        seed: u64,
    ) -> Result<ShEstimate, MicroError> {
        if l_max > gonio_process::sh::MAX_L_MAX {
            return Err(MicroError::invalid(
                "l_max",
                format!("must be at most {}", gonio_process::sh::MAX_L_MAX),
            ));
        }
        let l_filter = l_filter.unwrap_or(l_max);
        if l_filter > l_max {
            return Err(MicroError::invalid("l_filter", "must not exceed l_max"));
        }
        super::check_rays(rays)?;
        let nc = self.sample.channels.len();
        let bas = basis(l_max);
        let k = bas.len();
        let nt = k * (k + 1) / 2;
        let n_blocks = rays.div_ceil(BLOCK);
        let mut sum = vec![0.0; nc * nt];
        let mut sq = vec![0.0; nc * nt];
        let mut stats = TraceStats::default();
        run_ordered(
            n_blocks,
            self.cancel_flag(),
            |b| {
                let mut s = vec![0.0; nc * nt];
                let mut s2 = vec![0.0; nc * nt];
                let mut st = TraceStats::default();
                let mut w = vec![0.0; nc];
                let mut wt = vec![0.0; nc];
                let mut scratch = Scratch::new(nc);
                let (mut ya, mut yb) = (Vec::new(), Vec::new());
                for (o, mut rng) in self.block_rays(seed, PURPOSE_SH, 0, rays, b) {
                    // Uniform over the hemisphere: cos θ uniform in (0, 1].
                    let z = 1.0 - uniform(&mut rng);
                    let phi = TAU * uniform(&mut rng);
                    let wi = Dir::from_angles(z.acos(), phi);
                    let (end, order, d) = self.path(
                        o,
                        self.to_surface(wi.vec()),
                        None,
                        &mut rng,
                        &mut w,
                        &mut scratch,
                    );
                    self.count(&mut st, end, order, &w);
                    if end != End::Exit {
                        continue;
                    }
                    let wo = self.to_sample(d);
                    eval_basis(l_max, wi, &mut ya);
                    eval_basis(l_max, wo, &mut yb);
                    for (c, v) in wt.iter_mut().enumerate() {
                        *v = 16.0 * PI * w[c] / (wi.z + wo.z);
                    }
                    let mut p = 0;
                    for j in 0..k {
                        for kk in j..k {
                            let t = 0.5 * (ya[j] * yb[kk] + ya[kk] * yb[j]);
                            for c in 0..nc {
                                let x = wt[c] * t;
                                s[c * nt + p] += x;
                                s2[c * nt + p] += x * x;
                            }
                            p += 1;
                        }
                    }
                }
                (s, s2, st)
            },
            |_, (s, s2, st)| {
                sum.iter_mut().zip(&s).for_each(|(a, b)| *a += b);
                sq.iter_mut().zip(&s2).for_each(|(a, b)| *a += b);
                stats.merge(&st);
            },
        )?;
        let nr = rays as f64;
        let mut matrices = Vec::with_capacity(nc);
        let mut sigma = Vec::with_capacity(nc);
        for c in 0..nc {
            let mut m = vec![0.0; k * k];
            let mut e = vec![0.0; k * k];
            let mut p = 0;
            for j in 0..k {
                for kk in j..k {
                    let (mean, err) = mean_and_error(sum[c * nt + p], sq[c * nt + p], nr);
                    let t = taper(bas[j].0, l_filter, l_max) * taper(bas[kk].0, l_filter, l_max);
                    m[j * k + kk] = mean * t;
                    m[kk * k + j] = mean * t;
                    e[j * k + kk] = err;
                    e[kk * k + j] = err;
                    p += 1;
                }
            }
            matrices.push(m);
            sigma.push(e);
        }
        let sh = ShBrdf {
            channels: self.sample.channels.clone(),
            l_max,
            l_filter,
            basis: bas,
            matrices,
        };
        sh.validate()?;
        Ok(ShEstimate { sh, sigma, stats })
    }
}
