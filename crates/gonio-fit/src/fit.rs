//! Fitting sums of generalized cosine lobes (Lafortune et al. 1997, Sec. 6).
//!
//! **Start.** No start values are asked for. Lobes are added one at a time
//! (greedy), each from a grid of seeds — retro-reflective (β > 0), forward and
//! off-specular (β < 0), exponents from 1.5 to 100 — scored by the projected cost
//! (the linear coefficients solved exactly for each seed), the best four refined by
//! Levenberg–Marquardt together with the lobes already placed; the search runs on an
//! evenly thinned subset of at most `search_samples` pairs. The best model then gets
//! a final joint Levenberg–Marquardt refinement on all the data.
//!
//! **Errors.** Standard errors come from the Jacobian of the weighted residuals in the
//! model file's own parameters (ρd, m, Cx, Cy, Cz, n) at the optimum: cov = s² (JᵀJ)⁺
//! with s² = Σr²/(m − p), the reduced χ² of a fit weighted by 1/σ (so the errors do not
//! depend on whether the σ's overall scale is right).

use std::f64::consts::{FRAC_PI_4, PI};
use std::time::Instant;

use gonio_brdf::FitNote;
use gonio_brdf::Model;
use gonio_core::{Channels, Dir};
use nalgebra::DMatrix;
use rayon::prelude::*;
use serde::Serialize;

use crate::FitError;
use crate::data::FitData;
use crate::fastmath;
use crate::lobes::{Diffuse, LobeBasis, Natural, Shape};
use crate::varpro::{self, Basis};

/// Options of a lobe fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitOptions {
    /// Lobes, anisotropy, diffuse term.
    pub shape: Shape,
    /// One set of exponents for all channels.
    pub share_exponents: bool,
    /// Pairs the start search uses at most.
    pub search_samples: usize,
    /// Hold the directional albedo ≤ 1 at every incident direction of the data: the
    /// constrained optimum (see [`EnergyReport`]).
    pub conserve_energy: bool,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            shape: Shape {
                lobes: 3,
                anisotropic: false,
                diffuse: Diffuse::Lambert,
            },
            share_exponents: false,
            search_samples: 2000,
            conserve_energy: false,
        }
    }
}

/// One channel's result.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ChannelFit {
    /// The channel.
    pub channel: String,
    /// The fitted parameters.
    pub params: Natural,
    /// Their standard errors (same layout).
    pub std_err: Natural,
    /// RMS of f_model − f_data over the pairs, 1/sr (unweighted).
    pub rms: f64,
    /// RMS of the weighted residuals relative to the RMS of the weighted data: the
    /// metric's (or χ²'s) relative error.
    pub relative_rms: f64,
    /// Per incident polar angle (degrees, rounded to 0.01°): RMS and relative RMS.
    pub per_theta_i: Vec<(f64, f64, f64)>,
    /// Reduced χ² (Σr²/(m − p)).
    pub reduced_chi2: f64,
}

/// What was minimised: the objective's name, the sum in words, and why it was chosen.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ObjectiveReport {
    /// `cosine`, `chi2` or `relative`.
    pub name: String,
    /// The sum minimised, in words.
    pub formula: String,
    /// Asked for, or which branch of the default rule chose it.
    pub chosen: String,
}

/// An energy constraint at one incident direction.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ActiveConstraint {
    /// Incident polar angle, degrees.
    pub theta_i_deg: f64,
    /// Incident azimuth, degrees.
    pub phi_i_deg: f64,
    /// The fitted model's directional albedo there.
    pub albedo: f64,
    /// Its Lagrange multiplier: how much the channel's objective would fall per unit
    /// the bound 1 were raised there.
    pub multiplier: f64,
}

/// One channel under the energy constraint.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EnergyChannel {
    /// The channel.
    pub channel: String,
    /// The objective (Σ of squared weighted residuals) at the unconstrained optimum.
    pub unconstrained_cost: f64,
    /// The objective at the result (equal when no constraint was needed).
    pub cost: f64,
    /// The unconstrained optimum's largest albedo over the data's incident directions.
    pub unconstrained_max_albedo: f64,
    /// The result's largest albedo over them.
    pub max_albedo: f64,
    /// The active set: the directions where albedo ≤ 1 binds, with multipliers.
    pub active: Vec<ActiveConstraint>,
}

