//! The data a fit sees: pairs of directions, values per channel, and the weight of
//! each residual under the chosen objective.

use std::sync::Arc;

use gonio_core::Channels;
use gonio_process::{Samples, Table};
use rayon::prelude::*;
use serde::Serialize;

use crate::FitError;

/// What the squared residuals measure.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Metric {
    /// Lafortune et al. 1997, Sec. 6: the error of f_r · cos θi · cos θo.
    Lafortune,
    /// Ngan, Matusik & Durand 2005: the error of f_r · cos θi (the reflected radiance
    /// under a directional light), which weighs grazing exitance fully.
    Ngan,
}

impl Metric {
    /// The factor a residual f_model − f_data is multiplied by at a pair.
    pub fn factor(self, cos_i: f64, cos_o: f64) -> f64 {
        match self {
            Metric::Lafortune => cos_i * cos_o,
            Metric::Ngan => cos_i,
        }
    }
}

/// What a fit minimises: Σ (w · (f_model − f_data))² with the weight w of this objective.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Objective {
    /// Lafortune et al. 1997, Sec. 6 ("the mean-square error of the reflectance
    /// functions multiplied by the cosines of the incidence and exitance angles"):
    /// w = the [`Metric`]'s cosines.
    Cosine,
    /// χ²: w = 1/σ, the sample's own uncertainty (the maximum-likelihood fit under
    /// Gaussian noise); needs σ > 0 on every sample and channel.
    Chi2,
    /// The relative error: w = 1/max(|f_data|, floor), the floor
    /// [`RELATIVE_FLOOR`] × the channel's mean |f_data|, so that values near 0 (noise
    /// about a dark BRDF) do not take over the fit.
    Relative,
}

/// The relative objective's floor, as a fraction of the channel's mean |f_data|.
pub const RELATIVE_FLOOR: f64 = 0.01;

impl Objective {
    /// Every objective, in the order `--objective` lists them.
    pub const ALL: [Objective; 3] = [Objective::Cosine, Objective::Chi2, Objective::Relative];

    /// The name `--objective` takes and reports print.
    pub fn name(self) -> &'static str {
        match self {
            Objective::Cosine => "cosine",
            Objective::Chi2 => "chi2",
            Objective::Relative => "relative",
        }
    }

    /// The objective named `name`.
    pub fn from_name(name: &str) -> Option<Objective> {
        Objective::ALL.into_iter().find(|o| o.name() == name)
    }

    /// The sum minimised, in words.
    pub fn formula(self, metric: Metric) -> String {
        match (self, metric) {
            (Objective::Cosine, Metric::Lafortune) => {
                "sum of ((f_model - f_data) cos θi cos θo)² (Lafortune et al. 1997, Sec. 6)".into()
            }
            (Objective::Cosine, Metric::Ngan) => {
                "sum of ((f_model - f_data) cos θi)² (Ngan et al. 2005)".into()
            }
            (Objective::Chi2, _) => "sum of ((f_model - f_data) / σ)² (χ²)".into(),
            (Objective::Relative, _) => format!(
                "sum of ((f_model - f_data) / max(|f_data|, {RELATIVE_FLOOR} × the channel's \
                 mean |f_data|))² (relative error)"
            ),
        }
    }
}

/// Options that shape the data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DataOptions {
    /// The metric (the cosines of the cosine objective).
    pub metric: Metric,
    /// Leave out pairs with θi or θo above this, degrees (grazing data).
    pub cutoff_deg: f64,
    /// Whether the default rule may choose χ² (false: `--unweighted`).
    pub use_sigma: bool,
    /// The objective; `None` chooses by the default rule ([`DataOptions::objective_for`]).
    pub objective: Option<Objective>,
}

impl Default for DataOptions {
    fn default() -> Self {
        DataOptions {
            metric: Metric::Lafortune,
            cutoff_deg: 90.0,
            use_sigma: true,
            objective: None,
        }
    }
}

/// Whether every sample has σ > 0 on every channel.
fn all_sigma(s: &Samples) -> bool {
    s.samples
        .iter()
        .all(|x| x.sigma.as_ref().is_some_and(|v| v.iter().all(|s| *s > 0.0)))
}

impl DataOptions {
    /// The objective for samples `s`, and why it was chosen. The default rule: χ² when
    /// every sample has σ > 0 (it is then the maximum-likelihood fit, and its standard
    /// errors rest on the measurement's own uncertainty) unless `use_sigma` is off,
    /// else the cosine objective. An explicit χ² without σ > 0 everywhere is refused.
    pub fn objective_for(&self, s: &Samples) -> Result<(Objective, String), FitError> {
        match self.objective {
            Some(Objective::Chi2) => {
                if let Some(i) = s
                    .samples
                    .iter()
                    .position(|x| !x.sigma.as_ref().is_some_and(|v| v.iter().all(|s| *s > 0.0)))
                {
                    return Err(FitError::Data(format!(
                        "objective chi2 needs an uncertainty σ > 0 on every sample and channel; \
                         sample {i} has none or a zero"
                    )));
                }
                Ok((Objective::Chi2, "asked for".into()))
            }
            Some(o) => Ok((o, "asked for".into())),
            None if self.use_sigma && all_sigma(s) => {
                Ok((Objective::Chi2, "default: every sample has σ > 0".into()))
            }
            None if self.use_sigma => Ok((
                Objective::Cosine,
                "default: not every sample has σ > 0".into(),
            )),
            None => Ok((Objective::Cosine, "default with --unweighted".into())),
        }
    }
}

