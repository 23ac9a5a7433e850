//! Scattered BRDF samples (DeYoung Eq. 3.2), their interpolation by the nearest-j
//! Gaussian kernel of Sec. 3.2.1, resampling onto grids, and recognising samples
//! that already lie on a uniform grid.
//!
//! **Uncertainty.** A resampled value's σ is the samples' noise through the kernel's
//! weights and the interpolation's own error, estimated from the data
//! ([`ErrorModel`]), in quadrature; [`Samples::resample_detailed`] states the two
//! apart ([`Resampled`]).
//!
//! **Distance.** Two samples are compared as points of R⁶: the incident and outgoing
//! unit vectors side by side, d² = |ωi − ωi'|² + |ωo − ωo'|². It is DeYoung's "naive"
//! choice (Euclidean distance on the unit hemisphere), applied to both directions at
//! once; unlike angle differences it has no seam at φ = 0 and no singularity at the
//! pole. Isotropic samples are first turned about the normal so that φi = 0.

use std::collections::BTreeMap;

use gonio_core::dirfile::PairDeg;
use gonio_core::kdtree::{KdTree, SquaredEuclidean};
use gonio_core::{Channels, Dir, SphericalDeg};
use rayon::prelude::*;

use crate::{Axis, Grid, ProcessError, Table};

/// Samples per leaf of the interpolator's k-d tree.
const LEAF: usize = 12;

/// Squared R⁶ distance below which a query is on a sample (a repeat of its pair).
const EXACT: f64 = 1e-24;

mod interp_error;

pub use interp_error::{
    ChannelInterpolation, ErrorModel, Estimate, InterpolationReport, Resampled,
};

/// One sample: a pair of directions, a value per channel (1/sr), its standard
/// uncertainty where known, and flags.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    /// The directions, degrees, as measured or written.
    pub pair: PairDeg,
    /// One value per channel, 1/sr.
    pub value: Vec<f64>,
    /// One standard uncertainty per channel, 1/sr.
    pub sigma: Option<Vec<f64>>,
    /// Reading flags carried from the run (see `gonio_run::flags`).
    pub flags: u32,
}

/// A set of samples with their channels.
#[derive(Clone, Debug, PartialEq)]
pub struct Samples {
    /// The channels every sample has.
    pub channels: Channels,
    /// The samples.
    pub samples: Vec<Sample>,
    /// Whether the samples describe an isotropic material (φi may be taken as 0).
    pub isotropic: bool,
}

/// Options of the nearest-j Gaussian kernel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kernel {
    /// How many nearest samples take part (DeYoung's j).
    pub j: usize,
    /// The Gaussian's standard deviation as a multiple of the mean distance of the j
    /// samples from the query point ("on the order of the mean distance", Sec. 3.2.1).
    pub width: f64,
}

impl Default for Kernel {
    fn default() -> Self {
        Kernel { j: 8, width: 1.0 }
    }
}

impl Samples {
    /// Checks that every sample has one value (and uncertainty) per channel, finite
    /// values, and directions in the upper hemisphere.
    pub fn validate(&self) -> Result<(), ProcessError> {
        let nc = self.channels.len();
        if self.samples.is_empty() {
            return Err(ProcessError::Unsupported("no samples".into()));
        }
        for (i, s) in self.samples.iter().enumerate() {
            if s.value.len() != nc || s.sigma.as_ref().is_some_and(|v| v.len() != nc) {
                return Err(ProcessError::Shape(format!(
                    "sample {i} has {} values for {nc} channels",
                    s.value.len()
                )));
            }
            if s.value.iter().any(|v| !v.is_finite()) {
                return Err(ProcessError::Value(format!(
                    "sample {i} has a non-finite value"
                )));
            }
            if s.sigma
                .as_ref()
                .is_some_and(|v| v.iter().any(|x| !(x.is_finite() && *x >= 0.0)))
            {
                return Err(ProcessError::Value(format!(
                    "sample {i} has an uncertainty that is not a finite non-negative number"
                )));
            }
            let p = &s.pair;
            let th = [p.incident.theta_deg, p.outgoing.theta_deg];
            if th.iter().any(|t| !(0.0..=90.0).contains(t))
                || !p.incident.phi_deg.is_finite()
                || !p.outgoing.phi_deg.is_finite()
            {
                return Err(ProcessError::Value(format!(
                    "sample {i} has directions outside the upper hemisphere"
                )));
            }
        }
        Ok(())
    }

