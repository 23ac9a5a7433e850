//! Separable non-linear least squares by variable projection (Golub & Pereyra 1973),
//! driven by the `levenberg-marquardt` crate.
//!
//! Every model Gonio fits is a non-negative combination of columns that depend on a
//! few non-linear parameters θ: f = Σ_k c_k A_k(θ) — a Lafortune fit's columns are its
//! diffuse term and its lobes of unit strength, the linear coefficients their albedo
//! and strengths. For a given θ the best c ≥ 0 is a small non-negative least-squares
//! problem (Lawson–Hanson on the K × K normal equations), so Levenberg–Marquardt only
//! searches θ: the residual is r(θ) = W(A(θ) c(θ) − y) and its Jacobian is Kaufman's
//! (1975) approximation J = P⊥ W ∂A/∂θ c, with P⊥ the projection off the span of the
//! free columns. The linear parameters are always exactly optimal, the search space
//! shrinks by K dimensions, and no start value is needed for them.
//!
//! J itself is never formed: [`evaluate`] accumulates JᵀJ and Jᵀr chunk by chunk, and
//! [`Projected`] hands the crate an equivalent (P + 1)-row problem (`compress`).

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt, TerminationReason};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use rayon::prelude::*;

use crate::data::FitData;
use crate::fastmath::dot;

/// Columns of a separable model and their derivatives.
pub trait Basis: Sync {
    /// Non-linear parameters.
    fn n_params(&self) -> usize;
    /// Columns a channel.
    fn n_cols(&self) -> usize;
    /// The columns of channel `ch` at sample (wi, wo) into `cols`; with `d`, also
    /// ∂col_k/∂θ_p into `d[k * n_params + p]`.
    fn eval(
        &self,
        theta: &[f64],
        ch: usize,
        wi: [f64; 3],
        wo: [f64; 3],
        cols: &mut [f64],
        d: Option<&mut [f64]>,
    );

    /// [`eval`](Basis::eval) over consecutive samples: `cols` holds K values a sample,
    /// `d` K × P a sample. Bases whose columns share work across samples at one θ
    /// (the lobes' directions and exponents) override it.
    fn eval_chunk(
        &self,
        theta: &[f64],
        ch: usize,
        wi: &[[f64; 3]],
        wo: &[[f64; 3]],
        cols: &mut [f64],
        mut d: Option<&mut [f64]>,
    ) {
        let (k, p) = (self.n_cols(), self.n_params());
        for i in 0..wi.len() {
            let di = d.as_deref_mut().map(|d| &mut d[i * k * p..(i + 1) * k * p]);
            self.eval(theta, ch, wi[i], wo[i], &mut cols[i * k..(i + 1) * k], di);
        }
    }

    /// Scratch values a sample that [`columns`](Basis::columns) leaves for
    /// [`directional`](Basis::directional).
    fn scratch_len(&self) -> usize {
        0
    }

    /// The weighted columns `w_i A_k(θ; i)` of channel `ch` over a chunk, column-major
    /// (`cols[k * len + i]`), keeping in `scratch` (`scratch_len()` a sample, laid out
    /// as the basis likes) what [`directional`](Basis::directional) needs. The default
    /// calls [`eval`](Basis::eval) a sample.
    fn columns(
        &self,
        theta: &[f64],
        ch: usize,
        chunk: &Chunk,
        cols: &mut [f64],
        scratch: &mut [f64],
    ) {
        let _ = scratch;
        let (k, len) = (self.n_cols(), chunk.len());
        let mut row = vec![0.0; k];
        for i in 0..len {
            self.eval(theta, ch, chunk.wi[i], chunk.wo[i], &mut row, None);
            for (u, x) in row.iter().enumerate() {
                cols[u * len + i] = x * chunk.w[i];
            }
        }
    }

    /// `v[q * len + i] = w_i Σ_k c_k ∂A_k(θ; i)/∂θ_q` over a chunk (column-major), after
    /// [`columns`](Basis::columns) filled `cols` and `scratch` at the same θ. The
    /// default calls [`eval`](Basis::eval) with derivatives a sample.
    #[allow(clippy::too_many_arguments)]
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
        let _ = (cols, scratch);
        let (k, p) = (self.n_cols(), self.n_params());
        let mut row = vec![0.0; k];
        let mut d = vec![0.0; k * p];
        for i in 0..chunk.len() {
            d.fill(0.0);
            self.eval(theta, ch, chunk.wi[i], chunk.wo[i], &mut row, Some(&mut d));
            for q in 0..p {
                v[q * chunk.len() + i] =
                    chunk.w[i] * (0..k).map(|u| c[u] * d[u * p + q]).sum::<f64>();
            }
        }
    }
}

