//! Real spherical harmonics with a symmetric coefficient matrix: a compact, smooth and
//! *exactly* reciprocal representation of a tabulated BRDF (Westin, Arvo & Torrance
//! 1992, Sec. 2.3–2.5).
//!
//! # Representation
//! Westin et al. Eq. 8 writes the BRDF as a bilinear form in two vectors of spherical
//! harmonics, `f_r(wi, wo) ≈ Σ_j Σ_k M_jk Y_j(wi) Y_k(wo) = Yᵀ(wi) M Y(wo)`. When `M`
//! is symmetric, `Yᵀ(wi) M Y(wo) = Yᵀ(wo) M Y(wi)` (their Eq. 10), so the approximation
//! obeys reciprocity (their Eq. 9) whatever the data. [`ShBrdf::eval`] reads only the
//! upper triangle of `M` and pairs the terms `M_jk (a_j b_k + a_k b_j)`, so swapping
//! `wi` and `wo` gives the same value to the last bit.
//!
//! # Basis
//! The real harmonics of DeYoung's thesis, Eq. 3.4–3.6, normalised to be orthonormal
//! over the sphere ([`eval_basis`]). A BRDF lives on the upper hemisphere only; like
//! Westin et al. (Sec. 2.5, after Sillion et al.) it is extended evenly to the lower
//! one, `f(θ) = f(π − θ)`. Since `Y_lm(π − θ, φ) = (−1)^(l+m) Y_lm(θ, φ)`, the
//! coefficients of every harmonic with `l + m` odd vanish, and the ones with `l + m`
//! even are orthogonal over the upper hemisphere with squared norm ½. The basis of
//! degree `l_max` therefore has `K = (l_max + 1)(l_max + 2)/2` functions ([`basis`]),
//! and the coefficient of a hemisphere function `g` is `2 ∫_H g Y dω`.
//!
//! # Projection
//! `M_jk = 4 ∫_H ∫_H f(wi, wo) Y_j(wi) Y_k(wo) dωi dωo`, by a product rule on each
//! hemisphere: Gauss–Legendre in `cos θ` on [0, 1] times the uniform rule in φ. With
//! `n` polar nodes (`n ≥ l_max + 1`) and `2n` azimuths the rule integrates every
//! product of two basis functions exactly, so a BRDF that is a finite combination of
//! basis products of degree ≤ `l_max` is reproduced to rounding. With `Q` directions
//! and weights `W`, `M = 4 Bᵀ F B` where `B = W Y` (Q × K) and `F_ab = f(w_a, w_b)`;
//! `F` is evaluated in parallel in blocks of rows and multiplied with faer. `M` is then
//! replaced by `(M + Mᵀ)/2`, which is exactly the projection of the reciprocal part
//! `(f(wi, wo) + f(wo, wi))/2` of the input.
//!
//! # Filtering
//! Truncating at `l_max` rings near sharp lobes (the Gibbs phenomenon); Westin et al.
//! progressively attenuate the coefficients with `l_filter < l ≤ l_max`. Here the
//! attenuation is the cosine (Hann) taper [`taper`]: 1 up to `l_filter`, then
//! `½ (1 + cos(π (l − l_filter)/(l_max − l_filter + 1)))`, which would reach 0 at
//! `l_max + 1`. `M_jk` is multiplied by `taper(l_j) taper(l_k)`, which keeps it
//! symmetric. Without `l_filter` nothing is attenuated.
//!
//! # File
//! [`ShBrdf::to_toml`] and [`ShBrdf::from_toml`]: `kind = "spherical-harmonics"`,
//! `channels`, `l_max`, `l_filter`, and one `[[matrices]]` table a channel with the
//! upper triangle of its (already filtered) `M`, row by row, in [`basis`] order.

use std::f64::consts::{FRAC_1_SQRT_2, PI, TAU};
use std::fmt::Write as _;

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use gonio_core::{Channels, Dir, Vec3};
use rayon::prelude::*;
use serde::Deserialize;

use crate::ProcessError;
use crate::grid::{Axis, Grid, Table};

/// The largest `l_max` accepted.
///
/// Eq. 3.6 builds the unnormalised `P_mm = (−1)^m (2m − 1)!! sin^m θ`, which leaves the
/// range of `f64` for m ≳ 150; 128 keeps every intermediate within it (and is far
/// beyond what a projection can afford: by default it evaluates f ~ 64 l_max⁴ times).
pub const MAX_L_MAX: usize = 128;

/// The `kind` of a spherical-harmonics file.
pub const FILE_KIND: &str = "spherical-harmonics";

/// Rows of `F` evaluated at once: bounds the block to ~32 MB whatever `Q` is.
const BLOCK_VALUES: usize = 1 << 22;

/// Options of [`ShBrdf::project`] and [`ShBrdf::from_table`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShOptions {
    /// Largest degree l of the harmonics (at most [`MAX_L_MAX`]).
    pub l_max: usize,
    /// Degree above which coefficients are tapered ([`taper`]); `None` for no
    /// filtering (the same as `Some(l_max)`).
    pub l_filter: Option<usize>,
    /// Gauss–Legendre nodes in cos θ on each hemisphere (the azimuth gets twice as
    /// many); at least `l_max + 1`. `None` chooses `2 (l_max + 1)`, which also
    /// resolves data that are not band-limited reasonably well.
    pub quadrature: Option<usize>,
}

impl ShOptions {
    /// Degree `l_max`, no filtering, the default quadrature.
    pub fn new(l_max: usize) -> ShOptions {
        ShOptions {
            l_max,
            l_filter: None,
            quadrature: None,
        }
    }

    /// The same options with filtering above `l_filter`.
    pub fn with_filter(self, l_filter: usize) -> ShOptions {
        ShOptions {
            l_filter: Some(l_filter),
            ..self
        }
    }

    /// The same options with `n` polar quadrature nodes.
    pub fn with_quadrature(self, n: usize) -> ShOptions {
        ShOptions {
            quadrature: Some(n),
            ..self
        }
    }