    /// Tabulates a BRDF at the given pairs (no uncertainties).
    pub fn from_brdf(brdf: &dyn gonio_brdf::Brdf, pairs: &[PairDeg]) -> Samples {
        let nc = brdf.channels().len();
        let samples = pairs
            .iter()
            .map(|p| {
                let d = p.to_dirs();
                let mut v = vec![0.0; nc];
                brdf.eval(d.wi, d.wo, &mut v);
                Sample {
                    pair: *p,
                    value: v,
                    sigma: None,
                    flags: 0,
                }
            })
            .collect();
        Samples {
            channels: brdf.channels().clone(),
            samples,
            isotropic: false,
        }
    }

    /// An interpolator over these samples.
    pub fn interpolator(&self, kernel: Kernel) -> Result<Interpolator<'_>, ProcessError> {
        self.validate()?;
        if kernel.j == 0 || !(kernel.width > 0.0 && kernel.width.is_finite()) {
            return Err(ProcessError::Value(
                "the kernel needs j ≥ 1 and a positive width".into(),
            ));
        }
        let pts = self
            .samples
            .iter()
            .map(|s| key(&s.pair, self.isotropic))
            .collect();
        Ok(Interpolator {
            samples: self,
            tree: KdTree::with_leaf_size(pts, SquaredEuclidean, LEAF),
            kernel,
        })
    }

    /// Resamples onto a grid with the nearest-j kernel: every node gets a value and,
    /// when the samples have uncertainties, an uncertainty: the kernel-propagated
    /// noise and the interpolation's own error ([`Resampled`]) in quadrature.
    ///
    /// Refused when the samples do not cover the grid: a node farther from every
    /// sample than twice the grid's polar spacing (in the R⁶ distance, for incidence
    /// and exitance together) would be invented, not interpolated — an in-plane scan
    /// cannot be resampled onto a hemisphere.
    pub fn resample(&self, grid: Grid, kernel: Kernel) -> Result<Table, ProcessError> {
        Ok(self.resample_detailed(grid, kernel)?.table)
    }

    /// [`Samples::resample`], with the noise and the interpolation error of every
    /// node stated apart.
    pub fn resample_detailed(&self, grid: Grid, kernel: Kernel) -> Result<Resampled, ProcessError> {
        grid.validate()?;
        let interp = self.interpolator(kernel)?;
        let nc = self.channels.len();
        let n = grid.len();
        let spacing = |a: &Axis| if a.n > 1 { a.step } else { 0.0 };
        let limit = 2.0
            * spacing(&grid.theta_i)
                .hypot(spacing(&grid.theta_o))
                .max(1e-6);
        let pair_of = |i: usize| {
            let [pi, ti, po, to] = grid.angles(i);
            PairDeg {
                incident: SphericalDeg::new(ti.to_degrees(), pi.to_degrees()),
                outgoing: SphericalDeg::new(to.to_degrees(), po.to_degrees()),
            }
        };
        // Coverage first: a refusal costs no interpolation.
        let far = (0..n)
            .into_par_iter()
            .filter(|&i| interp.nearest_distance(&pair_of(i)) > limit)
            .count();
        if far > 0 {
            return Err(ProcessError::Unsupported(format!(
                "the samples do not cover the grid: {far} of {n} nodes lie farther than \
                 {:.1}° from every sample",
                limit.to_degrees()
            )));
        }
        let model = interp.error_model();
        let rows: Vec<Estimate> = (0..n)
            .into_par_iter()
            .map(|i| model.eval(&pair_of(i)))
            .collect();
        let mut values = vec![0.0; n * nc];
        let mut interpolation = vec![0.0; n * nc];
        let has_noise = rows.iter().all(|r| r.noise.is_some());
        let mut noise = has_noise.then(|| vec![0.0; n * nc]);
        let mut sigma = has_noise.then(|| vec![0.0; n * nc]);
        let mut exact = vec![false; n];
        for (i, r) in rows.into_iter().enumerate() {
            exact[i] = r.exact;
            for ch in 0..nc {
                let at = ch * n + i;
                values[at] = r.value[ch];
                interpolation[at] = r.interpolation[ch];
                if let (Some(out), Some(tot), Some(s)) =
                    (noise.as_mut(), sigma.as_mut(), r.noise.as_ref())
                {
                    out[at] = s[ch];
                    tot[at] = s[ch].hypot(r.interpolation[ch]);
                }
            }
        }
        Ok(Resampled {
            table: Table::new(self.channels.clone(), grid, values, sigma)?,
            noise,
            interpolation,
            exact,
        })
    }

    /// Resamples onto the hemisphere grid of `step` ([`crate::GridStep::grid`]); where
    /// the samples do not cover its incidences — a run measures at a few incident
    /// directions, not over the whole hemisphere of them — onto `step`'s outgoing
    /// hemisphere at the incidences measured ([`Samples::incidence_grid`]), when
    /// those form uniform axes. The finest table such a run supports.
    pub fn resample_step(
        &self,
        step: crate::GridStep,
        kernel: Kernel,
    ) -> Result<Table, ProcessError> {
        Ok(self.resample_step_detailed(step, kernel)?.table)
    }

    /// [`Samples::resample_step`], with the noise and the interpolation error of
    /// every node stated apart.
    pub fn resample_step_detailed(
        &self,
        step: crate::GridStep,
        kernel: Kernel,
    ) -> Result<Resampled, ProcessError> {
        match self.resample_detailed(step.grid(), kernel) {
            Err(ProcessError::Unsupported(why)) => match self.incidence_grid(step) {
                Some(g) => {
                    tracing::debug!(
                        "the samples do not cover the hemisphere's incidences ({why}): \
                         resampled at the {} measured",
                        g.n_in()
                    );
                    self.resample_detailed(g, kernel)
                }
                None => Err(ProcessError::Unsupported(why)),
            },
            r => r,
        }
    }

    /// `step`'s outgoing hemisphere (polar band midpoints, a full turn of azimuth, or
    /// of φo − φi for isotropic samples) at the incident directions the samples were
    /// measured at, when their polar angles and azimuths each form a uniform axis (or
    /// a single value) and every combination was measured.
    pub fn incidence_grid(&self, step: crate::GridStep) -> Option<Grid> {
        self.validate().ok()?;
        let q = |x: f64| (x * 1e6).round() as i64;
        let mut incidences = std::collections::BTreeSet::new();
        let (mut thetas, mut phis) = (
            std::collections::BTreeSet::new(),
            std::collections::BTreeSet::new(),
        );
        for s in &self.samples {
            let t = q(s.pair.incident.theta_deg);
            let p = if self.isotropic {
                0
            } else {
                q(s.pair.incident.phi_deg.rem_euclid(360.0)) % 360_000_000
            };
            incidences.insert((t, p));
            thetas.insert(t);
            phis.insert(p);
        }
        if incidences.len() != thetas.len() * phis.len() {
            return None;
        }
        let axis = |v: &std::collections::BTreeSet<i64>| -> Option<Axis> {
            let v: Vec<i64> = v.iter().copied().collect();
            if v.len() == 1 {
                return Some(Axis::single((v[0] as f64 * 1e-6).to_radians()));
            }
            let d = v[1] - v[0];
            v.windows(2)
                .all(|w| w[1] - w[0] == d)
                .then(|| Axis::from_deg(v[0] as f64 * 1e-6, d as f64 * 1e-6, v.len()))
        };
        let (ti, pi) = (axis(&thetas)?, axis(&phis)?);
        let (to, po) = (
            Axis::polar_midpoints(step.n_theta()),
            Axis::full_turn(step.n_phi()),
        );
        let g = if self.isotropic {
            Grid::isotropic(ti, po, to)
        } else {
            Grid::full(pi, ti, po, to)
        };
        g.validate().ok()?;
        Some(g)
    }

    /// The table these samples form when they lie on a complete uniform grid (each
    /// node measured at least once; repeats combined by their inverse-variance mean,
    /// or the plain mean with the spread as uncertainty when none is known). None
    /// when they do not.
    pub fn to_table(&self) -> Option<Table> {
        self.validate().ok()?;
        // Angles keyed in micro-degrees: exact for any grid a plan or file writes.
        let q = |x: f64| (x * 1e6).round() as i64;
        let wrap = |x: f64| q(x.rem_euclid(360.0)) % 360_000_000;
        let mut keys = Vec::with_capacity(self.samples.len());
        let (mut pis, mut tis, mut pos, mut tos) = (
            BTreeMap::new(),
            BTreeMap::new(),
            BTreeMap::new(),
            BTreeMap::new(),
        );
        for s in &self.samples {
            let p = &s.pair;
            let (pi, po) = if self.isotropic {
                (0, wrap(p.outgoing.phi_deg - p.incident.phi_deg))
            } else {
                (wrap(p.incident.phi_deg), wrap(p.outgoing.phi_deg))
            };
            let k = [pi, q(p.incident.theta_deg), po, q(p.outgoing.theta_deg)];
            pis.insert(k[0], ());
            tis.insert(k[1], ());
            pos.insert(k[2], ());
            tos.insert(k[3], ());
            keys.push(k);
        }
        let axis = |m: &BTreeMap<i64, ()>| -> Option<(Axis, BTreeMap<i64, usize>)> {
            let v: Vec<i64> = m.keys().copied().collect();
            let idx = v.iter().enumerate().map(|(i, k)| (*k, i)).collect();
            Some((axis_of_keys(&v)?, idx))
        };
        let (api, ipi) = axis(&pis)?;
        let (ati, iti) = axis(&tis)?;
        let (apo, ipo) = axis(&pos)?;
        let (ato, ito) = axis(&tos)?;
        let grid = Grid {
            phi_i: api,
            theta_i: ati,
            phi_o: apo,
            theta_o: ato,
            isotropic: self.isotropic,
        };
        grid.validate().ok()?;
        let n = grid.len();
        if n > self.samples.len() {
            return None;
        }
        let nc = self.channels.len();
        let mut groups: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (s, k) in keys.iter().enumerate() {
            let i = grid.index(ipi[&k[0]], iti[&k[1]], ipo[&k[2]], ito[&k[3]]);
            groups[i].push(s);
        }
        if groups.iter().any(Vec::is_empty) {
            return None;
        }
        let mut values = vec![0.0; n * nc];
        let mut sigma = vec![0.0; n * nc];
        let mut any_sigma = false;
        for (i, g) in groups.iter().enumerate() {
            for ch in 0..nc {
                let (v, s) = combine(g.iter().map(|&k| {
                    let smp = &self.samples[k];
                    (smp.value[ch], smp.sigma.as_ref().map(|s| s[ch]))
                }));
                values[ch * n + i] = v;
                if let Some(s) = s {
                    sigma[ch * n + i] = s;
                    any_sigma = true;
                }
            }
        }
        Table::new(
            self.channels.clone(),
            grid,
            values,
            any_sigma.then_some(sigma),
        )
        .ok()
    }

    /// The samples of a table, one a node.
    pub fn from_table(t: &Table) -> Samples {
        let n = t.grid.len();
        let nc = t.channels.len();
        let samples = (0..n)
            .map(|i| {
                let [pi, ti, po, to] = t.grid.angles(i);
                Sample {
                    pair: PairDeg {
                        incident: SphericalDeg::new(ti.to_degrees(), pi.to_degrees()),
                        outgoing: SphericalDeg::new(to.to_degrees(), po.to_degrees()),
                    },
                    value: (0..nc).map(|ch| t.values[ch * n + i]).collect(),
                    sigma: t
                        .sigma
                        .as_ref()
                        .map(|s| (0..nc).map(|ch| s[ch * n + i]).collect()),
                    flags: 0,
                }
            })
            .collect();
        Samples {
            channels: t.channels.clone(),
            samples,
            isotropic: t.grid.isotropic,
        }
    }
}

