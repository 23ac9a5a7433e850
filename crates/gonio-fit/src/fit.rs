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

use std::f64::consts::{FRAC_1_SQRT_2, FRAC_PI_4, PI, TAU};
use std::time::Instant;

use gonio_brdf::Model;
use gonio_core::{Channels, Dir};
use nalgebra::DMatrix;
use rayon::prelude::*;
use serde::Serialize;

use crate::FitError;
use crate::data::FitData;
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
    /// Scale the fitted model down where its directional albedo exceeds 1.
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

/// A lobe fit.
#[derive(Clone, Debug, Serialize)]
pub struct LobeFit {
    /// The model file's text (CONVENTIONS.md).
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
    /// The factor applied by `conserve_energy` (1 when none was needed).
    pub energy_scale: f64,
    /// Whether every residual weight was 1/σ.
    pub chi_square: bool,
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
        metric: d.metric,
        cut: d.cut,
    })
}

fn cost(basis: &dyn Basis, d: &FitData, theta: &[f64]) -> f64 {
    let e = varpro::evaluate(basis, d, theta, false);
    let c: f64 = e.residuals.iter().map(|r| r * r).sum();
    if c.is_finite() { c } else { f64::INFINITY }
}

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
                (cost(&basis, d, &t), t)
            })
            .collect();
        scored.sort_by(|a, b| a.0.total_cmp(&b.0));
        let best = scored
            .into_iter()
            .take(4)
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|(_, t)| {
                let s = varpro::solve(&basis, d, &t, 15);
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
    Group {
        basis,
        data: d,
        solved,
    }
}

/// ∂f/∂(ρd, m, per lobe Cx, [Cy], Cz, n) at one pair, for the standard errors.
fn natural_gradient(p: &Natural, shape: &Shape, wi: [f64; 3], wo: [f64; 3], out: &mut Vec<f64>) {
    out.clear();
    let t = wi[2] * wo[2];
    let tm = t.powf(p.m);
    out.push((p.m + 2.0) / TAU * tm);
    if shape.diffuse == Diffuse::Minnaert {
        out.push(p.rho_d * (tm / TAU + (p.m + 2.0) / TAU * tm * t.ln()));
    }
    let uv = [wi[0] * wo[0], wi[1] * wo[1], wi[2] * wo[2]];
    for l in &p.lobes {
        let x = l[0] * uv[0] + l[1] * uv[1] + l[2] * uv[2];
        let n = l[3];
        let (h, dh) = if x > 0.0 {
            let h = x.powf(n);
            (h, n * h / x)
        } else {
            (0.0, 0.0)
        };
        if shape.anisotropic {
            out.push(dh * uv[0]);
            out.push(dh * uv[1]);
        } else {
            out.push(dh * (uv[0] + uv[1]));
        }
        out.push(dh * uv[2]);
        out.push(if x > 0.0 { h * x.ln() } else { 0.0 });
    }
}

/// Standard errors of one channel's natural parameters.
fn std_errors(p: &Natural, shape: &Shape, d: &FitData, ch: usize, s2: f64) -> Natural {
    let mut g = Vec::new();
    natural_gradient(p, shape, d.wi[0], d.wo[0], &mut g);
    let np = g.len();
    let mut jtj = DMatrix::<f64>::zeros(np, np);
    for i in 0..d.len() {
        natural_gradient(p, shape, d.wi[i], d.wo[i], &mut g);
        let w = d.weight[ch][i];
        for a in 0..np {
            let ga = g[a] * w;
            if ga == 0.0 {
                continue;
            }
            for b in 0..np {
                jtj[(a, b)] += ga * g[b] * w;
            }
        }
    }
    // Pseudo-inverse: an inactive lobe leaves its parameters undetermined (infinite
    // error would be the truth; the pseudo-inverse reports 0 for the null space).
    let cov = jtj
        .clone()
        .pseudo_inverse(1e-14 * jtj.diagonal().max().max(f64::MIN_POSITIVE))
        .unwrap_or_else(|_| DMatrix::zeros(np, np));
    let se: Vec<f64> = (0..np)
        .map(|a| (s2 * cov[(a, a)]).max(0.0).sqrt())
        .collect();
    let mut it = se.into_iter();
    let mut next = || it.next().unwrap_or(f64::NAN);
    let rho_d = next();
    let m = if shape.diffuse == Diffuse::Minnaert {
        next()
    } else {
        0.0
    };
    let lobes = p
        .lobes
        .iter()
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
    let nc = channels.len();
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
    let _ = nc;
    Model::from_toml(&s, None).map_err(|e| FitError::Numerics(format!("fitted model: {e}")))
}