    /// Checks the options; returns `(l_filter, polar nodes)`.
    fn resolve(&self) -> Result<(usize, usize), ProcessError> {
        let l_max = self.l_max;
        if l_max > MAX_L_MAX {
            return Err(ProcessError::Value(format!(
                "l_max = {l_max} exceeds the supported {MAX_L_MAX}"
            )));
        }
        let l_filter = self.l_filter.unwrap_or(l_max);
        if l_filter > l_max {
            return Err(ProcessError::Value(format!(
                "l_filter = {l_filter} exceeds l_max = {l_max}"
            )));
        }
        let n = self.quadrature.unwrap_or(2 * (l_max + 1));
        if n < l_max + 1 {
            return Err(ProcessError::Value(format!(
                "quadrature = {n} polar nodes cannot integrate harmonics of degree {l_max} \
                 exactly; use at least {}",
                l_max + 1
            )));
        }
        Ok((l_filter, n))
    }
}

/// A BRDF as real spherical harmonics with a symmetric coefficient matrix per
/// channel (Westin et al. 1992, Eq. 8 and 10).
///
/// `f_r(wi, wo) = Σ_jk M_jk Y_j(wi) Y_k(wo)` over [`basis`]`(l_max)`, for directions
/// above the surface; at or below the horizon the value is 0, as for every
/// [`gonio_brdf::Brdf`].
#[derive(Clone, Debug, PartialEq)]
pub struct ShBrdf {
    /// The channels.
    pub channels: Channels,
    /// Largest degree l.
    pub l_max: usize,
    /// Degree above which the coefficients were tapered ([`taper`]); `l_max` when
    /// they were not.
    pub l_filter: usize,
    /// The basis, `(l, m)` with `l + m` even, in the order of [`basis`].
    pub basis: Vec<(usize, i64)>,
    /// Per channel, `M` as K × K row-major, symmetric, already tapered. Evaluation
    /// reads only the upper triangle.
    pub matrices: Vec<Vec<f64>>,
}

/// How far an [`ShBrdf`] is from a table at the table's nodes, per channel.
#[derive(Clone, Debug, PartialEq)]
pub struct ShError {
    /// Root-mean-square absolute error (1/sr).
    pub rms: Vec<f64>,
    /// `rms` over the root-mean-square of the table's values (0 when both vanish,
    /// infinite when only the values do).
    pub relative_rms: Vec<f64>,
    /// Largest absolute error (1/sr).
    pub max_abs: Vec<f64>,
}

/// The hemisphere-even basis of degree `l_max`: `(l, m)` for `l = 0..=l_max`,
/// `m = −l..=l` with `l + m` even, in that order; `(l_max + 1)(l_max + 2)/2` entries.
pub fn basis(l_max: usize) -> Vec<(usize, i64)> {
    let mut b = Vec::with_capacity(basis_len(l_max));
    for l in 0..=l_max {
        let li = l as i64;
        b.extend((-li..=li).filter(|m| (li + m) % 2 == 0).map(|m| (l, m)));
    }
    b
}

/// Number of functions in [`basis`]`(l_max)`.
pub fn basis_len(l_max: usize) -> usize {
    (l_max + 1) * (l_max + 2) / 2
}

/// All `Y_lm` of [`basis`]`(l_max)` at `dir`, in basis order, into `out` (cleared
/// first). DeYoung Eq. 3.4–3.6; valid on the whole sphere and accurate up to
/// [`MAX_L_MAX`].
pub fn eval_basis(l_max: usize, dir: Dir, out: &mut Vec<f64>) {
    let (t, s, cp, sp) = polar_parts(dir);
    fill_basis(l_max, t, s, cp, sp, true, out);
}

/// Every real `Y_lm`, `l ≤ l_max`, `m = −l..=l` (the whole-sphere basis, of which
/// [`eval_basis`] keeps the hemisphere-even half), at `dir`, into `out`.
pub fn eval_full_basis(l_max: usize, dir: Dir, out: &mut Vec<f64>) {
    let (t, s, cp, sp) = polar_parts(dir);
    fill_basis(l_max, t, s, cp, sp, false, out);
}

/// The attenuation of degree `l` (Westin et al. Sec. 2.5): 1 for `l ≤ l_filter`, then
/// the cosine taper `½ (1 + cos(π (l − l_filter)/(l_max − l_filter + 1)))`, which
/// falls smoothly and would reach 0 at `l_max + 1`; 0 beyond `l_max`.
pub fn taper(l: usize, l_filter: usize, l_max: usize) -> f64 {
    if l <= l_filter {
        1.0
    } else if l > l_max {
        0.0
    } else {
        let x = (l - l_filter) as f64 / (l_max - l_filter + 1) as f64;
        0.5 * (1.0 + (PI * x).cos())
    }
}

/// cos θ, sin θ, cos φ, sin φ of a direction; φ = 0 at the poles, where every m ≠ 0
/// term vanishes anyway.
fn polar_parts(dir: Dir) -> (f64, f64, f64, f64) {
    let v = dir.vec();
    let s = dir.sin_theta();
    if s > 0.0 {
        (v.z, s, v.x / s, v.y / s)
    } else {
        (v.z, 0.0, 1.0, 0.0)
    }
}

/// Index of (l, m ≥ 0) in the triangle of [`normalized_legendre`].
fn tri(l: usize, m: usize) -> usize {
    l * (l + 1) / 2 + m
}

