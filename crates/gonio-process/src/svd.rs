//! The leading singular values of DeYoung's matrix A and the Frobenius tails
//! ‖A − A^(k)‖_F² that P_s^(k) needs (Eq. 4.16–4.20).
//!
//! P_s^(k) for small k needs only the k largest singular values and ‖A‖_F², not the
//! whole spectrum: on a 5° × 2.5° table A is 2592 × 2592 and a full SVD costs
//! seconds. [`spectrum`] runs a block Krylov (block Lanczos) iteration with full
//! reorthogonalisation on A Aᵀ, from a seeded random start (the same numbers every
//! run), and then the Rayleigh–Ritz projection: with K an orthonormal basis of the
//! Krylov space and W = Aᵀ K = U_w S V_wᵀ, the Ritz triplets are σ_j = S_jj,
//! v_j = U_w e_j, u_j = K V_w e_j, with Aᵀ u_j = σ_j v_j exactly.
//!
//! **Error bound.** Once the leading Ritz values stop changing, the residuals
//! r_j = ‖A v_j − σ_j u_j‖ are computed: a singular value of A lies within r_j of
//! σ_j (Weyl's theorem applied to the symmetric [[0, A], [Aᵀ, 0]]), and the error
//! of a well separated one is of order r_j²/gap. A run whose residuals exceed
//! [`MAX_RESIDUAL`] · σ_1, or that does not converge in [`MAX_BASIS`] columns, falls
//! back to faer's full SVD, as do small matrices, where a full SVD is cheap.
//!
//! The tails are computed as ‖A‖_F² − Σ_{j≤k} σ_j², and, where that difference is
//! small against ‖A‖_F² (a nearly separable table, where it would cancel), as the
//! norm of the residual A − Σ σ_j u_j v_jᵀ itself, column by column. With Ritz
//! triplets the two are equal in exact arithmetic, and never below the true tail
//! (Eckart–Young): P_s^(k) from a truncated run is an upper bound, tight to second
//! order in the Ritz vectors' error.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::matmul::matmul;
use faer::linalg::svd::ComputeSvdVectors;
use faer::{Accum, Mat, MatRef, Par};
use rayon::prelude::*;

use crate::ProcessError;

/// Rows of a product's output computed as one unit of parallel work.
const PRODUCT_ROWS: usize = 128;

/// The product `a b`, its rows in fixed blocks of [`PRODUCT_ROWS`] on rayon, each
/// block by faer's sequential kernel: the blocks do not depend on the number of
/// threads, so neither does any bit of the result (faer's own parallel product
/// splits the sums by thread count).
fn product(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Mat<f64> {
    let (m, n) = (a.nrows(), b.ncols());
    let blocks: Vec<Mat<f64>> = (0..m)
        .step_by(PRODUCT_ROWS)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|r0| {
            let rows = PRODUCT_ROWS.min(m - r0);
            let mut out = Mat::zeros(rows, n);
            matmul(
                out.as_mut(),
                Accum::Replace,
                a.subrows(r0, rows),
                b,
                1.0,
                Par::Seq,
            );
            out
        })
        .collect();
    Mat::from_fn(m, n, |i, j| blocks[i / PRODUCT_ROWS][(i % PRODUCT_ROWS, j)])
}

/// A thin SVD's U and V.
type Vectors = (Mat<f64>, Mat<f64>);