/// Consecutive samples as a basis sees them.
pub struct Chunk<'a> {
    /// Incident directions.
    pub wi: &'a [[f64; 3]],
    /// Outgoing directions.
    pub wo: &'a [[f64; 3]],
    /// The componentwise products wi ∘ wo, by component.
    pub uv: [&'a [f64]; 3],
    /// Residual weights of the channel being evaluated.
    pub w: &'a [f64],
}

impl Chunk<'_> {
    /// Samples in the chunk.
    pub fn len(&self) -> usize {
        self.wi.len()
    }

    /// Whether it has none.
    pub fn is_empty(&self) -> bool {
        self.wi.is_empty()
    }
}

/// Fit data with what every evaluation reuses: wi ∘ wo by component, and the
/// weighted values.
pub struct Prepared<'a> {
    /// The data.
    pub data: &'a FitData,
    uv: [Vec<f64>; 3],
    wy: Vec<Vec<f64>>,
    /// The columns' and scratch buffers of the last evaluation, reused: allocating
    /// megabytes anew each time costs page faults and zeroing.
    buffers: std::sync::Mutex<Option<(Vec<f64>, Vec<f64>)>>,
}

impl<'a> Prepared<'a> {
    /// Prepares `data`.
    pub fn new(data: &'a FitData) -> Prepared<'a> {
        let uv = [0, 1, 2].map(|a| {
            data.wi
                .iter()
                .zip(data.wo.iter())
                .map(|(u, v)| u[a] * v[a])
                .collect()
        });
        let wy = data
            .weight
            .iter()
            .zip(&data.y)
            .map(|(w, y)| w.iter().zip(y).map(|(w, y)| w * y).collect())
            .collect();
        Prepared {
            data,
            uv,
            wy,
            buffers: std::sync::Mutex::new(None),
        }
    }

    /// wi ∘ wo of every sample, by component.
    pub fn uv(&self) -> [&[f64]; 3] {
        [&self.uv[0], &self.uv[1], &self.uv[2]]
    }

    /// W y of channel `ch`.
    pub fn weighted_values(&self, ch: usize) -> &[f64] {
        &self.wy[ch]
    }

    fn chunk(&self, ch: usize, lo: usize, hi: usize) -> Chunk<'_> {
        Chunk {
            wi: &self.data.wi[lo..hi],
            wo: &self.data.wo[lo..hi],
            uv: [
                &self.uv[0][lo..hi],
                &self.uv[1][lo..hi],
                &self.uv[2][lo..hi],
            ],
            w: &self.data.weight[ch][lo..hi],
        }
    }
}

/// Samples a chunk of the parallel loops handles; sums are formed a chunk at a time
/// and then added in chunk order, so results do not depend on the thread count.
const CHUNK: usize = 2048;

/// The projected problem at one θ.
pub struct Evaluation {
    /// Linear coefficients per channel (0 where the constraint c ≥ 0 is active).
    pub coef: Vec<Vec<f64>>,
    /// Σ r², the residuals being W(Ac − y) over every channel.
    pub cost: f64,
    /// With the Jacobian asked for: JᵀJ (P × P, row-major) and Jᵀr of Kaufman's
    /// Jacobian J = P⊥ W ∂A/∂θ c. The Jacobian itself (m × P) is never formed.
    pub normal: Option<(Vec<f64>, Vec<f64>)>,
    /// With the Jacobian asked for: the residuals and the Gram matrices of the full
    /// (unprojected) problem, for the standard errors.
    pub full: Option<Full>,
}

/// What the covariance of all parameters (θ and every channel's c) needs: the Gram
/// matrix of the full Jacobian [∂f/∂θ | ∂f/∂c] = [V | WA] per channel, and the
/// residuals.
#[derive(Clone, Debug)]
pub struct Full {
    /// W(Ac − y), channel after channel.
    pub residuals: Vec<f64>,
    /// Per channel: VᵀV (P × P), (WA)ᵀV (K × P), (WA)ᵀWA (K × K), row-major.
    pub grams: Vec<[Vec<f64>; 3]>,
}