/// The uniform axis of distinct angles keyed in micro-degrees, ascending (a single
/// node for one), or None when their steps differ: how [`Samples::to_table`] and the
/// column reader (`file::Columns`) recognise a grid, so that both give the same axes.
pub(crate) fn axis_of_keys(v: &[i64]) -> Option<Axis> {
    match v {
        [] => None,
        [only] => Some(Axis::single((*only as f64 * 1e-6).to_radians())),
        [a, b, ..] => {
            let step = b - a;
            if v.windows(2).any(|w| w[1] - w[0] != step) {
                return None;
            }
            Some(Axis::from_deg(
                *a as f64 * 1e-6,
                step as f64 * 1e-6,
                v.len(),
            ))
        }
    }
}

/// Combines repeated measurements of one value: the inverse-variance mean and its
/// uncertainty when every repeat has a positive uncertainty; else the plain mean with
/// the standard error of the spread (none for a single unqualified value).
fn combine(it: impl Iterator<Item = (f64, Option<f64>)>) -> (f64, Option<f64>) {
    let v: Vec<(f64, Option<f64>)> = it.collect();
    // One value is itself: 1/√(1/σ²) need not give σ back to the last bit.
    if let [only] = v[..] {
        return only;
    }
    if v.iter().all(|(_, s)| s.is_some_and(|s| s > 0.0)) {
        let (mut sw, mut swx) = (0.0, 0.0);
        for (x, s) in &v {
            let w = 1.0 / s.unwrap_or(1.0).powi(2);
            sw += w;
            swx += w * x;
        }
        return (swx / sw, Some(sw.sqrt().recip()));
    }
    let n = v.len() as f64;
    let mean = v.iter().map(|p| p.0).sum::<f64>() / n;
    if v.len() == 1 {
        return (mean, v[0].1);
    }
    let var = v.iter().map(|p| (p.0 - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, Some((var / n).sqrt()))
}

/// The R⁶ point of a pair (module docs), for the modules that search the same space.
pub(crate) fn key_of(p: &PairDeg, isotropic: bool) -> [f64; 6] {
    key(p, isotropic)
}

/// The R⁶ point of a pair (module docs).
fn key(p: &PairDeg, isotropic: bool) -> [f64; 6] {
    let (mut wi, mut wo) = (Dir::from(p.incident), Dir::from(p.outgoing));
    if isotropic {
        let turn = -p.incident.phi_deg.to_radians();
        wi = wi.rotate_about_normal(turn);
        wo = wo.rotate_about_normal(turn);
    }
    [wi.x, wi.y, wi.z, wo.x, wo.y, wo.z]
}

/// What the kernel sees around a pair ([`Interpolator::neighbours`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Neighbours {
    /// The kernel's estimate per channel, 1/sr.
    pub estimate: Vec<f64>,
    /// Kernel-weighted mean square deviation of the j nearest samples from the
    /// estimate, per channel, 1/sr².
    pub spread2: Vec<f64>,
    /// Kernel-weighted mean of their measurement variances, per channel, 1/sr².
    pub noise2: Vec<f64>,
    /// R⁶ distance to the nearest sample.
    pub nearest: f64,
    /// The samples taking part and their normalised kernel weights.
    pub members: Vec<(usize, f64)>,
}

