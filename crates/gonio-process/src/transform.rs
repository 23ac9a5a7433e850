//! DeYoung's transforms (Ch. 5): each moves a table towards one property by a
//! fraction δ ∈ [0, 1] (δ = 1: the table then has the property exactly).
//!
//! Where a table carries uncertainties, the averages of the reciprocity, isotropy
//! and separability transforms are weighted, as the introduction of Ch. 5 asks. The
//! weights are inverse variances, 1/σ²: DeYoung says "inversely proportional to the
//! estimate of the errors", and the inverse variance is the weighting whose average
//! has the least variance, which is what a metrologist means by it. Uncertainties are
//! propagated through every transform (first order, measurements independent).
//! The energy transform is a scaling, not a combination of values, so no weights
//! enter it; it scales the uncertainties with the values.

use serde::Serialize;

use crate::grid::interpolate;
use crate::measure::{Reciprocals, albedos, full_form, isotropic_mean, matrix};
use crate::separable::{factor, weights};
use crate::{ProcessError, Table};

fn check_delta(delta: f64) -> Result<(), ProcessError> {
    if (0.0..=1.0).contains(&delta) {
        Ok(())
    } else {
        Err(ProcessError::Value(format!(
            "δ must lie in [0, 1], got {delta}"
        )))
    }
}

/// Reciprocity, Eq. 5.1–5.2: f' = (1 − δ) f + δ f^r with f^r the (weighted) mean of
/// the value and its reciprocal. Nodes whose reciprocal lies outside the table are
/// left as they are.
pub fn reciprocity(t: &Table, delta: f64) -> Result<Table, ProcessError> {
    check_delta(delta)?;
    let g = &t.grid;
    let n = g.len();
    let rec = Reciprocals::new(g);
    let mut values = t.values.clone();
    let mut sigma = t.sigma.clone();
    for ch in 0..t.channels.len() {
        let v = t.channel(ch);
        let s = t.channel_sigma(ch);
        for i in 0..n {
            let Some(r) = rec.value(g, v, i) else {
                continue;
            };
            // Weights of the value and its reciprocal in f^r (equal without σ).
            let (wf, wr, sf, sr) = match s {
                Some(s) => {
                    let sr = rec.value(g, s, i).unwrap_or(s[i]);
                    if s[i] > 0.0 && sr > 0.0 {
                        (s[i].powi(-2), sr.powi(-2), s[i], sr)
                    } else {
                        (1.0, 1.0, s[i], sr)
                    }
                }
                None => (1.0, 1.0, 0.0, 0.0),
            };
            let alpha = 1.0 - delta + delta * wf / (wf + wr);
            let beta = delta * wr / (wf + wr);
            values[ch * n + i] = alpha * v[i] + beta * r;
            if let Some(out) = sigma.as_mut() {
                out[ch * n + i] = (alpha * alpha * sf * sf + beta * beta * sr * sr).sqrt();
            }
        }
    }
    Ok(t.with_values(values, sigma))
}

/// How the energy transform scales.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum EnergyMode {
    /// Each incident direction by its own factor (Eq. 5.4–5.5).
    PerDirection,
    /// One factor for the whole table, from the worst direction (Eq. 5.6).
    Global,
}

/// Energy conservation, Eq. 5.4–5.8. With ρ(ωi) = max(0, Σ f sinθo cosθo Δφo Δθo − τ)
/// (Eq. 5.7; τ = 1 is Eq. 4.4), every value of an incident direction becomes
/// f' = τ f / (δ ρ + τ) (Eq. 5.5 and 5.8), ρ taken per direction or as its maximum
/// over the table (Eq. 5.6). With δ = 1 no direction reflects more than τ.
pub fn energy(t: &Table, delta: f64, mode: EnergyMode, tau: f64) -> Result<Table, ProcessError> {
    check_delta(delta)?;
    if !(tau > 0.0 && tau <= 1.0) {
        return Err(ProcessError::Value(format!(
            "τ must lie in (0, 1], got {tau}"
        )));
    }
    let alb = albedos(t);
    let (p, q) = (t.grid.n_in(), t.grid.n_out());
    let n = p * q;
    let mut values = t.values.clone();
    let mut sigma = t.sigma.clone();
    for (ch, a) in alb.iter().enumerate() {
        let excess: Vec<f64> = a.iter().map(|x| (x - tau).max(0.0)).collect();
        let global = excess.iter().copied().fold(0.0, f64::max);
        for r in 0..p {
            let rho = match mode {
                EnergyMode::PerDirection => excess[r],
                EnergyMode::Global => global,
            };
            let scale = tau / (delta * rho + tau);
            for x in &mut values[ch * n + r * q..ch * n + (r + 1) * q] {
                *x *= scale;
            }
            if let Some(s) = sigma.as_mut() {
                for x in &mut s[ch * n + r * q..ch * n + (r + 1) * q] {
                    *x *= scale;
                }
            }
        }
    }
    Ok(t.with_values(values, sigma))
}

