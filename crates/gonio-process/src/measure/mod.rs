//! DeYoung's measures of the four properties of a tabulated BRDF (Ch. 4): each is 0
//! when the table has the property and grows with the departure from it, and none
//! depends on the number of samples (Sec. 4.1). Every measure is computed per channel.

pub mod floor;
use std::f64::consts::{FRAC_PI_2, TAU};

use faer::{Mat, MatRef};
use rayon::prelude::*;
use serde::Serialize;

use crate::grid::{interpolate, interpolate_by};
use crate::{Axis, Grid, ProcessError, Samples, Table, svd};

/// Whether the reciprocal angles of a node lie inside the table's axes, so that the
/// reciprocal value is data, not the held end value of an axis.
fn reciprocal_inside(g: &Grid, ang: [f64; 4]) -> bool {
    let inside = |ax: &Axis, x: f64| {
        ax.is_periodic() || ax.node_at(x).is_some() || {
            let (lo, hi) = (ax.start, ax.node(ax.n - 1));
            x >= lo - 1e-9 && x <= hi + 1e-9
        }
    };
    let [pi, ti, po, to] = ang;
    if g.isotropic {
        return inside(&g.theta_i, to) && inside(&g.theta_o, ti) && inside(&g.phi_o, pi - po);
    }
    inside(&g.phi_i, po) && inside(&g.theta_i, to) && inside(&g.phi_o, pi) && inside(&g.theta_o, ti)
}

/// Where each node's reciprocal value f(φo, θo, φi, θi) comes from: looked up when
/// the grid pairs (an index map, built once per table), interpolated quadrilinearly
/// when it does not (Sec. 4.2.1).
pub(crate) struct Reciprocals {
    map: Option<Vec<usize>>,
}

impl Reciprocals {
    pub(crate) fn new(g: &Grid) -> Reciprocals {
        if !g.is_paired() {
            return Reciprocals { map: None };
        }
        // Each node's on its own, on rayon: one pass over the table's nodes.
        let map = (0..g.len())
            .into_par_iter()
            .map(|i| {
                let [a, b, c, d] = g.unindex(i);
                if g.isotropic {
                    // f(θi, φ+, θo) ↔ f(θo, −φ+, θi); pairing guarantees the node.
                    let minus = g.phi_o.node_at(-g.phi_o.node(c)).unwrap_or(c);
                    g.index(0, d, minus, b)
                } else {
                    g.index(c, d, a, b)
                }
            })
            .collect();
        Reciprocals { map: Some(map) }
    }

    /// The reciprocal node of each node when the grid pairs (looked up), else none.
    pub(crate) fn map(&self) -> Option<&[usize]> {
        self.map.as_deref()
    }

    /// The reciprocal of node `i` in `values` (one channel); none when it lies
    /// outside the table.
    pub(crate) fn value(&self, g: &Grid, values: &[f64], i: usize) -> Option<f64> {
        self.value_by(g, |k| values[k], i)
    }

    /// [`Reciprocals::value`] of the values `x(node)` gives.
    #[inline]
    pub(crate) fn value_by(&self, g: &Grid, x: impl Fn(usize) -> f64, i: usize) -> Option<f64> {
        match &self.map {
            Some(m) => Some(x(m[i])),
            None => {
                let [pi, ti, po, to] = g.angles(i);
                reciprocal_inside(g, [pi, ti, po, to])
                    .then(|| interpolate_by(g, x, [po, to, pi, ti]))
            }
        }
    }
}

/// Nodes a block of a parallel sum has: fixed, so that the sum's order does not
/// depend on the number of threads.
const SUM_BLOCK: usize = 1 << 14;

/// P_r, DeYoung Eq. 4.1, per channel: the RMS difference between each value and its
/// reciprocal, with the factor 2 for each pair counted twice. Nodes whose reciprocal
/// lies outside the table are left out of both sums; the count used is returned.
pub fn reciprocity(t: &Table) -> (Vec<f64>, usize) {
    let rec = Reciprocals::new(&t.grid);
    let mut used = 0;
    let out = (0..t.channels.len())
        .map(|ch| {
            let v = t.channel(ch);
            let (p_r, count) = reciprocity_by(&t.grid, &rec, |k| v[k]);
            used = count;
            p_r
        })
        .collect();
    (out, used)
}

