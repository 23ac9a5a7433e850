//! One evaluation pass of the projected problem at θ: the columns and their Gram
//! matrices chunk by chunk, the non-negative linear coefficients, the cost, and
//! Kaufman's JᵀJ and Jᵀr (plus the full problem's Grams for the standard errors).

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use nalgebra::DMatrix;
use rayon::prelude::*;

use super::nnls::nnls;
use super::qp::{QpSolution, qp};
use super::{Basis, Prepared};
use crate::data::FitData;
use crate::fastmath::dot;

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
    /// Under the energy constraint ([`Prepared::limits`]), per channel: the albedo and
    /// the multiplier at each limit direction; empty without it.
    pub constraints: Vec<ChannelConstraint>,
}

/// One channel's energy constraint at the evaluated θ.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ChannelConstraint {
    /// Directional albedo B c at each limit direction.
    pub albedo: Vec<f64>,
    /// Lagrange multiplier of albedo ≤ 1 at each: the fall of Σr² per unit the bound
    /// were raised (0 where the constraint is inactive).
    pub multiplier: Vec<f64>,
}

/// The pseudo-inverse (n × m) of an m × n matrix; zeros when it is empty (no active
/// row, or no free coefficient), which nalgebra's SVD refuses.
fn pseudo_inverse(m: &DMatrix<f64>, eps: f64) -> DMatrix<f64> {
    let (r, c) = m.shape();
    if r == 0 || c == 0 {
        return DMatrix::zeros(c, r);
    }
    m.clone()
        .pseudo_inverse(eps)
        .unwrap_or_else(|_| DMatrix::zeros(c, r))
}

