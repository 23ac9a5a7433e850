//! Generalized cosine lobes (Lafortune et al. 1997, Eq. 8) as a separable basis.
//!
//! A lobe max(0, Cx ux vx + Cy uy vy + Cz uz vz)ⁿ is written s · max(0, ĉ·(u∘v))ⁿ with
//! ĉ = C/|C| a unit vector and s = |C|ⁿ ≥ 0: its strength s is then a linear
//! coefficient (found exactly by the projection) and only the direction of ĉ and the
//! exponent are searched. Isotropic lobes (Cx = Cy) have ĉ = (sin β/√2, sin β/√2,
//! cos β) — β > 0 retro-reflective, β < 0 forward; anisotropic ones ĉ = (sin β cos γ,
//! sin β sin γ, cos β). Exponents are n = e^η (never negative, any real value). The
//! diffuse term is Lambert's ρd/π or Minnaert's ρd (m+2)/(2π) (uz vz)^m (Eq. 6) with
//! m = κ² ≥ 0. The derivatives below are analytic; `tests/it/fit.rs` checks them against
//! central differences.

use std::f64::consts::{FRAC_1_SQRT_2, PI, TAU};

use crate::fastmath;
use crate::varpro::{Basis, Chunk};

/// The diffuse term.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Diffuse {
    /// ρd / π.
    Lambert,
    /// ρd (m+2)/(2π) (uz vz)^m (Lafortune Eq. 6).
    Minnaert,
}

/// The shape of a lobe model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Shape {
    /// Number of lobes.
    pub lobes: usize,
    /// Cx ≠ Cy allowed.
    pub anisotropic: bool,
    /// The diffuse term.
    pub diffuse: Diffuse,
}

impl Shape {
    /// Direction parameters a lobe.
    pub fn dir_params(&self) -> usize {
        if self.anisotropic { 2 } else { 1 }
    }

    /// Non-linear parameters a channel: directions, exponents, Minnaert's κ.
    pub fn params_per_channel(&self) -> usize {
        self.lobes * (self.dir_params() + 1) + usize::from(self.diffuse == Diffuse::Minnaert)
    }
}

/// The lobe basis over `channels` channels fitted together; with `shared`, the lobes'
/// exponents (and Minnaert's) are one set for all channels, the layout being
/// [η_1 … η_N, κ] then per channel [β_j (γ_j)]; otherwise per channel
/// [β_j (γ_j), η_j …, κ].
#[derive(Clone, Copy, Debug)]
pub struct LobeBasis {
    /// The model's shape.
    pub shape: Shape,
    /// Channels in this fit.
    pub channels: usize,
    /// Shared exponents.
    pub shared: bool,
}

/// Indices of one lobe's parameters in θ.
struct LobeIdx {
    beta: usize,
    gamma: Option<usize>,
    eta: usize,
}

impl LobeBasis {
    fn shared_len(&self) -> usize {
        self.shape.lobes + usize::from(self.shape.diffuse == Diffuse::Minnaert)
    }

    fn lobe_idx(&self, ch: usize, j: usize) -> LobeIdx {
        let s = &self.shape;
        let dp = s.dir_params();
        if self.shared {
            let base = self.shared_len() + ch * s.lobes * dp + j * dp;
            LobeIdx {
                beta: base,
                gamma: s.anisotropic.then_some(base + 1),
                eta: j,
            }
        } else {
            let base = ch * s.params_per_channel() + j * (dp + 1);
            LobeIdx {
                beta: base,
                gamma: s.anisotropic.then_some(base + 1),
                eta: base + dp,
            }
        }
    }

    /// Index of Minnaert's κ for a channel.
    pub fn kappa_idx(&self, ch: usize) -> Option<usize> {
        (self.shape.diffuse == Diffuse::Minnaert).then(|| {
            if self.shared {
                self.shape.lobes
            } else {
                ch * self.shape.params_per_channel()
                    + self.shape.lobes * (self.shape.dir_params() + 1)
            }
        })
    }

