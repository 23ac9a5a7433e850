//! The nearest-j kernel's interpolation error, estimated from the data and stated
//! apart from the noise.
//!
//! The kernel's value at a node is a weighted mean of its neighbours, so beside the
//! samples' noise it carries a bias: the BRDF's change between the neighbours and the
//! node. Two estimates of that error's square are taken from the samples themselves:
//!
//! - **Leave-one-out** (the neighbours' residuals): each distinct pair's samples are
//!   predicted by the kernel from the others; the squared residual less its noise
//!   variance is the kernel's squared error there. A node takes the kernel-weighted
//!   mean of its neighbours' values, each scaled by (h/h_k)⁴ (at most 1): the bias of
//!   a smoothing kernel goes as the square of its width, here the mean distance h of
//!   the node's j nearest samples against h_k of the leave-one-out prediction. It sees
//!   what the samples resolve (a peak their neighbours miss), but not the change
//!   along a sparse axis of a lattice between whose planes a node lies: a sample's
//!   nearest others lie along the dense axes.
//! - **Another order**: the kernel (a local constant) against a local linear fit at
//!   the node, over the nearest samples at 2j distinct pairs with Gaussian weights of
//!   the kernel's form, in the tangent coordinates of the incident and outgoing
//!   directions. Their difference, less its noise variance, is the part of the
//!   kernel's error a gradient explains, along any axis (and where the j nearest are
//!   all repeats of one pair). It is blind to curvature, which both share.
//!
//! Each is blind where the other sees, and their mean is the interpolation variance
//! (the one available when the other is not). A node on a sample is that sample: its
//! interpolation error is zero. Measured against analytic materials in
//! `tests/it/interpolation.rs` and in docs/processing.md.

use gonio_core::dirfile::PairDeg;
use rayon::prelude::*;
use serde::Serialize;

use super::{EXACT, Interpolator, combine, key};
use crate::Table;

/// The kernel's estimate at a pair with its two uncertainties, stated apart.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// The kernel's value per channel, 1/sr (as [`Interpolator::eval`]).
    pub value: Vec<f64>,
    /// The samples' noise through the kernel's weights, per channel, 1/sr; None when
    /// the samples have no uncertainties.
    pub noise: Option<Vec<f64>>,
    /// The interpolation's standard uncertainty per channel, 1/sr: zero on a sample.
    pub interpolation: Vec<f64>,
    /// Whether the pair is a sample's (an exact hit: nothing interpolated).
    pub exact: bool,
}

/// The kernel's interpolation error over a sample set, estimated from the data
/// ([`Interpolator::error_model`], module docs).
pub struct ErrorModel<'i, 'a> {
    interp: &'i Interpolator<'a>,
    /// Per sample and channel (`k * nc + ch`): the squared leave-one-out residual of
    /// the kernel at the sample's pair, less the noise's share of it (may be
    /// negative: an unbiased estimate).
    excess: Vec<f64>,
    /// Per sample: the mean distance of the samples in its pair's leave-one-out
    /// prediction (0 when it has none).
    loo_width: Vec<f64>,
}

/// A local linear fit's value at a point, as weights on the samples.
struct Fit {
    weights: Vec<(usize, f64)>,
}

/// A resampled table with the noise and the interpolation error of every node stated
/// apart ([`super::Samples::resample_detailed`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Resampled {
    /// The table; its σ (when the samples have σ) is the noise and the interpolation
    /// error in quadrature.
    pub table: Table,
    /// The kernel-propagated noise, the table's layout; None when the samples have
    /// no uncertainties (the table then has none either).
    pub noise: Option<Vec<f64>>,
    /// The interpolation's standard uncertainty, the table's layout: zero on a node
    /// that is a sample's.
    pub interpolation: Vec<f64>,
    /// Per node: whether it is a sample's pair (an exact hit).
    pub exact: Vec<bool>,
}

