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

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt, TerminationReason};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use rayon::prelude::*;

use crate::data::FitData;

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
}

/// Samples a chunk of the parallel loops handles.
const CHUNK: usize = 2048;

/// The evaluation of the projected problem at one θ.
pub struct Evaluation {
    /// Linear coefficients per channel (0 where the constraint c ≥ 0 is active).
    pub coef: Vec<Vec<f64>>,
    /// Residuals W(Ac − y), channel after channel.
    pub residuals: Vec<f64>,
    /// Kaufman's Jacobian, row-major (residuals × parameters), when asked for.
    pub jacobian: Option<Vec<f64>>,
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

/// Evaluates the projected problem at `theta`.
pub fn evaluate(basis: &dyn Basis, data: &FitData, theta: &[f64], jac: bool) -> Evaluation {
    let (k, p, m) = (basis.n_cols(), basis.n_params(), data.len());
    let nc = data.channels.len();
    let mut coef = Vec::with_capacity(nc);
    let mut residuals = vec![0.0; nc * m];
    let mut jacobian = jac.then(|| vec![0.0; nc * m * p]);
    for ch in 0..nc {
        // Weighted columns (m × K) and, with the Jacobian, derivatives (m × K × P).
        let mut a = vec![0.0; m * k];
        let mut da = if jac {
            vec![0.0; m * k * p]
        } else {
            Vec::new()
        };
        let w = &data.weight[ch];
        if jac {
            a.par_chunks_mut(CHUNK * k)
                .zip(da.par_chunks_mut(CHUNK * k * p))
                .enumerate()
                .for_each(|(ci, (rows, drows))| {
                    let lo = ci * CHUNK;
                    let hi = lo + rows.len() / k;
                    basis.eval_chunk(
                        theta,
                        ch,
                        &data.wi[lo..hi],
                        &data.wo[lo..hi],
                        rows,
                        Some(drows),
                    );
                    for (r, row) in rows.chunks_mut(k).enumerate() {
                        let wr = w[lo + r];
                        for x in row.iter_mut() {
                            *x *= wr;
                        }
                    }
                    for (r, row) in drows.chunks_mut(k * p).enumerate() {
                        let wr = w[lo + r];
                        for x in row.iter_mut() {
                            *x *= wr;
                        }
                    }
                });
        } else {
            a.par_chunks_mut(CHUNK * k)
                .enumerate()
                .for_each(|(ci, rows)| {
                    let lo = ci * CHUNK;
                    let hi = lo + rows.len() / k;
                    basis.eval_chunk(theta, ch, &data.wi[lo..hi], &data.wo[lo..hi], rows, None);
                    for (r, row) in rows.chunks_mut(k).enumerate() {
                        let wr = w[lo + r];
                        for x in row.iter_mut() {
                            *x *= wr;
                        }
                    }
                });
        }
        let y = &data.y[ch];
        // Normal equations G = (WA)ᵀWA, h = (WA)ᵀWy, summed in fixed chunks so the
        // result does not depend on the thread count.
        let (g, h) = a
            .par_chunks(CHUNK * k)
            .enumerate()
            .map(|(ci, rows)| {
                let mut g = vec![0.0; k * k];
                let mut h = vec![0.0; k];
                for (r, row) in rows.chunks(k).enumerate() {
                    let i = ci * CHUNK + r;
                    let wy = w[i] * y[i];
                    for u in 0..k {
                        h[u] += row[u] * wy;
                        for v in 0..k {
                            g[u * k + v] += row[u] * row[v];
                        }
                    }
                }
                (g, h)
            })
            .collect::<Vec<_>>()
            .into_iter()
            .fold(
                (vec![0.0; k * k], vec![0.0; k]),
                |(mut g, mut h), (gc, hc)| {
                    for (x, y) in g.iter_mut().zip(gc) {
                        *x += y;
                    }
                    for (x, y) in h.iter_mut().zip(hc) {
                        *x += y;
                    }
                    (g, h)
                },
            );
        let c = nnls(&g, &h, k);
        residuals[ch * m..(ch + 1) * m]
            .par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(ci, res)| {
                for (r, out) in res.iter_mut().enumerate() {
                    let i = ci * CHUNK + r;
                    *out = (0..k).map(|u| a[i * k + u] * c[u]).sum::<f64>() - w[i] * y[i];
                }
            });
        if let Some(jm) = jacobian.as_mut() {
            // v_p = W ∂A/∂θ_p c, then projected off the free columns.
            let free: Vec<usize> = (0..k).filter(|&u| c[u] > 0.0).collect();
            let nf = free.len();
            // G_F⁻¹ through the equilibrated matrix (see `nnls`).
            let ds: Vec<f64> = free.iter().map(|&u| g[u * k + u].sqrt()).collect();
            let gf = DMatrix::from_fn(nf, nf, |x, z| {
                g[free[x] * k + free[z]] / (ds[x] * ds[z]) + if x == z { 1e-13 } else { 0.0 }
            });
            let gs_inv = gf
                .clone()
                .cholesky()
                .map(|ch| ch.inverse())
                .or_else(|| gf.try_inverse())
                .unwrap_or_else(|| DMatrix::zeros(nf, nf));
            let gf_inv = DMatrix::from_fn(nf, nf, |x, z| gs_inv[(x, z)] / (ds[x] * ds[z]));
            // v_p = W ∂A/∂θ_p c, written straight into the Jacobian's rows.
            let block = &mut jm[ch * m * p..(ch + 1) * m * p];
            block
                .par_chunks_mut(CHUNK * p)
                .enumerate()
                .for_each(|(ci, rows)| {
                    for (r, row) in rows.chunks_mut(p).enumerate() {
                        let i = ci * CHUNK + r;
                        for (q, out) in row.iter_mut().enumerate() {
                            *out = (0..k).map(|u| da[(i * k + u) * p + q] * c[u]).sum();
                        }
                    }
                });
            // Aᵀ_F v (nf × p), summed in fixed chunks (thread-count independent).
            let atv = block
                .par_chunks(CHUNK * p)
                .enumerate()
                .map(|(ci, rows)| {
                    let mut acc = vec![0.0; nf * p];
                    for (r, row) in rows.chunks(p).enumerate() {
                        let i = ci * CHUNK + r;
                        for (x, &u) in free.iter().enumerate() {
                            let aiu = a[i * k + u];
                            for q in 0..p {
                                acc[x * p + q] += aiu * row[q];
                            }
                        }
                    }
                    acc
                })
                .collect::<Vec<_>>()
                .into_iter()
                .fold(vec![0.0; nf * p], |mut s, c| {
                    for (x, y) in s.iter_mut().zip(c) {
                        *x += y;
                    }
                    s
                });
            let mut coefs = vec![0.0; nf * p];
            for x in 0..nf {
                for q in 0..p {
                    coefs[x * p + q] = (0..nf).map(|z| gf_inv[(x, z)] * atv[z * p + q]).sum();
                }
            }
            // J = v − A_F G_F⁻¹ Aᵀ_F v.
            block
                .par_chunks_mut(CHUNK * p)
                .enumerate()
                .for_each(|(ci, rows)| {
                    for (r, row) in rows.chunks_mut(p).enumerate() {
                        let i = ci * CHUNK + r;
                        for (q, out) in row.iter_mut().enumerate() {
                            let proj: f64 = free
                                .iter()
                                .enumerate()
                                .map(|(x, &u)| a[i * k + u] * coefs[x * p + q])
                                .sum();
                            *out -= proj;
                        }
                    }
                });
        }
        coef.push(c);
    }
    Evaluation {
        coef,
        residuals,
        jacobian,
    }
}