/// Isotropy, Eq. 5.9–5.10: f' = (1 − δ) f + δ μ_i(θi, φo − φi, θo), μ_i the mean over
/// φi of Eq. 4.8 (inverse-variance weighted when the table has uncertainties).
pub fn isotropy(t: &Table, delta: f64) -> Result<Table, ProcessError> {
    check_delta(delta)?;
    if t.grid.isotropic {
        return Ok(t.clone());
    }
    let (mu, _) = isotropic_mean(t, true)?;
    let g = &t.grid;
    let n = g.len();
    let mut values = t.values.clone();
    let mut sigma = t.sigma.clone();
    for ch in 0..t.channels.len() {
        let v = t.channel(ch);
        let m = mu.channel(ch);
        for i in 0..n {
            let ang = g.angles(i);
            let mean = interpolate(&mu.grid, m, ang);
            values[ch * n + i] = (1.0 - delta) * v[i] + delta * mean;
            if let (Some(out), Some(s)) = (sigma.as_mut(), t.channel_sigma(ch)) {
                out[ch * n + i] = match mu.channel_sigma(ch) {
                    // The value is one of the terms of its own weighted mean: with
                    // W = Σ 1/σ² (so σ_μ² = 1/W) and w = 1/σ², f' has variance
                    // ((1−δ) + δw/W)²/w + δ²(W − w)/W².
                    Some(ms) if s[i] > 0.0 => {
                        let w = s[i].powi(-2);
                        let big_w = interpolate(&mu.grid, ms, ang).powi(-2);
                        let a = 1.0 - delta + delta * w / big_w;
                        (a * a / w + delta * delta * (big_w - w).max(0.0) / (big_w * big_w)).sqrt()
                    }
                    _ => (1.0 - delta) * s[i],
                };
            }
        }
    }
    Ok(t.with_values(values, sigma))
}

/// k-separability, Eq. 5.15: f' = (1 − δ) A + δ A^(k), A^(k) the best rank-k
/// approximation of DeYoung's matrix A (weighted by the uncertainties when the table
/// has them; see [`crate::separable`]). An isotropic table comes back in its 4D form.
/// The uncertainties are kept: the projection's own covariance is not propagated.
pub fn separable(t: &Table, k: usize, delta: f64) -> Result<Table, ProcessError> {
    check_delta(delta)?;
    if k == 0 {
        return Err(ProcessError::Value("k must be at least 1".into()));
    }
    let full = full_form(t)?;
    let (p, q) = (full.grid.n_in(), full.grid.n_out());
    let n = p * q;
    let mut values = full.values.clone();
    for ch in 0..full.channels.len() {
        let a = matrix(&full, ch);
        let w = weights(&full, ch);
        let (us, vk, _) = factor(&a, w.as_ref(), k)?;
        let ak = &us * vk.transpose();
        for r in 0..p {
            for c in 0..q {
                let x = &mut values[ch * n + r * q + c];
                *x = (1.0 - delta) * *x + delta * ak[(r, c)];
            }
        }
    }
    let sigma = full.sigma.clone();
    Ok(full.with_values(values, sigma))
}

/// One step of a correction pipeline, as `gonio correct` takes them.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub enum Step {
    /// Reciprocity with δ.
    Reciprocity(f64),
    /// Energy conservation with δ, mode and τ.
    Energy(f64, EnergyMode, f64),
    /// Isotropy with δ.
    Isotropy(f64),
    /// k-separability with δ.
    Separable(usize, f64),
}

impl Step {
    /// Applies the step.
    pub fn apply(&self, t: &Table) -> Result<Table, ProcessError> {
        match *self {
            Step::Reciprocity(d) => reciprocity(t, d),
            Step::Energy(d, m, tau) => energy(t, d, m, tau),
            Step::Isotropy(d) => isotropy(t, d),
            Step::Separable(k, d) => separable(t, k, d),
        }
    }

    /// Parses the argument of `--energy`: `δ[:per-direction|:global][:tau=T]`.
    pub fn parse_energy(arg: &str) -> Result<Step, String> {
        let mut parts = arg.split(':');
        let delta = parse_delta(parts.next().unwrap_or(""))?;
        let (mut mode, mut tau) = (EnergyMode::PerDirection, 1.0);
        for p in parts {
            match p {
                "per-direction" => mode = EnergyMode::PerDirection,
                "global" => mode = EnergyMode::Global,
                _ => match p.strip_prefix("tau=") {
                    Some(x) => {
                        tau = x
                            .parse::<f64>()
                            .ok()
                            .filter(|t| *t > 0.0 && *t <= 1.0)
                            .ok_or_else(|| format!("tau must be a number in (0, 1], got {x:?}"))?;
                    }
                    None => {
                        return Err(format!(
                            "unknown energy option {p:?} (per-direction, global or tau=T)"
                        ));
                    }
                },
            }
        }
        Ok(Step::Energy(delta, mode, tau))
    }

    /// Parses the argument of `--separable`: `k[:δ]` (δ = 1 when left out).
    pub fn parse_separable(arg: &str) -> Result<Step, String> {
        let (k, d) = arg.split_once(':').unwrap_or((arg, "1"));
        let k = k
            .trim()
            .parse::<usize>()
            .ok()
            .filter(|k| *k >= 1)
            .ok_or_else(|| format!("k must be a whole number ≥ 1, got {k:?}"))?;
        Ok(Step::Separable(k, parse_delta(d)?))
    }
}

/// Parses δ ∈ [0, 1].
pub fn parse_delta(s: &str) -> Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .ok()
        .filter(|d| (0.0..=1.0).contains(d))
        .ok_or_else(|| format!("δ must be a number in [0, 1], got {s:?}"))
}