/// The energy-constrained fit (`conserve_energy`): directional albedo ≤ 1 at each of
/// the data's incident directions, per channel. When the unconstrained optimum already
/// satisfies it, it is the result unchanged; otherwise Levenberg–Marquardt continues
/// from it on the constrained problem, in which each θ's linear coefficients (ρd and
/// the lobes' strengths, in which every albedo is linear) solve the constrained least
/// squares exactly.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EnergyReport {
    /// Incident directions constrained (isotropic fits: one a distinct θi).
    pub directions: usize,
    /// Whether the constraint changed the result.
    pub constrained: bool,
    /// Per channel.
    pub channels: Vec<EnergyChannel>,
}

/// A lobe fit.
#[derive(Clone, Debug, Serialize)]
pub struct LobeFit {
    /// The model file's text (docs/CONVENTIONS.md).
    pub model_toml: String,
    /// Per channel.
    pub channels: Vec<ChannelFit>,
    /// The shape fitted.
    pub shape: Shape,
    /// Whether exponents were shared.
    pub shared_exponents: bool,
    /// Pairs fitted.
    pub samples: usize,
    /// Residual evaluations of the final refinement (all channels).
    pub evaluations: usize,
    /// Wall time, s.
    pub seconds: f64,
    /// Largest directional albedo of the fitted model (θi from 0 to 89°, any
    /// channel), and the factor it was scaled by when energy was conserved.
    pub max_albedo: f64,
    /// Kept for readers of older reports: always 1 (energy is conserved by the
    /// constrained fit, [`LobeFit::energy`], never by rescaling).
    pub energy_scale: f64,
    /// Whether every residual weight was 1/σ.
    pub chi_square: bool,
    /// What was minimised.
    pub objective: ObjectiveReport,
    /// The energy constraint's outcome, when asked for.
    pub energy: Option<EnergyReport>,
    /// The fitted model.
    #[serde(skip)]
    pub model: Option<Model>,
}