/// The projected problem as the `levenberg-marquardt` crate sees it.
pub struct Projected<'a> {
    basis: &'a dyn Basis,
    data: &'a FitData,
    theta: DVector<f64>,
    /// The Jacobian computed with the last residuals (the crate asks for it at the
    /// point it has just accepted, so one pass serves both).
    cached: std::sync::Mutex<Option<(Vec<f64>, Vec<f64>)>>,
}

impl<'a> Projected<'a> {
    /// The problem at a starting θ.
    pub fn new(basis: &'a dyn Basis, data: &'a FitData, theta: &[f64]) -> Self {
        Projected {
            basis,
            data,
            theta: DVector::from_column_slice(theta),
            cached: std::sync::Mutex::new(None),
        }
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
        let e = evaluate(self.basis, self.data, self.theta.as_slice(), true);
        if let (Ok(mut c), Some(j)) = (self.cached.lock(), e.jacobian) {
            *c = Some((self.theta.as_slice().to_vec(), j));
        }
        let r = DVector::from_vec(e.residuals);
        r.iter().all(|x| x.is_finite()).then_some(r)
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let p = self.basis.n_params();
        let rows = self.data.len() * self.data.channels.len();
        let cached = self
            .cached
            .lock()
            .ok()
            .and_then(|mut c| c.take())
            .filter(|(t, _)| t.as_slice() == self.theta.as_slice())
            .map(|(_, j)| j);
        let j = match cached {
            Some(j) => j,
            None => evaluate(self.basis, self.data, self.theta.as_slice(), true).jacobian?,
        };
        let j = DMatrix::from_row_slice(rows, p, &j);
        j.iter().all(|x| x.is_finite()).then_some(j)
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
}

/// Minimises the projected problem from `theta`.
pub fn solve(basis: &dyn Basis, data: &FitData, theta: &[f64], patience: usize) -> Solved {
    let lm = LevenbergMarquardt::new()
        .with_patience(patience)
        .with_ftol(1e-12)
        .with_xtol(1e-10)
        .with_gtol(1e-12);
    let (problem, report) = lm.minimize(Projected::new(basis, data, theta));
    let theta = problem.theta.as_slice().to_vec();
    let e = evaluate(basis, data, &theta, false);
    let cost = e.residuals.iter().map(|r| r * r).sum();
    Solved {
        theta,
        coef: e.coef,
        cost,
        evaluations: report.number_of_evaluations,
        termination: report.termination,
    }
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