/// Kaufman's JᵀJ and Jᵀr when the albedo rows R of B c ≤ 1 are active (`sol`): the
/// coefficients then move with θ along ∂c/∂θ = D, the smallest step with
/// B_R D = −(∂B_R/∂θ) c on the free coefficients, so the residual's derivative is
/// V' = V + W A D, projected off the columns W A N that the free coefficients still
/// span within the active rows (N: the null space of B_R on them). With the
/// multipliers μ this gives the exact gradient of the projected cost,
/// 2 Jᵀr = 2 Vᵀr + μᵀ(∂B/∂θ)c (Danskin). `acc` holds (WA)ᵀ[V | r] then
/// [V | r]ᵀ[V | r] as [`evaluate_prepared`] accumulates them. Returns JᵀJ (p × p,
/// row-major) and Jᵀr.
#[allow(clippy::too_many_arguments)]
fn constrained_normal(
    acc: &[f64],
    g: &[f64],
    k: usize,
    p: usize,
    sol: &QpSolution,
    b: &[f64],
    db: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    let q = p + 1;
    // Equilibrated coordinates (unit Gram diagonal): c̃ = s ∘ c.
    let sc: Vec<f64> = (0..k)
        .map(|u| {
            let x = g[u * k + u];
            if x > 0.0 && x.is_finite() {
                x.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let inv = |u: usize| if sc[u] > 0.0 { 1.0 / sc[u] } else { 0.0 };
    let gs = DMatrix::from_fn(k, k, |u, v| g[u * k + v] * inv(u) * inv(v));
    let am = DMatrix::from_fn(k, q, |u, bcol| acc[u * q + bcol] * inv(u));
    let mm = DMatrix::from_fn(q, q, |a, bcol| acc[(k + a) * q + bcol]);
    let free: Vec<usize> = (0..k)
        .filter(|&u| !sol.at_bound[u] && sc[u] > 0.0)
        .collect();
    let rows: Vec<usize> = (0..sol.row_active.len())
        .filter(|&l| sol.row_active[l])
        .collect();
    let nf = free.len();
    // B_R on the free coefficients (equilibrated), and −(∂B_R/∂θ) c.
    let brf = DMatrix::from_fn(rows.len(), nf, |r, x| {
        b[rows[r] * k + free[x]] * inv(free[x])
    });
    let e = DMatrix::from_fn(rows.len(), q, |r, a| {
        if a == p {
            return 0.0;
        }
        -(0..k)
            .map(|u| db[(rows[r] * k + u) * p + a] * sol.c[u])
            .sum::<f64>()
    });
    let pinv = pseudo_inverse(&brf, 1e-12);
    let df = &pinv * e;
    let mut d = DMatrix::<f64>::zeros(k, q);
    for (x, &u) in free.iter().enumerate() {
        for a in 0..q {
            d[(u, a)] = df[(x, a)];
        }
    }
    // [V' | r] = [V | r] + W A D.
    let am2 = &am + &gs * &d;
    let mm2 = &mm + d.transpose() * &am + am.transpose() * &d + d.transpose() * &gs * &d;
    // N: an orthonormal basis of the null space of B_R on the free coefficients.
    let mut n = DMatrix::<f64>::zeros(k, 0);
    if nf > 0 {
        let proj = DMatrix::<f64>::identity(nf, nf) - &pinv * &brf;
        let eig = proj.symmetric_eigen();
        let basis: Vec<usize> = (0..nf).filter(|&i| eig.eigenvalues[i] > 0.5).collect();
        n = DMatrix::<f64>::zeros(k, basis.len());
        for (col, &i) in basis.iter().enumerate() {
            for (x, &u) in free.iter().enumerate() {
                n[(u, col)] = eig.eigenvectors[(x, i)];
            }
        }
    }
    let x = n.transpose() * &am2;
    let h = n.transpose() * &gs * &n;
    let hinv = pseudo_inverse(&h, 1e-13);
    let full = mm2 - x.transpose() * hinv * &x;
    let jtj = (0..p * p).map(|i| full[(i / p, i % p)]).collect();
    let jtr = (0..p).map(|a| full[(a, p)]).collect();
    (jtj, jtr)
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
fn gram(a: &[f64], na: usize, b: &[f64], nb: usize, len: usize, out: &mut [f64]) {
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
    let mut coef = Vec::with_capacity(nc);
    let mut cost = 0.0;
    let mut jtj = vec![0.0; p * p];
    let mut jtr = vec![0.0; p];
    let mut full = jac.then(|| Full {
        residuals: prep.spare_residuals(nc * prep.data.len()),
        grams: Vec::with_capacity(nc),
    });
    let limits = prep.limits.as_deref().filter(|l| !l.is_empty());
    let mut constraints = Vec::new();
    for ch in 0..nc {
        let q = if jac { p + 1 } else { 0 };
        let mut cl = columns(basis, prep, theta, ch, q);
        let (c, bounded) = match limits {
            None => (nnls(&cl.g, &cl.h, k), None),
            Some(lim) => {
                let (sol, bm, dbm, constraint) = bounded_solve(basis, theta, ch, lim, &cl, jac);
                constraints.push(constraint);
                (sol.c.clone(), Some((sol, bm, dbm)))
            }
        };
        let parts = chunk_pass(basis, prep, theta, ch, &mut cl, &c, jac);
        let mut acc = vec![0.0; if jac { (k + q) * q } else { 1 }];
        for a in parts {
            acc = add_into(acc, a);
        }
        if let Some(f) = full.as_mut() {
            // The residuals, in the columns' blocks after [WA | V]: copied out in
            // order, into a buffer of an earlier evaluation's.
            for block in cl.cols.chunks(CHUNK * (k + q)) {
                let len = block.len() / (k + q);
                f.residuals
                    .extend_from_slice(&block[len * (k + p)..len * (k + q)]);
            }
        }
        if !jac {
            cost += acc[0];
        } else {
            let am = |u: usize, b: usize| acc[u * q + b];
            let mm = |a: usize, b: usize| acc[(k + a) * q + b];
            cost += mm(p, p);
            if let Some(f) = full.as_mut() {
                let vv = (0..p * p).map(|i| mm(i / p, i % p)).collect();
                let av = (0..k * p).map(|i| am(i / p, i % p)).collect();
                f.grams.push([vv, av, cl.g.clone()]);
            }
            match &bounded {
                Some((sol, bm, dbm)) => {
                    let (a2, r2) = constrained_normal(&acc, &cl.g, k, p, sol, bm, dbm);
                    for (x, y) in jtj.iter_mut().zip(&a2) {
                        *x += y;
                    }
                    for (x, y) in jtr.iter_mut().zip(&r2) {
                        *x += y;
                    }
                }
                None => free_normal(&acc, &cl.g, k, p, &c, &mut jtj, &mut jtr),
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
        constraints,
    }
}

/// Channel `ch`'s coefficients under the albedo limits: the QP's solution, the
/// albedo rows B at the limit directions (with ∂B/∂θ when `jac`), and the channel's
/// constraint report (B c and the multipliers).
fn bounded_solve(
    basis: &dyn Basis,
    theta: &[f64],
    ch: usize,
    lim: &[[f64; 3]],
    cl: &Columns,
    jac: bool,
) -> (QpSolution, Vec<f64>, Vec<f64>, ChannelConstraint) {
    let (k, p) = (basis.n_cols(), basis.n_params());
    let nl = lim.len();
    let mut bm = vec![0.0; nl * k];
    let mut dbm = vec![0.0; if jac { nl * k * p } else { 0 }];
    basis.albedo_rows(theta, ch, lim, &mut bm, jac.then_some(&mut dbm[..]));
    let sol = qp(&cl.g, &cl.h, k, &bm, nl);
    let constraint = ChannelConstraint {
        albedo: (0..nl)
            .map(|l| (0..k).map(|u| bm[l * k + u] * sol.c[u]).sum())
            .collect(),
        multiplier: sol.multiplier.clone(),
    };
    (sol, bm, dbm, constraint)
}

/// The parallel pass over channel `ch`'s chunks at the coefficients `c`: per
/// chunk, with X = [WA | V | r] (V = W ∂A/∂θ c) left in the chunk's block,
/// Xᵀ[V | r], (k + p + 1) × (p + 1) row-major — (WA)ᵀ[V | r] then [V | r]ᵀ[V | r],
/// whose last entry is Σr²; without the Jacobian only Σr².
fn chunk_pass(
    basis: &dyn Basis,
    prep: &Prepared,
    theta: &[f64],
    ch: usize,
    cl: &mut Columns,
    c: &[f64],
    jac: bool,
) -> Vec<Vec<f64>> {
    let (k, p) = (basis.n_cols(), basis.n_params());
    let s = basis.scratch_len().max(1);
    let q = if jac { p + 1 } else { 0 };
    let stride = k + q;
    let wy = &prep.wy[ch];
    let width = if jac { stride * q } else { 1 };
    cl.cols
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
                return vec![dot(r, r)];
            }
            let chunk = prep.chunk(ch, lo, lo + len);
            basis.directional(theta, ch, &chunk, cc, sc, c, &mut vr[..len * p]);
            let mut acc = vec![0.0; width];
            gram_tail(block, stride, k, len, &mut acc);
            acc
        })
        .collect()
}

/// Adds an unconstrained channel's share to JᵀJ (upper triangle) and Jᵀr:
/// JᵀJ = VᵀV − (A_FᵀV)ᵀ G_F⁻¹ A_FᵀV and Jᵀr = Vᵀr − (A_FᵀV)ᵀ G_F⁻¹ A_Fᵀr, with
/// J = (I − A_F G_F⁻¹ A_Fᵀ) V over the free (positive) coefficients of `c`. (A_Fᵀr
/// vanishes at the projection's optimum up to rounding; it is kept rather than
/// assumed.)
fn free_normal(
    acc: &[f64],
    g: &[f64],
    k: usize,
    p: usize,
    c: &[f64],
    jtj: &mut [f64],
    jtr: &mut [f64],
) {
    let q = p + 1;
    let am = |u: usize, b: usize| acc[u * q + b];
    let mm = |a: usize, b: usize| acc[(k + a) * q + b];
    let free: Vec<usize> = (0..k).filter(|&u| c[u] > 0.0).collect();
    let nf = free.len();
    let gi = free_inverse(g, k, &free);
    // G_F⁻¹ A_Fᵀ M, nf × (p + 1).
    let mut gm = vec![0.0; nf * q];
    for x in 0..nf {
        for (z, &u) in free.iter().enumerate() {
            for b in 0..q {
                gm[x * q + b] += gi[(x, z)] * am(u, b);
            }
        }
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