/// The singular values of `a`, descending, and its thin U and V when `vectors`, by
/// faer on one thread (the same bits on any number of threads).
fn svd_seq(a: MatRef<'_, f64>, vectors: bool) -> Result<(Vec<f64>, Option<Vectors>), ProcessError> {
    let (m, n) = a.shape();
    let k = m.min(n);
    let mut s = faer::diag::Diag::<f64>::zeros(k);
    let (mut u, mut v) = if vectors {
        (Some(Mat::zeros(m, k)), Some(Mat::zeros(n, k)))
    } else {
        (None, None)
    };
    let compute = if vectors {
        ComputeSvdVectors::Thin
    } else {
        ComputeSvdVectors::No
    };
    let mut mem = MemBuffer::new(faer::linalg::svd::svd_scratch::<f64>(
        m,
        n,
        compute,
        compute,
        Par::Seq,
        Default::default(),
    ));
    faer::linalg::svd::svd(
        a,
        s.as_mut(),
        u.as_mut().map(|x| x.as_mut()),
        v.as_mut().map(|x| x.as_mut()),
        Par::Seq,
        MemStack::new(&mut mem),
        Default::default(),
    )
    .map_err(|e| ProcessError::Numerics(format!("SVD did not converge: {e:?}")))?;
    let values = s.column_vector().iter().copied().collect();
    Ok((values, u.zip(v)))
}

/// The eigenvalues of the symmetric `a` (its lower triangle), ascending, on one
/// thread.
fn eigenvalues_seq(a: MatRef<'_, f64>) -> Option<Vec<f64>> {
    let n = a.nrows();
    let mut s = faer::diag::Diag::<f64>::zeros(n);
    let mut mem = MemBuffer::new(faer::linalg::evd::self_adjoint_evd_scratch::<f64>(
        n,
        faer::linalg::evd::ComputeEigenvectors::No,
        Par::Seq,
        Default::default(),
    ));
    faer::linalg::evd::self_adjoint_evd(
        a,
        s.as_mut(),
        None,
        Par::Seq,
        MemStack::new(&mut mem),
        Default::default(),
    )
    .ok()?;
    Some(s.column_vector().iter().copied().collect())
}

/// Below this many rows or columns a full SVD is used: it costs milliseconds.
pub const MIN_TRUNCATED: usize = 256;

/// The largest residual r_j / σ_1 a truncated run may leave (else the full SVD).
pub const MAX_RESIDUAL: f64 = 1e-8;

/// The largest Krylov basis, in columns, before falling back to the full SVD.
pub const MAX_BASIS: usize = 600;

/// The relative change of the leading Ritz values below which the iteration stops.
const CONVERGED: f64 = 1e-14;

/// Extra columns in each block beyond the singular values wanted.
const OVERSAMPLE: usize = 8;

/// The singular values of a matrix needed for P_s^(k), and its Frobenius tails.
#[derive(Clone, Debug, PartialEq)]
pub struct Spectrum {
    /// Singular values, descending: all of them from a full SVD, the leading
    /// `k_max` from a truncated one.
    pub values: Vec<f64>,
    /// ‖A − A^(k)‖_F² for k = 0..=k_max from a truncated run; none from a full SVD
    /// (the tail is then the sum of the dropped σ_j²).
    tails: Option<Vec<f64>>,
    /// The largest residual r_j / σ_1 of the leading triplets (0 for a full SVD).
    pub residual: f64,
}

impl Spectrum {
    /// Whether every singular value was computed (a full SVD).
    pub fn is_full(&self) -> bool {
        self.tails.is_none()
    }

    /// ‖A − A^(k)‖_F², the sum of the squared singular values A^(k) drops
    /// (Eckart–Young). For a truncated spectrum, `k` at most the `k_max` asked.
    pub fn tail_sq(&self, k: usize) -> f64 {
        match &self.tails {
            None => self.values.iter().skip(k).map(|d| d * d).sum(),
            Some(t) => t[k.min(t.len() - 1)],
        }
    }
}

/// A thin SVD: the singular values, U and V.
pub(crate) type Thin = (Vec<f64>, Mat<f64>, Mat<f64>);

/// The thin SVD of `a` on this thread, (singular values, U, V): faer's default
/// parallelism splits the work by the number of threads, so that its last bits would
/// depend on it (issue 40: the same bytes on any number of threads).
pub(crate) fn thin(a: MatRef<'_, f64>) -> Result<Thin, ProcessError> {
    let (s, uv) = svd_seq(a, true)?;
    let (u, v) = uv.ok_or_else(|| ProcessError::Numerics("SVD without its vectors".into()))?;
    Ok((s, u, v))
}

