//! Where to measure next: the scores an adaptive run chooses its next batch of
//! directions by, and the error of a reconstruction against a known BRDF, by which
//! the choice is judged.
//!
//! **The error.** A reconstruction f̂ (the nearest-j kernel of DeYoung Sec. 3.2.1 over
//! the samples) is compared with the truth f at the nodes of an outgoing hemisphere
//! grid (polar midpoints, a full turn of azimuth) at each measured incidence:
//!
//! E = √( Σ w (f̂ − f)² / Σ w f² ),  w = cos θo · sin θo (the node's projected solid
//! angle, up to the constant dθ dφ),
//!
//! summed over channels: the cosine-weighted relative RMS error, which weighs a node
//! by the share of reflected flux it carries.
//!
//! **The choice.** A measurement at a direction c improves the reconstruction over
//! about the region closer to c than to any measured sample, of area ≈ d(c)², d the
//! chord to the nearest sample; how much it improves it there is the local
//! uncertainty u(c). The expected drop of E's numerator is then
//! cos θo · u(c)² · d(c)² — raised to a higher power of d ([`gap_exponent`]) in
//! practice — and a batch takes the n candidates of highest score
//! greedily, each pick shrinking d (and so the score) of the candidates around it,
//! which spreads a batch over the regions that need it rather than stacking it on
//! one. Three estimates of u are offered ([`Aim`]):
//!
//! - **residual** (the default of plans): the kernel's leave-one-out residuals at
//!   the j nearest samples, f_k − f̂₋ₖ(x_k) (each sample predicted from its
//!   neighbours without it; its measurement variance taken off), kernel-weighted,
//!   with the same floor: a direct measure of the reconstruction's error at the
//!   samples' own spacing — small where the kernel already predicts well, however
//!   steep the BRDF, and large where a feature falls between samples;
//! - **variation**: the spread of the j nearest samples' values about the kernel's
//!   estimate at c (kernel-weighted, their own measurement variance taken off, so
//!   that noise is not chased), with a floor of [`FLOOR`] × f̂ so that no region is
//!   forgotten: where neighbours disagree, the reconstruction is uncertain;
//! - **value**: f̂ itself, a warp of the sampling density towards where the BRDF is
//!   large (Dupuy & Jakob 2018 warp by the microfacet distribution they learn).

use gonio_core::dirfile::PairDeg;
use gonio_core::{Dir, SphericalDeg};
use rayon::prelude::*;

use crate::ProcessError;
use crate::samples::{Interpolator, Kernel, Samples};

/// The share of the estimated value taken as the least uncertainty of a direction
/// (variation aim): what the kernel could miss between samples that agree.
pub const FLOOR: f64 = 0.05;

/// The power of the gap d in a candidate's score. Area alone (2) is what one point
/// covers; but u is itself measured by samples about a gap apart and grows with it
/// wherever the BRDF is resolved, so a higher power favours filling gaps over
/// crowding a feature already found. Chosen per aim over 2 to 8 on eleven samples
/// from Lambertian to n = 500 (BENCHMARKS.md, "Adaptive acquisition"): 3 for the
/// residuals (which already scale with the spacing squared), 5 for the others.
pub fn gap_exponent(aim: Aim) -> i32 {
    match aim {
        Aim::Residual => 3,
        Aim::Variation | Aim::Value => 5,
    }
}

/// What a batch looks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Aim {
    /// The kernel's leave-one-out residuals at the measured neighbours.
    Residual,
    /// Local disagreement of the measured neighbours.
    Variation,
    /// The reconstructed value.
    Value,
}

/// One direction chosen, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct Pick {
    /// Index in the candidates.
    pub candidate: usize,
    /// Its score when taken (the expected drop of E², unnormalised).
    pub score: f64,
    /// The reconstruction there, summed over channels, 1/sr.
    pub value: f64,
    /// The local uncertainty u, summed over channels in quadrature, 1/sr.
    pub uncertainty: f64,
    /// Angle to the nearest measured (or already chosen) direction, degrees.
    pub gap_deg: f64,
}

/// The per-candidate quantities a choice starts from.
#[derive(Clone, Copy, Debug)]
struct Base {
    /// cos θo · u².
    weight: f64,
    value: f64,
    uncertainty: f64,
    /// Chord to the nearest sample.
    gap: f64,
}