/// The account of a resampling: how many nodes were interpolated, and per channel the
/// interpolation error beside the noise ([`Resampled::report`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct InterpolationReport {
    /// The table's nodes.
    pub nodes: usize,
    /// The nodes interpolated.
    pub interpolated: usize,
    /// The nodes on a sample's pair (nothing interpolated: σ is the noise alone).
    pub exact: usize,
    /// Per channel.
    pub channels: Vec<ChannelInterpolation>,
}

/// One channel's interpolation error over a resampled table, relative to the values,
/// beside the noise ([`Resampled::report`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ChannelInterpolation {
    /// The channel's name.
    pub channel: String,
    /// Median over the interpolated nodes of σ_interpolation / |value|.
    pub rel_median: f64,
    /// Its largest value.
    pub rel_max: f64,
    /// Median over the same nodes of σ_noise / |value|; None when the noise is
    /// unknown.
    pub noise_rel_median: Option<f64>,
    /// Its largest value.
    pub noise_rel_max: Option<f64>,
}

impl Resampled {
    /// How many nodes are a sample's pair (nothing interpolated).
    pub fn exact_nodes(&self) -> usize {
        self.exact.iter().filter(|e| **e).count()
    }

    /// How many nodes were interpolated.
    pub fn interpolated_nodes(&self) -> usize {
        self.exact.len() - self.exact_nodes()
    }

    /// The node counts and, per channel, the relative interpolation error and noise
    /// over the interpolated nodes with a non-zero value (zeros when there are none).
    pub fn report(&self) -> InterpolationReport {
        InterpolationReport {
            nodes: self.exact.len(),
            interpolated: self.interpolated_nodes(),
            exact: self.exact_nodes(),
            channels: self.channels(),
        }
    }

    /// [`Resampled::report`]'s channels.
    fn channels(&self) -> Vec<ChannelInterpolation> {
        let n = self.table.grid.len();
        let names = self.table.channels.names();
        (0..self.table.channels.len())
            .map(|ch| {
                let rel = |s: &[f64]| -> (f64, f64) {
                    let mut r: Vec<f64> = (0..n)
                        .filter(|&i| !self.exact[i] && self.table.values[ch * n + i] != 0.0)
                        .map(|i| s[ch * n + i] / self.table.values[ch * n + i].abs())
                        .collect();
                    r.sort_by(f64::total_cmp);
                    let median = match r.len() {
                        0 => 0.0,
                        m if m % 2 == 1 => r[m / 2],
                        m => 0.5 * (r[m / 2 - 1] + r[m / 2]),
                    };
                    (median, r.last().copied().unwrap_or(0.0))
                };
                let (rel_median, rel_max) = rel(&self.interpolation);
                let noise = self.noise.as_deref().map(rel);
                ChannelInterpolation {
                    channel: names.get(ch).cloned().unwrap_or_default(),
                    rel_median,
                    rel_max,
                    noise_rel_median: noise.map(|x| x.0),
                    noise_rel_max: noise.map(|x| x.1),
                }
            })
            .collect()
    }
}