/// The full SVD's singular values (faer, on one thread: the same bits on any
/// number of threads).
pub fn full(a: MatRef<'_, f64>) -> Result<Spectrum, ProcessError> {
    let (values, _) = svd_seq(a, false)?;
    Ok(Spectrum {
        values,
        tails: None,
        residual: 0.0,
    })
}

/// The spectrum P_s^(k) for k ≤ `k_max` needs: truncated (block Krylov, see the
/// module) for a large matrix, else, or when the truncated run fails its error
/// bound, the full SVD.
pub fn spectrum(a: MatRef<'_, f64>, k_max: usize) -> Result<Spectrum, ProcessError> {
    let n = a.nrows().min(a.ncols());
    let b = k_max + OVERSAMPLE;
    if n < MIN_TRUNCATED || 8 * b > n || k_max == 0 {
        return full(a);
    }
    match truncated(a, k_max, b) {
        Some(s) => Ok(s),
        None => full(a),
    }
}

/// A small seeded generator (SplitMix64): the start block, the same every run.
struct SplitMix(u64);

impl SplitMix {
    /// Uniform in [−1, 1).
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 * (2.0 / (1u64 << 53) as f64) - 1.0
    }
}

fn dot(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(a, b)| a * b).sum()
}

/// Orthonormalises the `b` columns of `y` (column-major, `rows` long) against the
/// `m` columns of `basis` and each other (two passes of block then column
/// Gram–Schmidt), appending them to `basis`. A column that vanishes (A of lower rank
/// than the basis) is replaced by a random one. False when even that fails.
fn extend_basis(basis: &mut Vec<f64>, rows: usize, y: &mut [f64], rng: &mut SplitMix) -> bool {
    let b = y.len() / rows;
    for _pass in 0..2 {
        let m = basis.len() / rows;
        if m == 0 {
            break;
        }
        let k = MatRef::from_column_major_slice(basis.as_slice(), rows, m);
        let c = product(k.transpose(), MatRef::from_column_major_slice(&*y, rows, b));
        let kc = product(k, c.as_ref());
        for j in 0..b {
            for (v, s) in y[j * rows..(j + 1) * rows]
                .iter_mut()
                .zip(kc.col_as_slice(j))
            {
                *v -= s;
            }
        }
    }
    for j in 0..b {
        let mut col = y[j * rows..(j + 1) * rows].to_vec();
        let mut ok = false;
        for attempt in 0..3 {
            if attempt > 0 {
                col.iter_mut().for_each(|v| *v = rng.next());
            }
            let before = dot(&col, &col).sqrt();
            for _pass in 0..2 {
                for q in basis.chunks_exact(rows) {
                    let c = dot(q, &col);
                    col.iter_mut().zip(q).for_each(|(v, x)| *v -= c * x);
                }
            }
            let after = dot(&col, &col).sqrt();
            // What is left after removing the basis must be more than rounding.
            if after > 1e-10 * before && after > 0.0 && after.is_finite() {
                col.iter_mut().for_each(|v| *v /= after);
                ok = true;
                break;
            }
        }
        if !ok {
            return false;
        }
        basis.extend_from_slice(&col);
    }
    true
}