/// P_r of one channel whose value at node k is `x(k)`, and the nodes it counts
/// ([`reciprocity`]): the floors measure their counterparts this way without storing
/// them.
pub(crate) fn reciprocity_by(
    g: &Grid,
    rec: &Reciprocals,
    x: impl Fn(usize) -> f64 + Sync,
) -> (f64, usize) {
    let n = g.len();
    // Fixed blocks of nodes summed on rayon, their sums added in order: the same
    // bits on any number of threads.
    let blocks: Vec<(f64, usize)> = (0..n.div_ceil(SUM_BLOCK))
        .into_par_iter()
        .map(|b| {
            let (mut sum, mut count) = (0.0, 0usize);
            for i in b * SUM_BLOCK..((b + 1) * SUM_BLOCK).min(n) {
                if let Some(r) = rec.value_by(g, &x, i) {
                    sum += (x(i) - r).powi(2);
                    count += 1;
                }
            }
            (sum, count)
        })
        .collect();
    let (mut sum, mut count) = (0.0, 0usize);
    for (s, c) in blocks {
        sum += s;
        count += c;
    }
    let p_r = if count == 0 {
        0.0
    } else {
        (sum / (2.0 * count as f64)).sqrt()
    };
    (p_r, count)
}

/// How the directional albedos of the energy measure were formed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum EnergyMethod {
    /// DeYoung's sum over the grid's outgoing nodes, Eq. 4.4 (exact on polar band
    /// midpoints over the whole hemisphere).
    Sum,
    /// The triangulated hemisphere of Sec. 4.2.2 (Nusselt analogue) over the
    /// samples of each incident direction, the band to the horizon held from the
    /// data's edge ([`crate::hemisphere`]).
    Triangulated,
}

/// Energy conservation of a table, DeYoung Sec. 4.2.2.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Energy {
    /// P_ec per channel, Eq. 4.5.
    pub p_ec: Vec<f64>,
    /// How the albedos were formed.
    pub method: EnergyMethod,
    /// The incident directions of the albedo rows, (θi°, φi°).
    pub incident: Vec<(f64, f64)>,
    /// The directional albedo M/E per channel and incident direction (Eq. 4.3 as the
    /// sum of Eq. 4.4 before the −1), rows in incident-node order (φi, θi).
    pub albedo: Vec<Vec<f64>>,
    /// Standard uncertainties of the albedos from the data's noise, same layout, when
    /// the data carry σ (triangulated form only).
    pub albedo_sigma: Option<Vec<Vec<f64>>>,
    /// Standard uncertainties of the albedos from their discretisation, same layout,
    /// estimated from the data (Richardson on coarser rules, and for the triangulated
    /// form the band beyond the data's edge: [`sum_quadrature`],
    /// [`crate::hemisphere::IncidentAlbedo::quadrature`]). Independent of
    /// `albedo_sigma`; an albedo's whole uncertainty is the two in quadrature.
    pub albedo_quadrature_sigma: Vec<Vec<f64>>,
    /// The standard uncertainty of P_ec per channel from the albedos' noise, when the
    /// data carry σ ([`p_ec_sigma`]).
    pub p_ec_noise_sigma: Option<Vec<f64>>,
    /// The standard uncertainty of P_ec per channel from the albedos'
    /// discretisation ([`p_ec_sigma`]).
    pub p_ec_quadrature_sigma: Vec<f64>,
    /// The fraction of the outgoing hemisphere's projected solid angle the data
    /// cover: the outgoing axes' bands for the sum (the albedo undercounts by about
    /// this fraction when it is below 1), the smallest convex hull of any incident
    /// direction's samples for the triangulated form.
    pub coverage: f64,
    /// The largest fraction of the projected hemisphere, over the incident
    /// directions, whose values were held from the data's edge to the horizon
    /// (triangulated form; 0 for the sum).
    pub extrapolated: f64,
    /// The incident directions with the largest albedo, worst first: (θi°, φi°, the
    /// albedo per channel).
    pub worst: Vec<(f64, f64, Vec<f64>)>,
}

/// The weight of outgoing node (c, d) in DeYoung's sum, sinθo cosθo Δφo Δθo (Eq. 4.4).
pub(crate) fn out_weights(g: &Grid) -> Vec<f64> {
    let (dp, dt) = (g.phi_o.delta(), g.theta_o.delta());
    let mut w = Vec::with_capacity(g.n_out());
    for _c in 0..g.phi_o.n {
        for d in 0..g.theta_o.n {
            let th = g.theta_o.node(d);
            w.push(th.sin() * th.cos() * dp * dt);
        }
    }
    w
}