/// `N_lm P_lm(t)` for `0 ≤ m ≤ l ≤ l_max` at [`tri`]`(l, m)`, with `s = √(1 − t²)`.
///
/// `P_lm` by the recurrence of DeYoung Eq. 3.6, `N_lm` of Eq. 3.5 by running ratios
/// (`N_mm / N_{m−1,m−1}` and `N_lm / N_{l−1,m}`), so no factorial is ever formed.
fn normalized_legendre(l_max: usize, t: f64, s: f64, out: &mut Vec<f64>) {
    out.clear();
    out.resize(tri(l_max + 1, 0), 0.0);
    let mut p_mm = 1.0;
    // N_00 = √(1/2π) (Eq. 3.5).
    let mut n_mm = (1.0 / TAU).sqrt();
    for m in 0..=l_max {
        let mf = m as f64;
        if m > 0 {
            p_mm *= (1.0 - 2.0 * mf) * s;
            // N_mm² / N_{m−1,m−1}² = (2m + 1)/(2m − 1) · 1/((2m)(2m − 1)).
            n_mm *= ((2.0 * mf + 1.0) / ((2.0 * mf - 1.0) * (2.0 * mf) * (2.0 * mf - 1.0))).sqrt();
        }
        out[tri(m, m)] = n_mm * p_mm;
        if m == l_max {
            break;
        }
        let mut p2 = p_mm;
        let mut p1 = t * (2.0 * mf + 1.0) * p_mm;
        // l = m + 1: (2l + 1)/(2l − 1) · (l − m)/(l + m).
        let mut n = n_mm * ((2.0 * mf + 3.0) / ((2.0 * mf + 1.0) * (2.0 * mf + 1.0))).sqrt();
        out[tri(m + 1, m)] = n * p1;
        for l in m + 2..=l_max {
            let lf = l as f64;
            let p = (t * (2.0 * lf - 1.0) * p1 - (lf + mf - 1.0) * p2) / (lf - mf);
            n *= ((2.0 * lf + 1.0) * (lf - mf) / ((2.0 * lf - 1.0) * (lf + mf))).sqrt();
            out[tri(l, m)] = n * p;
            p2 = p1;
            p1 = p;
        }
    }
}

/// The real harmonics of DeYoung Eq. 3.4 from cos θ, sin θ, cos φ, sin φ.
fn fill_basis(l_max: usize, t: f64, s: f64, cp: f64, sp: f64, even_only: bool, out: &mut Vec<f64>) {
    let mut leg = Vec::new();
    normalized_legendre(l_max, t, s, &mut leg);
    // cos mφ, sin mφ by angle addition.
    let mut trig = Vec::with_capacity(l_max + 1);
    let (mut c, mut sn) = (1.0, 0.0);
    for _ in 0..=l_max {
        trig.push((c, sn));
        (c, sn) = (c * cp - sn * sp, sn * cp + c * sp);
    }
    out.clear();
    out.reserve(if even_only {
        basis_len(l_max)
    } else {
        (l_max + 1) * (l_max + 1)
    });
    for l in 0..=l_max {
        let li = l as i64;
        for m in -li..=li {
            if even_only && (li + m) % 2 != 0 {
                continue;
            }
            let am = m.unsigned_abs() as usize;
            let np = leg[tri(l, am)];
            out.push(match m {
                0 => np * FRAC_1_SQRT_2,
                m if m > 0 => np * trig[am].0,
                _ => np * trig[am].1,
            });
        }
    }
}

/// Gauss–Legendre nodes and weights on [−1, 1], ascending.
fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut x = vec![0.0; n];
    let mut w = vec![0.0; n];
    let nf = n as f64;
    for i in 0..n.div_ceil(2) {
        // Tricomi's estimate of the i-th largest root, then Newton.
        let mut z = (PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, z);
            for k in 2..=n {
                let kf = k as f64;
                (p0, p1) = (p1, ((2.0 * kf - 1.0) * z * p1 - (kf - 1.0) * p0) / kf);
            }
            let p = if n == 0 { 1.0 } else { p1 };
            let pm1 = if n == 1 { 1.0 } else { p0 };
            dp = nf * (z * p - pm1) / (z * z - 1.0);
            let dz = p / dp;
            z -= dz;
            if dz.abs() <= 1e-16 * z.abs().max(1e-3) {
                break;
            }
        }
        let wi = 2.0 / ((1.0 - z * z) * dp * dp);
        x[n - 1 - i] = z;
        x[i] = -z;
        w[i] = wi;
        w[n - 1 - i] = wi;
    }
    (x, w)
}

/// The two nodes of an axis around a value and their weights (from [`Axis::locate`]).
type Stencil = [(usize, f64); 2];

fn stencil(ax: &Axis, x: f64) -> Stencil {
    let (k0, k1, t) = ax.locate(x);
    [(k0, 1.0 - t), (k1, t)]
}

/// [`Table::eval_angles`] at pairs of quadrature nodes, bit for bit, with every
/// [`Axis::locate`] done once per node (or per pair of azimuths), not once per pair:
/// the per-pair work drops to 16 multiply–adds.
struct TableAtNodes<'t> {
    grid: &'t Grid,
    /// Per node, the incident (φi, θi) stencil as (φi node · nθi + θi node, wa·wb),
    /// in the order the interpolation sums.
    incident: Vec<[(usize, f64); 4]>,
    /// Per node, the θo stencil.
    theta_o: Vec<Stencil>,
    /// Per node the φo stencil; for an isotropic grid, per pair of azimuth indices
    /// (φ+ = φo − φi depends on both).
    phi_o: Vec<Stencil>,
    /// Azimuths per polar ring of the quadrature.
    n_phi: usize,
}