    /// The unit direction ĉ of lobe j in channel ch, and its exponent.
    pub fn lobe(&self, theta: &[f64], ch: usize, j: usize) -> ([f64; 3], f64) {
        let ix = self.lobe_idx(ch, j);
        let b = theta[ix.beta];
        let c = match ix.gamma {
            Some(g) => {
                let g = theta[g];
                [b.sin() * g.cos(), b.sin() * g.sin(), b.cos()]
            }
            None => [b.sin() * FRAC_1_SQRT_2, b.sin() * FRAC_1_SQRT_2, b.cos()],
        };
        (c, theta[ix.eta].exp())
    }

    /// Minnaert's exponent m for a channel (0 for Lambert).
    pub fn diffuse_exponent(&self, theta: &[f64], ch: usize) -> f64 {
        self.kappa_idx(ch).map_or(0.0, |k| theta[k] * theta[k])
    }

    /// Sets lobe j of channel ch from a direction angle β (γ) and exponent n.
    pub fn set_lobe(&self, theta: &mut [f64], ch: usize, j: usize, beta: f64, gamma: f64, n: f64) {
        let ix = self.lobe_idx(ch, j);
        theta[ix.beta] = beta;
        if let Some(g) = ix.gamma {
            theta[g] = gamma;
        }
        theta[ix.eta] = n.max(1e-3).ln();
    }
}

/// One lobe at a θ: ĉ, ∂ĉ/∂β, ∂ĉ/∂γ, n and its parameter indices.
struct Lobe {
    c: [f64; 3],
    dc_db: [f64; 3],
    dc_dg: Option<(usize, [f64; 3])>,
    n: f64,
    beta: usize,
    eta: usize,
}

impl LobeBasis {
    /// The lobes of channel `ch` at θ (computed once a chunk).
    fn lobes_at(&self, theta: &[f64], ch: usize) -> Vec<Lobe> {
        (0..self.shape.lobes)
            .map(|j| {
                let ix = self.lobe_idx(ch, j);
                let (sb, cb) = theta[ix.beta].sin_cos();
                let (c, dc_db, dc_dg) = match ix.gamma {
                    Some(gi) => {
                        let (sg, cg) = theta[gi].sin_cos();
                        (
                            [sb * cg, sb * sg, cb],
                            [cb * cg, cb * sg, -sb],
                            Some((gi, [-sb * sg, sb * cg, 0.0])),
                        )
                    }
                    None => (
                        [sb * FRAC_1_SQRT_2, sb * FRAC_1_SQRT_2, cb],
                        [cb * FRAC_1_SQRT_2, cb * FRAC_1_SQRT_2, -sb],
                        None,
                    ),
                };
                Lobe {
                    c,
                    dc_db,
                    dc_dg,
                    n: theta[ix.eta].exp(),
                    beta: ix.beta,
                    eta: ix.eta,
                }
            })
            .collect()
    }
}

impl Basis for LobeBasis {
    fn n_params(&self) -> usize {
        if self.shared {
            self.shared_len() + self.channels * self.shape.lobes * self.shape.dir_params()
        } else {
            self.channels * self.shape.params_per_channel()
        }
    }

    fn n_cols(&self) -> usize {
        1 + self.shape.lobes
    }

    fn eval(
        &self,
        theta: &[f64],
        ch: usize,
        wi: [f64; 3],
        wo: [f64; 3],
        cols: &mut [f64],
        d: Option<&mut [f64]>,
    ) {
        self.eval_chunk(theta, ch, &[wi], &[wo], cols, d);
    }