/// Directional albedo of every incident node, per channel: Σ f sinθo cosθo Δφo Δθo.
pub(crate) fn albedos(t: &Table) -> Vec<Vec<f64>> {
    let w = out_weights(&t.grid);
    let (p, q) = (t.grid.n_in(), t.grid.n_out());
    (0..t.channels.len())
        .map(|ch| {
            let v = t.channel(ch);
            // Each row on its own: the same bits on any number of threads.
            (0..p)
                .into_par_iter()
                .map(|r| {
                    v[r * q..(r + 1) * q]
                        .iter()
                        .zip(&w)
                        .map(|(a, b)| a * b)
                        .sum()
                })
                .collect()
        })
        .collect()
}

/// The measure of energy conservation, Eq. 4.4–4.5 (with the threshold τ of Eq. 4.7
/// in place of 1 when given; DeYoung's measure is τ = 1).
pub fn energy(t: &Table, tau: f64, worst: usize) -> Energy {
    let g = &t.grid;
    let alb = albedos(t);
    let p_ec = alb
        .iter()
        .map(|a| a.iter().map(|x| (x - tau).max(0.0)).sum::<f64>() / a.len() as f64)
        .collect();
    let span_phi = if g.phi_o.n == 1 {
        1.0
    } else {
        (g.phi_o.n as f64 * g.phi_o.step / TAU).min(1.0)
    };
    // ∫ sinθ cosθ dθ over the bands the polar nodes stand for, against 1/2.
    let (t0, dt, nt) = (g.theta_o.start, g.theta_o.delta(), g.theta_o.n);
    let lo = (t0 - 0.5 * dt).max(0.0);
    let hi = (t0 + (nt as f64 - 0.5) * dt).min(FRAC_PI_2);
    let span_theta = if nt == 1 {
        0.0
    } else {
        (hi.sin().powi(2) - lo.sin().powi(2)).clamp(0.0, 1.0)
    };
    let mut order: Vec<usize> = (0..g.n_in()).collect();
    let peak = |r: usize| alb.iter().map(|a| a[r]).fold(f64::NEG_INFINITY, f64::max);
    order.sort_by(|&a, &b| peak(b).total_cmp(&peak(a)));
    let worst = order
        .into_iter()
        .take(worst)
        .map(|r| {
            let (a, b) = (r / g.theta_i.n, r % g.theta_i.n);
            (
                g.theta_i.node_deg(b),
                g.phi_i.node_deg(a),
                alb.iter().map(|x| x[r]).collect(),
            )
        })
        .collect();
    let incident = (0..g.n_in())
        .map(|r| {
            let (a, b) = (r / g.theta_i.n, r % g.theta_i.n);
            (g.theta_i.node_deg(b), g.phi_i.node_deg(a))
        })
        .collect();
    let quad = sum_quadrature(t);
    let (p_ec_noise_sigma, p_ec_quadrature_sigma) = p_ec_sigma(&alb, None, &quad, tau);
    Energy {
        p_ec,
        method: EnergyMethod::Sum,
        incident,
        albedo: alb,
        albedo_sigma: None,
        albedo_quadrature_sigma: quad,
        p_ec_noise_sigma,
        p_ec_quadrature_sigma,
        coverage: span_phi * span_theta,
        extrapolated: 0.0,
        worst,
    }
}

/// The standard uncertainty of P_ec (Eq. 4.5) per channel, from the albedos' noise
/// σ (when given) and from their discretisation, both `[channel][row]`.
///
/// P_ec averages max(0, ρ − τ) over the incidences, which has no derivative at
/// ρ = τ; each albedo's part is weighted by the derivative of its expected excess,
/// Φ((ρ − τ)/u) with u its whole standard uncertainty (noise and discretisation in
/// quadrature; Φ the standard normal distribution function): 1 well above τ, 0 well
/// below, ½ at it. The noise is independent between incidences, so its parts add in
/// quadrature; the discretisation's errors of neighbouring incidences come from the
/// same grid and are taken as fully correlated, so its parts add linearly.
pub fn p_ec_sigma(
    albedo: &[Vec<f64>],
    noise: Option<&[Vec<f64>]>,
    quadrature: &[Vec<f64>],
    tau: f64,
) -> (Option<Vec<f64>>, Vec<f64>) {
    let phi = |z: f64| 0.5 * gonio_core::special::erfc(-z / std::f64::consts::SQRT_2);
    let mut out_noise = Vec::with_capacity(albedo.len());
    let mut out_quad = Vec::with_capacity(albedo.len());
    for (ch, a) in albedo.iter().enumerate() {
        let n = a.len().max(1) as f64;
        let (mut var, mut lin) = (0.0, 0.0);
        for (r, x) in a.iter().enumerate() {
            let sn = noise.map_or(0.0, |s| s[ch][r]);
            let sq = quadrature[ch][r];
            let u = sn.hypot(sq);
            let weight = if u > 0.0 {
                phi((x - tau) / u)
            } else if *x > tau {
                1.0
            } else {
                0.0
            };
            // An albedo more than six of its σ below τ has no part.
            let weight = if weight < 1e-9 { 0.0 } else { weight };
            var += (weight * sn).powi(2);
            lin += weight * sq;
        }
        out_noise.push(var.sqrt() / n);
        out_quad.push(lin / n);
    }
    (noise.map(|_| out_noise), out_quad)
}