impl Full {
    /// s² (JᵀJ)⁺ over (θ, c_0, …, c_{nc−1}) with s² = Σr²/(m − parameters): the
    /// covariance of the weighted least-squares estimate. The pseudo-inverse (after
    /// equilibration, relative cut 1e-14) reports 0 for parameters the data do not
    /// determine, such as the direction of a lobe of strength 0.
    pub fn covariance(&self, p: usize, k: usize) -> (DMatrix<f64>, f64) {
        let nc = self.grams.len();
        let n = p + nc * k;
        let mut m = DMatrix::<f64>::zeros(n, n);
        for (ch, [vv, av, aa]) in self.grams.iter().enumerate() {
            let o = p + ch * k;
            for a in 0..p {
                for b in 0..p {
                    m[(a, b)] += vv[a.min(b) * p + a.max(b)];
                }
            }
            for u in 0..k {
                for a in 0..p {
                    m[(o + u, a)] = av[u * p + a];
                    m[(a, o + u)] = av[u * p + a];
                }
                for v in 0..k {
                    m[(o + u, o + v)] = aa[u * k + v];
                }
            }
        }
        let d: Vec<f64> = (0..n)
            .map(|a| {
                let x = m[(a, a)];
                if x > 0.0 && x.is_finite() {
                    1.0 / x.sqrt()
                } else {
                    0.0
                }
            })
            .collect();
        let s = DMatrix::from_fn(n, n, |a, b| m[(a, b)] * d[a] * d[b]);
        let pinv = s
            .pseudo_inverse(1e-14 * n as f64)
            .unwrap_or_else(|_| DMatrix::zeros(n, n));
        let rows = self.residuals.len();
        let rss: f64 = self.residuals.iter().map(|r| r * r).sum();
        let s2 = if rows > n {
            rss / (rows - n) as f64
        } else {
            0.0
        };
        (
            DMatrix::from_fn(n, n, |a, b| s2 * pinv[(a, b)] * d[a] * d[b]),
            s2,
        )
    }
}

/// Adds `b` into `a` elementwise.
fn add_into(mut a: Vec<f64>, b: Vec<f64>) -> Vec<f64> {
    for (x, y) in a.iter_mut().zip(b) {
        *x += y;
    }
    a
}

/// `out = Aᵀ B` (na × nb, row-major) for column-major A (len × na) and B (len × nb):
/// faer's matrix product, whose kernels use the CPU's vector units.
pub(crate) fn gram(a: &[f64], na: usize, b: &[f64], nb: usize, len: usize, out: &mut [f64]) {
    let am = MatRef::from_column_major_slice(&a[..len * na], len, na);
    let bm = MatRef::from_column_major_slice(&b[..len * nb], len, nb);
    let mut dst = Mat::<f64>::zeros(na, nb);
    matmul(
        dst.as_mut(),
        Accum::Replace,
        am.transpose(),
        bm,
        1.0,
        Par::Seq,
    );
    for u in 0..na {
        for v in 0..nb {
            out[u * nb + v] = dst[(u, v)];
        }
    }
}

/// `out = Xᵀ X[:, k..]` for column-major X (len × stride): ((stride) × (stride − k),
/// row-major).
fn gram_tail(x: &[f64], stride: usize, k: usize, len: usize, out: &mut [f64]) {
    let xm = MatRef::from_column_major_slice(&x[..len * stride], len, stride);
    let q = stride - k;
    let mut dst = Mat::<f64>::zeros(stride, q);
    matmul(
        dst.as_mut(),
        Accum::Replace,
        xm.transpose(),
        xm.subcols(k, q),
        1.0,
        Par::Seq,
    );
    for u in 0..stride {
        for v in 0..q {
            out[u * q + v] = dst[(u, v)];
        }
    }
}

/// One channel's columns over all samples (chunk after chunk, each column-major) and
/// the basis's scratch.
struct Columns {
    cols: Vec<f64>,
    scratch: Vec<f64>,
    /// G = (WA)ᵀWA, h = (WA)ᵀWy.
    g: Vec<f64>,
    h: Vec<f64>,
}

