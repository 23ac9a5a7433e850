//! The start of a fit (module docs of [`super`]): lobes added one at a time, each
//! from a grid of seeds scored by the projected cost, the best refined together
//! with the lobes already placed, on an evenly thinned subset of the data.

use std::f64::consts::{FRAC_PI_4, PI};

use rayon::prelude::*;

use crate::data::FitData;
use crate::fastmath;
use crate::lobes::{LobeBasis, Shape};
use crate::varpro::{self, Basis};

/// Every k-th pair, so that at most `max` remain (deterministic).
pub(super) fn thin(d: &FitData, max: usize) -> FitData {
    if d.len() <= max {
        return d.clone();
    }
    let step = d.len().div_ceil(max);
    let keep: Vec<usize> = (0..d.len()).step_by(step).collect();
    FitData {
        channels: d.channels.clone(),
        wi: keep.iter().map(|&i| d.wi[i]).collect(),
        wo: keep.iter().map(|&i| d.wo[i]).collect(),
        y: d.y
            .iter()
            .map(|v| keep.iter().map(|&i| v[i]).collect())
            .collect(),
        weight: d
            .weight
            .iter()
            .map(|v| keep.iter().map(|&i| v[i]).collect())
            .collect(),
        chi_square: d.chi_square,
        objective: d.objective,
        objective_rule: d.objective_rule.clone(),
        metric: d.metric,
        cut: d.cut,
    }
}

/// Relative cost reduction at which the start search's refinements stop.
const SEARCH_FTOL: f64 = 1e-8;

/// Seeds of a new lobe: (β, γ, n).
fn seeds(anisotropic: bool) -> Vec<(f64, f64, f64)> {
    let betas = [1.3, 0.9, 0.5, -0.2, -0.5, -0.8, -1.1, -1.4];
    let ns = [1.5, 3.0, 6.0, 12.0, 25.0, 50.0, 100.0];
    let gammas: &[f64] = if anisotropic {
        &[FRAC_PI_4, 0.0, PI / 2.0]
    } else {
        &[FRAC_PI_4]
    };
    let mut out = Vec::new();
    for &b in &betas {
        for &g in gammas {
            for &n in &ns {
                // Anisotropic directions: a negative β flips both x and y (forward).
                out.push((b, g, n));
            }
        }
    }
    out
}

/// Reads lobe j of channel ch as (β, γ, n).
fn get_lobe(basis: &LobeBasis, theta: &[f64], ch: usize, j: usize) -> (f64, f64, f64) {
    let (c, n) = basis.lobe(theta, ch, j);
    let beta = c[2].clamp(-1.0, 1.0).acos();
    if basis.shape.anisotropic {
        let gamma = c[1].atan2(c[0]);
        (beta, gamma, n)
    } else {
        // c = (sin β/√2, sin β/√2, cos β): the sign of c[0] is the sign of β.
        let b = if c[0] < 0.0 { -beta } else { beta };
        (b, FRAC_PI_4, n)
    }
}

/// One channel's weighted columns but the last (the lobe being placed), their Gram
/// matrix and products with the data, for scoring seeds of that lobe.
struct Fixed {
    /// Columns 0..K−1, each over all pairs.
    cols: Vec<Vec<f64>>,
    /// Their Gram matrix, (K−1)², and products with Wy.
    g: Vec<f64>,
    h: Vec<f64>,
}

impl Fixed {
    fn new(basis: &LobeBasis, prep: &varpro::Prepared, theta: &[f64], ch: usize) -> Fixed {
        let mut cols = varpro::column_vectors(basis, prep, theta, ch);
        cols.pop();
        let k = cols.len();
        let wy = prep.weighted_values(ch);
        let mut g = vec![0.0; k * k];
        for u in 0..k {
            for v in 0..k {
                g[u * k + v] = fastmath::dot(&cols[u.min(v)], &cols[u.max(v)]);
            }
        }
        let h = cols.iter().map(|c| fastmath::dot(c, wy)).collect();
        Fixed { cols, g, h }
    }