    fn eval_chunk(
        &self,
        theta: &[f64],
        ch: usize,
        wi: &[[f64; 3]],
        wo: &[[f64; 3]],
        cols: &mut [f64],
        mut d: Option<&mut [f64]>,
    ) {
        let (np, k) = (self.n_params(), self.n_cols());
        let lobes = self.lobes_at(theta, ch);
        let kappa = self.kappa_idx(ch).map(|ki| (ki, theta[ki]));
        if let Some(d) = d.as_deref_mut() {
            d.fill(0.0);
        }
        for i in 0..wi.len() {
            let (u, v) = (wi[i], wo[i]);
            let col = &mut cols[i * k..(i + 1) * k];
            let mut drow = d
                .as_deref_mut()
                .map(|d| &mut d[i * k * np..(i + 1) * k * np]);
            match kappa {
                None => col[0] = 1.0 / PI,
                Some((ki, kp)) => {
                    let m = kp * kp;
                    let t = u[2] * v[2];
                    let lt = t.ln();
                    let tm = (m * lt).exp();
                    col[0] = (m + 2.0) / TAU * tm;
                    if let Some(dr) = drow.as_deref_mut() {
                        // d/dm [(m+2)/(2π) t^m] = t^m/(2π) + (m+2)/(2π) t^m ln t; dm/dκ = 2κ.
                        dr[ki] = 2.0 * kp * (tm / TAU + (m + 2.0) / TAU * tm * lt);
                    }
                }
            }
            let uv = [u[0] * v[0], u[1] * v[1], u[2] * v[2]];
            for (j, l) in lobes.iter().enumerate() {
                let x = l.c[0] * uv[0] + l.c[1] * uv[1] + l.c[2] * uv[2];
                if x <= 0.0 {
                    col[1 + j] = 0.0;
                    continue;
                }
                // x^n as exp(n ln x): the logarithm is needed for ∂/∂η anyway.
                let lx = x.ln();
                let h = (l.n * lx).exp();
                col[1 + j] = h;
                let Some(dr) = drow.as_deref_mut() else {
                    continue;
                };
                let row = &mut dr[(1 + j) * np..(2 + j) * np];
                let dh_dx = l.n * h / x;
                row[l.beta] =
                    dh_dx * (l.dc_db[0] * uv[0] + l.dc_db[1] * uv[1] + l.dc_db[2] * uv[2]);
                if let Some((gi, dg)) = l.dc_dg {
                    row[gi] = dh_dx * (dg[0] * uv[0] + dg[1] * uv[1]);
                }
                row[l.eta] = h * lx * l.n;
            }
        }
    }

    fn scratch_len(&self) -> usize {
        self.shape.lobes + usize::from(self.shape.diffuse == Diffuse::Minnaert)
    }

    // The diffuse column's albedo is exact (Lambert: 1; Minnaert: u_z^m, as
    // `gonio-brdf` integrates Eq. 6); a lobe's is Eq. 5's scale |ĉ∘u|ⁿ times the exact
    // hemispherical integral of a cosine lobe about ĉ∘u (`gonio_brdf::lobe`), whose
    // derivatives in β, γ and η are central differences (step 1e-5: the integral is
    // good to ~1e-12 relative, so they are good to ~1e-7).
    fn albedo_rows(
        &self,
        theta: &[f64],
        ch: usize,
        wi: &[[f64; 3]],
        b: &mut [f64],
        mut db: Option<&mut [f64]>,
    ) {
        let (k, np) = (self.n_cols(), self.n_params());
        if let Some(d) = db.as_deref_mut() {
            d.fill(0.0);
        }
        let kappa = self.kappa_idx(ch).map(|ki| (ki, theta[ki]));
        let lobes = self.lobes_at(theta, ch);
        const H: f64 = 1e-5;
        for (l, u) in wi.iter().enumerate() {
            let row = l * k;
            match kappa {
                None => b[row] = 1.0,
                Some((ki, kp)) => {
                    let tm = u[2].powf(kp * kp);
                    b[row] = tm;
                    if let Some(d) = db.as_deref_mut() {
                        d[row * np + ki] = tm * u[2].ln() * 2.0 * kp;
                    }
                }
            }
            for (j, lb) in lobes.iter().enumerate() {
                let col = row + 1 + j;
                b[col] = lobe_albedo(lb.c, lb.n, *u);
                let Some(d) = db.as_deref_mut() else {
                    continue;
                };
                let ix = self.lobe_idx(ch, j);
                let mut params = vec![ix.beta, ix.eta];
                params.extend(ix.gamma);
                for q in params {
                    let mut t = theta.to_vec();
                    t[q] = theta[q] + H;
                    let (cp, np_) = self.lobe(&t, ch, j);
                    t[q] = theta[q] - H;
                    let (cm, nm) = self.lobe(&t, ch, j);
                    d[col * np + q] =
                        (lobe_albedo(cp, np_, *u) - lobe_albedo(cm, nm, *u)) / (2.0 * H);
                }
            }
        }
    }