/// Chooses up to `n` of `candidates` to measure next (see the module docs); none
/// closer than `min_gap_deg` to a measured or chosen direction. Deterministic: ties
/// go to the lower index.
pub fn choose(
    samples: &Samples,
    candidates: &[PairDeg],
    n: usize,
    aim: Aim,
    min_gap_deg: f64,
) -> Result<Vec<Pick>, ProcessError> {
    let interp = samples.interpolator(Kernel::default())?;
    let keys: Vec<[f64; 6]> = candidates
        .iter()
        .map(|p| crate::samples::key_of(p, samples.isotropic))
        .collect();
    // Leave-one-out residuals², noise taken off, summed over channels.
    let residual2: Vec<f64> = if aim == Aim::Residual {
        (0..samples.samples.len())
            .into_par_iter()
            .map(|k| {
                let s = &samples.samples[k];
                interp.leave_one_out(k).map_or(0.0, |v| {
                    v.iter()
                        .zip(&s.value)
                        .enumerate()
                        .map(|(ch, (a, b))| {
                            let noise = s.sigma.as_ref().map_or(0.0, |sg| sg[ch] * sg[ch]);
                            ((a - b) * (a - b) - noise).max(0.0)
                        })
                        .sum()
                })
            })
            .collect()
    } else {
        Vec::new()
    };
    let base: Vec<Base> = candidates
        .par_iter()
        .map(|c| base_of(&interp, c, aim, &residual2))
        .collect();
    let chord = |deg: f64| 2.0 * (deg.to_radians() / 2.0).sin();
    let min_gap = chord(min_gap_deg);
    let q = gap_exponent(aim);
    let mut gap: Vec<f64> = base.iter().map(|b| b.gap).collect();
    let score = |i: usize, g: f64| {
        if g < min_gap {
            0.0
        } else {
            base[i].weight * g.powi(q)
        }
    };
    let mut scores: Vec<f64> = (0..candidates.len()).map(|i| score(i, gap[i])).collect();
    let mut picks = Vec::with_capacity(n.min(candidates.len()));
    while picks.len() < n {
        let mut best: Option<(usize, f64)> = None;
        for (i, &s) in scores.iter().enumerate() {
            if s > 0.0 && best.is_none_or(|(_, b)| s > b) {
                best = Some((i, s));
            }
        }
        let Some((k, s)) = best else { break };
        picks.push(Pick {
            candidate: k,
            score: s,
            value: base[k].value,
            uncertainty: base[k].uncertainty,
            gap_deg: 2.0 * (gap[k] / 2.0).min(1.0).asin().to_degrees(),
        });
        let kk = keys[k];
        for (i, key) in keys.iter().enumerate() {
            let d2: f64 = key.iter().zip(&kk).map(|(a, b)| (a - b) * (a - b)).sum();
            if d2 < gap[i] * gap[i] {
                gap[i] = d2.sqrt();
                scores[i] = score(i, gap[i]);
            }
        }
        scores[k] = 0.0;
    }
    Ok(picks)
}

/// A candidate's weight, value, uncertainty and gap.
fn base_of(interp: &Interpolator<'_>, c: &PairDeg, aim: Aim, residual2: &[f64]) -> Base {
    let n = interp.neighbours(c);
    let cos_o = Dir::from(c.outgoing).z.max(0.0);
    let value: f64 = n.estimate.iter().sum();
    let floor: f64 = n.estimate.iter().map(|f| (FLOOR * f).powi(2)).sum();
    let uncertainty = match aim {
        Aim::Residual => {
            let r2: f64 = n
                .members
                .iter()
                .map(|&(k, w)| w * residual2.get(k).copied().unwrap_or(0.0))
                .sum();
            (r2 + floor).sqrt()
        }
        Aim::Variation => {
            let spread: f64 = n
                .spread2
                .iter()
                .zip(&n.noise2)
                .map(|(s, e)| (s - e).max(0.0))
                .sum();
            (spread + floor).sqrt()
        }
        Aim::Value => value.abs(),
    };
    Base {
        weight: cos_o * uncertainty * uncertainty,
        value,
        uncertainty,
        gap: n.nearest,
    }
}

