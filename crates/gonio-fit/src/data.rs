//! The data a fit sees: pairs of directions, values per channel, and the weight of
//! each residual under the chosen objective.

use std::sync::Arc;

use gonio_core::dirfile::PairDeg;
use gonio_core::{Channels, SphericalDeg, sin_cos_deg};
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

/// The first sample without σ > 0 on every channel, if any.
fn first_without_sigma(s: &Samples) -> Option<usize> {
    s.samples
        .iter()
        .position(|x| !x.sigma.as_ref().is_some_and(|v| v.iter().all(|s| *s > 0.0)))
}

impl DataOptions {
    /// The objective for samples `s`, and why it was chosen. The default rule: χ² when
    /// every sample has σ > 0 (it is then the maximum-likelihood fit, and its standard
    /// errors rest on the measurement's own uncertainty) unless `use_sigma` is off,
    /// else the cosine objective. An explicit χ² without σ > 0 everywhere is refused.
    pub fn objective_for(&self, s: &Samples) -> Result<(Objective, String), FitError> {
        self.objective_given(first_without_sigma(s))
    }

    /// [`DataOptions::objective_for`] given the first sample without σ > 0 on every
    /// channel (`None`: every sample has it).
    fn objective_given(&self, without: Option<usize>) -> Result<(Objective, String), FitError> {
        match self.objective {
            Some(Objective::Chi2) => {
                if let Some(i) = without {
                    return Err(FitError::Data(format!(
                        "objective chi2 needs an uncertainty σ > 0 on every sample and channel; \
                         sample {i} has none or a zero"
                    )));
                }
                Ok((Objective::Chi2, "asked for".into()))
            }
            Some(o) => Ok((o, "asked for".into())),
            None if self.use_sigma && without.is_none() => {
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

/// Samples as columns, one slice a quantity and all of one length: what a reader of a
/// sample file gives a fit, with no per-row structure in between.
#[derive(Clone, Copy, Debug)]
pub struct Columns<'a> {
    /// The channels, in the order of `values` and `sigma`.
    pub channels: &'a Channels,
    /// Incident polar angles, degrees.
    pub theta_i: &'a [f64],
    /// Incident azimuths, degrees.
    pub phi_i: &'a [f64],
    /// Outgoing polar angles, degrees.
    pub theta_o: &'a [f64],
    /// Outgoing azimuths, degrees.
    pub phi_o: &'a [f64],
    /// Values per channel, 1/sr.
    pub values: &'a [&'a [f64]],
    /// Standard uncertainties per channel, 1/sr, if the samples have them (0: none).
    pub sigma: Option<&'a [&'a [f64]]>,
}

impl Columns<'_> {
    /// Rows.
    pub fn len(&self) -> usize {
        self.theta_i.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.theta_i.is_empty()
    }
}

/// Rows as the data path reads them, from columns or from samples: one implementation
/// of the checks and of the fit data for both (monomorphised, so columns are read as
/// slices).
trait Rows: Sync {
    /// Rows.
    fn len(&self) -> usize;
    /// Channels.
    fn channels(&self) -> &Channels;
    /// θi and θo of row `i`, degrees.
    fn thetas(&self, i: usize) -> (f64, f64);
    /// Row `i`'s directions.
    fn pair(&self, i: usize) -> PairDeg;
    /// Row `i`'s value in channel `ch` (NaN for a row whose values do not number the
    /// channels).
    fn value(&self, i: usize, ch: usize) -> f64;
    /// Row `i`'s σ in channel `ch`, `None` where it has none.
    fn sigma(&self, i: usize, ch: usize) -> Option<f64>;
}

impl Rows for Columns<'_> {
    fn len(&self) -> usize {
        self.theta_i.len()
    }
    fn channels(&self) -> &Channels {
        self.channels
    }
    fn thetas(&self, i: usize) -> (f64, f64) {
        (self.theta_i[i], self.theta_o[i])
    }
    fn pair(&self, i: usize) -> PairDeg {
        PairDeg {
            incident: SphericalDeg::new(self.theta_i[i], self.phi_i[i]),
            outgoing: SphericalDeg::new(self.theta_o[i], self.phi_o[i]),
        }
    }
    fn value(&self, i: usize, ch: usize) -> f64 {
        self.values[ch][i]
    }
    fn sigma(&self, i: usize, ch: usize) -> Option<f64> {
        self.sigma.map(|s| s[ch][i])
    }
}

