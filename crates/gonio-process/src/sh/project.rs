//! The projection of a BRDF (a function or a table) onto the basis by the product
//! quadrature on each hemisphere: Gauss–Legendre nodes, the table read at them, and
//! `M = 4 Bᵀ F B` in parallel blocks.

use std::f64::consts::{PI, TAU};

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use gonio_core::{Channels, Dir, Vec3};
use rayon::prelude::*;

use super::basis::fill_basis;
use super::{ShBrdf, ShOptions, basis, basis_len, taper};
use crate::ProcessError;
use crate::grid::{Axis, Grid, Table};

/// Rows of `F` evaluated at once: bounds the block to ~32 MB whatever `Q` is.
const BLOCK_VALUES: usize = 1 << 22;

/// Gauss–Legendre nodes and weights on [−1, 1], ascending.
pub(super) fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
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
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