impl<'t> TableAtNodes<'t> {
    fn new(table: &'t Table, nodes: &Nodes) -> TableAtNodes<'t> {
        let g = &table.grid;
        // The isotropic interpolation measures φo from φi and sets φi to 0.
        let incident = nodes
            .angles
            .iter()
            .map(|&[phi, theta]| {
                let sa = stencil(&g.phi_i, if g.isotropic { 0.0 } else { phi });
                let sb = stencil(&g.theta_i, theta);
                let mut out = [(0, 0.0); 4];
                for (i, (a, wa)) in sa.into_iter().enumerate() {
                    for (j, (b, wb)) in sb.into_iter().enumerate() {
                        out[2 * i + j] = (a * g.theta_i.n + b, wa * wb);
                    }
                }
                out
            })
            .collect();
        let theta_o = nodes
            .angles
            .iter()
            .map(|&[_, theta]| stencil(&g.theta_o, theta))
            .collect();
        let n_phi = nodes.n_phi;
        let phi_o = if g.isotropic {
            // Ring azimuths are the same for every ring: index c ↦ angles[c][0].
            let az: Vec<f64> = nodes.angles[..n_phi].iter().map(|a| a[0]).collect();
            az.iter()
                .flat_map(|&pi| az.iter().map(move |&po| po - pi))
                .map(|d| stencil(&g.phi_o, d))
                .collect()
        } else {
            nodes
                .angles
                .iter()
                .map(|&[phi, _]| stencil(&g.phi_o, phi))
                .collect()
        };
        TableAtNodes {
            grid: g,
            incident,
            theta_o,
            phi_o,
            n_phi,
        }
    }

    /// The interpolated value of channel values `v` at nodes (`a`, `b`).
    fn eval(&self, v: &[f64], a: usize, b: usize) -> f64 {
        let g = self.grid;
        let pc = if g.isotropic {
            &self.phi_o[(a % self.n_phi) * self.n_phi + b % self.n_phi]
        } else {
            &self.phi_o[b]
        };
        let pd = &self.theta_o[b];
        let mut acc = 0.0;
        // Same terms, same order and same products as `grid::interpolate`; its
        // zero-weight skips only leave out exact zeros.
        for &(p, wab) in &self.incident[a] {
            for &(c, wc) in pc {
                let base = (p * g.phi_o.n + c) * g.theta_o.n;
                for &(d, wd) in pd {
                    acc += wab * wc * wd * v[base + d];
                }
            }
        }
        acc
    }
}

/// The product rule on the upper hemisphere: directions, their angles and weights.
struct Nodes {
    dirs: Vec<Dir>,
    /// (φ, θ), radians.
    angles: Vec<[f64; 2]>,
    /// Weighted basis `B = W Y`, Q × K.
    weighted: Mat<f64>,
    /// Azimuths per polar ring; node `a` has azimuth index `a % n_phi`.
    n_phi: usize,
}

impl Nodes {
    fn new(l_max: usize, n_mu: usize) -> Nodes {
        let n_phi = 2 * n_mu;
        let (x, w) = gauss_legendre(n_mu);
        let dphi = TAU / n_phi as f64;
        let q = n_mu * n_phi;
        let k = basis_len(l_max);
        let mut dirs = Vec::with_capacity(q);
        let mut angles = Vec::with_capacity(q);
        let mut ys = Vec::with_capacity(q * k);
        let mut weights = Vec::with_capacity(q);
        let mut y = Vec::with_capacity(k);
        for (xi, wi) in x.iter().zip(&w) {
            // cos θ on [0, 1].
            let t = 0.5 * (xi + 1.0);
            let s = ((1.0 - t) * (1.0 + t)).sqrt();
            let theta = s.atan2(t);
            for c in 0..n_phi {
                let phi = c as f64 * dphi;
                let (sp, cp) = phi.sin_cos();
                dirs.push(Dir::from_unit(Vec3::new(s * cp, s * sp, t)));
                angles.push([phi, theta]);
                weights.push(0.5 * wi * dphi);
                fill_basis(l_max, t, s, cp, sp, true, &mut y);
                ys.extend_from_slice(&y);
            }
        }
        let weighted = Mat::from_fn(q, k, |a, j| weights[a] * ys[a * k + j]);
        Nodes {
            dirs,
            angles,
            weighted,
            n_phi,
        }
    }

    /// `4 Bᵀ F B` for `F_ab = f(a, b)`, symmetrised and tapered.
    fn project_channel(
        &self,
        f: &(impl Fn(usize, usize) -> f64 + Sync),
        l_max: usize,
        l_filter: usize,
    ) -> Vec<f64> {
        let b = self.weighted.as_ref();
        let (q, k) = (b.nrows(), b.ncols());
        let par = Par::rayon(0);
        let rows = (BLOCK_VALUES / q).clamp(1, q);
        let mut m = Mat::<f64>::zeros(k, k);
        let mut buf = vec![0.0; rows * q];
        let mut g = Mat::<f64>::zeros(rows, k);
        for r0 in (0..q).step_by(rows) {
            let nr = rows.min(q - r0);
            let block = &mut buf[..nr * q];
            block.par_chunks_mut(q).enumerate().for_each(|(r, row)| {
                for (c, v) in row.iter_mut().enumerate() {
                    *v = f(r0 + r, c);
                }
            });
            let fb = MatRef::from_row_major_slice(block, nr, q);
            matmul(
                g.as_mut().subrows_mut(0, nr),
                Accum::Replace,
                fb,
                b,
                1.0,
                par,
            );
            matmul(
                m.as_mut(),
                Accum::Add,
                b.subrows(r0, nr).transpose(),
                g.as_ref().subrows(0, nr),
                4.0,
                par,
            );
        }
        let taper_of: Vec<f64> = basis(l_max)
            .iter()
            .map(|&(l, _)| taper(l, l_filter, l_max))
            .collect();
        let mut out = vec![0.0; k * k];
        for i in 0..k {
            for j in i..k {
                // (a + b)/2 is bitwise the same whichever side is a, so M is exactly
                // symmetric.
                let v = 0.5 * (m[(i, j)] + m[(j, i)]) * (taper_of[i] * taper_of[j]);
                out[i * k + j] = v;
                out[j * k + i] = v;
            }
        }
        out
    }
}

impl ShBrdf {
    /// Projects `f(ch, wi, wo)`, a BRDF on the upper hemisphere, onto the basis of
    /// degree `opts.l_max` by the product quadrature of the module docs, then keeps
    /// its reciprocal part, `M = (M + Mᵀ)/2`, and tapers it ([`taper`]).
    ///
    /// `f` is called for every channel at `Q²` pairs (`Q = 2n²` directions for `n`
    /// polar nodes), in parallel.
    pub fn project(
        channels: Channels,
        f: impl Fn(usize, Dir, Dir) -> f64 + Sync,
        opts: &ShOptions,
    ) -> Result<ShBrdf, ProcessError> {
        let (l_filter, n) = opts.resolve()?;
        let nodes = Nodes::new(opts.l_max, n);
        let dirs = &nodes.dirs;
        let matrices = (0..channels.len())
            .map(|ch| nodes.project_channel(&|a, b| f(ch, dirs[a], dirs[b]), opts.l_max, l_filter))
            .collect();
        ShBrdf::checked(channels, opts.l_max, l_filter, matrices)
    }

