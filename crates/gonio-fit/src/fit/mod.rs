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

use std::time::Instant;

use gonio_brdf::FitNote;
use gonio_brdf::Model;
use gonio_core::Channels;
use rayon::prelude::*;
use serde::Serialize;

use crate::FitError;
use crate::data::FitData;
use crate::lobes::{Diffuse, Natural, Shape};

mod group;
mod report;
mod search;

use group::{energy_of, fit_group};
use report::{Reported, max_albedo, report};

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