/// The standard uncertainty of the discretisation of every row's sum (Eq. 4.4), per
/// channel and row: Richardson's estimate from coarser rules on the same nodes.
/// **Azimuth**: on a full turn of at least four nodes, every other azimuth (each
/// parity, periodic trapezoid weights) against all; the fine rule's error is the
/// difference over 2² − 1, the two parities averaged in square. **Polar angle**, on
/// at least three nodes: the difference to the rule that integrates the quadratic
/// through each node and its neighbours over its band, taken whole (it sees a peak
/// at a node that a coarser rule can step over); and on polar band midpoints whose
/// count is a multiple of 3, the midpoint rule on bands three times as wide (their
/// midpoints are every third node), the difference over 3² − 1 (it sees what lies
/// between the nodes). All terms add in quadrature.
pub fn sum_quadrature(t: &Table) -> Vec<Vec<f64>> {
    let g = &t.grid;
    let (p, q) = (g.n_in(), g.n_out());
    let (np, nt) = (g.phi_o.n, g.theta_o.n);
    let (dp, dt) = (g.phi_o.delta(), g.theta_o.delta());
    let th: Vec<f64> = (0..nt).map(|d| g.theta_o.node(d)).collect();
    let wt: Vec<f64> = th.iter().map(|x| x.sin() * x.cos() * dt).collect();
    // Azimuth subsets: (kept azimuths, their periodic trapezoid weights).
    let mut az: Vec<(Vec<usize>, Vec<f64>)> = Vec::new();
    if g.phi_o.is_periodic() && np >= 4 {
        for parity in 0..2 {
            let keep: Vec<usize> = (0..np).filter(|c| c % 2 == parity).collect();
            let m = keep.len();
            let w = (0..m)
                .map(|j| {
                    let next = (keep[(j + 1) % m] + np - keep[j]) % np;
                    let prev = (keep[j] + np - keep[(j + m - 1) % m]) % np;
                    0.5 * (next + prev) as f64 * dp
                })
                .collect();
            az.push((keep, w));
        }
    }
    // Polar rules to compare with: weights per node, and the factor to the fine error.
    let midpoints = nt >= 3
        && (g.theta_o.start - 0.5 * dt).abs() < 1e-9
        && (nt as f64 * dt - FRAC_PI_2).abs() < 1e-9;
    let mut polar: Vec<(Vec<f64>, f64)> = Vec::new();
    if midpoints && nt % 3 == 0 {
        let w = (0..nt)
            .map(|d| {
                if d % 3 == 1 {
                    th[d].sin() * th[d].cos() * 3.0 * dt
                } else {
                    0.0
                }
            })
            .collect();
        polar.push((w, 1.0 / 8.0));
    }
    if nt >= 3 {
        polar.push((quadratic_band_weights(&th, dt), 1.0));
    }
    (0..t.channels.len())
        .map(|ch| {
            let v = t.channel(ch);
            (0..p)
                .into_par_iter()
                .map(|r| {
                    let row = &v[r * q..(r + 1) * q];
                    let at = |c: usize, d: usize| row[c * nt + d];
                    let ring = |c: usize| (0..nt).map(|d| at(c, d) * wt[d]).sum::<f64>();
                    let fine: f64 = (0..np).map(|c| ring(c) * dp).sum();
                    let mut var = 0.0;
                    if !az.is_empty() {
                        let ms: f64 = az
                            .iter()
                            .map(|(keep, w)| {
                                let coarse: f64 =
                                    keep.iter().zip(w).map(|(&c, wc)| ring(c) * wc).sum();
                                (coarse - fine).powi(2)
                            })
                            .sum::<f64>()
                            / az.len() as f64;
                        var += ms / 9.0;
                    }
                    for (w, factor) in &polar {
                        let other: f64 = (0..np)
                            .map(|c| (0..nt).map(|d| at(c, d) * w[d]).sum::<f64>() * dp)
                            .sum();
                        var += ((other - fine) * factor).powi(2);
                    }
                    var.sqrt()
                })
                .collect()
        })
        .collect()
}