    /// Projects a table ([`Table::eval_angles`] between its nodes); full and
    /// isotropic grids alike.
    pub fn from_table(table: &Table, opts: &ShOptions) -> Result<ShBrdf, ProcessError> {
        table.grid.validate()?;
        let n = table.grid.len();
        let nc = table.channels.len();
        if table.values.len() != n * nc {
            return Err(ProcessError::Shape(format!(
                "{} values for a grid of {n} nodes × {nc} channels",
                table.values.len()
            )));
        }
        let (l_filter, nq) = opts.resolve()?;
        let nodes = Nodes::new(opts.l_max, nq);
        let at = TableAtNodes::new(table, &nodes);
        let matrices = (0..nc)
            .map(|ch| {
                let v = table.channel(ch);
                nodes.project_channel(&|a, b| at.eval(v, a, b), opts.l_max, l_filter)
            })
            .collect();
        ShBrdf::checked(table.channels.clone(), opts.l_max, l_filter, matrices)
    }

    fn checked(
        channels: Channels,
        l_max: usize,
        l_filter: usize,
        matrices: Vec<Vec<f64>>,
    ) -> Result<ShBrdf, ProcessError> {
        for (ch, m) in matrices.iter().enumerate() {
            if m.iter().any(|v| !v.is_finite()) {
                return Err(ProcessError::Value(format!(
                    "channel {}: the projected function is not finite somewhere on the \
                     hemisphere",
                    channels.name(ch)
                )));
            }
        }
        let sh = ShBrdf {
            channels,
            l_max,
            l_filter,
            basis: basis(l_max),
            matrices,
        };
        sh.validate()?;
        Ok(sh)
    }

    /// Checks the invariants that [`eval`](ShBrdf::eval) relies on: degrees within
    /// range, the basis of `l_max`, one finite K × K matrix a channel.
    pub fn validate(&self) -> Result<(), ProcessError> {
        if self.l_max > MAX_L_MAX {
            return Err(ProcessError::Value(format!(
                "l_max = {} exceeds the supported {MAX_L_MAX}",
                self.l_max
            )));
        }
        if self.l_filter > self.l_max {
            return Err(ProcessError::Value(format!(
                "l_filter = {} exceeds l_max = {}",
                self.l_filter, self.l_max
            )));
        }
        if self.basis != basis(self.l_max) {
            return Err(ProcessError::Shape(format!(
                "the basis is not the hemisphere-even basis of l_max = {}",
                self.l_max
            )));
        }
        if self.matrices.len() != self.channels.len() {
            return Err(ProcessError::Shape(format!(
                "{} matrices for {} channels",
                self.matrices.len(),
                self.channels.len()
            )));
        }
        let k = self.basis.len();
        for (ch, m) in self.matrices.iter().enumerate() {
            if m.len() != k * k {
                return Err(ProcessError::Shape(format!(
                    "channel {}: {} coefficients, expected {k} × {k}",
                    self.channels.name(ch),
                    m.len()
                )));
            }
            if let Some(i) = m.iter().position(|v| !v.is_finite()) {
                return Err(ProcessError::Value(format!(
                    "channel {}: coefficient {i} is not finite",
                    self.channels.name(ch)
                )));
            }
        }
        Ok(())
    }

    /// `f_r(wi, wo)` for every channel into `out` (one entry a channel); 0 when either
    /// direction is at or below the horizon.
    ///
    /// Bitwise reciprocal: the sum pairs `M_jk (a_j b_k + a_k b_j)` over the upper
    /// triangle, which is the same expression with `wi` and `wo` swapped.
    ///
    /// # Panics
    /// If `out` does not have one entry a channel.
    pub fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        assert_eq!(out.len(), self.channels.len(), "one output value a channel");
        if !wi.is_above() || !wo.is_above() {
            out.fill(0.0);
            return;
        }
        let (mut a, mut b) = (Vec::new(), Vec::new());
        eval_basis(self.l_max, wi, &mut a);
        eval_basis(self.l_max, wo, &mut b);
        for (o, m) in out.iter_mut().zip(&self.matrices) {
            *o = symmetric_form(m, &a, &b);
        }
    }

    /// Number of independent coefficients stored: K(K + 1)/2 a channel, M being
    /// symmetric.
    pub fn coefficient_count(&self) -> usize {
        let k = self.basis.len();
        self.channels.len() * k * (k + 1) / 2
    }

    /// [`coefficient_count`](ShBrdf::coefficient_count) over the number of values of
    /// `table` (all channels): below 1 the representation is the smaller.
    pub fn compression(&self, table: &Table) -> f64 {
        self.coefficient_count() as f64 / table.values.len() as f64
    }