    // The fast path: per lobe, x = ĉ·(u∘v) for the whole chunk and then ln x and xⁿ
    // by the vectorised kernel; ln x is kept for the derivatives.
    fn columns(
        &self,
        theta: &[f64],
        ch: usize,
        chunk: &Chunk,
        cols: &mut [f64],
        scratch: &mut [f64],
    ) {
        let len = chunk.len();
        let nl = self.shape.lobes;
        let uz = chunk.uv[2];
        let (c0, rest) = cols.split_at_mut(len);
        match self.kappa_idx(ch) {
            None => {
                for (o, w) in c0.iter_mut().zip(chunk.w) {
                    *o = w / PI;
                }
            }
            Some(ki) => {
                let m = theta[ki] * theta[ki];
                let lt = &mut scratch[nl * len..(nl + 1) * len];
                fastmath::ln_pow(uz, m, lt, c0);
                let f = (m + 2.0) / TAU;
                for (o, w) in c0.iter_mut().zip(chunk.w) {
                    *o *= f * w;
                }
            }
        }
        for (j, l) in self.lobes_at(theta, ch).iter().enumerate() {
            fastmath::lobe_column(
                l.c,
                l.n,
                chunk.uv,
                chunk.w,
                &mut scratch[j * len..(j + 1) * len],
                &mut rest[j * len..(j + 1) * len],
            );
        }
    }

    fn directional(
        &self,
        theta: &[f64],
        ch: usize,
        chunk: &Chunk,
        cols: &[f64],
        scratch: &[f64],
        c: &[f64],
        v: &mut [f64],
    ) {
        let len = chunk.len();
        v.fill(0.0);
        if let Some(ki) = self.kappa_idx(ch) {
            // d/dκ [w ρ (m+2)/(2π) t^m] = 2κ ρ w t^m/(2π) (1 + (m+2) ln t), m = κ².
            let kp = theta[ki];
            let m = kp * kp;
            let lt = &scratch[self.shape.lobes * len..(self.shape.lobes + 1) * len];
            let f = c[0] * 2.0 * kp;
            for ((o, col), lt) in v[ki * len..(ki + 1) * len]
                .iter_mut()
                .zip(&cols[..len])
                .zip(lt)
            {
                *o = f * (col / (m + 2.0) + col * lt);
            }
        }
        let mut out: Vec<&mut [f64]> = v.chunks_mut(len).collect();
        for (j, l) in self.lobes_at(theta, ch).iter().enumerate() {
            let s = c[1 + j];
            if s == 0.0 {
                continue;
            }
            let derivatives = fastmath::LobeDerivatives {
                beta: std::mem::take(&mut out[l.beta]),
                gamma: l.dc_dg.map(|(gi, dg)| (std::mem::take(&mut out[gi]), dg)),
                eta: std::mem::take(&mut out[l.eta]),
            };
            fastmath::lobe_derivatives(
                l.c,
                l.dc_db,
                s * l.n,
                chunk.uv,
                &cols[(1 + j) * len..(2 + j) * len],
                &scratch[j * len..(j + 1) * len],
                derivatives,
            );
        }
    }
}