/// Pairs, values and residual weights, channel by channel.
#[derive(Clone, Debug, PartialEq)]
pub struct FitData {
    /// The channels.
    pub channels: Channels,
    /// Incident directions (unit vectors); shared, so per-channel copies of the data
    /// do not copy the directions.
    pub wi: Arc<[[f64; 3]]>,
    /// Outgoing directions.
    pub wo: Arc<[[f64; 3]]>,
    /// Values per channel, 1/sr.
    pub y: Vec<Vec<f64>>,
    /// Residual weights per channel.
    pub weight: Vec<Vec<f64>>,
    /// Whether the weights are 1/σ (a χ² fit): `objective == Objective::Chi2`.
    pub chi_square: bool,
    /// The objective the weights are those of.
    pub objective: Objective,
    /// Why that objective (asked for, or which branch of the default rule).
    pub objective_rule: String,
    /// The metric.
    pub metric: Metric,
    /// Samples left out by the cutoff.
    pub cut: usize,
}

impl FitData {
    /// Number of pairs.
    pub fn len(&self) -> usize {
        self.wi.len()
    }

    /// Whether there are no pairs.
    pub fn is_empty(&self) -> bool {
        self.wi.is_empty()
    }

    /// From samples. Refuses NaN or infinite values and uncertainties, data with no
    /// pair above the cutoff, and data from a single incident direction (the lobes'
    /// Cx, Cz and n are then not separately determined). Negative values are kept:
    /// noise around a small BRDF is legitimately negative, and dropping it would bias
    /// the fit upwards.
    pub fn from_samples(s: &Samples, opts: &DataOptions) -> Result<FitData, FitError> {
        let nc = s.channels.len();
        if s.samples.is_empty() {
            return Err(FitError::Data("no samples".into()));
        }
        for (i, x) in s.samples.iter().enumerate() {
            if x.value.len() != nc || x.value.iter().any(|v| !v.is_finite()) {
                return Err(FitError::Data(format!(
                    "sample {i} ({:?}) has a value that is not a finite number",
                    x.pair
                )));
            }
            if x.sigma
                .as_ref()
                .is_some_and(|v| v.iter().any(|s| !(s.is_finite() && *s >= 0.0)))
            {
                return Err(FitError::Data(format!(
                    "sample {i} has an uncertainty that is not a finite non-negative number"
                )));
            }
        }
        let (objective, objective_rule) = opts.objective_for(s)?;
        let chi_square = objective == Objective::Chi2;
        let kept: Vec<&gonio_process::Sample> = s
            .samples
            .iter()
            .filter(|x| {
                let p = &x.pair;
                p.incident.theta_deg <= opts.cutoff_deg
                    && p.outgoing.theta_deg <= opts.cutoff_deg
                    && p.incident.theta_deg < 90.0
                    && p.outgoing.theta_deg < 90.0
            })
            .collect();
        let mut incident: Vec<[i64; 2]> = Vec::new();
        for x in &kept {
            let p = &x.pair;
            // At normal incidence every φi is the same direction.
            let phi = if p.incident.theta_deg == 0.0 {
                0.0
            } else {
                p.incident.phi_deg
            };
            let key = [
                (p.incident.theta_deg * 1e6).round() as i64,
                (phi.rem_euclid(360.0) * 1e6).round() as i64,
            ];
            if !incident.contains(&key) {
                incident.push(key);
                if incident.len() == 2 {
                    break;
                }
            }
        }
        // The directions' trigonometry is most of this function's time on large
        // inputs: in parallel, in order.
        let (wis, wos): (Vec<[f64; 3]>, Vec<[f64; 3]>) = kept
            .par_iter()
            .map(|x| {
                let d = x.pair.to_dirs();
                ([d.wi.x, d.wi.y, d.wi.z], [d.wo.x, d.wo.y, d.wo.z])
            })
            .unzip();
        let mut d = FitData {
            channels: s.channels.clone(),
            wi: Arc::from([]),
            wo: Arc::from([]),
            y: (0..nc)
                .map(|ch| kept.iter().map(|x| x.value[ch]).collect())
                .collect(),
            weight: (0..nc)
                .map(|ch| {
                    kept.iter()
                        .zip(wis.iter().zip(&wos))
                        .map(|(x, (wi, wo))| match (&x.sigma, objective) {
                            (Some(sg), Objective::Chi2) => 1.0 / sg[ch],
                            _ => opts.metric.factor(wi[2], wo[2]),
                        })
                        .collect()
                })
                .collect(),
            chi_square,
            objective,
            objective_rule,
            metric: opts.metric,
            cut: s.samples.len() - kept.len(),
        };
        d.wi = wis.into();
        d.wo = wos.into();
        if d.is_empty() {
            return Err(FitError::Data(format!(
                "no sample below the {}° cutoff",
                opts.cutoff_deg
            )));
        }
        if objective == Objective::Relative {
            for ch in 0..nc {
                let mean = d.y[ch].iter().map(|v| v.abs()).sum::<f64>() / d.len() as f64;
                if mean <= 0.0 {
                    return Err(FitError::Data(format!(
                        "objective relative: every value of channel {} is 0",
                        d.channels.name(ch)
                    )));
                }
                let floor = RELATIVE_FLOOR * mean;
                for (w, y) in d.weight[ch].iter_mut().zip(&d.y[ch]) {
                    *w = 1.0 / y.abs().max(floor);
                }
            }
        }
        if incident.len() < 2 {
            return Err(FitError::Data(
                "all samples share one incident direction: a BRDF fit needs several".into(),
            ));
        }
        Ok(d)
    }

    /// From a table (its nodes).
    pub fn from_table(t: &Table, opts: &DataOptions) -> Result<FitData, FitError> {
        FitData::from_samples(&Samples::from_table(t), opts)
    }
}