/// The weight of each polar node in ∫ f sin θ cos θ dθ when f is taken as the
/// quadratic through each node and its two neighbours (the first and last nodes'
/// triples shifted inwards) over the node's band [θ − Δθ/2, θ + Δθ/2] clipped to
/// [0°, 90°]; 8-point Gauss–Legendre on each band.
fn quadratic_band_weights(th: &[f64], dt: f64) -> Vec<f64> {
    const GL8: [(f64, f64); 8] = [
        (-0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
        (-0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
        (-0.525_532_409_916_329_0, 0.313_706_645_877_887_3),
        (-0.183_434_642_495_649_8, 0.362_683_783_378_362_0),
        (0.183_434_642_495_649_8, 0.362_683_783_378_362_0),
        (0.525_532_409_916_329_0, 0.313_706_645_877_887_3),
        (0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
        (0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
    ];
    let n = th.len();
    let mut w = vec![0.0; n];
    for d in 0..n {
        let j0 = d.saturating_sub(1).min(n - 3);
        let (lo, hi) = (
            (th[d] - 0.5 * dt).max(0.0),
            (th[d] + 0.5 * dt).min(FRAC_PI_2),
        );
        if hi <= lo {
            continue;
        }
        for (x, wq) in GL8 {
            let t = lo + 0.5 * (hi - lo) * (1.0 + x);
            let jac = 0.5 * (hi - lo) * wq * t.sin() * t.cos();
            for j in j0..j0 + 3 {
                // Lagrange basis of node j over the triple.
                let l: f64 = (j0..j0 + 3)
                    .filter(|&m| m != j)
                    .map(|m| (t - th[m]) / (th[j] - th[m]))
                    .product();
                w[j] += jac * l;
            }
        }
    }
    w
}

/// The measure of energy conservation of scattered samples, Eq. 4.5 over the
/// albedos of DeYoung's triangulated hemisphere (Sec. 4.2.2; [`crate::hemisphere`]),
/// with the threshold τ of Eq. 4.7 as in [`energy`].
pub fn energy_scattered(s: &Samples, tau: f64, worst: usize) -> Result<Energy, ProcessError> {
    Ok(energy_of_rows(
        &crate::hemisphere::albedos(s)?,
        s.channels.len(),
        tau,
        worst,
    ))
}

/// The triangulated measure of a table's nodes ([`crate::hemisphere::albedos_of_table`]),
/// as [`energy_scattered`] would give for the table's samples, a row at a time.
pub fn energy_triangulated(t: &Table, tau: f64, worst: usize) -> Result<Energy, ProcessError> {
    Ok(energy_of_rows(
        &crate::hemisphere::albedos_of_table(t)?,
        t.channels.len(),
        tau,
        worst,
    ))
}

/// Eq. 4.5 over directional albedos of the triangulated form.
fn energy_of_rows(
    rows: &[crate::hemisphere::IncidentAlbedo],
    nc: usize,
    tau: f64,
    worst: usize,
) -> Energy {
    let albedo: Vec<Vec<f64>> = (0..nc)
        .map(|ch| rows.iter().map(|r| r.albedo[ch]).collect())
        .collect();
    let albedo_sigma = rows.iter().all(|r| r.sigma.is_some()).then(|| {
        (0..nc)
            .map(|ch| {
                rows.iter()
                    .map(|r| r.sigma.as_ref().map_or(0.0, |s| s[ch]))
                    .collect()
            })
            .collect()
    });
    let quad: Vec<Vec<f64>> = (0..nc)
        .map(|ch| rows.iter().map(|r| r.quadrature[ch]).collect())
        .collect();
    let p_ec = albedo
        .iter()
        .map(|a| a.iter().map(|x| (x - tau).max(0.0)).sum::<f64>() / a.len() as f64)
        .collect();
    let (p_ec_noise_sigma, p_ec_quadrature_sigma) =
        p_ec_sigma(&albedo, albedo_sigma.as_deref(), &quad, tau);
    let mut order: Vec<usize> = (0..rows.len()).collect();
    let peak = |r: usize| {
        rows[r]
            .albedo
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max)
    };
    order.sort_by(|&a, &b| peak(b).total_cmp(&peak(a)));
    let worst = order
        .into_iter()
        .take(worst)
        .map(|r| {
            (
                rows[r].theta_i_deg,
                rows[r].phi_i_deg,
                rows[r].albedo.clone(),
            )
        })
        .collect();
    Energy {
        p_ec,
        method: EnergyMethod::Triangulated,
        incident: rows.iter().map(|r| (r.theta_i_deg, r.phi_i_deg)).collect(),
        albedo,
        albedo_sigma,
        albedo_quadrature_sigma: quad,
        p_ec_noise_sigma,
        p_ec_quadrature_sigma,
        coverage: rows.iter().map(|r| r.covered).fold(1.0, f64::min),
        extrapolated: rows.iter().map(|r| r.extrapolated).fold(0.0, f64::max),
        worst,
    }
}

/// The isotropic mean of a table, μ_i of Eq. 4.8, on the grid (θi, φ+, θo) with φ+
/// the outgoing azimuth steps, and P_i of Eq. 4.10 per channel (from σ_i, Eq. 4.9).
/// With `weighted`, the mean weights each value by its inverse variance (Ch. 5
/// introduction) and carries the uncertainty of the mean; P_i is always DeYoung's
/// unweighted measure.
pub fn isotropic_mean(t: &Table, weighted: bool) -> Result<(Table, Vec<f64>), ProcessError> {
    let g = &t.grid;
    if g.isotropic {
        return Ok((t.clone(), vec![0.0; t.channels.len()]));
    }
    let mg = mean_grid(g);
    let m = mg.len();
    let nc = t.channels.len();
    let use_sigma = weighted && t.sigma.as_ref().is_some_and(|s| s.iter().all(|x| *x > 0.0));
    let mut mu = vec![0.0; m * nc];
    let mut mu_sigma = use_sigma.then(|| vec![0.0; m * nc]);
    let mut p_i = vec![0.0; nc];
    for ch in 0..nc {
        let v = t.channel(ch);
        let s = t.channel_sigma(ch).filter(|_| use_sigma);
        let mut total = 0.0;
        for (j, (mean, sd, spread)) in isotropic_nodes(g, &mg, |k| v[k], s).into_iter().enumerate()
        {
            total += spread;
            mu[ch * m + j] = mean;
            if let Some(ms) = mu_sigma.as_mut() {
                ms[ch * m + j] = sd;
            }
        }
        p_i[ch] = total / m as f64;
    }
    let table = Table::new(t.channels.clone(), mg, mu, mu_sigma)?;
    Ok((table, p_i))
}

/// The grid of μ_i (Eq. 4.8) of a 4D grid: (θi, φ+, θo), φ+ the outgoing azimuth
/// steps.
pub(crate) fn mean_grid(g: &Grid) -> Grid {
    let plus = Axis::new(g.phi_o.start - g.phi_i.start, g.phi_o.step, g.phi_o.n);
    Grid::isotropic(g.theta_i, plus, g.theta_o)
}

/// μ_i of one channel of a 4D grid `g` whose value at node k is `x(k)`, on
/// [`mean_grid`], and its P_i (Eq. 4.10, unweighted): the floors measure their
/// counterparts this way without storing them.
pub(crate) fn isotropy_by(g: &Grid, x: impl Fn(usize) -> f64 + Sync) -> (Vec<f64>, f64) {
    let mg = mean_grid(g);
    let nodes = isotropic_nodes(g, &mg, x, None);
    let mut total = 0.0;
    let mu = nodes
        .iter()
        .map(|(mean, _, spread)| {
            total += spread;
            *mean
        })
        .collect();
    (mu, total / mg.len() as f64)
}

/// Each node of μ_i (Eq. 4.8) on `mg` of one channel whose value at node k of `g` is
/// `v(k)`: (the mean, its σ, the spread σ_i of Eq. 4.9). With `sigma`, the mean
/// weights each value by its inverse variance and carries its σ; else it is the plain
/// mean and its σ 0. Nodes on rayon, each on its own: the same bits on any number of
/// threads.
fn isotropic_nodes(
    g: &Grid,
    mg: &Grid,
    v: impl Fn(usize) -> f64 + Sync,
    sigma: Option<&[f64]>,
) -> Vec<(f64, f64, f64)> {
    let na = g.phi_i.n;
    // Both azimuth axes the same full turn: φ+ = φo − φi stays on the nodes.
    let same_phi = g.phi_i.same_as(&g.phi_o) && g.phi_o.is_periodic();
    (0..mg.len())
        .into_par_iter()
        .map_init(
            || (vec![0.0; na], vec![0.0; na]),
            |(vals, sig), j| {
                let [_, ti, pp, to] = mg.angles(j);
                let [_, b, c, d] = mg.unindex(j);
                for a in 0..na {
                    if same_phi {
                        // φi + φ+ is node a + c of the shared azimuth axis: a lookup.
                        let k = g.index(a, b, (a + c) % g.phi_o.n, d);
                        vals[a] = v(k);
                        if let Some(s) = sigma {
                            sig[a] = s[k];
                        }
                        continue;
                    }
                    let pi = g.phi_i.node(a);
                    vals[a] = interpolate_by(g, &v, [pi, ti, pi + pp, to]);
                    if let Some(s) = sigma {
                        sig[a] = interpolate(g, s, [pi, ti, pi + pp, to]);
                    }
                }
                let mean = vals.iter().sum::<f64>() / na as f64;
                let spread =
                    (vals.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / na as f64).sqrt();
                if sigma.is_some() {
                    let sw: f64 = sig.iter().map(|s| s.powi(-2)).sum();
                    let wm = vals
                        .iter()
                        .zip(sig.iter())
                        .map(|(x, s)| x / (s * s))
                        .sum::<f64>()
                        / sw;
                    (wm, sw.sqrt().recip(), spread)
                } else {
                    (mean, 0.0, spread)
                }
            },
        )
        .collect()
}

/// P_i, DeYoung Eq. 4.8–4.10, per channel (0 for a table in the isotropic form).
pub fn isotropy(t: &Table) -> Result<Vec<f64>, ProcessError> {
    Ok(isotropic_mean(t, false)?.1)
}

/// Separability of one channel: the singular values of DeYoung's matrix A (Eq. 4.13)
/// and P_s^(k) of Eq. 4.20 for the k asked.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Separability {
    /// Singular values, descending: all of them when A has fewer than 256 rows or
    /// columns, else the leading max(k) ([`crate::svd::spectrum`]).
    pub singular_values: Vec<f64>,
    /// (k, P_s^(k)); k = 1 is P_s of Eq. 4.16.
    pub p_s: Vec<(usize, f64)>,
}

/// DeYoung's matrix A of one channel (Sec. 4.2.4): rows the incident nodes (φi, θi),
/// columns the outgoing nodes (φo, θo), both lexicographic.
pub(crate) fn matrix(t: &Table, ch: usize) -> Mat<f64> {
    let (p, q) = (t.grid.n_in(), t.grid.n_out());
    let v = t.channel(ch);
    Mat::from_fn(p, q, |r, c| v[r * q + c])
}

/// The 4D form separability works on: an isotropic table expands over a full turn
/// of φi with its own φ+ steps.
pub(crate) fn full_form(t: &Table) -> Result<Table, ProcessError> {
    if !t.grid.isotropic {
        return Ok(t.clone());
    }
    if !t.grid.phi_o.is_periodic() {
        return Err(ProcessError::Unsupported(
            "separability of an isotropic table needs its φ+ axis to close a full turn".into(),
        ));
    }
    t.to_full(t.grid.phi_o.n)
}

/// P_s^(k), Eq. 4.16–4.20, per channel. ‖A − A^(k)‖_F² is the sum of the squared
/// singular values A^(k) drops (Eckart–Young), so no product is formed; a large A
/// gets only its leading max(k) singular values and ‖A‖_F² ([`crate::svd`]).
pub fn separability(t: &Table, ks: &[usize]) -> Result<Vec<Separability>, ProcessError> {
    // Only an isotropic table is expanded; a 4D one is measured where it lies.
    let expanded;
    let full = if t.grid.isotropic {
        expanded = full_form(t)?;
        &expanded
    } else {
        t
    };
    let n = full.grid.len() as f64;
    let (p, q) = (full.grid.n_in(), full.grid.n_out());
    let k_max = ks.iter().copied().max().unwrap_or(0);
    (0..full.channels.len())
        .into_par_iter()
        .map(|ch| {
            // The channel's rows (φi, θi) of q values are Aᵀ in column-major order: a
            // view, not a copy, with A's singular values.
            let at = MatRef::from_column_major_slice(full.channel(ch), q, p);
            let s = svd::spectrum(at, k_max)?;
            let p_s = ks.iter().map(|&k| (k, (s.tail_sq(k) / n).sqrt())).collect();
            Ok(Separability {
                singular_values: s.values,
                p_s,
            })
        })
        .collect()
}

/// All four measures of a table.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    /// Channel names.
    pub channels: Vec<String>,
    /// Nodes of the table.
    pub nodes: usize,
    /// Whether the grid pairs incident and outgoing nodes (else reciprocals are
    /// interpolated).
    pub paired: bool,
    /// P_r per channel.
    pub reciprocity: Vec<f64>,
    /// Nodes whose reciprocal lies in the table (the count P_r averages over).
    pub reciprocity_nodes: usize,
    /// Energy conservation.
    pub energy: Energy,
    /// P_i per channel.
    pub isotropy: Vec<f64>,
    /// Separability per channel (none when the table cannot be expanded to 4D).
    pub separability: Option<Vec<Separability>>,
    /// What a BRDF with each property would read under the same sampling and noise
    /// ([`floor`]); none when it could not be formed.
    pub floor: Option<floor::Floors>,
}

/// Measures a table: P_r, P_ec (with the `worst` incident directions), P_i, and
/// P_s^(k) for each k of `ks`, each with its floor ([`floor`]). The energy measure is [`energy`]'s sum when the
/// outgoing nodes are polar band midpoints over the whole hemisphere, else
/// [`energy_scattered`] over the table's nodes (a half turn of an isotropic table
/// unfolded first, [`crate::hemisphere::unfold`]).
pub fn report(t: &Table, ks: &[usize], worst: usize) -> Result<Report, ProcessError> {
    report_with(t, None, ks, worst)
}

/// [`report`], with the energy measure taken from the `measured` samples the table
/// was formed from when given (triangulated, Sec. 4.2.2): measured data keep their
/// own directions rather than a grid's.
pub fn report_with(
    t: &Table,
    measured: Option<&Samples>,
    ks: &[usize],
    worst: usize,
) -> Result<Report, ProcessError> {
    let draws = floor::draws_for(t.values.len());
    let floor_draws = if t.sigma.is_some() { draws } else { 0 };
    // The measures are independent of each other, and each floor needs only its own
    // measure: P_s and its floor (whose SVDs run mostly on one thread) beside the
    // other three measures and then their floors, each the same numbers on any
    // number of threads.
    let ((reciprocity, energy, isotropy, three), (separability, sep_floor)) = rayon::join(
        || {
            let (((reciprocity, reciprocity_nodes), energy), isotropy) = rayon::join(
                || {
                    rayon::join(
                        || reciprocity(t),
                        || match measured {
                            Some(s) => energy_scattered(s, 1.0, worst),
                            None => {
                                let sum = energy(t, 1.0, worst);
                                Ok(if sum.coverage >= 0.999 {
                                    sum
                                } else {
                                    energy_triangulated(t, 1.0, worst).unwrap_or(sum)
                                })
                            }
                        },
                    )
                },
                || isotropy(t),
            );
            let three = match (&energy, &isotropy) {
                (Ok(e), Ok(i)) => Some(floor::three_floors(
                    t,
                    measured,
                    &reciprocity,
                    e,
                    i,
                    floor_draws,
                )),
                _ => None,
            };
            ((reciprocity, reciprocity_nodes), energy, isotropy, three)
        },
        || {
            let separability = separability(t, ks).ok();
            let floor = floor::separability_floor(t, separability.as_deref(), ks, floor_draws);
            (separability, floor)
        },
    );
    let (reciprocity, reciprocity_nodes) = reciprocity;
    let mut report = Report {
        channels: t.channels.names(),
        nodes: t.grid.len(),
        paired: t.grid.is_paired(),
        reciprocity,
        reciprocity_nodes,
        energy: energy?,
        isotropy: isotropy?,
        separability,
        floor: None,
    };
    // `three` is formed whenever the measures above were.
    report.floor = match three.map(|three| floor::assemble(floor_draws, three, sep_floor)) {
        Some(Ok(f)) => Some(f),
        Some(Err(e)) => {
            tracing::warn!(error = %e, "the measures' floors could not be formed");
            None
        }
        None => None,
    };
    Ok(report)
}