/// The block Krylov iteration of the module; none when it does not converge within
/// [`MAX_BASIS`] columns or fails its error bound.
fn truncated(a: MatRef<'_, f64>, k_max: usize, b: usize) -> Option<Spectrum> {
    let (p, q) = (a.nrows(), a.ncols());
    let max_basis = MAX_BASIS.min(p.min(q) / 2);
    let mut rng = SplitMix(0x6f6e_696f_5f73_7664);
    let omega = Mat::from_fn(q, b, |_, _| rng.next());
    let mut y: Vec<f64> = mat_to_vec(&product(a, omega.as_ref()));
    let mut basis: Vec<f64> = Vec::with_capacity(p * max_basis);
    let mut w: Vec<f64> = Vec::with_capacity(q * max_basis);
    let mut prev: Vec<f64> = Vec::new();
    loop {
        let m0 = basis.len() / p;
        if !extend_basis(&mut basis, p, &mut y, &mut rng) {
            return None;
        }
        let m = basis.len() / p;
        let knew = MatRef::from_column_major_slice(&basis[m0 * p..], p, m - m0);
        let wn = product(a.transpose(), knew);
        w.extend_from_slice(&mat_to_vec(&wn));
        let wr = MatRef::from_column_major_slice(w.as_slice(), q, m);
        let gram = product(wr.transpose(), wr);
        let mut ev = eigenvalues_seq(gram.as_ref())?;
        ev.reverse();
        let sv: Vec<f64> = ev.iter().take(k_max).map(|l| l.max(0.0).sqrt()).collect();
        let done = prev.len() == sv.len()
            && sv
                .iter()
                .zip(&prev)
                .all(|(s, t)| (s - t).abs() <= CONVERGED * sv[0]);
        prev = sv;
        if done {
            break;
        }
        if m + b > max_basis {
            return None;
        }
        y = mat_to_vec(&product(a, wn.as_ref()));
    }
    let m = basis.len() / p;
    let wr = MatRef::from_column_major_slice(w.as_slice(), q, m);
    let (s, vectors) = svd_seq(wr, true).ok()?;
    let (su, sv) = vectors?;
    let values: Vec<f64> = s[..k_max].to_vec();
    let vk = su.subcols(0, k_max).to_owned();
    let uk = product(
        MatRef::from_column_major_slice(basis.as_slice(), p, m),
        sv.subcols(0, k_max),
    );
    let av = product(a, vk.as_ref());
    let sigma1 = values[0];
    let residual = (0..k_max)
        .map(|j| {
            let r: f64 = av
                .col_as_slice(j)
                .iter()
                .zip(uk.col_as_slice(j))
                .map(|(x, u)| (x - values[j] * u).powi(2))
                .sum();
            r.sqrt()
        })
        .fold(0.0, f64::max)
        / if sigma1 > 0.0 { sigma1 } else { 1.0 };
    if residual.is_nan() || residual > MAX_RESIDUAL {
        return None;
    }
    let frob: f64 = (0..q)
        .map(|c| a.col(c).iter().map(|x| x * x).sum::<f64>())
        .sum();
    let mut tails = Vec::with_capacity(k_max + 1);
    tails.push(frob);
    let mut acc = frob;
    for v in &values {
        acc -= v * v;
        tails.push(acc.max(0.0));
    }
    // Where the difference cancels, the residual's own norm (see the module).
    if tails.iter().any(|t| *t < 1e-6 * frob) {
        tails = residual_tails(a, &uk, &vk, &values);
    }
    Some(Spectrum {
        values,
        tails: Some(tails),
        residual,
    })
}

/// ‖A − Σ_{j<k} σ_j u_j v_jᵀ‖_F² for k = 0..=len, column by column.
fn residual_tails(a: MatRef<'_, f64>, uk: &Mat<f64>, vk: &Mat<f64>, s: &[f64]) -> Vec<f64> {
    let (p, q) = (a.nrows(), a.ncols());
    let mut tails = vec![0.0; s.len() + 1];
    let mut col = vec![0.0; p];
    for c in 0..q {
        for (r, v) in col.iter_mut().enumerate() {
            *v = a[(r, c)];
        }
        tails[0] += dot(&col, &col);
        for (j, sj) in s.iter().enumerate() {
            let coef = sj * vk[(c, j)];
            col.iter_mut()
                .zip(uk.col_as_slice(j))
                .for_each(|(v, u)| *v -= coef * u);
            tails[j + 1] += dot(&col, &col);
        }
    }
    tails
}

