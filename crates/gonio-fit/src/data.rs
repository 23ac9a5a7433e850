//! The data a fit sees: pairs of directions, values per channel, and the weight of
//! each residual under the chosen metric.

use std::sync::Arc;

use gonio_core::Channels;
use gonio_process::{Samples, Table};
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

/// Options that shape the data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DataOptions {
    /// The metric.
    pub metric: Metric,
    /// Leave out pairs with θi or θo above this, degrees (grazing data).
    pub cutoff_deg: f64,
    /// Divide each residual by the sample's uncertainty where known (a χ² fit); the
    /// metric's factor then cancels, as it scales the value and its σ alike.
    pub use_sigma: bool,
}

impl Default for DataOptions {
    fn default() -> Self {
        DataOptions {
            metric: Metric::Lafortune,
            cutoff_deg: 90.0,
            use_sigma: true,
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
    /// Whether the weights are 1/σ (a χ² fit).
    pub chi_square: bool,
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
        let chi_square = opts.use_sigma
            && s.samples
                .iter()
                .all(|x| x.sigma.as_ref().is_some_and(|v| v.iter().all(|s| *s > 0.0)));
        let (mut wis, mut wos) = (Vec::new(), Vec::new());
        let mut d = FitData {
            channels: s.channels.clone(),
            wi: Arc::from([]),
            wo: Arc::from([]),
            y: vec![Vec::new(); nc],
            weight: vec![Vec::new(); nc],
            chi_square,
            metric: opts.metric,
            cut: 0,
        };
        let mut incident: Vec<[i64; 2]> = Vec::new();
        for x in &s.samples {
            let p = &x.pair;
            if p.incident.theta_deg > opts.cutoff_deg
                || p.outgoing.theta_deg > opts.cutoff_deg
                || p.incident.theta_deg >= 90.0
                || p.outgoing.theta_deg >= 90.0
            {
                d.cut += 1;
                continue;
            }
            let dirs = p.to_dirs();
            let (wi, wo) = (dirs.wi, dirs.wo);
            wis.push([wi.x, wi.y, wi.z]);
            wos.push([wo.x, wo.y, wo.z]);
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
            if !incident.contains(&key) && incident.len() < 2 {
                incident.push(key);
            }
            let f = opts.metric.factor(wi.z, wo.z);
            for ch in 0..nc {
                d.y[ch].push(x.value[ch]);
                d.weight[ch].push(match (&x.sigma, chi_square) {
                    (Some(sg), true) => 1.0 / sg[ch],
                    _ => f,
                });
            }
        }
        d.wi = wis.into();
        d.wo = wos.into();
        if d.is_empty() {
            return Err(FitError::Data(format!(
                "no sample below the {}° cutoff",
                opts.cutoff_deg
            )));
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