/// The nearest-j Gaussian kernel over a sample set (DeYoung Sec. 3.2.1). The j
/// nearest samples are found with [`gonio_core::kdtree`]; samples at equal distance
/// are taken in the order of their index (a linear scan's answer).
pub struct Interpolator<'a> {
    samples: &'a Samples,
    tree: KdTree<6, SquaredEuclidean>,
    kernel: Kernel,
}

impl Interpolator<'_> {
    /// Values per channel at a pair, and their uncertainties when the samples have
    /// them: f = Σ w_k f_k / Σ w_k with w_k = exp(−d_k² / 2s²), s = width × mean d_k;
    /// σ² = Σ w_k² σ_k² / (Σ w_k)². A query on a sample returns it (repeats at the
    /// same pair averaged).
    pub fn eval(&self, pair: &PairDeg) -> (Vec<f64>, Option<Vec<f64>>) {
        let (weights, _, _) = self.weights(pair);
        let nc = self.samples.channels.len();
        let sw: f64 = weights.iter().map(|w| w.0).sum();
        let mut v = vec![0.0; nc];
        let mut var = vec![0.0; nc];
        let mut known = true;
        for &(w, k) in &weights {
            let s = &self.samples.samples[k];
            for (o, x) in v.iter_mut().zip(&s.value) {
                *o += w * x / sw;
            }
            match &s.sigma {
                Some(sg) => {
                    for ch in 0..nc {
                        var[ch] += (w * sg[ch] / sw).powi(2);
                    }
                }
                None => known = false,
            }
        }
        (v, known.then(|| var.into_iter().map(f64::sqrt).collect()))
    }

    /// The kernel's weights at a pair (not normalised) with the samples they weigh,
    /// whether the pair is a sample's (then only the samples at it take part, with
    /// equal weights), and the mean distance of the j nearest samples (the kernel's
    /// width is `width` times it).
    fn weights(&self, pair: &PairDeg) -> (Vec<(f64, usize)>, bool, f64) {
        let q = key(pair, self.samples.isotropic);
        self.weights_of(&self.tree.nearest(&q, self.kernel.j))
    }

    /// [`Interpolator::weights`] from the j nearest samples (`(d², index)`, nearest
    /// first).
    fn weights_of(&self, near: &[(f64, usize)]) -> (Vec<(f64, usize)>, bool, f64) {
        let mean_d = near.iter().map(|(d2, _)| d2.sqrt()).sum::<f64>() / near.len() as f64;
        let exact: Vec<&(f64, usize)> = near.iter().filter(|(d2, _)| *d2 < EXACT).collect();
        if exact.is_empty() {
            let s2 = 2.0 * (self.kernel.width * mean_d).powi(2);
            (
                near.iter().map(|&(d2, k)| ((-d2 / s2).exp(), k)).collect(),
                false,
                mean_d,
            )
        } else {
            (
                exact.iter().map(|&&(_, k)| (1.0, k)).collect(),
                true,
                mean_d,
            )
        }
    }

    /// The kernel's view of a pair: its estimate per channel, the kernel-weighted
    /// spread of the j nearest samples about it, their kernel-weighted measurement
    /// variance (zero where unknown), and the R⁶ distance to the nearest sample.
    pub fn neighbours(&self, pair: &PairDeg) -> Neighbours {
        let q = key(pair, self.samples.isotropic);
        let near = self.tree.nearest(&q, self.kernel.j);
        let nc = self.samples.channels.len();
        let nearest = near.first().map_or(f64::INFINITY, |(d2, _)| d2.sqrt());
        let mean_d = near.iter().map(|(d2, _)| d2.sqrt()).sum::<f64>() / near.len().max(1) as f64;
        let s2 = 2.0 * (self.kernel.width * mean_d).powi(2);
        let weights: Vec<(f64, usize)> = if s2 > 0.0 {
            near.iter().map(|&(d2, k)| ((-d2 / s2).exp(), k)).collect()
        } else {
            near.iter().map(|&(_, k)| (1.0, k)).collect()
        };
        let sw: f64 = weights
            .iter()
            .map(|w| w.0)
            .sum::<f64>()
            .max(f64::MIN_POSITIVE);
        let mut estimate = vec![0.0; nc];
        for &(w, k) in &weights {
            for (o, x) in estimate.iter_mut().zip(&self.samples.samples[k].value) {
                *o += w * x / sw;
            }
        }
        let mut spread2 = vec![0.0; nc];
        let mut noise2 = vec![0.0; nc];
        for &(w, k) in &weights {
            let s = &self.samples.samples[k];
            for ch in 0..nc {
                spread2[ch] += w * (s.value[ch] - estimate[ch]).powi(2) / sw;
                if let Some(sg) = &s.sigma {
                    noise2[ch] += w * sg[ch] * sg[ch] / sw;
                }
            }
        }
        Neighbours {
            estimate,
            spread2,
            noise2,
            nearest,
            members: weights.iter().map(|&(w, k)| (k, w / sw)).collect(),
        }
    }

    /// The kernel's estimate per channel at sample `k` from the others (every sample
    /// at `k`'s pair left out, so that a repeat does not answer for it): the
    /// leave-one-out prediction whose residual measures the reconstruction's error
    /// at the samples' own spacing. None when no other sample exists.
    pub fn leave_one_out(&self, k: usize) -> Option<Vec<f64>> {
        let s = self.samples.samples.get(k)?;
        let q = key(&s.pair, self.samples.isotropic);
        // The j nearest others: a few more asked for, in case of repeats.
        let near: Vec<(f64, usize)> = self
            .tree
            .nearest(&q, self.kernel.j + 4)
            .into_iter()
            .filter(|(d2, _)| *d2 >= EXACT)
            .take(self.kernel.j)
            .collect();
        if near.is_empty() {
            return None;
        }
        let mean_d = near.iter().map(|(d2, _)| d2.sqrt()).sum::<f64>() / near.len() as f64;
        let s2 = 2.0 * (self.kernel.width * mean_d).powi(2);
        let w: Vec<(f64, usize)> = near.iter().map(|&(d2, i)| ((-d2 / s2).exp(), i)).collect();
        let sw: f64 = w.iter().map(|x| x.0).sum::<f64>().max(f64::MIN_POSITIVE);
        let mut v = vec![0.0; self.samples.channels.len()];
        for &(wi, i) in &w {
            for (o, x) in v.iter_mut().zip(&self.samples.samples[i].value) {
                *o += wi * x / sw;
            }
        }
        Some(v)
    }

    /// The R⁶ distance from a pair to the nearest sample.
    pub fn nearest_distance(&self, pair: &PairDeg) -> f64 {
        let q = key(pair, self.samples.isotropic);
        self.tree
            .nearest(&q, 1)
            .first()
            .map_or(f64::INFINITY, |(d2, _)| d2.sqrt())
    }

    /// Channel values only, at a pair of directions.
    pub fn eval_dirs(&self, wi: Dir, wo: Dir) -> Vec<f64> {
        let pair = PairDeg {
            incident: SphericalDeg::from(wi),
            outgoing: SphericalDeg::from(wo),
        };
        self.eval(&pair).0
    }
}