/// The cosine-weighted relative RMS error E (module docs) of the kernel
/// reconstruction from `samples` against `truth`, at each of `incidences`, on an
/// outgoing grid of `n_theta` polar midpoints × `n_phi` azimuths.
pub fn weighted_rms_error(
    samples: &Samples,
    truth: &dyn gonio_brdf::Brdf,
    incidences: &[SphericalDeg],
    n_theta: usize,
    n_phi: usize,
) -> Result<f64, ProcessError> {
    if n_theta == 0 || n_phi == 0 || incidences.is_empty() {
        return Err(ProcessError::Value(
            "the error needs incidences and a grid of at least one node".into(),
        ));
    }
    let interp = samples.interpolator(Kernel::default())?;
    let nc = truth.channels().len();
    if nc != samples.channels.len() {
        return Err(ProcessError::Shape(format!(
            "the truth has {nc} channels, the samples {}",
            samples.channels.len()
        )));
    }
    let nodes: Vec<(SphericalDeg, SphericalDeg)> = incidences
        .iter()
        .flat_map(|&inc| {
            (0..n_theta).flat_map(move |a| {
                (0..n_phi).map(move |b| {
                    let t = (a as f64 + 0.5) * 90.0 / n_theta as f64;
                    let p = b as f64 * 360.0 / n_phi as f64;
                    (inc, SphericalDeg::new(t, p))
                })
            })
        })
        .collect();
    // Each node's terms in parallel, summed in node order: a parallel reduction's
    // order (and so its last bits) depends on the thread count and the schedule.
    let terms: Vec<(f64, f64)> = nodes
        .par_iter()
        .map(|&(inc, out)| {
            let pair = PairDeg {
                incident: inc,
                outgoing: out,
            };
            let d = pair.to_dirs();
            let w = d.wo.z * (1.0 - d.wo.z * d.wo.z).max(0.0).sqrt();
            let mut f = vec![0.0; nc];
            truth.eval(d.wi, d.wo, &mut f);
            let (g, _) = interp.eval(&pair);
            let num: f64 = f.iter().zip(&g).map(|(a, b)| (a - b) * (a - b)).sum();
            let den: f64 = f.iter().map(|a| a * a).sum();
            (w * num, w * den)
        })
        .collect();
    let (num, den) = terms.iter().fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    if den <= 0.0 {
        return Err(ProcessError::Value(
            "the truth is zero at every node".into(),
        ));
    }
    Ok((num / den).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::samples::Sample;
    use gonio_core::Channels;

    fn lattice(n: usize) -> Vec<SphericalDeg> {
        SphericalDeg::fibonacci_hemisphere(n, 0.0)
    }

    fn samples_of(f: impl Fn(&PairDeg) -> f64, pairs: &[PairDeg]) -> Samples {
        Samples {
            channels: Channels::Single,
            samples: pairs
                .iter()
                .map(|p| Sample {
                    pair: *p,
                    value: vec![f(p)],
                    sigma: None,
                    flags: 0,
                })
                .collect(),
            isotropic: false,
        }
    }

    fn at(inc: f64, out: &[SphericalDeg]) -> Vec<PairDeg> {
        out.iter()
            .map(|o| PairDeg {
                incident: SphericalDeg::new(inc, 0.0),
                outgoing: *o,
            })
            .collect()
    }

    #[test]
    fn a_constant_is_reconstructed_exactly_and_a_batch_fills_the_largest_gaps() {
        let lambert = gonio_brdf::Model::from_toml(
            "kind = \"lambert\"\nchannels = [\"value\"]\nrho = [0.5]\n",
            None,
        )
        .expect("model");
        let measured = at(30.0, &lattice(200));
        let s = samples_of(|_| 0.5 / std::f64::consts::PI, &measured);
        let e = weighted_rms_error(&s, &lambert, &[SphericalDeg::new(30.0, 0.0)], 45, 180)
            .expect("error");
        assert!(e < 1e-12, "{e}");
        // A constant has no variation: the floor alone scores, by gap and cos θo.
        // The first pick is the candidate farthest from the samples, cosine-weighted.
        let cand = at(30.0, &lattice(5000));
        let picks = choose(&s, &cand, 10, Aim::Variation, 0.1).expect("picks");
        assert_eq!(picks.len(), 10);
        let best = cand
            .iter()
            .map(|c| {
                let d = c.to_dirs();
                let g = measured
                    .iter()
                    .map(|m| (m.to_dirs().wo.vec() - d.wo.vec()).norm())
                    .fold(f64::INFINITY, f64::min);
                d.wo.z * g * g
            })
            .enumerate()
            .fold((0, 0.0), |b, (i, v)| if v > b.1 { (i, v) } else { b });
        assert_eq!(picks[0].candidate, best.0);
        // Scores fall as the batch goes (greedy), and no two picks coincide.
        assert!(picks.windows(2).all(|w| w[0].score >= w[1].score));
        for (i, a) in picks.iter().enumerate() {
            for b in &picks[..i] {
                assert_ne!(a.candidate, b.candidate);
            }
        }
    }

    #[test]
    fn a_batch_goes_where_a_narrow_peak_is() {
        // A narrow Gaussian bump at (θo, φo) = (30°, 180°) on a small constant.
        let peak = Dir::from(SphericalDeg::new(30.0, 180.0));
        let f = |p: &PairDeg| {
            let d = Dir::from(p.outgoing);
            let c = d.vec().dot(peak.vec());
            0.1 + 50.0 * (-(1.0 - c) / (1.0 - 4f64.to_radians().cos())).exp()
        };
        let measured = at(30.0, &lattice(150));
        let s = samples_of(f, &measured);
        let cand = at(30.0, &lattice(8000));
        let picks = choose(&s, &cand, 40, Aim::Variation, 0.1).expect("picks");
        let near = picks
            .iter()
            .filter(|p| {
                let d = Dir::from(cand[p.candidate].outgoing);
                d.vec().dot(peak.vec()).acos().to_degrees() < 20.0
            })
            .count();
        // The 20° cap around the peak is 3% of the hemisphere; it gets most picks.
        assert!(near >= 30, "{near} of 40 near the peak");
    }
}