/// With `extra` > 0 every chunk's block has room for that many more columns after
/// its K (pass B writes [V | r] there, so one matrix product covers [A | V | r]).
fn columns(basis: &dyn Basis, prep: &Prepared, theta: &[f64], ch: usize, extra: usize) -> Columns {
    let (k, m) = (basis.n_cols(), prep.data.len());
    let stride = k + extra;
    let s = basis.scratch_len().max(1);
    // Every entry is written by `Basis::columns` before it is read.
    let (mut cols, mut scratch) = prep
        .buffers
        .lock()
        .ok()
        .and_then(|mut b| b.take())
        .unwrap_or_default();
    // A fresh zeroed allocation (calloc: pages the kernel zeroes on first touch) rather
    // than growing the old one (which fills it twice, once with zeros).
    if cols.len() < m * stride {
        cols = vec![0.0; m * stride];
    }
    cols.truncate(m * stride);
    if scratch.len() < m * s {
        scratch = vec![0.0; m * s];
    }
    scratch.truncate(m * s);
    let wy = &prep.wy[ch];
    let parts: Vec<Vec<f64>> = cols
        .par_chunks_mut(CHUNK * stride)
        .zip(scratch.par_chunks_mut(CHUNK * s))
        .enumerate()
        .map(|(ci, (block, sc))| {
            let lo = ci * CHUNK;
            let len = block.len() / stride;
            let cc = &mut block[..len * k];
            let chunk = prep.chunk(ch, lo, lo + len);
            basis.columns(theta, ch, &chunk, cc, sc);
            // [G (k × k) | h (k)] of this chunk.
            let mut acc = vec![0.0; k * k + k];
            gram(cc, k, cc, k, len, &mut acc[..k * k]);
            for u in 0..k {
                acc[k * k + u] = dot(&cc[u * len..(u + 1) * len], &wy[lo..lo + len]);
            }
            acc
        })
        .collect();
    let acc = parts.into_iter().fold(vec![0.0; k * k + k], add_into);
    // Symmetric by construction, not by the product's rounding.
    let mut g = acc[..k * k].to_vec();
    for u in 0..k {
        for v in 0..u {
            g[u * k + v] = g[v * k + u];
        }
    }
    Columns {
        cols,
        scratch,
        g,
        h: acc[k * k..].to_vec(),
    }
}

/// The weighted columns of channel `ch` at θ, each over all samples.
pub fn column_vectors(
    basis: &dyn Basis,
    prep: &Prepared,
    theta: &[f64],
    ch: usize,
) -> Vec<Vec<f64>> {
    let k = basis.n_cols();
    let cl = columns(basis, prep, theta, ch, 0);
    let mut out = vec![Vec::with_capacity(prep.data.len()); k];
    for cc in cl.cols.chunks(CHUNK * k) {
        let len = cc.len() / k;
        for (u, o) in out.iter_mut().enumerate() {
            o.extend_from_slice(&cc[u * len..(u + 1) * len]);
        }
    }
    out
}

/// (G_F)⁻¹ of the free columns through the equilibrated matrix (see [`nnls`]).
fn free_inverse(g: &[f64], k: usize, free: &[usize]) -> DMatrix<f64> {
    let nf = free.len();
    let ds: Vec<f64> = free.iter().map(|&u| g[u * k + u].sqrt()).collect();
    let gf = DMatrix::from_fn(nf, nf, |x, z| {
        g[free[x] * k + free[z]] / (ds[x] * ds[z]) + if x == z { 1e-13 } else { 0.0 }
    });
    let inv = gf
        .clone()
        .cholesky()
        .map(|ch| ch.inverse())
        .or_else(|| gf.try_inverse())
        .unwrap_or_else(|| DMatrix::zeros(nf, nf));
    DMatrix::from_fn(nf, nf, |x, z| inv[(x, z)] / (ds[x] * ds[z]))
}

/// Evaluates the projected problem at `theta`.
pub fn evaluate(basis: &dyn Basis, data: &FitData, theta: &[f64], jac: bool) -> Evaluation {
    evaluate_prepared(basis, &Prepared::new(data), theta, jac)
}