fn mat_to_vec(m: &Mat<f64>) -> Vec<f64> {
    let mut v = Vec::with_capacity(m.nrows() * m.ncols());
    for j in 0..m.ncols() {
        v.extend_from_slice(m.col_as_slice(j));
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A P × Q matrix of rank `rank` with singular values `decay^j`, plus uniform
    /// noise of amplitude `noise`.
    fn low_rank(p: usize, q: usize, rank: usize, decay: f64, noise: f64, seed: u64) -> Mat<f64> {
        let mut rng = SplitMix(seed);
        let u = Mat::from_fn(p, rank, |_, _| rng.next());
        let v = Mat::from_fn(q, rank, |_, _| rng.next());
        let d = Mat::from_fn(
            rank,
            rank,
            |i, j| if i == j { decay.powi(i as i32) } else { 0.0 },
        );
        let mut a = &u * &d * v.transpose();
        for j in 0..q {
            for i in 0..p {
                a[(i, j)] += noise * rng.next();
            }
        }
        a
    }

    fn check(a: &Mat<f64>, k_max: usize, truncates: bool) {
        let exact = full(a.as_ref()).expect("full");
        let t = spectrum(a.as_ref(), k_max).expect("truncated");
        assert_eq!(!t.is_full(), truncates, "{}×{}", a.nrows(), a.ncols());
        assert!(t.residual <= MAX_RESIDUAL, "{}", t.residual);
        let s1 = exact.values[0];
        for j in 0..k_max {
            assert!(
                (t.values[j] - exact.values[j]).abs() <= 1e-10 * s1,
                "σ_{j}: {} vs {}",
                t.values[j],
                exact.values[j]
            );
        }
        for k in 0..=k_max {
            let (x, y) = (t.tail_sq(k), exact.tail_sq(k));
            assert!(
                (x - y).abs() <= 1e-9 * exact.tail_sq(0),
                "tail {k}: {x} vs {y}"
            );
        }
    }

    #[test]
    fn truncated_values_agree_with_the_full_svd() {
        // Uniform random entries: a flat spectrum whose leading gaps are too small to
        // converge in the basis allowed, so the full SVD answers (the same values).
        let mut rng = SplitMix(7);
        let random = Mat::from_fn(300, 280, |_, _| rng.next());
        check(&random, 5, false);
        // Random with columns scaled by 0.97^j: a decaying spectrum, no exact rank.
        let scaled = Mat::from_fn(400, 300, |_, j| rng.next() * 0.97f64.powi(j as i32));
        check(&scaled, 10, true);
        // Rank 12 plus noise, wide and tall.
        check(&low_rank(320, 400, 12, 0.7, 1e-3, 3), 10, true);
        check(&low_rank(500, 300, 12, 0.8, 1e-6, 4), 10, true);
    }

    #[test]
    fn an_exactly_low_rank_matrix_has_zero_tails() {
        // Rank 3: the Krylov space runs out of directions (random replacements), and
        // the tails beyond k = 3 are the residual's norm, ~0, not a cancelled difference.
        let a = low_rank(300, 300, 3, 0.5, 0.0, 9);
        let t = spectrum(a.as_ref(), 5).expect("spectrum");
        assert!(!t.is_full());
        assert!(t.tail_sq(3) <= 1e-24 * t.tail_sq(0), "{}", t.tail_sq(3));
        assert!(t.values[3] <= 1e-12 * t.values[0]);
        let exact = full(a.as_ref()).expect("full");
        assert!((t.values[2] - exact.values[2]).abs() <= 1e-12 * exact.values[0]);
    }

    #[test]
    fn small_matrices_get_the_full_svd() {
        let mut rng = SplitMix(1);
        let a = Mat::from_fn(40, 60, |_, _| rng.next());
        let s = spectrum(a.as_ref(), 3).expect("spectrum");
        assert!(s.is_full());
        assert_eq!(s.values.len(), 40);
        // The same seed, the same numbers: a truncated run is deterministic.
        let b = low_rank(300, 300, 8, 0.6, 1e-4, 5);
        assert_eq!(spectrum(b.as_ref(), 4), spectrum(b.as_ref(), 4));
    }
}