/// The directional albedo at incident direction `u` of the unit-strength lobe
/// max(0, ĉ·(u∘v))ⁿ: with w = ĉ∘u, |w|ⁿ times the albedo of a unit cosine lobe about
/// w/|w| (Lafortune et al. Eq. 5).
pub fn lobe_albedo(c: [f64; 3], n: f64, u: [f64; 3]) -> f64 {
    let w = [c[0] * u[0], c[1] * u[1], c[2] * u[2]];
    let norm = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
    if norm == 0.0 {
        return 0.0;
    }
    norm.powf(n) * gonio_brdf::lobe::hemisphere_albedo(n, w[2] / norm)
}

/// Natural parameters of one channel's fitted model: ρd, Minnaert's m, and per lobe
/// (Cx, Cy, Cz, n) with C = s^{1/n} ĉ.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Natural {
    /// Diffuse albedo at normal incidence.
    pub rho_d: f64,
    /// Minnaert exponent (0: Lambert).
    pub m: f64,
    /// (Cx, Cy, Cz, n) per lobe.
    pub lobes: Vec<[f64; 4]>,
}

impl LobeBasis {
    /// ∂(natural parameters of channel `ch`)/∂(θ, c_0, …, c_{channels−1}): one row a
    /// natural parameter in the order (ρd, \[m\], per lobe Cx, \[Cy\], Cz, n) — Cy only
    /// when anisotropic — for the delta method. A lobe of strength 0 has zero rows for
    /// its C (its direction is not determined).
    pub fn natural_jacobian(&self, theta: &[f64], ch: usize, coef: &[f64]) -> Vec<Vec<f64>> {
        let (p, k) = (self.n_params(), self.n_cols());
        let n_all = p + self.channels * k;
        let c0 = p + ch * k;
        let mut rows = Vec::new();
        let mut row = vec![0.0; n_all];
        row[c0] = 1.0;
        rows.push(row);
        if let Some(ki) = self.kappa_idx(ch) {
            let mut row = vec![0.0; n_all];
            row[ki] = 2.0 * theta[ki];
            rows.push(row);
        }
        let dirs = self.lobes_at(theta, ch);
        for (j, l) in dirs.iter().enumerate() {
            let s = coef[1 + j];
            let n = l.n;
            let r = if s > 0.0 { s.powf(1.0 / n) } else { 0.0 };
            let comps: &[usize] = if self.shape.anisotropic {
                &[0, 1, 2]
            } else {
                &[0, 2]
            };
            for &a in comps {
                let mut row = vec![0.0; n_all];
                if s > 0.0 {
                    row[l.beta] = r * l.dc_db[a];
                    if let Some((gi, dg)) = l.dc_dg {
                        row[gi] = r * dg[a];
                    }
                    // r = s^{1/n}: ∂r/∂s = r/(n s), ∂r/∂η = −r ln s / n (n = e^η).
                    row[c0 + 1 + j] = l.c[a] * r / (n * s);
                    row[l.eta] = -l.c[a] * r * s.ln() / n;
                }
                rows.push(row);
            }
            let mut row = vec![0.0; n_all];
            row[l.eta] = n;
            rows.push(row);
        }
        rows
    }

    /// The natural parameters of channel `ch` from θ and its linear coefficients.
    pub fn natural(&self, theta: &[f64], ch: usize, coef: &[f64]) -> Natural {
        let lobes = (0..self.shape.lobes)
            .map(|j| {
                let (c, n) = self.lobe(theta, ch, j);
                let r = coef[1 + j].max(0.0).powf(1.0 / n);
                [r * c[0], r * c[1], r * c[2], n]
            })
            .collect();
        Natural {
            rho_d: coef[0],
            m: self.diffuse_exponent(theta, ch),
            lobes,
        }
    }
}