impl Rows for Samples {
    fn len(&self) -> usize {
        self.samples.len()
    }
    fn channels(&self) -> &Channels {
        &self.channels
    }
    fn thetas(&self, i: usize) -> (f64, f64) {
        let p = &self.samples[i].pair;
        (p.incident.theta_deg, p.outgoing.theta_deg)
    }
    fn pair(&self, i: usize) -> PairDeg {
        self.samples[i].pair
    }
    fn value(&self, i: usize, ch: usize) -> f64 {
        let v = &self.samples[i].value;
        if v.len() == self.channels.len() {
            v[ch]
        } else {
            f64::NAN
        }
    }
    fn sigma(&self, i: usize, ch: usize) -> Option<f64> {
        // A σ list shorter than the channels has none (0) where it ends.
        self.samples[i]
            .sigma
            .as_ref()
            .map(|v| v.get(ch).copied().unwrap_or(0.0))
    }
}

/// The sine and cosine of the last angle seen, degrees.
#[derive(Clone, Copy)]
struct SinCos {
    bits: u64,
    sc: (f64, f64),
}

impl Default for SinCos {
    fn default() -> Self {
        // NaN's bits: no finite angle matches them.
        SinCos {
            bits: f64::NAN.to_bits(),
            sc: (f64::NAN, f64::NAN),
        }
    }
}

impl SinCos {
    /// `sin_cos_deg(x)`, computed only when `x` differs from the last angle.
    fn of(&mut self, x: f64) -> (f64, f64) {
        if x.to_bits() != self.bits {
            *self = SinCos {
                bits: x.to_bits(),
                sc: sin_cos_deg(x),
            };
        }
        self.sc
    }