/// [`evaluate`] on prepared data.
pub fn evaluate_prepared(
    basis: &dyn Basis,
    prep: &Prepared,
    theta: &[f64],
    jac: bool,
) -> Evaluation {
    let (k, p) = (basis.n_cols(), basis.n_params());
    let nc = prep.data.channels.len();
    let s = basis.scratch_len().max(1);
    let mut coef = Vec::with_capacity(nc);
    let mut cost = 0.0;
    let mut jtj = vec![0.0; p * p];
    let mut jtr = vec![0.0; p];
    let mut full = jac.then(|| Full {
        residuals: Vec::with_capacity(nc * prep.data.len()),
        grams: Vec::with_capacity(nc),
    });
    for ch in 0..nc {
        let q = if jac { p + 1 } else { 0 };
        let stride = k + q;
        let mut cl = columns(basis, prep, theta, ch, q);
        let c = nnls(&cl.g, &cl.h, k);
        let free: Vec<usize> = (0..k).filter(|&u| c[u] > 0.0).collect();
        let nf = free.len();
        let wy = &prep.wy[ch];
        // Per chunk, with X = [WA | V | r] (V = W ∂A/∂θ c): Xᵀ[V | r], (k + p + 1) ×
        // (p + 1) row-major — (WA)ᵀ[V | r] then [V | r]ᵀ[V | r], whose last entry is
        // Σr²; without the Jacobian only Σr².
        let width = if jac { stride * q } else { 1 };
        let parts: Vec<(Vec<f64>, Vec<f64>)> = cl
            .cols
            .par_chunks_mut(CHUNK * stride)
            .zip(cl.scratch.par_chunks(CHUNK * s))
            .enumerate()
            .map(|(ci, (block, sc))| {
                let lo = ci * CHUNK;
                let len = block.len() / stride;
                let (cc, vr) = block.split_at_mut(len * k);
                let mut r_local = Vec::new();
                let r: &mut [f64] = if jac {
                    &mut vr[len * p..len * q]
                } else {
                    r_local.resize(len, 0.0);
                    &mut r_local
                };
                for (ri, y) in r.iter_mut().zip(&wy[lo..lo + len]) {
                    *ri = -y;
                }
                for (u, cu) in c.iter().enumerate() {
                    if *cu != 0.0 {
                        for (ri, a) in r.iter_mut().zip(&cc[u * len..(u + 1) * len]) {
                            *ri += cu * a;
                        }
                    }
                }
                if !jac {
                    return (vec![dot(r, r)], Vec::new());
                }
                let r = r.to_vec();
                let chunk = prep.chunk(ch, lo, lo + len);
                basis.directional(theta, ch, &chunk, cc, sc, &c, &mut vr[..len * p]);
                let mut acc = vec![0.0; width];
                gram_tail(block, stride, k, len, &mut acc);
                (acc, r)
            })
            .collect();
        let mut acc = vec![0.0; width];
        for (a, r) in parts {
            acc = add_into(acc, a);
            if let Some(f) = full.as_mut() {
                f.residuals.extend_from_slice(&r);
            }
        }
        if !jac {
            cost += acc[0];
        } else {
            let am = |u: usize, b: usize| acc[u * q + b];
            let mm = |a: usize, b: usize| acc[(k + a) * q + b];
            cost += mm(p, p);
            // JᵀJ = VᵀV − (A_FᵀV)ᵀ G_F⁻¹ A_FᵀV and Jᵀr = Vᵀr − (A_FᵀV)ᵀ G_F⁻¹ A_Fᵀr:
            // J = (I − A_F G_F⁻¹ A_Fᵀ) V. (A_Fᵀr vanishes at the projection's optimum
            // up to rounding; it is kept rather than assumed.)
            let gi = free_inverse(&cl.g, k, &free);
            // G_F⁻¹ A_Fᵀ M, nf × (p + 1).
            let mut gm = vec![0.0; nf * q];
            for x in 0..nf {
                for (z, &u) in free.iter().enumerate() {
                    for b in 0..q {
                        gm[x * q + b] += gi[(x, z)] * am(u, b);
                    }
                }
            }
            if let Some(f) = full.as_mut() {
                let vv = (0..p * p).map(|i| mm(i / p, i % p)).collect();
                let av = (0..k * p).map(|i| am(i / p, i % p)).collect();
                f.grams.push([vv, av, cl.g.clone()]);
            }
            for a in 0..p {
                let proj = |b: usize| -> f64 {
                    free.iter()
                        .enumerate()
                        .map(|(x, &u)| am(u, a) * gm[x * q + b])
                        .sum()
                };
                jtr[a] += mm(a, p) - proj(p);
                for b in a..p {
                    jtj[a * p + b] += mm(a, b) - proj(b);
                }
            }
        }
        coef.push(c);
        if let Ok(mut b) = prep.buffers.lock() {
            *b = Some((cl.cols, cl.scratch));
        }
    }
    for a in 0..p {
        for b in 0..a {
            jtj[a * p + b] = jtj[b * p + a];
        }
    }
    Evaluation {
        coef,
        cost,
        normal: jac.then_some((jtj, jtr)),
        full,
    }
}