impl<'a> Interpolator<'a> {
    /// The interpolation error model of this kernel over its samples (module docs):
    /// each distinct pair's leave-one-out residual, computed once.
    pub fn error_model(&self) -> ErrorModel<'_, 'a> {
        let s = self.samples;
        let n = s.samples.len();
        let nc = s.channels.len();
        let keys = self.tree.points();
        // The samples at each distinct pair (a group), and each sample's group.
        let mut group = vec![usize::MAX; n];
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for k in 0..n {
            if group[k] != usize::MAX {
                continue;
            }
            let mut m = 16;
            loop {
                let near = self.tree.nearest(&keys[k], m);
                let at = near.iter().take_while(|(d2, _)| *d2 < EXACT).count();
                if at < near.len() || near.len() == n {
                    // k itself is among them; one already grouped stays where it is.
                    let members: Vec<usize> = near[..at]
                        .iter()
                        .map(|&(_, i)| i)
                        .filter(|&i| group[i] == usize::MAX)
                        .collect();
                    for &i in &members {
                        group[i] = groups.len();
                    }
                    groups.push(members);
                    break;
                }
                m *= 4;
            }
        }
        let sigma = |i: usize, ch: usize| s.samples[i].sigma.as_ref().map_or(0.0, |g| g[ch]);
        // Per group: its leave-one-out excess per channel and its prediction's width.
        let per_group: Vec<(Vec<f64>, f64)> = groups
            .par_iter()
            .enumerate()
            .map(|(g, members)| {
                let near = self
                    .tree
                    .nearest_where(&keys[members[0]], self.kernel.j, |i| group[i] != g);
                if near.is_empty() {
                    return (vec![0.0; nc], 0.0);
                }
                let (w, width) = self.gaussian(&near);
                let excess = (0..nc)
                    .map(|ch| {
                        let (y, vy) = combine(members.iter().map(|&i| {
                            let x = &s.samples[i];
                            (x.value[ch], x.sigma.as_ref().map(|g| g[ch]))
                        }));
                        let (mut pred, mut vp) = (0.0, 0.0);
                        for &(wi, i) in &w {
                            pred += wi * s.samples[i].value[ch];
                            vp += (wi * sigma(i, ch)).powi(2);
                        }
                        (y - pred).powi(2) - vy.unwrap_or(0.0).powi(2) - vp
                    })
                    .collect();
                (excess, width)
            })
            .collect();
        let mut excess = vec![0.0; n * nc];
        let mut loo_width = vec![0.0; n];
        for k in 0..n {
            let (e, width) = &per_group[group[k]];
            excess[k * nc..(k + 1) * nc].copy_from_slice(e);
            loo_width[k] = *width;
        }
        ErrorModel {
            interp: self,
            excess,
            loo_width,
        }
    }

    /// The kernel's normalised Gaussian weights over `near` (`(d², index)`), and the
    /// mean distance its width is a multiple of.
    fn gaussian(&self, near: &[(f64, usize)]) -> (Vec<(f64, usize)>, f64) {
        let mean_d = near.iter().map(|(d2, _)| d2.sqrt()).sum::<f64>() / near.len() as f64;
        let s2 = 2.0 * (self.kernel.width * mean_d).powi(2);
        let w: Vec<(f64, usize)> = near.iter().map(|&(d2, i)| ((-d2 / s2).exp(), i)).collect();
        let sw = w.iter().map(|x| x.0).sum::<f64>().max(f64::MIN_POSITIVE);
        (w.into_iter().map(|(x, i)| (x / sw, i)).collect(), mean_d)
    }

    /// The local linear fit at `q` over the nearest samples at 2j distinct pairs
    /// (`near` holds the nearest few as `(d², index)`; the tree is asked for more when
    /// they are too few), with the kernel's Gaussian weights, in the tangent
    /// coordinates of the incident and outgoing directions (a small ridge keeps a
    /// direction the samples do not span, such as φi of isotropic samples, at zero
    /// slope). None when the system is not positive definite.
    fn local_linear(&self, q: &[f64; 6], mut near: Vec<(f64, usize)>) -> Option<Fit> {
        let n = self.samples.samples.len();
        let keys = self.tree.points();
        let want = 2 * self.kernel.j;
        loop {
            // Repeats of a pair are neighbours in the distance order.
            let distinct = 1 + near
                .windows(2)
                .filter(|p| sq_dist(&keys[p[0].1], &keys[p[1].1]) >= EXACT)
                .count();
            if distinct >= want || near.len() >= n {
                break;
            }
            near = self.tree.nearest(q, (2 * near.len()).min(n));
        }
        let mean_d = near.iter().map(|(d2, _)| d2.sqrt()).sum::<f64>() / near.len() as f64;
        let s2 = 2.0 * (self.kernel.width * mean_d).powi(2);
        let [ti1, ti2] = tangents([q[0], q[1], q[2]]);
        let [to1, to2] = tangents([q[3], q[4], q[5]]);
        let dot = |a: &[f64], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let rows: Vec<([f64; 5], f64, usize)> = near
            .iter()
            .map(|&(d2, k)| {
                let p = &keys[k];
                let d: [f64; 6] = std::array::from_fn(|i| p[i] - q[i]);
                (
                    [
                        1.0,
                        dot(&d[..3], ti1),
                        dot(&d[..3], ti2),
                        dot(&d[3..], to1),
                        dot(&d[3..], to2),
                    ],
                    (-d2 / s2).exp(),
                    k,
                )
            })
            .collect();
        let mut a = [0.0; 25];
        for (x, w, _) in &rows {
            for i in 0..5 {
                for j in 0..5 {
                    a[i * 5 + j] += w * x[i] * x[j];
                }
            }
        }
        let ridge = 1e-6 * (1..5).map(|i| a[i * 5 + i]).sum::<f64>() + f64::MIN_POSITIVE;
        for i in 1..5 {
            a[i * 5 + i] += ridge;
        }
        // The fit's value at q is e₁ᵀ(XᵀWX)⁻¹XᵀW y: a weight per sample.
        let mut e1 = [1.0, 0.0, 0.0, 0.0, 0.0];
        if !cholesky_solve(&mut a, &mut e1) {
            return None;
        }
        Some(Fit {
            weights: rows
                .iter()
                .map(|(x, w, k)| (*k, w * (0..5).map(|i| e1[i] * x[i]).sum::<f64>()))
                .collect(),
        })
    }
}