    /// The unit vector of `d`, as `Dir::from(d)` computes it.
    fn dir(d: SphericalDeg, theta: &mut SinCos, phi: &mut SinCos) -> [f64; 3] {
        let (st, ct) = theta.of(d.theta_deg);
        let (sp, cp) = phi.of(d.phi_deg);
        [st * cp, st * sp, ct]
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
    /// Values per channel, 1/sr; shared like the directions (a channel's own fit
    /// takes its columns without copying them).
    pub y: Vec<Arc<[f64]>>,
    /// Residual weights per channel.
    pub weight: Vec<Arc<[f64]>>,
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

    /// From samples: the same checks and data as [`FitData::from_columns`] of their
    /// columns (a sample whose values do not number the channels reads as not finite;
    /// one without σ, or with fewer than the channels, as having none there).
    pub fn from_samples(s: &Samples, opts: &DataOptions) -> Result<FitData, FitError> {
        FitData::from_rows(s, opts)
    }

    /// From columns. Refuses columns of different lengths, NaN or infinite angles,
    /// values and uncertainties, data with no pair above the cutoff, and data from a single
    /// incident direction (the lobes' Cx, Cz and n are then not separately
    /// determined). Negative values are kept: noise around a small BRDF is
    /// legitimately negative, and dropping it would bias the fit upwards. Errors name
    /// the first faulty row (0-based) as `sample i`.
    pub fn from_columns(c: &Columns, opts: &DataOptions) -> Result<FitData, FitError> {
        let (n, nc) = (c.len(), c.channels.len());
        let fits = |cols: &[&[f64]]| cols.len() == nc && cols.iter().all(|v| v.len() == n);
        if ![c.phi_i, c.theta_o, c.phi_o].iter().all(|v| v.len() == n)
            || !fits(c.values)
            || !c.sigma.is_none_or(fits)
        {
            return Err(FitError::Data(format!(
                "columns of different lengths ({n} incident polar angles, {nc} channels)"
            )));
        }
        FitData::from_rows(c, opts)
    }

    /// [`FitData::from_columns`] of rows of either kind.
    fn from_rows(c: &impl Rows, opts: &DataOptions) -> Result<FitData, FitError> {
        let (n, nc) = (c.len(), c.channels().len());
        if n == 0 {
            return Err(FitError::Data("no samples".into()));
        }
        let cutoff = opts.cutoff_deg;
        let keep = |i: usize| {
            let (ti, to) = c.thetas(i);
            ti <= cutoff && to <= cutoff && ti < 90.0 && to < 90.0
        };
        // One sequential pass for every check (a few operations a row: parallel
        // passes would cost more in synchronisation on a loaded machine than they
        // save). Rows are checked in order, a row's values before its
        // uncertainties: the first faulty row is reported, whichever its fault.
        let (mut without, mut all_kept) = (None, true);
        for i in 0..n {
            let (mut bad_value, mut bad_sigma) = (false, false);
            for ch in 0..nc {
                bad_value |= !c.value(i, ch).is_finite();
                let s = c.sigma(i, ch);
                bad_sigma |= s.is_some_and(|s| !(s.is_finite() && s >= 0.0));
                if without.is_none() && !s.is_some_and(|s| s > 0.0) {
                    without = Some(i);
                }
            }
            let p = c.pair(i);
            let angles = [p.incident, p.outgoing].map(|d| [d.theta_deg, d.phi_deg]);
            if !angles.as_flattened().iter().all(|x| x.is_finite()) {
                return Err(FitError::Data(format!(
                    "sample {i} ({p:?}) has an angle that is not a finite number"
                )));
            }
            if bad_value {
                return Err(FitError::Data(format!(
                    "sample {i} ({p:?}) has a value that is not a finite number"
                )));
            }
            if bad_sigma {
                return Err(FitError::Data(format!(
                    "sample {i} has an uncertainty that is not a finite non-negative number"
                )));
            }
            all_kept &= keep(i);
        }
        let (objective, objective_rule) = opts.objective_given(without)?;
        let chi_square = objective == Objective::Chi2;
        // The rows kept, when some are left out (usually none is: no index list).
        let kept: Option<Vec<usize>> = (!all_kept).then(|| (0..n).filter(|i| keep(*i)).collect());
        let row = |k: usize| kept.as_ref().map_or(k, |v| v[k]);
        let m = kept.as_ref().map_or(n, Vec::len);
        if m == 0 {
            return Err(FitError::Data(format!(
                "no sample below the {cutoff}° cutoff"
            )));
        }
        let mut incident: Vec<[i64; 2]> = Vec::new();
        for k in 0..m {
            let p = c.pair(row(k)).incident;
            // At normal incidence every φi is the same direction.
            let phi = if p.theta_deg == 0.0 { 0.0 } else { p.phi_deg };
            let key = [
                (p.theta_deg * 1e6).round() as i64,
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
        // inputs: in parallel, written in place into the shared arrays (collecting
        // into vectors first would touch and copy twice the memory), and each angle's
        // sine and cosine reused while it repeats from row to row (a measurement's
        // rows come in runs of one θi, φi and θo): the same values as
        // `Dir::from(SphericalDeg)`, computed once a run.
        const PART: usize = 4096;
        let zeros = || -> Arc<[[f64; 3]]> { (0..m).map(|_| [0.0; 3]).collect() };
        let (mut wi, mut wo) = (zeros(), zeros());
        if let (Some(a), Some(b)) = (Arc::get_mut(&mut wi), Arc::get_mut(&mut wo)) {
            a.par_chunks_mut(PART)
                .zip(b.par_chunks_mut(PART))
                .enumerate()
                .for_each(|(part, (a, b))| {
                    let mut memo = [SinCos::default(); 4];
                    for (j, (a, b)) in a.iter_mut().zip(b.iter_mut()).enumerate() {
                        let p = c.pair(row(part * PART + j));
                        let [ti, pi, to, po] = &mut memo;
                        *a = SinCos::dir(p.incident, ti, pi);
                        *b = SinCos::dir(p.outgoing, to, po);
                    }
                });
        }
        // Straight into the shared columns: one allocation and one pass each.
        fn pick(m: usize, row: impl Fn(usize) -> usize, f: impl Fn(usize) -> f64) -> Arc<[f64]> {
            (0..m).map(|k| f(row(k))).collect()
        }
        let y: Vec<Arc<[f64]>> = (0..nc).map(|ch| pick(m, row, |i| c.value(i, ch))).collect();
        let mut weight = Vec::with_capacity(nc);
        for (ch, y) in y.iter().enumerate() {
            weight.push(match objective {
                // χ² was chosen or accepted only with σ > 0 on every row.
                Objective::Chi2 => pick(m, row, |i| 1.0 / c.sigma(i, ch).unwrap_or(0.0)),
                Objective::Relative => {
                    let mean = y.iter().map(|v| v.abs()).sum::<f64>() / m as f64;
                    if mean <= 0.0 {
                        return Err(FitError::Data(format!(
                            "objective relative: every value of channel {} is 0",
                            c.channels().name(ch)
                        )));
                    }
                    let floor = RELATIVE_FLOOR * mean;
                    y.iter().map(|y| 1.0 / y.abs().max(floor)).collect()
                }
                Objective::Cosine => wi
                    .iter()
                    .zip(wo.iter())
                    .map(|(wi, wo)| opts.metric.factor(wi[2], wo[2]))
                    .collect(),
            });
        }
        if incident.len() < 2 {
            return Err(FitError::Data(
                "all samples share one incident direction: a BRDF fit needs several".into(),
            ));
        }
        Ok(FitData {
            channels: c.channels().clone(),
            wi,
            wo,
            y,
            weight,
            chi_square,
            objective,
            objective_rule,
            metric: opts.metric,
            cut: n - m,
        })
    }

    /// From a table (its nodes).
    pub fn from_table(t: &Table, opts: &DataOptions) -> Result<FitData, FitError> {
        FitData::from_samples(&Samples::from_table(t), opts)
    }
}