/// The largest directional albedo of a model over θi ∈ [0, 89°] (φi = 0 and 90°).
fn max_albedo(model: &Model) -> f64 {
    use gonio_brdf::Brdf;
    let nc = model.channels().len();
    let mut out = vec![0.0; nc];
    let mut best = 0.0f64;
    for t in 0..90 {
        for phi in [0.0, 90.0f64] {
            model.albedo(
                Dir::from_angles(f64::from(t).to_radians(), phi.to_radians()),
                &mut out,
            );
            best = out.iter().copied().fold(best, f64::max);
        }
    }
    best
}

/// Fits lobes to `data`.
pub fn fit_lobes(data: &FitData, opts: &FitOptions) -> Result<LobeFit, FitError> {
    let started = Instant::now();
    if opts.shape.lobes == 0 && opts.shape.diffuse == Diffuse::Lambert {
        // Only ρd: still a valid (Lambertian) fit.
    }
    let nc = data.channels.len();
    let shared = opts.share_exponents && nc > 1;
    let groups: Vec<Group> = if shared {
        vec![fit_group(data.clone(), opts.shape, true, opts)]
    } else {
        (0..nc)
            .map(|ch| channel_data(data, ch))
            .collect::<Result<Vec<_>, _>>()?
            .into_par_iter()
            .map(|d| fit_group(d, opts.shape, false, opts))
            .collect()
    };
    let mut params = Vec::new();
    let mut channels = Vec::new();
    let mut evaluations = 0;
    for (gi, g) in groups.iter().enumerate() {
        evaluations += g.solved.evaluations;
        let e = varpro::evaluate(&g.basis, &g.data, &g.solved.theta, false);
        let m = g.data.len();
        let dof = (m * g.data.channels.len())
            .saturating_sub(g.basis.n_params() + g.basis.n_cols() * g.data.channels.len());
        let rss: f64 = e.residuals.iter().map(|r| r * r).sum();
        let s2 = if dof > 0 { rss / dof as f64 } else { 0.0 };
        for ch in 0..g.data.channels.len() {
            let global = if shared { ch } else { gi };
            let p = g.basis.natural(&g.solved.theta, ch, &e.coef[ch]);
            let res = &e.residuals[ch * m..(ch + 1) * m];
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
            for i in 0..m {
                let th =
                    (g.data.wi[i][2].clamp(-1.0, 1.0).acos().to_degrees() * 100.0).round() as i64;
                let e = by_theta.entry(th).or_insert((0.0, 0.0, 0));
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
            let std_err = std_errors(&p, &opts.shape, &g.data, ch, s2);
            channels.push(ChannelFit {
                channel: data.channels.name(global),
                params: p.clone(),
                std_err,
                rms,
                relative_rms: if scale > 0.0 { wrms / scale } else { 0.0 },
                per_theta_i,
                reduced_chi2: s2,
            });
            params.push(p);
        }
    }
    let mut model = to_model(&data.channels, &params, &opts.shape)?;
    let alb = max_albedo(&model);
    let mut energy_scale = 1.0;
    if opts.conserve_energy && alb > 1.0 {
        // DeYoung Eq. 5.6 applied to the model: one factor, the worst direction's.
        energy_scale = 1.0 / alb;
        for p in &mut params {
            p.rho_d *= energy_scale;
            for l in &mut p.lobes {
                let r = energy_scale.powf(1.0 / l[3]);
                l[0] *= r;
                l[1] *= r;
                l[2] *= r;
            }
        }
        for (c, p) in channels.iter_mut().zip(&params) {
            c.params = p.clone();
        }
        model = to_model(&data.channels, &params, &opts.shape)?;
    }
    let _ = FRAC_1_SQRT_2;
    Ok(LobeFit {
        model_toml: model.to_toml(),
        channels,
        shape: opts.shape,
        shared_exponents: shared,
        samples: data.len(),
        evaluations,
        seconds: started.elapsed().as_secs_f64(),
        max_albedo: alb,
        energy_scale,
        chi_square: data.chi_square,
        model: Some(model),
    })
}