/// Every k-th pair, so that at most `max` remain (deterministic).
fn thin(d: &FitData, max: usize) -> FitData {
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

/// The data of one channel.
fn channel_data(d: &FitData, ch: usize) -> Result<FitData, FitError> {
    let name = d.channels.name(ch);
    Ok(FitData {
        channels: Channels::from_names(&[name.as_str()])
            .or_else(|_| Channels::from_names(&["value"]))
            .map_err(|e| FitError::Data(e.to_string()))?,
        wi: d.wi.clone(),
        wo: d.wo.clone(),
        y: vec![d.y[ch].clone()],
        weight: vec![d.weight[ch].clone()],
        chi_square: d.chi_square,
        objective: d.objective,
        objective_rule: d.objective_rule.clone(),
        metric: d.metric,
        cut: d.cut,
    })
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
fn search(d: &FitData, shape: Shape, shared: bool) -> Vec<f64> {
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

/// A fitted channel group (one channel, or all with shared exponents).
struct Group {
    basis: LobeBasis,
    data: FitData,
    solved: varpro::Solved,
    /// Under `conserve_energy`: the limit directions, the unconstrained solution's
    /// per-channel cost and constraint state, and whether the result is constrained.
    energy: Option<GroupEnergy>,
}

struct GroupEnergy {
    limits: Vec<[f64; 3]>,
    unconstrained_cost: Vec<f64>,
    unconstrained: Vec<varpro::ChannelConstraint>,
    constrained: bool,
}

/// The distinct incident directions of the data: for an isotropic model (whose albedo
/// does not depend on φi) one a distinct θi, at φi = 0.
fn incident_directions(d: &FitData, anisotropic: bool) -> Vec<[f64; 3]> {
    let key = |w: &[f64; 3]| -> [i64; 3] {
        if anisotropic {
            w.map(|x| (x * 1e9).round() as i64)
        } else {
            [0, 0, (w[2] * 1e9).round() as i64]
        }
    };
    let mut seen = std::collections::BTreeMap::new();
    let mut last = None;
    for w in d.wi.iter() {
        // Pairs come in runs of one incident direction.
        if last == Some(*w) {
            continue;
        }
        last = Some(*w);
        seen.entry(key(w)).or_insert_with(|| {
            if anisotropic {
                *w
            } else {
                let z = w[2].clamp(-1.0, 1.0);
                [(1.0 - z * z).max(0.0).sqrt(), 0.0, z]
            }
        });
    }
    seen.into_values().collect()
}

/// Σr² of each channel of a group from its residuals.
fn channel_costs(full: &varpro::Full, channels: usize) -> Vec<f64> {
    let m = full.residuals.len() / channels.max(1);
    (0..channels)
        .map(|ch| {
            full.residuals[ch * m..(ch + 1) * m]
                .iter()
                .map(|r| r * r)
                .sum()
        })
        .collect()
}

fn fit_group(d: FitData, shape: Shape, shared: bool, opts: &FitOptions) -> Group {
    let sub = thin(&d, opts.search_samples);
    let theta0 = search(&sub, shape, shared);
    let basis = LobeBasis {
        shape,
        channels: d.channels.len(),
        shared,
    };
    let solved = varpro::solve(&basis, &d, &theta0, 200);
    let mut energy = None;
    let mut solved = solved;
    if opts.conserve_energy {
        let limits = incident_directions(&d, shape.anisotropic);
        // The unconstrained optimum's albedos: the constrained problem at the same θ
        // with no row active reproduces them, so evaluate them directly.
        let nl = limits.len();
        let k = varpro::Basis::n_cols(&basis);
        let unconstrained: Vec<varpro::ChannelConstraint> = (0..d.channels.len())
            .map(|ch| {
                let mut b = vec![0.0; nl * k];
                varpro::Basis::albedo_rows(&basis, &solved.theta, ch, &limits, &mut b, None);
                varpro::ChannelConstraint {
                    albedo: (0..nl)
                        .map(|l| (0..k).map(|u| b[l * k + u] * solved.coef[ch][u]).sum())
                        .collect(),
                    multiplier: vec![0.0; nl],
                }
            })
            .collect();
        let unconstrained_cost = channel_costs(&solved.full, d.channels.len());
        let exceeds = unconstrained
            .iter()
            .any(|c| c.albedo.iter().any(|a| *a > 1.0));
        if exceeds {
            solved =
                varpro::solve_with(&basis, &d, &solved.theta, 200, 1e-10, Some(limits.clone()));
        }
        energy = Some(GroupEnergy {
            limits,
            unconstrained_cost,
            unconstrained,
            constrained: exceeds,
        });
    }
    Group {
        basis,
        data: d,
        solved,
        energy,
    }
}

/// Standard errors of channel `ch`'s natural parameters by the delta method from the
/// covariance of (θ, c): the same as from the Jacobian in the natural parameters,
/// without another pass over the data.
fn std_errors(
    basis: &LobeBasis,
    theta: &[f64],
    coef: &[f64],
    cov: &DMatrix<f64>,
    ch: usize,
) -> Natural {
    let se: Vec<f64> = basis
        .natural_jacobian(theta, ch, coef)
        .iter()
        .map(|d| {
            let mut v = 0.0;
            for (a, da) in d.iter().enumerate() {
                if *da != 0.0 {
                    for (b, db) in d.iter().enumerate() {
                        v += da * cov[(a, b)] * db;
                    }
                }
            }
            v.max(0.0).sqrt()
        })
        .collect();
    let shape = &basis.shape;
    let mut it = se.into_iter();
    let mut next = || it.next().unwrap_or(f64::NAN);
    let rho_d = next();
    let m = if shape.diffuse == Diffuse::Minnaert {
        next()
    } else {
        0.0
    };
    let lobes = (0..shape.lobes)
        .map(|_| {
            if shape.anisotropic {
                let (cx, cy, cz, n) = (next(), next(), next(), next());
                [cx, cy, cz, n]
            } else {
                let (c, cz, n) = (next(), next(), next());
                [c, c, cz, n]
            }
        })
        .collect();
    Natural { rho_d, m, lobes }
}

/// The model file of the fitted parameters.
pub fn to_model(channels: &Channels, params: &[Natural], shape: &Shape) -> Result<Model, FitError> {
    to_model_noted(channels, params, shape, None)
}

/// [`to_model`] with the model file's `[fit]` table (what was minimised).
pub fn to_model_noted(
    channels: &Channels,
    params: &[Natural],
    shape: &Shape,
    note: Option<FitNote>,
) -> Result<Model, FitError> {
    let names = channels.names();
    let list = |f: &dyn Fn(&Natural) -> f64| -> String {
        let v: Vec<String> = params.iter().map(|p| format!("{:?}", f(p))).collect();
        format!("[{}]", v.join(", "))
    };
    let mut s = format!(
        "kind = \"lafortune\"\nchannels = [{}]\n[diffuse]\nrho = {}\n",
        names
            .iter()
            .map(|n| format!("{n:?}"))
            .collect::<Vec<_>>()
            .join(", "),
        list(&|p| p.rho_d)
    );
    if shape.diffuse == Diffuse::Minnaert {
        s.push_str(&format!("n = {}\n", list(&|p| p.m)));
    }
    for j in 0..shape.lobes {
        s.push_str(&format!(
            "[[lobes]]\ncx = {}\ncy = {}\ncz = {}\nn = {}\n",
            list(&|p| p.lobes[j][0]),
            list(&|p| p.lobes[j][1]),
            list(&|p| p.lobes[j][2]),
            list(&|p| p.lobes[j][3].max(0.0)),
        ));
    }
    let model =
        Model::from_toml(&s, None).map_err(|e| FitError::Numerics(format!("fitted model: {e}")))?;
    Ok(match (model, note) {
        (Model::Lafortune(l), Some(n)) => Model::Lafortune(l.with_fit_note(n)),
        (m, _) => m,
    })
}

/// The largest directional albedo of a model over θi ∈ [0, 89°] by 1°, at φi = 0
/// and, for an anisotropic model, also 90°: every 3° (and 89°) first, then the 1°
/// neighbours of the largest — a lobe model's albedo is smooth in θi, and each value
/// is an adaptive integral.
fn max_albedo(model: &Model, anisotropic: bool) -> f64 {
    use gonio_brdf::Brdf;
    let nc = model.channels().len();
    let phis: &[f64] = if anisotropic { &[0.0, 90.0] } else { &[0.0] };
    let at = |ts: &[i32]| -> Vec<(i32, f64)> {
        ts.iter()
            .flat_map(|&t| phis.iter().map(move |&phi| (t, phi)))
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|(t, phi): (i32, f64)| {
                let mut out = vec![0.0; nc];
                model.albedo(
                    Dir::from_angles(f64::from(t).to_radians(), phi.to_radians()),
                    &mut out,
                );
                (t, out.into_iter().fold(0.0f64, f64::max))
            })
            .collect()
    };
    let coarse: Vec<i32> = (0..90).step_by(3).chain([89]).collect();
    let first = at(&coarse);
    let (t0, best) = first
        .iter()
        .copied()
        .fold((0, 0.0f64), |a, b| if b.1 > a.1 { b } else { a });
    let near: Vec<i32> = [-2, -1, 1, 2]
        .iter()
        .map(|d| t0 + d)
        .filter(|t| (0..90).contains(t) && !coarse.contains(t))
        .collect();
    at(&near).into_iter().map(|x| x.1).fold(best, f64::max)
}

/// One channel's statistics, parameters and energy constraint.
type Reported = (ChannelFit, Natural, Option<EnergyChannel>);

/// A channel's energy constraint from its group's.
fn energy_channel(g: &Group, ch: usize, name: String) -> Option<EnergyChannel> {
    let e = g.energy.as_ref()?;
    let after = if e.constrained {
        g.solved.constraints.get(ch)?
    } else {
        &e.unconstrained[ch]
    };
    let m = g.data.len();
    let cost = if e.constrained {
        g.solved
            .full
            .residuals
            .get(ch * m..(ch + 1) * m)
            .map_or(f64::NAN, |r| r.iter().map(|x| x * x).sum())
    } else {
        e.unconstrained_cost[ch]
    };
    let max = |a: &[f64]| a.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let active = e
        .limits
        .iter()
        .zip(after.albedo.iter().zip(&after.multiplier))
        .filter(|(_, (a, mu))| e.constrained && (**mu > 0.0 || **a >= 1.0 - 1e-9))
        .map(|(w, (a, mu))| ActiveConstraint {
            theta_i_deg: w[2].clamp(-1.0, 1.0).acos().to_degrees(),
            phi_i_deg: w[1].atan2(w[0]).to_degrees().rem_euclid(360.0),
            albedo: *a,
            multiplier: *mu,
        })
        .collect();
    Some(EnergyChannel {
        channel: name,
        unconstrained_cost: e.unconstrained_cost[ch],
        cost,
        unconstrained_max_albedo: max(&e.unconstrained[ch].albedo),
        max_albedo: max(&after.albedo),
        active,
    })
}

/// The fitted parameters and statistics of a group's channels; `channel` is the
/// group's index in `names` when it holds one channel of several.
fn report(g: &Group, names: &Channels, channel: Option<usize>) -> Vec<Reported> {
    let m = g.data.len();
    let theta = &g.solved.theta;
    let coef = &g.solved.coef;
    // The final refinement's last evaluation is normally at θ; recompute if not.
    let computed;
    let full = if g.solved.full.residuals.len() == m * g.data.channels.len() {
        &g.solved.full
    } else {
        computed = varpro::evaluate(&g.basis, &g.data, theta, true).full;
        match &computed {
            Some(f) => f,
            None => &g.solved.full,
        }
    };
    let residuals = &full.residuals;
    let (cov, s2) = full.covariance(g.basis.n_params(), g.basis.n_cols());
    let mut out = Vec::new();
    for ch in 0..g.data.channels.len() {
        let p = g.basis.natural(&g.solved.theta, ch, &coef[ch]);
        let res = &residuals[ch * m..(ch + 1) * m];
        let wy: Vec<f64> = (0..m)
            .map(|i| g.data.weight[ch][i] * g.data.y[ch][i])
            .collect();
        let wrms = (res.iter().map(|r| r * r).sum::<f64>() / m as f64).sqrt();
        let rms = (res
            .iter()
            .zip(&g.data.weight[ch])
            .map(|(r, w)| if *w != 0.0 { (r / w).powi(2) } else { 0.0 })
            .sum::<f64>()
            / m as f64)
            .sqrt();
        let scale = (wy.iter().map(|x| x * x).sum::<f64>() / m as f64).sqrt();
        let mut by_theta: std::collections::BTreeMap<i64, (f64, f64, usize)> =
            std::collections::BTreeMap::new();
        // Pairs come in runs of one incident direction: one acos a run.
        let mut last = (f64::NAN, 0i64);
        for i in 0..m {
            let cz = g.data.wi[i][2];
            if cz != last.0 {
                let th = (cz.clamp(-1.0, 1.0).acos().to_degrees() * 100.0).round() as i64;
                last = (cz, th);
            }
            let e = by_theta.entry(last.1).or_insert((0.0, 0.0, 0));
            e.0 += res[i] * res[i];
            e.1 += wy[i] * wy[i];
            e.2 += 1;
        }
        let per_theta_i = by_theta
            .into_iter()
            .map(|(k, (r2, y2, n))| {
                let rms = (r2 / n as f64).sqrt();
                (
                    k as f64 / 100.0,
                    rms,
                    if y2 > 0.0 { (r2 / y2).sqrt() } else { 0.0 },
                )
            })
            .collect();
        let std_err = std_errors(&g.basis, theta, &coef[ch], &cov, ch);
        let name = names.name(channel.unwrap_or(ch));
        out.push((
            ChannelFit {
                channel: name.clone(),
                params: p.clone(),
                std_err,
                rms,
                relative_rms: if scale > 0.0 { wrms / scale } else { 0.0 },
                per_theta_i,
                reduced_chi2: s2,
            },
            p,
            energy_channel(g, ch, name),
        ));
    }
    out
}

/// The most lobes a fit may place: eight. Lafortune et al. fit at most three; each
/// further lobe is another greedy round of multi-start searches, so the time grows
/// with the count, and `--lobes 100000` would never end.
pub const MAX_LOBES: usize = 8;

/// Fits lobes to `data`.
pub fn fit_lobes(data: &FitData, opts: &FitOptions) -> Result<LobeFit, FitError> {
    if opts.shape.lobes > MAX_LOBES {
        return Err(FitError::Options(format!(
            "{} lobes: at most {MAX_LOBES} are fitted",
            opts.shape.lobes
        )));
    }
    let started = Instant::now();
    let nc = data.channels.len();
    let shared = opts.share_exponents && nc > 1;
    // Each group is fitted and reported in one parallel task, so a channel that
    // finishes early computes its statistics while the others still fit.
    let groups: Vec<(usize, Vec<Reported>, usize, bool)> = if shared {
        let g = fit_group(data.clone(), opts.shape, true, opts);
        let e = energy_of(&g);
        vec![(
            g.solved.evaluations,
            report(&g, &data.channels, None),
            e.0,
            e.1,
        )]
    } else {
        (0..nc)
            .map(|ch| channel_data(data, ch).map(|d| (ch, d)))
            .collect::<Result<Vec<_>, _>>()?
            .into_par_iter()
            .map(|(ch, d)| {
                let g = fit_group(d, opts.shape, false, opts);
                let e = energy_of(&g);
                (
                    g.solved.evaluations,
                    report(&g, &data.channels, Some(ch)),
                    e.0,
                    e.1,
                )
            })
            .collect()
    };
    let evaluations = groups.iter().map(|g| g.0).sum();
    let directions = groups.iter().map(|g| g.2).max().unwrap_or(0);
    let constrained = groups.iter().any(|g| g.3);
    let mut channels = Vec::new();
    let mut params = Vec::new();
    let mut energy_channels = Vec::new();
    for (c, p, e) in groups.into_iter().flat_map(|g| g.1) {
        channels.push(c);
        params.push(p);
        energy_channels.extend(e);
    }
    let objective = ObjectiveReport {
        name: data.objective.name().into(),
        formula: data.objective.formula(data.metric),
        chosen: data.objective_rule.clone(),
    };
    let note = FitNote {
        objective: objective.name.clone(),
        minimised: objective.formula.clone(),
        constraint: opts
            .conserve_energy
            .then(|| "directional albedo <= 1 at every incident direction of the data".to_string()),
    };
    let model = to_model_noted(&data.channels, &params, &opts.shape, Some(note))?;
    let alb = max_albedo(&model, opts.shape.anisotropic);
    Ok(LobeFit {
        model_toml: model.to_toml(),
        channels,
        shape: opts.shape,
        shared_exponents: shared,
        samples: data.len(),
        evaluations,
        seconds: started.elapsed().as_secs_f64(),
        max_albedo: alb,
        energy_scale: 1.0,
        chi_square: data.chi_square,
        objective,
        energy: opts.conserve_energy.then_some(EnergyReport {
            directions,
            constrained,
            channels: energy_channels,
        }),
        model: Some(model),
    })
}

/// A group's constrained directions and whether the constraint changed it.
fn energy_of(g: &Group) -> (usize, bool) {
    g.energy
        .as_ref()
        .map_or((0, false), |e| (e.limits.len(), e.constrained))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_refined_albedo_maximum_is_the_one_degree_maximum() {
        use gonio_brdf::Brdf;
        // Table 1 of Lafortune et al. (its largest albedo is at grazing incidence) and
        // a forward lobe whose albedo peaks inside the range.
        for text in [
            "kind = \"lafortune\"\nchannels = [\"550nm\"]\n[diffuse]\nrho = [0.408]\n\
             [[lobes]]\ncx = [0.86]\ncz = [0.77]\nn = [18.6]\n[[lobes]]\ncx = [-0.41]\n\
             cz = [0.018]\nn = [2.58]\n[[lobes]]\ncx = [-1.03]\ncz = [0.70]\nn = [63.8]\n",
            "kind = \"lafortune\"\nchannels = [\"550nm\"]\n[diffuse]\nrho = [0.1]\n\
             [[lobes]]\ncx = [-0.9]\ncz = [1.1]\nn = [8.0]\n",
        ] {
            let model = Model::from_toml(text, None).expect("model");
            let mut out = [0.0];
            let brute = (0..90)
                .map(|t| {
                    model.albedo(Dir::from_angles(f64::from(t).to_radians(), 0.0), &mut out);
                    out[0]
                })
                .fold(0.0f64, f64::max);
            assert_eq!(max_albedo(&model, false), brute);
        }
    }
}