impl ErrorModel<'_, '_> {
    /// The kernel's estimate at a pair with its noise and interpolation uncertainties
    /// (module docs).
    pub fn eval(&self, pair: &PairDeg) -> Estimate {
        let s = self.interp.samples;
        let nc = s.channels.len();
        let q = key(pair, s.isotropic);
        let j = self.interp.kernel.j;
        let near = self.interp.tree.nearest(&q, 3 * j);
        let (weights, exact, width) = self.interp.weights_of(&near[..j.min(near.len())]);
        let sw: f64 = weights.iter().map(|w| w.0).sum();
        let mut value = vec![0.0; nc];
        let mut var = vec![0.0; nc];
        let mut loo = vec![0.0; nc];
        let mut known = true;
        let mut loo_known = false;
        for &(w, k) in &weights {
            let x = &s.samples[k];
            let w = w / sw;
            // A smoothing kernel's bias goes as its width squared.
            let scale = if self.loo_width[k] > 0.0 {
                loo_known = true;
                (width / self.loo_width[k]).min(1.0).powi(4)
            } else {
                0.0
            };
            for ch in 0..nc {
                value[ch] += w * x.value[ch];
                loo[ch] += w * scale * self.excess[k * nc + ch];
            }
            match &x.sigma {
                Some(g) => {
                    for ch in 0..nc {
                        var[ch] += (w * g[ch]).powi(2);
                    }
                }
                None => known = false,
            }
        }
        let noise = known.then(|| var.into_iter().map(f64::sqrt).collect());
        if exact {
            return Estimate {
                value,
                noise,
                interpolation: vec![0.0; nc],
                exact,
            };
        }
        let fit = self.interp.local_linear(&q, near);
        // The kernel less the fit, as weights on the samples (merged by index).
        let diff: Option<Vec<(usize, f64)>> = fit.map(|f| {
            let mut c: Vec<(usize, f64)> = weights.iter().map(|&(w, k)| (k, w / sw)).collect();
            c.extend(f.weights.iter().map(|&(k, l)| (k, -l)));
            c.sort_by_key(|x| x.0);
            let mut merged: Vec<(usize, f64)> = Vec::with_capacity(c.len());
            for (k, x) in c {
                match merged.last_mut() {
                    Some(last) if last.0 == k => last.1 += x,
                    _ => merged.push((k, x)),
                }
            }
            merged
        });
        let interpolation = (0..nc)
            .map(|ch| {
                let order = diff.as_ref().map(|c| {
                    let (mut d, mut v) = (0.0, 0.0);
                    for &(k, ck) in c {
                        d += ck * s.samples[k].value[ch];
                        if let Some(g) = &s.samples[k].sigma {
                            v += (ck * g[ch]).powi(2);
                        }
                    }
                    (d * d - v).max(0.0)
                });
                let loo = loo_known.then(|| loo[ch].max(0.0));
                match (loo, order) {
                    (Some(a), Some(b)) => (0.5 * (a + b)).sqrt(),
                    (Some(a), None) | (None, Some(a)) => a.sqrt(),
                    (None, None) => 0.0,
                }
            })
            .collect();
        Estimate {
            value,
            noise,
            interpolation,
            exact,
        }
    }
}

