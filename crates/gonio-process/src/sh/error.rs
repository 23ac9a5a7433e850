//! How far an [`ShBrdf`] is from a table at the table's nodes: the error estimate,
//! and the compression the representation achieves.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use gonio_core::Dir;

use super::{ShBrdf, eval_basis};
use crate::ProcessError;
use crate::grid::{Axis, Table};

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

impl ShBrdf {
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
}