    /// The error against `table` at its nodes, per channel (see [`ShError`]).
    ///
    /// Evaluates `Y_in M Y_outᵀ` over all incident × outgoing nodes at once; the same
    /// values as [`eval`](ShBrdf::eval) up to rounding.
    pub fn error_against(&self, table: &Table) -> Result<ShError, ProcessError> {
        self.validate()?;
        let nc = self.channels.len();
        if table.channels.len() != nc {
            return Err(ProcessError::Shape(format!(
                "a table of {} channels against a representation of {nc}",
                table.channels.len()
            )));
        }
        let g = &table.grid;
        let n = g.len();
        if table.values.len() != n * nc {
            return Err(ProcessError::Shape(format!(
                "{} values for a grid of {n} nodes × {nc} channels",
                table.values.len()
            )));
        }
        let k = self.basis.len();
        // Incident and outgoing node directions in grid order: index = p · n_out + q.
        let dirs_of = |pa: &Axis, ta: &Axis| {
            let mut y = Vec::new();
            let mut rows = Vec::with_capacity(pa.n * ta.n * k);
            for a in 0..pa.n {
                for b in 0..ta.n {
                    let d = Dir::from_angles(ta.node(b), pa.node(a));
                    if d.is_above() {
                        eval_basis(self.l_max, d, &mut y);
                        rows.extend_from_slice(&y);
                    } else {
                        rows.extend(std::iter::repeat_n(0.0, k));
                    }
                }
            }
            rows
        };
        let yi = dirs_of(&g.phi_i, &g.theta_i);
        let yo = dirs_of(&g.phi_o, &g.theta_o);
        let (ni, no) = (g.n_in(), g.n_out());
        let yi = MatRef::from_row_major_slice(&yi, ni, k);
        let yo = MatRef::from_row_major_slice(&yo, no, k);
        let par = Par::rayon(0);
        let mut err = ShError {
            rms: Vec::with_capacity(nc),
            relative_rms: Vec::with_capacity(nc),
            max_abs: Vec::with_capacity(nc),
        };
        let mut ym = Mat::<f64>::zeros(ni, k);
        let mut v = Mat::<f64>::zeros(ni, no);
        for (ch, m) in self.matrices.iter().enumerate() {
            let full = Mat::from_fn(
                k,
                k,
                |i, j| {
                    if i <= j { m[i * k + j] } else { m[j * k + i] }
                },
            );
            matmul(ym.as_mut(), Accum::Replace, yi, full.as_ref(), 1.0, par);
            matmul(
                v.as_mut(),
                Accum::Replace,
                ym.as_ref(),
                yo.transpose(),
                1.0,
                par,
            );
            let vals = table.channel(ch);
            let (mut se, mut sv, mut mx) = (0.0_f64, 0.0_f64, 0.0_f64);
            for p in 0..ni {
                for q in 0..no {
                    let t = vals[p * no + q];
                    let e = (v[(p, q)] - t).abs();
                    se += e * e;
                    sv += t * t;
                    mx = mx.max(e);
                }
            }
            let rms = (se / n as f64).sqrt();
            let rms_v = (sv / n as f64).sqrt();
            err.rms.push(rms);
            err.relative_rms.push(if rms == 0.0 {
                0.0
            } else if rms_v == 0.0 {
                f64::INFINITY
            } else {
                rms / rms_v
            });
            err.max_abs.push(mx);
        }
        Ok(err)
    }

    /// The representation as a TOML file (see the module docs); floats are written
    /// in their shortest exact form, so [`from_toml`](ShBrdf::from_toml) gives back
    /// the same matrices bit for bit.
    pub fn to_toml(&self) -> String {
        let k = self.basis.len();
        let names = self.channels.names();
        let mut s = String::new();
        // Writing to a String cannot fail; the results are ignored for that reason.
        let _ = writeln!(
            s,
            "# f_r(wi, wo) = sum_jk M_jk Y_j(wi) Y_k(wo), M symmetric (Westin et al. 1992, Eq. 8-10)"
        );
        let _ = writeln!(
            s,
            "# basis: l = 0..=l_max, m = -l..=l with l + m even (DeYoung Eq. 3.4-3.6);"
        );
        let _ = writeln!(
            s,
            "# upper: the upper triangle of M, row j from column j, one row a line"
        );
        let _ = writeln!(s, "kind = {}", toml::Value::from(FILE_KIND));
        let chans = toml::Value::Array(
            names
                .iter()
                .map(|n| toml::Value::from(n.as_str()))
                .collect(),
        );
        let _ = writeln!(s, "channels = {chans}");
        let _ = writeln!(s, "l_max = {}", self.l_max);
        let _ = writeln!(s, "l_filter = {}", self.l_filter);
        for (name, m) in names.iter().zip(&self.matrices) {
            let _ = writeln!(s, "\n[[matrices]]");
            let _ = writeln!(s, "channel = {}", toml::Value::from(name.as_str()));
            let _ = writeln!(s, "upper = [");
            for j in 0..k {
                s.push(' ');
                for v in &m[j * k + j..(j + 1) * k] {
                    // Debug is Rust's shortest round-trip form, and always TOML: `1.0`,
                    // `-2.5e-7`, `3e20`.
                    let _ = write!(s, " {v:?},");
                }
                s.push('\n');
            }
            let _ = writeln!(s, "]");
        }
        s
    }

    /// Reads [`to_toml`](ShBrdf::to_toml)'s format strictly (unknown keys are errors);
    /// errors name the line and field (`matrices[1].upper`).
    /// `path` only labels errors.
    pub fn from_toml(
        text: &str,
        path: Option<&std::path::Path>,
    ) -> Result<ShBrdf, gonio_core::tomlfile::FileError> {
        const KIND: &str = "spherical-harmonics file";
        let file: ShFile = gonio_core::tomlfile::parse(KIND, text, path, ShFile::check)?;
        let k = basis_len(file.l_max);
        let matrices = file
            .matrices
            .iter()
            .map(|mf| {
                let mut m = vec![0.0; k * k];
                let mut it = mf.upper.iter();
                for j in 0..k {
                    for i in j..k {
                        let v = it.next().copied().unwrap_or(f64::NAN);
                        m[j * k + i] = v;
                        m[i * k + j] = v;
                    }
                }
                m
            })
            .collect();
        let sh = ShBrdf {
            channels: file.channels,
            l_max: file.l_max,
            l_filter: file.l_filter,
            basis: basis(file.l_max),
            matrices,
        };
        sh.validate()
            .map_err(|e| gonio_core::tomlfile::FileError::whole(KIND, path, e.to_string()))?;
        Ok(sh)
    }
}

/// `Σ_j M_jj a_j b_j + Σ_{j<k} M_jk (a_j b_k + a_k b_j)`, symmetric in `a` and `b`
/// bit for bit.
fn symmetric_form(m: &[f64], a: &[f64], b: &[f64]) -> f64 {
    let k = a.len();
    let mut acc = 0.0;
    for j in 0..k {
        let row = &m[j * k..(j + 1) * k];
        let mut r = row[j] * (a[j] * b[j]);
        for i in j + 1..k {
            r += row[i] * (a[j] * b[i] + a[i] * b[j]);
        }
        acc += r;
    }
    acc
}