/// The squared distance between two R⁶ points.
fn sq_dist(a: &[f64; 6], b: &[f64; 6]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// Two orthonormal directions perpendicular to the unit vector `w`.
fn tangents(w: [f64; 3]) -> [[f64; 3]; 2] {
    let a = if w[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let d = a[0] * w[0] + a[1] * w[1] + a[2] * w[2];
    let t = [a[0] - d * w[0], a[1] - d * w[1], a[2] - d * w[2]];
    let norm = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
    let t = t.map(|x| x / norm);
    let u = [
        w[1] * t[2] - w[2] * t[1],
        w[2] * t[0] - w[0] * t[2],
        w[0] * t[1] - w[1] * t[0],
    ];
    [t, u]
}

/// Solves the symmetric positive definite 5 × 5 system `a x = b` (row-major) in
/// place by Cholesky; false when `a` is not positive definite.
fn cholesky_solve(a: &mut [f64; 25], b: &mut [f64; 5]) -> bool {
    const N: usize = 5;
    for j in 0..N {
        let mut d = a[j * N + j];
        for k in 0..j {
            d -= a[j * N + k] * a[j * N + k];
        }
        if !(d > 0.0 && d.is_finite()) {
            return false;
        }
        let d = d.sqrt();
        a[j * N + j] = d;
        for i in j + 1..N {
            let mut v = a[i * N + j];
            for k in 0..j {
                v -= a[i * N + k] * a[j * N + k];
            }
            a[i * N + j] = v / d;
        }
    }
    for i in 0..N {
        let mut v = b[i];
        for k in 0..i {
            v -= a[i * N + k] * b[k];
        }
        b[i] = v / a[i * N + i];
    }
    for i in (0..N).rev() {
        let mut v = b[i];
        for k in i + 1..N {
            v -= a[k * N + i] * b[k];
        }
        b[i] = v / a[i * N + i];
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_solves_a_known_system() {
        // A diagonally dominant symmetric matrix and a known solution.
        let mut a = [0.0; 25];
        for i in 0..5 {
            for j in 0..5 {
                a[i * 5 + j] = if i == j {
                    4.0
                } else {
                    1.0 / (1.0 + (i + j) as f64)
                };
            }
        }
        let x = [1.0, -2.0, 0.5, 3.0, -1.0];
        let mut b = [0.0; 5];
        for i in 0..5 {
            b[i] = (0..5).map(|j| a[i * 5 + j] * x[j]).sum();
        }
        let mut f = a;
        assert!(cholesky_solve(&mut f, &mut b));
        for i in 0..5 {
            assert!((b[i] - x[i]).abs() < 1e-12, "{b:?}");
        }
        let mut singular = [0.0; 25];
        assert!(!cholesky_solve(&mut singular, &mut [1.0; 5]));
    }

    #[test]
    fn tangents_are_orthonormal_and_perpendicular() {
        for w in [
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            [0.6, 0.0, 0.8],
            [0.36, 0.48, 0.8],
        ] {
            let [t, u] = tangents(w);
            let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
            for (a, b, want) in [
                (t, t, 1.0),
                (u, u, 1.0),
                (t, u, 0.0),
                (t, w, 0.0),
                (u, w, 0.0),
            ] {
                assert!((dot(a, b) - want).abs() < 1e-12, "{w:?}");
            }
        }
    }
}
