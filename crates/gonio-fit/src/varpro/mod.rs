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

mod eval;
mod lm;
mod nnls;
mod qp;

use crate::data::FitData;

pub use eval::{
    ChannelConstraint, Evaluation, Full, column_vectors, evaluate, evaluate_prepared, residuals,
};
pub use lm::{Projected, Solved, solve, solve_to, solve_with};
pub use nnls::nnls;
pub use qp::{QpSolution, qp};

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

    /// The directional albedo of each column of channel `ch` (unit coefficient) at
    /// incident directions `wi`: `b[l * K + u]`; with `db`, also ∂b/∂θ_q into
    /// `db[(l * K + u) * P + q]`. An energy-constrained fit holds B c ≤ 1. The default
    /// has no albedo (all 0: no constraint).
    fn albedo_rows(
        &self,
        theta: &[f64],
        ch: usize,
        wi: &[[f64; 3]],
        b: &mut [f64],
        db: Option<&mut [f64]>,
    ) {
        let _ = (theta, ch, wi);
        b.fill(0.0);
        if let Some(db) = db {
            db.fill(0.0);
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
    /// Residual buffers of evaluations no longer needed, reused likewise (a search
    /// keeps only its best evaluation's).
    spare: std::sync::Mutex<Vec<Vec<f64>>>,
    /// Incident directions at which the directional albedo is held ≤ 1 (the energy
    /// constraint), if any.
    pub limits: Option<Vec<[f64; 3]>>,
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
            .map(|(w, y)| w.iter().zip(y.iter()).map(|(w, y)| w * y).collect())
            .collect();
        Prepared {
            data,
            uv,
            wy,
            buffers: std::sync::Mutex::new(None),
            spare: std::sync::Mutex::new(Vec::new()),
            limits: None,
        }
    }

    /// An empty buffer for `n` residuals: a spare one if there is one.
    fn spare_residuals(&self, n: usize) -> Vec<f64> {
        let mut v = self
            .spare
            .lock()
            .ok()
            .and_then(|mut s| s.pop())
            .unwrap_or_default();
        v.clear();
        v.reserve(n);
        v
    }

    /// Hands back an evaluation's residual buffer for the next evaluations.
    fn give_back(&self, e: Evaluation) {
        if let (Some(f), Ok(mut s)) = (e.full, self.spare.lock()) {
            s.push(f.residuals);
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