/// The linear coefficients and the residuals W(Ac − y), channel after channel.
pub fn residuals(basis: &dyn Basis, data: &FitData, theta: &[f64]) -> (Vec<Vec<f64>>, Vec<f64>) {
    let prep = Prepared::new(data);
    let (k, m) = (basis.n_cols(), data.len());
    let mut coef = Vec::new();
    let mut out = Vec::with_capacity(m * data.channels.len());
    for ch in 0..data.channels.len() {
        let cl = columns(basis, &prep, theta, ch, 0);
        let c = nnls(&cl.g, &cl.h, k);
        for (ci, cc) in cl.cols.chunks(CHUNK * k).enumerate() {
            let len = cc.len() / k;
            for i in 0..len {
                let fit: f64 = (0..k).map(|u| c[u] * cc[u * len + i]).sum();
                out.push(fit - prep.wy[ch][ci * CHUNK + i]);
            }
        }
        coef.push(c);
    }
    (coef, out)
}

/// Levenberg–Marquardt's view of JᵀJ and Jᵀr: a (P + 1) × P Jacobian R and residual
/// r̃ with RᵀR = JᵀJ, Rᵀr̃ = Jᵀr and ‖r̃‖² = Σr². Every quantity the crate's steps
/// and tests use (gradient, column norms, predicted and actual reductions) is the
/// same as for the m-row problem, at O(P²) memory instead of O(mP).
fn compress(jtj: &[f64], jtr: &[f64], cost: f64, p: usize) -> (DVector<f64>, DMatrix<f64>) {
    if p == 0 {
        return (
            DVector::from_element(1, cost.max(0.0).sqrt()),
            DMatrix::zeros(1, 0),
        );
    }
    // Equilibrate (unit diagonal) before the eigen-decomposition: columns differ by
    // many orders of magnitude.
    let d: Vec<f64> = (0..p)
        .map(|a| {
            let x = jtj[a * p + a];
            if x > 0.0 && x.is_finite() {
                x.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let s = DMatrix::from_fn(p, p, |a, b| {
        if d[a] > 0.0 && d[b] > 0.0 {
            jtj[a * p + b] / (d[a] * d[b])
        } else {
            0.0
        }
    });
    let eig = s.symmetric_eigen();
    let mut r = DMatrix::zeros(p + 1, p);
    let mut rt = DVector::zeros(p + 1);
    let mut explained = 0.0;
    for e in 0..p {
        let lam = eig.eigenvalues[e];
        if lam <= 1e-15 * p as f64 {
            continue;
        }
        let sl = lam.sqrt();
        let q = eig.eigenvectors.column(e);
        // Row e of R = √λ qᵀ D; r̃_e = qᵀ D⁻¹ Jᵀr / √λ.
        let mut proj = 0.0;
        for a in 0..p {
            r[(e, a)] = sl * q[a] * d[a];
            if d[a] > 0.0 {
                proj += q[a] * jtr[a] / d[a];
            }
        }
        rt[e] = proj / sl;
        explained += rt[e] * rt[e];
    }
    rt[p] = (cost - explained).max(0.0).sqrt();
    (rt, r)
}

/// The projected problem as the `levenberg-marquardt` crate sees it: compressed to
/// P + 1 rows (see [`compress`]).
pub struct Projected<'a> {
    basis: &'a dyn Basis,
    prep: Prepared<'a>,
    theta: DVector<f64>,
    /// The compressed Jacobian computed with the last residuals (the crate asks for
    /// it at the point it has just accepted, so one pass serves both).
    cached: std::sync::Mutex<Option<(Vec<f64>, DMatrix<f64>)>>,
    /// θ and the evaluation with the smallest cost yet (where the crate ends).
    last: std::sync::Mutex<Option<(Vec<f64>, Evaluation)>>,
}

impl<'a> Projected<'a> {
    /// The problem at a starting θ.
    pub fn new(basis: &'a dyn Basis, data: &'a FitData, theta: &[f64]) -> Self {
        Projected {
            basis,
            prep: Prepared::new(data),
            theta: DVector::from_column_slice(theta),
            cached: std::sync::Mutex::new(None),
            last: std::sync::Mutex::new(None),
        }
    }

    fn compressed(&self) -> Option<(DVector<f64>, DMatrix<f64>)> {
        let mut e = evaluate_prepared(self.basis, &self.prep, self.theta.as_slice(), true);
        let (jtj, jtr) = e.normal.take()?;
        let finite = e.cost.is_finite() && jtj.iter().chain(&jtr).all(|x| x.is_finite());
        let out = finite.then(|| compress(&jtj, &jtr, e.cost, self.basis.n_params()));
        if let Ok(mut l) = self.last.lock()
            && finite
            && l.as_ref().is_none_or(|b| e.cost <= b.1.cost)
        {
            *l = Some((self.theta.as_slice().to_vec(), e));
        }
        out
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Projected<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.theta.copy_from(x);
    }

    fn params(&self) -> DVector<f64> {
        self.theta.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let (r, j) = self.compressed()?;
        if let Ok(mut c) = self.cached.lock() {
            *c = Some((self.theta.as_slice().to_vec(), j));
        }
        Some(r)
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let cached = self
            .cached
            .lock()
            .ok()
            .and_then(|mut c| c.take())
            .filter(|(t, _)| t.as_slice() == self.theta.as_slice())
            .map(|(_, j)| j);
        match cached {
            Some(j) => Some(j),
            None => self.compressed().map(|x| x.1),
        }
    }
}

/// The outcome of one Levenberg–Marquardt search.
pub struct Solved {
    /// The non-linear parameters.
    pub theta: Vec<f64>,
    /// The linear coefficients per channel.
    pub coef: Vec<Vec<f64>>,
    /// Sum of squared residuals.
    pub cost: f64,
    /// Residual evaluations the search made.
    pub evaluations: usize,
    /// Why it stopped.
    pub termination: TerminationReason,
    /// Residuals and Gram matrices at θ (for the standard errors).
    pub full: Full,
}

/// Minimises the projected problem from `theta` to full precision (relative cost
/// reduction 1e-10, relative step 1e-8): far below χ²'s own statistical spread,
/// √(2/N) relative.
pub fn solve(basis: &dyn Basis, data: &FitData, theta: &[f64], patience: usize) -> Solved {
    solve_to(basis, data, theta, patience, 1e-10)
}

/// [`solve`] stopping once a step reduces the cost by less than `ftol` relative (and
/// moves θ by less than 100 `ftol`): the start search's refinements need a basin, not
/// its last digits, which the final refinement supplies.
pub fn solve_to(
    basis: &dyn Basis,
    data: &FitData,
    theta: &[f64],
    patience: usize,
    ftol: f64,
) -> Solved {
    if basis.n_params() == 0 {
        // Nothing non-linear (a Lambertian fit): the projection is the whole answer.
        let e = evaluate(basis, data, theta, true);
        return Solved {
            theta: theta.to_vec(),
            coef: e.coef,
            cost: e.cost,
            evaluations: 1,
            termination: TerminationReason::Converged {
                ftol: true,
                xtol: true,
            },
            full: e.full.unwrap_or(Full {
                residuals: Vec::new(),
                grams: Vec::new(),
            }),
        };
    }
    let lm = LevenbergMarquardt::new()
        .with_patience(patience)
        .with_ftol(ftol)
        .with_xtol((100.0 * ftol).max(1e-10))
        .with_gtol(1e-12);
    let (problem, report) = lm.minimize(Projected::new(basis, data, theta));
    let theta = problem.theta.as_slice().to_vec();
    // The crate leaves θ at an accepted point, whose evaluation is usually kept.
    let kept = problem
        .last
        .lock()
        .ok()
        .and_then(|mut l| l.take())
        .filter(|(t, _)| *t == theta)
        .map(|x| x.1);
    let e = kept.unwrap_or_else(|| evaluate_prepared(basis, &problem.prep, &theta, true));
    Solved {
        theta,
        coef: e.coef,
        cost: e.cost,
        evaluations: report.number_of_evaluations,
        termination: report.termination,
        full: e.full.unwrap_or(Full {
            residuals: Vec::new(),
            grams: Vec::new(),
        }),
    }
}

/// Solves min ‖A c − b‖ with c ≥ 0 from the normal equations G = AᵀA, h = Aᵀb
/// (Lawson & Hanson's active-set method); K is a handful, so this is exact and cheap.
/// The columns are equilibrated first (unit diagonal): a sharp lobe's column can be
/// 10⁻¹³ of the diffuse one's and still carry a strength of 10¹³.
pub fn nnls(g: &[f64], h: &[f64], k: usize) -> Vec<f64> {
    let dscale: Vec<f64> = (0..k).map(|i| g[i * k + i].max(0.0).sqrt()).collect();
    let usable: Vec<bool> = dscale.iter().map(|d| *d > 0.0 && d.is_finite()).collect();
    let gs = |i: usize, j: usize| g[i * k + j] / (dscale[i] * dscale[j]);
    let hs = |i: usize| h[i] / dscale[i];
    let mut free = vec![false; k];
    let mut c = vec![0.0; k];
    let solve_free = |free: &[bool]| -> Vec<f64> {
        let idx: Vec<usize> = (0..k).filter(|&i| free[i]).collect();
        let n = idx.len();
        let mut out = vec![0.0; k];
        if n == 0 {
            return out;
        }
        // A tiny ridge keeps collinear columns (two identical lobes) solvable.
        let m = DMatrix::from_fn(n, n, |a, b| {
            gs(idx[a], idx[b]) + if a == b { 1e-13 } else { 0.0 }
        });
        let r = DVector::from_fn(n, |a, _| hs(idx[a]));
        let x = m
            .clone()
            .cholesky()
            .map(|ch| ch.solve(&r))
            .or_else(|| m.lu().solve(&r))
            .unwrap_or_else(|| DVector::zeros(n));
        for (a, &i) in idx.iter().enumerate() {
            out[i] = x[a];
        }
        out
    };
    for _outer in 0..3 * k + 3 {
        // The negative gradient of ½‖Ac − b‖² in the equilibrated variables.
        let w: Vec<f64> = (0..k)
            .map(|i| {
                if usable[i] {
                    hs(i)
                        - (0..k)
                            .filter(|&j| usable[j])
                            .map(|j| gs(i, j) * c[j])
                            .sum::<f64>()
                } else {
                    0.0
                }
            })
            .collect();
        let tol = 1e-12
            * (0..k)
                .filter(|&i| usable[i])
                .map(|i| hs(i).abs())
                .fold(1e-300, f64::max);
        let pick = (0..k)
            .filter(|&i| usable[i] && !free[i] && w[i] > tol)
            .max_by(|&a, &b| w[a].total_cmp(&w[b]));
        let Some(j) = pick else { break };
        free[j] = true;
        loop {
            let z = solve_free(&free);
            if (0..k).all(|i| !free[i] || z[i] > 0.0) {
                c = z;
                break;
            }
            // Step back to the first coefficient that reaches 0 and drop it.
            let mut alpha = 1.0f64;
            for i in 0..k {
                if free[i] && z[i] <= 0.0 {
                    alpha = alpha.min(c[i] / (c[i] - z[i]));
                }
            }
            for i in 0..k {
                c[i] += alpha * (z[i] - c[i]);
                if free[i] && c[i] <= 1e-300 {
                    free[i] = false;
                    c[i] = 0.0;
                }
            }
        }
    }
    (0..k)
        .map(|i| if usable[i] { c[i] / dscale[i] } else { 0.0 })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nnls_matches_the_constrained_optimum() {
        // Columns e1, e2, (e1 + e2)/√2 in 2-D: b = (1, −1) is best fit by c = (1, 0, 0).
        let a = [
            [1.0, 0.0, std::f64::consts::FRAC_1_SQRT_2],
            [0.0, 1.0, std::f64::consts::FRAC_1_SQRT_2],
        ];
        let b = [1.0, -1.0];
        let k = 3;
        let mut g = vec![0.0; 9];
        let mut h = vec![0.0; 3];
        for u in 0..k {
            for r in 0..2 {
                h[u] += a[r][u] * b[r];
                for v in 0..k {
                    g[u * k + v] += a[r][u] * a[r][v];
                }
            }
        }
        let c = nnls(&g, &h, k);
        assert!(
            (c[0] - 1.0).abs() < 1e-12 && c[1] == 0.0 && c[2] == 0.0,
            "{c:?}"
        );
        // Unconstrained optimum inside the orthant is returned as is.
        let c = nnls(&[2.0, 0.0, 0.0, 3.0], &[4.0, 6.0], 2);
        assert!((c[0] - 2.0).abs() < 1e-12 && (c[1] - 2.0).abs() < 1e-12);
    }
}