/// The TOML file of an [`ShBrdf`].
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ShFile {
    kind: String,
    channels: Channels,
    l_max: usize,
    l_filter: usize,
    matrices: Vec<ShFileMatrix>,
}

/// One channel's `[[matrices]]` table.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ShFileMatrix {
    channel: String,
    upper: Vec<f64>,
}

impl ShFile {
    /// The faults serde cannot see, as (field, why).
    fn check(&self) -> Result<(), (String, String)> {
        let fault = |field: &str, why: String| Err((field.to_string(), why));
        if self.kind != FILE_KIND {
            return fault(
                "kind",
                format!("expected \"{FILE_KIND}\", got \"{}\"", self.kind),
            );
        }
        if self.l_max > MAX_L_MAX {
            return fault(
                "l_max",
                format!("{} exceeds the supported {MAX_L_MAX}", self.l_max),
            );
        }
        if self.l_filter > self.l_max {
            return fault(
                "l_filter",
                format!("{} exceeds l_max = {}", self.l_filter, self.l_max),
            );
        }
        if self.matrices.len() != self.channels.len() {
            return fault(
                "matrices",
                format!(
                    "{} [[matrices]] tables for {} channels",
                    self.matrices.len(),
                    self.channels.len()
                ),
            );
        }
        let k = basis_len(self.l_max);
        let want = k * (k + 1) / 2;
        for (i, m) in self.matrices.iter().enumerate() {
            let name = self.channels.name(i);
            if m.channel != name {
                return fault(
                    &format!("matrices[{i}].channel"),
                    format!("expected \"{name}\" (channel {i}), got \"{}\"", m.channel),
                );
            }
            if m.upper.len() != want {
                return fault(
                    &format!("matrices[{i}].upper"),
                    format!(
                        "{} values; the upper triangle for l_max = {} has {want}",
                        m.upper.len(),
                        self.l_max
                    ),
                );
            }
            if let Some(j) = m.upper.iter().position(|v| !v.is_finite()) {
                return fault(
                    &format!("matrices[{i}].upper"),
                    format!("value {j} is not finite ({})", m.upper[j]),
                );
            }
        }
        Ok(())
    }
}

/// A harmonics representation evaluates anywhere, so it is a `Brdf` (sampled by the
/// cosine proposal; its values may dip below zero where a truncated series rings).
impl gonio_brdf::Brdf for ShBrdf {
    fn channels(&self) -> &Channels {
        &self.channels
    }

    fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        ShBrdf::eval(self, wi, wo, out);
    }

    fn proposals(&self, _wi: Dir, out: &mut Vec<gonio_brdf::Weighted>) {
        crate::grid::cosine_proposal(out);
    }

    fn is_reciprocal(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Product rule on the sphere (or the upper hemisphere): `n` Gauss nodes in cos θ,
    /// `2n` azimuths; exact for products of harmonics of degree < n.
    fn sphere_rule(n: usize, upper_only: bool) -> Vec<(Dir, f64)> {
        let (x, w) = gauss_legendre(n);
        let n_phi = 2 * n;
        let dphi = TAU / n_phi as f64;
        let mut out = Vec::new();
        for (xi, wi) in x.iter().zip(&w) {
            let (t, wt) = if upper_only {
                (0.5 * (xi + 1.0), 0.5 * wi)
            } else {
                (*xi, *wi)
            };
            let s = ((1.0 - t) * (1.0 + t)).sqrt();
            for c in 0..n_phi {
                let (sp, cp) = (c as f64 * dphi).sin_cos();
                out.push((Dir::from_unit(Vec3::new(s * cp, s * sp, t)), wt * dphi));
            }
        }
        out
    }

    /// `Σ w Y_j Y_k` over a rule, as a dense matrix.
    fn gram(rule: &[(Dir, f64)], l_max: usize, full: bool) -> (usize, Vec<f64>) {
        let mut y = Vec::new();
        let mut g: Vec<f64> = Vec::new();
        let mut k = 0;
        for &(d, w) in rule {
            if full {
                eval_full_basis(l_max, d, &mut y);
            } else {
                eval_basis(l_max, d, &mut y);
            }
            if g.is_empty() {
                k = y.len();
                g = vec![0.0; k * k];
            }
            for i in 0..k {
                for j in 0..k {
                    g[i * k + j] += w * y[i] * y[j];
                }
            }
        }
        (k, g)
    }

    #[test]
    fn gauss_legendre_integrates_polynomials() {
        for n in [1, 2, 5, 17, 40] {
            let (x, w) = gauss_legendre(n);
            assert!((w.iter().sum::<f64>() - 2.0).abs() < 1e-14, "n = {n}");
            // ∫ x^(2n−2) dx on [−1, 1] = 2/(2n − 1).
            let p = 2 * n as i32 - 2;
            let s: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(p)).sum();
            assert!((s - 2.0 / (p as f64 + 1.0)).abs() < 1e-14, "n = {n}: {s}");
            assert!(x.windows(2).all(|p| p[0] < p[1]));
        }
    }

    #[test]
    fn full_basis_is_orthonormal_over_the_sphere() {
        let l_max = 16;
        let rule = sphere_rule(l_max + 1, false);
        let (k, g) = gram(&rule, l_max, true);
        assert_eq!(k, (l_max + 1) * (l_max + 1));
        let mut worst: f64 = 0.0;
        for i in 0..k {
            for j in 0..k {
                let want = if i == j { 1.0 } else { 0.0 };
                worst = worst.max((g[i * k + j] - want).abs());
            }
        }
        assert!(worst < 1e-12, "worst deviation {worst:e}");
    }

    #[test]
    fn even_basis_has_norm_one_half_over_the_upper_hemisphere() {
        let l_max = 16;
        let rule = sphere_rule(l_max + 1, true);
        let (k, g) = gram(&rule, l_max, false);
        assert_eq!(k, basis_len(l_max));
        let mut worst: f64 = 0.0;
        for i in 0..k {
            for j in 0..k {
                let want = if i == j { 0.5 } else { 0.0 };
                worst = worst.max((g[i * k + j] - want).abs());
            }
        }
        assert!(worst < 1e-12, "worst deviation {worst:e}");
    }

    #[test]
    fn low_degree_harmonics_match_closed_forms() {
        let d = Dir::from_angles(0.7, 2.1);
        let v = d.vec();
        let mut y = Vec::new();
        eval_full_basis(2, d, &mut y);
        let c0 = (1.0 / (4.0 * PI)).sqrt();
        let c1 = (3.0 / (4.0 * PI)).sqrt();
        let c2 = (15.0 / (4.0 * PI)).sqrt();
        let c20 = (5.0 / (16.0 * PI)).sqrt();
        // Order l = 0; l = 1: m = −1, 0, 1; l = 2: m = −2..=2. Eq. 3.6 carries the
        // Condon–Shortley sign (1 − 2m), so the odd-m terms are negated.
        let want = [
            c0,
            -c1 * v.y,
            c1 * v.z,
            -c1 * v.x,
            c2 * v.x * v.y,
            -c2 * v.y * v.z,
            c20 * (3.0 * v.z * v.z - 1.0),
            -c2 * v.x * v.z,
            0.5 * c2 * (v.x * v.x - v.y * v.y),
        ];
        for (i, (a, b)) in y.iter().zip(want).enumerate() {
            assert!((a - b).abs() < 1e-14, "Y[{i}] = {a}, want {b}");
        }
        // The even basis keeps exactly the l + m even ones.
        eval_basis(2, d, &mut y);
        assert_eq!(
            basis(2),
            vec![(0, 0), (1, -1), (1, 1), (2, -2), (2, 0), (2, 2)]
        );
        let want_even = [want[0], want[1], want[3], want[4], want[6], want[8]];
        for (a, b) in y.iter().zip(want_even) {
            assert!((a - b).abs() < 1e-14);
        }
    }

    #[test]
    fn parity_under_reflection_through_the_surface() {
        let l_max = 12;
        let d = Dir::from_angles(0.4, 1.3);
        let (mut a, mut b) = (Vec::new(), Vec::new());
        eval_full_basis(l_max, d, &mut a);
        eval_full_basis(l_max, d.flip_z(), &mut b);
        let mut i = 0;
        for l in 0..=l_max as i64 {
            for m in -l..=l {
                let sign = if (l + m) % 2 == 0 { 1.0 } else { -1.0 };
                assert!((b[i] - sign * a[i]).abs() < 1e-12, "l = {l}, m = {m}");
                i += 1;
            }
        }
    }

    #[test]
    fn high_degrees_stay_finite_and_bounded() {
        // |Y_lm| ≤ √((2l + 1)/2π) for the real harmonics.
        let mut y = Vec::new();
        for theta in [1e-9, 0.3, 1.2, PI / 2.0] {
            eval_full_basis(MAX_L_MAX, Dir::from_angles(theta, 0.9), &mut y);
            let bound = ((2.0 * MAX_L_MAX as f64 + 1.0) / TAU).sqrt();
            assert!(y.iter().all(|v| v.is_finite() && v.abs() <= bound + 1e-9));
        }
    }

    #[test]
    fn table_at_nodes_is_eval_angles_bit_for_bit() {
        let f = |a: [f64; 4]| 1.0 + a[0].sin() * a[1] + a[2].cos() * a[3] * a[3] + a[0] * a[2];
        let t = Axis::polar_midpoints(7);
        let grids = [
            Grid::hemisphere(7, 24),
            Grid::isotropic(t, Axis::full_turn(24), t),
            // A half turn of φ+: differences below 0 hold the end value.
            Grid::isotropic(t, Axis::from_deg(0.0, 10.0, 19), t),
            Grid::full(
                Axis::from_deg(0.0, 30.0, 5),
                Axis::from_deg(0.0, 15.0, 7),
                Axis::full_turn(18),
                Axis::from_deg(0.0, 10.0, 10),
            ),
        ];
        for g in grids {
            let v: Vec<f64> = (0..g.len()).map(|i| f(g.angles(i))).collect();
            let table = Table::new(Channels::Single, g, v, None).expect("table");
            let nodes = Nodes::new(3, 9);
            let at = TableAtNodes::new(&table, &nodes);
            let q = nodes.angles.len();
            for a in 0..q {
                for b in 0..q {
                    let ([pi, ti], [po, to]) = (nodes.angles[a], nodes.angles[b]);
                    let want = table.eval_angles(0, [pi, ti, po, to]);
                    assert_eq!(at.eval(table.channel(0), a, b).to_bits(), want.to_bits());
                }
            }
        }
    }

    #[test]
    fn taper_is_one_then_falls_smoothly() {
        assert_eq!(taper(3, 3, 3), 1.0);
        assert_eq!(taper(2, 4, 8), 1.0);
        assert!((taper(5, 4, 7) - 0.5 * (1.0 + (PI / 4.0).cos())).abs() < 1e-15);
        assert!((taper(6, 4, 7) - 0.5).abs() < 1e-15);
        assert_eq!(taper(9, 4, 8), 0.0);
        let t: Vec<f64> = (4..=8).map(|l| taper(l, 4, 8)).collect();
        assert!(t.windows(2).all(|p| p[1] < p[0]) && t[4] > 0.0);
    }

    #[test]
    fn options_are_checked() {
        let f = |_: usize, _: Dir, _: Dir| 1.0;
        let e = ShBrdf::project(Channels::Single, f, &ShOptions::new(4).with_filter(5));
        assert!(matches!(e, Err(ProcessError::Value(m)) if m.contains("l_filter")));
        let e = ShBrdf::project(Channels::Single, f, &ShOptions::new(4).with_quadrature(4));
        assert!(matches!(e, Err(ProcessError::Value(m)) if m.contains("at least 5")));
        let e = ShBrdf::project(Channels::Single, f, &ShOptions::new(MAX_L_MAX + 1));
        assert!(e.is_err());
        let e = ShBrdf::project(Channels::Single, |_, _, _| f64::NAN, &ShOptions::new(1));
        assert!(matches!(e, Err(ProcessError::Value(m)) if m.contains("not finite")));
    }
}