    /// The projected cost of channel `ch` with the last lobe as in `theta`.
    fn cost(&self, basis: &LobeBasis, prep: &varpro::Prepared, theta: &[f64], ch: usize) -> f64 {
        let d = prep.data;
        let (c, n) = basis.lobe(theta, ch, basis.shape.lobes - 1);
        let mut lx = vec![0.0; d.len()];
        let mut col = vec![0.0; d.len()];
        fastmath::lobe_column(c, n, prep.uv(), &d.weight[ch], &mut lx, &mut col);
        let wy = prep.weighted_values(ch);
        let k = self.cols.len() + 1;
        let mut g = vec![0.0; k * k];
        let mut h = self.h.clone();
        for u in 0..k - 1 {
            for v in 0..k - 1 {
                g[u * k + v] = self.g[u * (k - 1) + v];
            }
            let x = fastmath::dot(&self.cols[u], &col);
            g[u * k + k - 1] = x;
            g[(k - 1) * k + u] = x;
        }
        g[k * k - 1] = fastmath::dot(&col, &col);
        h.push(fastmath::dot(&col, wy));
        let coef = varpro::nnls(&g, &h, k);
        // Σr² from the residuals themselves (no cancellation against Σ(Wy)²).
        let mut r: Vec<f64> = wy.iter().map(|y| -y).collect();
        for (u, cu) in coef.iter().enumerate() {
            if *cu != 0.0 {
                let cv = if u + 1 == k { &col } else { &self.cols[u] };
                for (ri, a) in r.iter_mut().zip(cv) {
                    *ri += cu * a;
                }
            }
        }
        fastmath::dot(&r, &r)
    }
}

/// The greedy multi-start search on `d` (module docs); returns θ for `shape`.
pub(super) fn search(d: &FitData, shape: Shape, shared: bool) -> Vec<f64> {
    let nc = d.channels.len();
    let mut prev: Option<(LobeBasis, Vec<f64>)> = None;
    for l in 1..=shape.lobes {
        let basis = LobeBasis {
            shape: Shape { lobes: l, ..shape },
            channels: nc,
            shared,
        };
        let mut base = vec![0.0; basis.n_params()];
        for ch in 0..nc {
            if let Some(k) = basis.kappa_idx(ch) {
                base[k] = 0.5;
            }
        }
        if let Some((pb, pt)) = &prev {
            for ch in 0..nc {
                for j in 0..l - 1 {
                    let (b, g, n) = get_lobe(pb, pt, ch, j);
                    basis.set_lobe(&mut base, ch, j, b, g, n);
                }
                if let (Some(a), Some(b)) = (pb.kappa_idx(ch), basis.kappa_idx(ch)) {
                    base[b] = pt[a];
                }
            }
        }
        // Only the new lobe's column changes from seed to seed: the others (and
        // their Gram matrix) are computed once.
        let prep = varpro::Prepared::new(d);
        let fixed: Vec<Fixed> = (0..nc)
            .map(|ch| Fixed::new(&basis, &prep, &base, ch))
            .collect();
        let mut scored: Vec<(f64, Vec<f64>)> = seeds(shape.anisotropic)
            .into_par_iter()
            .map(|(b, g, n)| {
                let mut t = base.clone();
                for ch in 0..nc {
                    let (bb, gg) = if shape.anisotropic && b < 0.0 {
                        (-b, g + PI)
                    } else {
                        (b, g)
                    };
                    basis.set_lobe(&mut t, ch, l - 1, bb, gg, n);
                }
                let c: f64 = fixed
                    .iter()
                    .enumerate()
                    .map(|(ch, f)| f.cost(&basis, &prep, &t, ch))
                    .sum();
                (if c.is_finite() { c } else { f64::INFINITY }, t)
            })
            .collect();
        scored.sort_by(|a, b| a.0.total_cmp(&b.0));
        let best = scored
            .into_iter()
            .take(4)
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|(_, t)| {
                let s = varpro::solve_to(&basis, d, &t, 15, SEARCH_FTOL);
                (s.cost, s.theta)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|x| x.1)
            .unwrap_or(base);
        prev = Some((basis, best));
    }
    prev.map(|p| p.1).unwrap_or_default()
}
