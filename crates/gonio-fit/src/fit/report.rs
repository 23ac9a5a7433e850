//! What a fitted group reports: each channel's statistics, parameters with their
//! standard errors, and energy constraint, and a model's largest directional
//! albedo.

use gonio_brdf::Model;
use gonio_core::{Channels, Dir};
use rayon::prelude::*;

use crate::lobes::Natural;
use crate::varpro::{self, Basis};

use super::group::{Group, std_errors};
use super::{ActiveConstraint, ChannelFit, EnergyChannel};

/// The largest directional albedo of a model over θi ∈ [0, 89°] by 1°, at φi = 0
/// and, for an anisotropic model, also 90°: every 3° (and 89°) first, then the 1°
/// neighbours of the largest — a lobe model's albedo is smooth in θi, and each value
/// is an adaptive integral.
pub(super) fn max_albedo(model: &Model, anisotropic: bool) -> f64 {
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
pub(super) type Reported = (ChannelFit, Natural, Option<EnergyChannel>);

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
pub(super) fn report(g: &Group, names: &Channels, channel: Option<usize>) -> Vec<Reported> {
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
            .zip(g.data.weight[ch].iter())
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
