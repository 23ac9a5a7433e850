//! From a run's readings to BRDF samples with uncertainties.
//!
//! **The formula.** A reading of the sample at (ωi, ωo) measures reflected flux; the
//! BRDF is that flux over the incident flux, the detector's solid angle Ω and the
//! projection cos θo (DeYoung App. A, Eq. A.15):
//!
//!   f_r = (S_o − S_dark) / ((S_in − S_dark) · Ω · cos θo)
//!
//! with S_in the incident-beam reading divided by the transmittance T of the filter
//! in the beam during it. Relative to a reference standard of known BRDF f_std
//! measured at (ωi', ωo'), the same formula with the standard's reading solved for
//! the incident flux gives (S_in − S_dark)/T = (S_std − S_dark) / (f_std Ω cos θo');
//! both calibrations are thus one estimate of the incident flux Φ.
//!
//! **Dark.** The lock-in's X and Y average to the coherent signal, while R of a dark
//! reading is mostly noise (its mean is σ√(π/2), not zero), so the dark is subtracted
//! as a vector: S = |(X − X_dark, Y − Y_dark)|.
//!
//! **Drift.** The drift reference pair is re-measured every N points. Its readings
//! define the source's relative level g(t): a straight line fitted to them when it
//! explains their scatter (χ² within three standard deviations of its degrees of
//! freedom), else linear in instrument time between them (continued along the first
//! and last segments beyond them). Every calibration reading k then estimates the
//! same constant C = Φ_k / g(t_k); their inverse-variance mean C gives Φ(t) = C g(t)
//! for every sample. Without references, calibrations repeated at the end of the run
//! are interpolated linearly in time instead; a single calibration is held constant.
//!
//! **Uncertainty budget.** Each sample's σ is the quadrature sum of the terms of
//! [`TERMS`], each reported per channel ([`BudgetTerm`]) with its source and how it
//! is shared between samples:
//! - `noise`: the lock-in's noise in the sample reading. Per snapshot its variance is
//!   pooled over the run's readings as a + b·R (amplifier and shot noise) rather
//!   than taken from each reading's own few correlated snapshots, whose scatter is
//!   itself uncertain (by a third for ten, entirely for two); the variance of the
//!   mean of n snapshots spaced one time constant plus [`Options::snapshot_gap_s`]
//!   apart is then exact for the first-order correlation ρ = e^−(1 + gap/T)
//!   ([`variance_factors`]). The pool spans time constants and snapshot counts:
//!   the output noise is white noise of density d(R)² = a' + b'·R through the
//!   filter, so a snapshot's variance is d²·ENBW(T, slope) (ENBW ∝ 1/T at one
//!   slope, `gonio_proto::sr830::FilterSlope::enbw_hz`), and n enters only through
//!   each reading's own variance factors. One line is fitted per filter slope, at
//!   the time constant of its first reading, each reading's variance divided by its
//!   ENBW ratio to it (exactly 1 in a run at one time constant) and weighted by its
//!   n − 1 degrees of freedom relative to the first reading's. A slope with fewer
//!   than eight usable readings takes each reading's own scatter; a reading of one
//!   snapshot, which has none, borrows the nearest slope's line scaled by the
//!   ratio of the two ENBWs, and keeps a noise term of 0 (with a warning) only when
//!   the run has no line at all. A reading that reached the plan's
//!   `reading.max_s` before its target (flag `capped`) is reduced like any other,
//!   with the precision it reached; the report counts them.
//! - `resolution`: the lock-in's six-digit replies (a rounding step /√12).
//! - `dark`: the dark vector's own noise, subtracted from every reading: one error
//!   shared by all samples, larger for weak signals (it is additive).
//! - `calibration`: the calibration readings' noise (scaled up when they disagree),
//!   and the drift level at the calibrations' time.
//! - `drift`: the uncertainty of g(t) relative to the calibrations' g.
//! - `standard`: the reference standard's own BRDF uncertainty
//!   ([`Options::standard_rel_sigma`]), when the standard calibrates.
//!
//! **DC readings.** When the run's stored instrument config names a Keithley 6485
//! picoammeter (`[detector] kind = "k6485"`, [`Detector::of_instrument`]), the
//! readings are currents, A, and Eq. A.15 is applied to them with a budget of their
//! own ([`DC_TERMS`]):
//! - the dark is a scalar: the mean of the dark readings' mean currents, subtracted
//!   with its sign (a dark current has a true mean, unlike the lock-in's R);
//! - `noise`: the samples of a reading are independent conversions (ρ = 0), so the
//!   mean's σ is s/√n; where enough readings share a range, integration time and
//!   sample count, s² is pooled as a + b·I (the meter's and the shunt's noise, and
//!   shot noise growing with the current);
//! - `resolution`: the 6485's seven-digit replies (`+1.234567E-09A`);
//! - `dark`: s/√n of the dark readings, combined;
//! - `range accuracy`: the manual's 1-year accuracy of each reading's range
//!   (`gonio_proto::k6485::accuracy_a`), a ± bound taken as a rectangular
//!   distribution (σ = bound/√3, GUM 4.3.7). It is one systematic error per range,
//!   shared by every reading on that range: it cancels between a sample and a
//!   calibration read on the same range and does not between ranges (see
//!   [`DC_CORRELATIONS`]).
//!
//! The report's budget lines name amps, and its unit is `A`: the JSON's `dark_a`
//! ([I_dark, 0]) and `incident_a` where a lock-in's has `dark_v` and `incident_v`.

pub mod adaptive;
mod group;
mod noise;
pub mod spectral;

use std::collections::BTreeMap;

use gonio_core::Channels;
use gonio_core::dirfile::PairDeg;
use gonio_core::radiometry::Aperture;
use gonio_plan::StepKind;
pub use gonio_process::reduction::{BudgetTerm, ChannelReport, Report};
use gonio_process::{Sample, Samples};
use gonio_run::{ReadingRecord, RunStore, StoreError, StoredStep, flags};
use serde::Serialize;

use group::{Grouped, flag_reason};
use noise::Noise;
pub use noise::variance_factors;

/// The variance factor of a lock-in mean over samples one time constant apart, as
/// the reduction used it before the budget was pooled (kept for callers).
pub const CORRELATION_FACTOR: f64 = 2.2;

/// The terms of the uncertainty budget, in the order of [`Reduction::budget`].
pub const TERMS: [&str; 6] = [
    "noise",
    "resolution",
    "dark",
    "calibration",
    "drift",
    "standard",
];

/// How each term of [`TERMS`] is shared between samples.
pub const CORRELATIONS: [&str; 6] = [
    "independent",
    "independent",
    "common",
    "common",
    "segment",
    "common",
];

/// The terms of a DC (picoammeter) run's budget: [`TERMS`] and the meter's range
/// accuracy. [`Reduction::budget`] is indexed by these for every run; a lock-in
/// run's `range accuracy` is 0 and is not reported.
pub const DC_TERMS: [&str; 7] = [
    "noise",
    "resolution",
    "dark",
    "calibration",
    "drift",
    "standard",
    "range accuracy",
];

/// How each term of [`DC_TERMS`] is shared between samples. The range accuracy is
/// `range`: one error per current range, shared by all readings on it — the samples
/// read on one range share it, and every sample shares the calibration's and the
/// dark's; it cancels in the ratio of readings on the same range.
pub const DC_CORRELATIONS: [&str; 7] = [
    "independent",
    "independent",
    "common",
    "common",
    "segment",
    "common",
    "range",
];

/// The number of budget terms kept per sample and channel: [`DC_TERMS`], then the
/// wavelength term of a spectral run ([`spectral::TERM`]; 0 and not reported
/// otherwise).
pub const N_TERMS: usize = 8;

/// What the run's detector measures, which decides how its readings are reduced.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Detector {
    /// An SR830 lock-in: readings are (X, Y) vectors in volts (every run before
    /// the picoammeter, and any run whose instrument config names no other kind).
    LockIn,
    /// A Keithley 6485 picoammeter on a photodiode: readings are DC currents, A.
    Dc,
}

impl Detector {
    /// The detector a run's stored instrument config text names: `Dc` for
    /// `[detector] kind = "k6485"`, else `LockIn` (the config's default kind, and
    /// what a text that does not parse is taken for, as runs before the
    /// picoammeter never named a kind).
    pub fn of_instrument(text: &str) -> Detector {
        let kind = toml::from_str::<toml::Table>(text).ok().and_then(|t| {
            t.get("detector")?
                .get("kind")?
                .as_str()
                .map(str::to_ascii_lowercase)
        });
        if kind.as_deref() == Some("k6485") {
            Detector::Dc
        } else {
            Detector::LockIn
        }
    }
}

/// The time between the end of one lock-in snapshot and the start of the next
/// beyond one time constant, s, by default: the `SNAP?1,2` exchange at the SR830's
/// 9600 baud (9 characters out, about 27 back, 10 bits each) plus 5 ms of latency.
pub const SNAPSHOT_GAP_S: f64 = 0.0425;

/// Which calibration gives the incident flux.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Calibration {
    /// The incident-beam reading where the run has one, else the standard.
    Auto,
    /// The incident-beam reading (absolute).
    Incident,
    /// The reference standard (relative).
    Standard,
}

/// How the source's level is followed through the run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Drift {
    /// By the drift reference readings when the run has them, else by the
    /// calibrations repeated at the end (interpolated in time).
    Auto,
    /// By the calibrations alone, interpolated in time.
    Calibrations,
    /// Not at all: one level, the mean of the calibrations.
    None,
}

/// Options of the reduction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// The calibration to use.
    pub calibration: Calibration,
    /// How the source's drift is corrected.
    pub drift: Drift,
    /// Readings with any of these flags are left out (their count is reported).
    pub reject_flags: u32,
    /// The gap between lock-in snapshots beyond one time constant, s (sets their
    /// correlation; [`SNAPSHOT_GAP_S`] by default).
    pub snapshot_gap_s: f64,
    /// The relative standard uncertainty of the reference standard's BRDF (its
    /// certificate's), carried as the budget's `standard` term when the standard
    /// calibrates. 0 by default: a model file states none.
    pub standard_rel_sigma: f64,
    /// Whether a DC run's noise is pooled per range as a + b·I over the run's
    /// readings (the default: n = 5 samples give s² only to ±70 %), or taken from
    /// each reading's own s/√n. A lock-in run always pools.
    pub dc_pool_noise: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            calibration: Calibration::Auto,
            drift: Drift::Auto,
            reject_flags: flags::INPUT_OVERLOAD
                | flags::FILTER_OVERLOAD
                | flags::OUTPUT_OVERLOAD
                | flags::UNLOCK,
            snapshot_gap_s: SNAPSHOT_GAP_S,
            standard_rel_sigma: 0.0,
            dc_pool_noise: true,
        }
    }
}

/// Why a run could not be reduced.
#[derive(Debug, thiserror::Error)]
pub enum ReduceError {
    /// The run file could not be read.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// The run lacks what the reduction needs.
    #[error("{path}: {why}")]
    Missing {
        /// The run file.
        path: String,
        /// What is missing.
        why: String,
    },
}

/// Samples and the report.
#[derive(Clone, Debug, PartialEq)]
pub struct Reduction {
    /// The BRDF samples.
    pub samples: Samples,
    /// What was done.
    pub report: Report,
    /// Per sample (in the order of `samples.samples`), per channel, the standard
    /// uncertainty of each term of [`DC_TERMS`], 1/sr: their quadrature sum is the
    /// sample's σ. Terms of the same kind are correlated as [`DC_CORRELATIONS`]
    /// says. The last, the range accuracy, is 0 for a lock-in run.
    pub budget: Vec<Vec<[f64; N_TERMS]>>,
    /// The detector the readings came from.
    pub detector: Detector,
}

/// A value with its standard uncertainty.
#[derive(Clone, Copy, Debug)]
struct Measured {
    t: f64,
    v: f64,
    s: f64,
}

/// The lock-in's reply rounding, relative: six significant digits, a step of
/// 10^(⌊log₁₀ v⌋ − 5), uniformly distributed (σ = step/√12). Not averaged down by
/// the snapshots: without noise they all round alike.
fn resolution_rel(v: f64) -> f64 {
    if v > 0.0 {
        10f64.powf(v.log10().floor() - 5.0) / 12f64.sqrt() / v
    } else {
        0.0
    }
}

/// The 6485's reply rounding of a current `i`, A, relative to the signal `v`: its
/// replies carry seven significant digits (`+1.234567E-09A`, `d.ddddddE±xx`), a
/// step of 10^(⌊log₁₀ |i|⌋ − 6) on the raw reading, uniformly distributed (σ =
/// step/√12). The rounding is of the reading, not of the dark-subtracted signal;
/// like the lock-in's it is not taken as averaged down by the n samples (without
/// noise they all round alike).
fn dc_resolution_rel(i: f64, v: f64) -> f64 {
    if i != 0.0 && i.is_finite() && v > 0.0 {
        10f64.powf(i.abs().log10().floor() - 6.0) / 12f64.sqrt() / v
    } else {
        0.0
    }
}

/// The 6485's range accuracy of a DC reading as a standard uncertainty, A, with
/// the range it belongs to: the manual's 1-year ±bound (Appendix A, ±(% rdg +
/// offset), [`gonio_proto::k6485::accuracy_a`]) as the half-width of a
/// rectangular distribution, σ = bound/√3 (GUM 4.3.7): the manual states a limit,
/// not a distribution. `None` for a range index the 6485 has not.
fn range_sigma(r: &ReadingRecord) -> Option<(usize, f64)> {
    let range = gonio_proto::k6485::Range::new(r.sensitivity)?;
    let bound = gonio_proto::k6485::accuracy_a(range, r.x_mean);
    Some((usize::from(r.sensitivity), bound / 3f64.sqrt()))
}

/// The 6485's ranges (2 nA … 20 mA), the range-accuracy coefficients' length.
const RANGES: usize = gonio_proto::k6485::Range::COUNT as usize;

/// Inverse-variance mean of values, with its uncertainty, scaled by the Birge ratio
/// √(χ²/(n − 1)) when the values disagree beyond their noise (χ² more than three
/// standard deviations above n − 1): the scatter of two or three readings is too
/// uncertain to replace their noise unless it is significant. Without
/// uncertainties (any of them 0), the plain mean and its scatter's standard error.
fn weighted_mean(m: &[Measured]) -> (f64, f64) {
    let n = m.len() as f64;
    if m.iter().all(|x| x.s > 0.0) {
        let sw: f64 = m.iter().map(|x| x.s.powi(-2)).sum();
        let mean = m.iter().map(|x| x.v / (x.s * x.s)).sum::<f64>() / sw;
        let s = sw.sqrt().recip();
        if m.len() < 2 {
            return (mean, s);
        }
        let chi2: f64 = m.iter().map(|x| ((x.v - mean) / x.s).powi(2)).sum();
        let dof = n - 1.0;
        let s = if chi2 > dof + 3.0 * (2.0 * dof).sqrt() {
            s * (chi2 / dof).sqrt()
        } else {
            s
        };
        return (mean, s);
    }
    let mean = m.iter().map(|x| x.v).sum::<f64>() / n;
    if m.len() < 2 {
        return (mean, 0.0);
    }
    let scatter = (m.iter().map(|x| (x.v - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
    (mean, scatter)
}

/// Linear interpolation in time of measured values, with the interpolated
/// uncertainty. Beyond the ends the value holds, or with `extend` the first or last
/// segment's line continues (a drifting source keeps drifting past the last
/// reference, to the end-of-run calibrations a little later).
fn interp(m: &[Measured], t: f64, extend: bool) -> (f64, f64) {
    let line = |a: Measured, b: Measured| {
        let w = if b.t > a.t {
            (t - a.t) / (b.t - a.t)
        } else {
            0.0
        };
        ((1.0 - w) * a.v + w * b.v, ((1.0 - w) * a.s).hypot(w * b.s))
    };
    match m {
        [] => (1.0, 0.0),
        [only] => (only.v, only.s),
        _ => {
            let last = m[m.len() - 1];
            if t <= m[0].t {
                return if extend {
                    line(m[0], m[1])
                } else {
                    (m[0].v, m[0].s)
                };
            }
            if t >= last.t {
                return if extend {
                    line(m[m.len() - 2], last)
                } else {
                    (last.v, last.s)
                };
            }
            let k = m.partition_point(|x| x.t <= t).max(1);
            line(m[k - 1], m[k])
        }
    }
}

/// The source's relative level g(t) from the drift references.
enum Level {
    /// A straight line g = p0 + p1 (t − t̄), fitted by weighted least squares; p0
    /// and p1 are uncorrelated about the weighted mean time t̄.
    Line {
        t_mean: f64,
        p0: f64,
        p1: f64,
        s1: f64,
    },
    /// Linear between the references.
    Piecewise(Vec<Measured>),
}

impl Level {
    /// Fits a line to the references, kept when its χ² lies within three standard
    /// deviations of its degrees of freedom (the references then show nothing a
    /// line does not); else the references are interpolated.
    fn from_refs(refs: Vec<Measured>) -> Level {
        if refs.len() < 3 || refs.iter().any(|m| m.s <= 0.0) {
            return Level::Piecewise(refs);
        }
        let w: Vec<f64> = refs.iter().map(|m| m.s.powi(-2)).collect();
        let sw: f64 = w.iter().sum();
        let t_mean = refs.iter().zip(&w).map(|(m, w)| w * m.t).sum::<f64>() / sw;
        let p0 = refs.iter().zip(&w).map(|(m, w)| w * m.v).sum::<f64>() / sw;
        let stt: f64 = refs
            .iter()
            .zip(&w)
            .map(|(m, w)| w * (m.t - t_mean).powi(2))
            .sum();
        if stt <= 0.0 {
            return Level::Piecewise(refs);
        }
        let p1 = refs
            .iter()
            .zip(&w)
            .map(|(m, w)| w * (m.t - t_mean) * m.v)
            .sum::<f64>()
            / stt;
        let chi2: f64 = refs
            .iter()
            .map(|m| ((m.v - p0 - p1 * (m.t - t_mean)) / m.s).powi(2))
            .sum();
        let dof = (refs.len() - 2) as f64;
        if chi2 > dof + 3.0 * (2.0 * dof).sqrt() {
            return Level::Piecewise(refs);
        }
        Level::Line {
            t_mean,
            p0,
            p1,
            s1: stt.sqrt().recip(),
        }
    }

    /// g(t) and its standard uncertainty.
    fn at(&self, t: f64) -> (f64, f64) {
        match self {
            Level::Line { t_mean, p0, p1, .. } => (p0 + p1 * (t - t_mean), 0.0),
            Level::Piecewise(m) => interp(m, t, true),
        }
    }

    /// The relative uncertainty of g(t)/g(t_c), t_c the calibrations' time: the
    /// budget's `drift` term. A line's offset cancels in the ratio; its slope's
    /// error does not. Interpolated references carry their own noise.
    fn ratio_rel(&self, t: f64, t_c: f64) -> f64 {
        match self {
            Level::Line { p0, s1, .. } => (t - t_c).abs() * s1 / p0,
            Level::Piecewise(_) => {
                let (g, s) = self.at(t);
                if g > 0.0 { s / g } else { 0.0 }
            }
        }
    }

    /// The relative uncertainty of g at the calibrations' times, shared by every
    /// sample (0 for a line, whose offset cancels).
    fn calibration_rel(&self, times: &[f64]) -> f64 {
        match self {
            Level::Line { .. } => 0.0,
            Level::Piecewise(_) => {
                let n = times.len().max(1) as f64;
                let v: f64 = times
                    .iter()
                    .map(|&t| {
                        let (g, s) = self.at(t);
                        if g > 0.0 { (s / g).powi(2) } else { 0.0 }
                    })
                    .sum();
                (v / n / n).sqrt()
            }
        }
    }

    fn describe(&self) -> String {
        match self {
            Level::Line { .. } => {
                "a line fitted to the drift references (its slope's uncertainty)".into()
            }
            Level::Piecewise(m) => format!(
                "the {} drift references interpolated in time (their noise)",
                m.len()
            ),
        }
    }
}

/// A pair's directions, its (value, budget) per channel as the channels are
/// reduced, and the union of its readings' flags.
type PerPair = (PairDeg, Vec<Option<(f64, [f64; N_TERMS])>>, u32);

/// The incident flux Φ(t) a sample reading is divided by.
enum Flux {
    /// C g(t), g from the drift references.
    Drift { c: f64, level: Level, t_c: f64 },
    /// The calibration readings interpolated in time.
    Interpolated(Vec<Measured>),
    /// One level for the whole run.
    Constant(f64),
}

impl Flux {
    /// Φ at instrument time `t`, the relative uncertainty of its time dependence
    /// (the `drift` term) and, for interpolated calibrations, of the interpolated
    /// calibration itself.
    fn at(&self, t: f64) -> (f64, f64, f64) {
        let rel = |v: f64, s: f64| if v > 0.0 { s / v } else { 0.0 };
        match self {
            Flux::Drift { c, level, t_c } => {
                let (g, _) = level.at(t);
                (c * g, level.ratio_rel(t, *t_c), 0.0)
            }
            Flux::Interpolated(m) => {
                let (v, s) = interp(m, t, false);
                (v, 0.0, rel(v, s))
            }
            Flux::Constant(c) => (*c, 0.0, 0.0),
        }
    }
}

/// The median and the largest of values (0 for none).
fn median_max(mut v: Vec<f64>) -> (f64, f64) {
    if v.is_empty() {
        return (0.0, 0.0);
    }
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[v.len() - 1])
}

/// Reduces a run to BRDF samples.
pub fn reduce(store: &RunStore, opts: &Options) -> Result<Reduction, ReduceError> {
    let path = store.path().display().to_string();
    let missing = |why: String| ReduceError::Missing {
        path: path.clone(),
        why,
    };
    let stored = store.run_meta()?;
    let detector = Detector::of_instrument(&stored.instrument);
    let bandpass = spectral::Bandpass::of_instrument(&stored.instrument);
    let isotropic = gonio_plan::Plan::from_toml(&stored.plan, None)
        .is_ok_and(|p| matches!(p.points, gonio_plan::plan::Points::Isotropic { .. }));
    let geo = &stored.geometry;
    let omega = Aperture {
        radius_m: geo.detector_radius_m,
        distance_m: geo.detector_distance_m,
    }
    .solid_angle_sr();
    let steps = store.steps()?;
    let readings = store.readings()?;
    let groups = Grouped::new(&steps, &readings);
    let noise = Noise::of_run(&groups.kept(opts.reject_flags), opts, detector);
    // Readings kept although they reached the plan's time cap before their target.
    let capped = groups.capped(opts.reject_flags);
    let channel_names = groups.channel_names();
    let channels = group::channels(&channel_names).map_err(&missing)?;
    let standard = match &stored.standard_model {
        Some(t) => Some(
            gonio_brdf::Model::from_toml(t, None)
                .map_err(|e| missing(format!("stored reference standard model: {e}")))?,
        ),
        None => None,
    };
    let of = |kind: StepKind, ch: &Option<String>| groups.of(kind, ch);

    let mut rejected: BTreeMap<String, usize> = BTreeMap::new();
    let mut max_pos = 0.0f64;
    let mut reports = Vec::new();
    // Per pair and repeat, the value per channel.
    let mut values: BTreeMap<(usize, u32), PerPair> = BTreeMap::new();
    let nc = channels.len();
    for (ci, ch) in channel_names.iter().enumerate() {
        let name = channels.name(ci);
        let darks = of(StepKind::Dark, ch);
        let dark = if darks.is_empty() {
            [0.0, 0.0]
        } else {
            let n = darks.len() as f64;
            [
                darks.iter().map(|(_, r)| r.x_mean).sum::<f64>() / n,
                darks.iter().map(|(_, r)| r.y_mean).sum::<f64>() / n,
            ]
        };
        // The σ of each component of the dark vector's mean.
        let dark_sigma = if darks.is_empty() {
            0.0
        } else {
            darks
                .iter()
                .map(|(_, r)| noise.sigma_mean(r, true).powi(2))
                .sum::<f64>()
                .sqrt()
                / darks.len() as f64
        };
        // A DC dark is a scalar, the mean of the dark currents (the y components
        // are 0), and its range-accuracy error per range: the mean of the dark
        // readings' errors, each on its own range.
        let mut dark_acc = [0.0f64; RANGES];
        if detector == Detector::Dc {
            for (_, r) in &darks {
                let (k, u) = range_sigma(r).ok_or_else(|| {
                    missing(format!(
                        "step {}: range index {} is not a 6485 range",
                        r.step_id, r.sensitivity
                    ))
                })?;
                dark_acc[k] += u / darks.len() as f64;
            }
        }
        // The signal, its noise σ, its unit vector (the direction a dark error
        // moves it in) and its relative resolution. A DC signal is the mean
        // current less the dark, signed: a dark error moves it along +1.
        let signal = |r: &ReadingRecord| match detector {
            Detector::LockIn => {
                let (x, y) = (r.x_mean - dark[0], r.y_mean - dark[1]);
                let s = x.hypot(y);
                let u = if s > 0.0 { [x / s, y / s] } else { [1.0, 0.0] };
                (s, noise.sigma_mean(r, false), u, resolution_rel(s))
            }
            Detector::Dc => {
                let v = r.x_mean - dark[0];
                (
                    v,
                    noise.sigma_mean(r, false),
                    [1.0, 0.0],
                    dc_resolution_rel(r.x_mean, v),
                )
            }
        };
        // A reading's range-accuracy error relative to its signal, per range.
        let range_rel = |r: &ReadingRecord, v: f64| -> Result<[f64; RANGES], ReduceError> {
            let mut out = [0.0; RANGES];
            if detector == Detector::Dc && v > 0.0 {
                let (k, u) = range_sigma(r).ok_or_else(|| {
                    missing(format!(
                        "step {}: range index {} is not a 6485 range",
                        r.step_id, r.sensitivity
                    ))
                })?;
                out[k] = u / v;
            }
            Ok(out)
        };
        let incident = of(StepKind::Incident, ch);
        let standard_readings = of(StepKind::Standard, ch);
        let use_standard = match opts.calibration {
            Calibration::Incident => false,
            Calibration::Standard => true,
            Calibration::Auto => incident.is_empty(),
        };
        let mut cal: Vec<Measured> = Vec::new();
        // The calibration signals' dark sensitivity: Σ u/S over the readings.
        let mut cal_dark = [0.0f64; 2];
        let mut cal_res = 0.0f64;
        // The calibration signals' range-accuracy sensitivity: Σ e/S per range.
        let mut cal_acc = [0.0f64; RANGES];
        if use_standard {
            let model = standard.as_ref().ok_or_else(|| {
                missing(format!("channel {name}: no reference standard in the run"))
            })?;
            let mc = gonio_brdf::Brdf::channels(model);
            let mut out = vec![0.0; mc.len()];
            for (s, r) in &standard_readings {
                let Some(p) = s.step.pair else { continue };
                let d = p.to_dirs();
                gonio_brdf::Brdf::eval(model, d.wi, d.wo, &mut out);
                // An unnamed channel takes a spectrally flat standard's one value.
                let idx = match mc.index_of(&name).or((mc.len() == 1).then_some(0)) {
                    Some(i) => i,
                    None if ch.is_none() && out.iter().all(|v| *v == out[0]) => 0,
                    None => {
                        return Err(missing(format!(
                            "channel {name}: the standard's model has no such channel"
                        )));
                    }
                };
                let k = out[idx] * omega * d.wo.z;
                if k > 0.0 {
                    let (v, sv, u, res) = signal(r);
                    cal.push(Measured {
                        t: groups.time_of(r),
                        v: v / k,
                        s: sv / k,
                    });
                    if v > 0.0 {
                        cal_dark[0] += u[0] / v;
                        cal_dark[1] += u[1] / v;
                    }
                    cal_res += res.powi(2);
                    for (a, e) in cal_acc.iter_mut().zip(range_rel(r, v)?) {
                        *a += e;
                    }
                }
            }
        } else {
            for (_, r) in &incident {
                let (v, sv, u, res) = signal(r);
                cal.push(Measured {
                    t: groups.time_of(r),
                    v: v / stored.transmittance,
                    s: sv / stored.transmittance,
                });
                if v > 0.0 {
                    cal_dark[0] += u[0] / v;
                    cal_dark[1] += u[1] / v;
                }
                cal_res += res.powi(2);
                for (a, e) in cal_acc.iter_mut().zip(range_rel(r, v)?) {
                    *a += e;
                }
            }
        }
        if cal.is_empty() {
            return Err(missing(format!(
                "channel {name}: no {} reading to calibrate with",
                if use_standard {
                    "reference-standard"
                } else {
                    "incident-beam"
                }
            )));
        }
        let ncal = cal.len() as f64;
        let cal_dark = [cal_dark[0] / ncal, cal_dark[1] / ncal];
        let cal_res = cal_res.sqrt() / ncal;
        // The calibration's relative range-accuracy error per range: its readings'
        // own (a plain mean over them, as for the dark) less the dark's, which moves
        // every calibration signal by −e_dark.
        let cal_acc: [f64; RANGES] =
            std::array::from_fn(|k| cal_acc[k] / ncal - dark_acc[k] * cal_dark[0]);
        cal.sort_by(|a, b| a.t.total_cmp(&b.t));
        let mut refs: Vec<Measured> = if opts.drift == Drift::Auto {
            of(StepKind::Reference, ch)
                .iter()
                .map(|(_, r)| {
                    let (v, s, _, _) = signal(r);
                    Measured {
                        t: groups.time_of(r),
                        v,
                        s,
                    }
                })
                .filter(|m| m.v > 0.0)
                .collect()
        } else {
            Vec::new()
        };
        refs.sort_by(|a, b| a.t.total_cmp(&b.t));
        // Normalise g to its mean so that C is in volts at the run's mean level.
        if !refs.is_empty() {
            let mean = refs.iter().map(|m| m.v).sum::<f64>() / refs.len() as f64;
            for m in &mut refs {
                m.v /= mean;
                m.s /= mean;
            }
        }
        let drift_max = refs.iter().map(|m| (m.v - 1.0).abs()).fold(0.0, f64::max);
        let n_refs = refs.len();
        // Φ(t), C, the calibration's relative uncertainty, and how drift is followed.
        let (flux, c_mean, c_rel, drift_source) = if refs.is_empty() {
            let (c, cs) = weighted_mean(&cal);
            let spread =
                opts.drift != Drift::None && cal.iter().any(|m| (m.t - cal[0].t).abs() > 1.0);
            if spread {
                (
                    Flux::Interpolated(cal.clone()),
                    c,
                    0.0,
                    "none: the calibrations, interpolated in time, follow the source".to_string(),
                )
            } else {
                (
                    Flux::Constant(c),
                    c,
                    if c > 0.0 { cs / c } else { 0.0 },
                    "none: the source's level is held constant".to_string(),
                )
            }
        } else {
            let level = Level::from_refs(refs);
            let per: Vec<Measured> = cal
                .iter()
                .map(|m| {
                    let (g, _) = level.at(m.t);
                    Measured {
                        t: m.t,
                        v: m.v / g,
                        s: m.s / g,
                    }
                })
                .collect();
            let (c, cs) = weighted_mean(&per);
            let times: Vec<f64> = cal.iter().map(|m| m.t).collect();
            let rel = if c > 0.0 { cs / c } else { 0.0 };
            let rel = rel.hypot(level.calibration_rel(&times));
            let t_c = times.iter().sum::<f64>() / times.len() as f64;
            let source = level.describe();
            (Flux::Drift { c, level, t_c }, c, rel, source)
        };
        if c_mean.is_nan() || c_mean <= 0.0 {
            return Err(missing(format!(
                "channel {name}: the calibration reading is not above the dark"
            )));
        }
        let standard_rel = if use_standard {
            opts.standard_rel_sigma.max(0.0)
        } else {
            0.0
        };
        let mut count = 0;
        let mut rels: [Vec<f64>; N_TERMS] = Default::default();
        for (s, r) in of(StepKind::Sample, ch) {
            let (Some(pair), Some(index)) = (s.step.pair, s.step.plan_index) else {
                continue;
            };
            max_pos = max_pos.max(position_error(&pair, &r.read_pair));
            if r.flags & opts.reject_flags != 0 {
                *rejected
                    .entry(flag_reason(r.flags & opts.reject_flags))
                    .or_default() += 1;
                continue;
            }
            let cos_o = pair.to_dirs().wo.z;
            if cos_o <= 0.0 {
                *rejected.entry("grazing".into()).or_default() += 1;
                continue;
            }
            let (v, sv, u, res) = signal(r);
            let (phi, drift_rel, interp_rel) = flux.at(groups.time_of(r));
            let scale = phi * omega * cos_o;
            let f = v / scale;
            let terms = if v > 0.0 {
                // A dark error d moves S by −u·d and the calibration by −u_c·d: f by
                // f (u_c/S_c − u/S)·d.
                let dk = [cal_dark[0] - u[0] / v, cal_dark[1] - u[1] / v];
                // Each range's error z_k moves f (Eq. A.15 is S/Φ) by the sample's
                // relative error on it less the calibration's, the dark's moving
                // both: on one range, gain errors cancel in the ratio.
                let own = range_rel(r, v)?;
                let acc = (0..RANGES)
                    .map(|k| own[k] - dark_acc[k] / v - cal_acc[k])
                    .map(|c| c * c)
                    .sum::<f64>()
                    .sqrt();
                [
                    sv / v,
                    res,
                    dark_sigma * dk[0].hypot(dk[1]),
                    c_rel.hypot(interp_rel).hypot(cal_res),
                    drift_rel,
                    standard_rel,
                    acc,
                    0.0,
                ]
            } else {
                [
                    sv / scale / f.abs().max(f64::MIN_POSITIVE),
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                    0.0,
                ]
            };
            for (k, t) in terms.iter().enumerate() {
                rels[k].push(*t);
            }
            let abs: [f64; N_TERMS] = if v > 0.0 {
                terms.map(|t| t * f)
            } else {
                [sv / scale, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
            };
            let entry = values
                .entry((index, s.step.repeat))
                .or_insert_with(|| (pair, vec![None; nc], 0));
            entry.1[ci] = Some((f, abs));
            // How a reading was taken is no concern of the sample's.
            entry.2 |= r.flags & !flags::HOW_READ;
            count += 1;
        }
        let standard_source = if use_standard {
            "the reference standard's BRDF (its stated relative uncertainty)".to_string()
        } else {
            "the reference standard: not used (incident-beam calibration)".to_string()
        };
        let calibration_source = format!(
            "the {} calibration reading(s)' noise (scaled by their Birge ratio when they disagree), and the source's level at their time",
            cal.len()
        );
        let capped_note = if capped > 0 {
            format!(
                "; {capped} reading(s) reached the plan's reading.max_s before their target precision (flagged capped) and carry the precision they reached"
            )
        } else {
            String::new()
        };
        let sources: Vec<String> = match detector {
            Detector::Dc => {
                let cal_readings = if use_standard {
                    &standard_readings
                } else {
                    &incident
                };
                let labels = |rs: &[(&StoredStep, &ReadingRecord)]| {
                    ranges_label(rs.iter().map(|(_, r)| r.sensitivity))
                };
                vec![
                    format!(
                        "the picoammeter's noise, {} (a mean of n independent samples: s²/n, ρ = 0)",
                        if noise.lines.is_empty() {
                            "each reading's own sample scatter".to_string()
                        } else {
                            format!(
                                "pooled per range over the run's readings as a + b·I per sample ({}; other settings: their own s)",
                                noise
                                    .lines
                                    .iter()
                                    .map(|((_, range, _), l)| format!(
                                        "{}: a = {:.3e} A², b = {:.3e} A",
                                        ranges_label(std::iter::once(*range)),
                                        l.a,
                                        l.b
                                    ))
                                    .collect::<Vec<_>>()
                                    .join("; ")
                            )
                        }
                    ) + &capped_note,
                    "the 6485's seven-digit replies (step/√12)".into(),
                    format!(
                        "the dark current's noise ({} reading(s), mean {:.3e} A subtracted as a scalar, σ {:.3e} A from s/√n)",
                        darks.len(),
                        dark[0],
                        dark_sigma
                    ),
                    calibration_source,
                    format!("the source's drift: {drift_source}"),
                    standard_source,
                    format!(
                        "the 6485's 1-year accuracy per range (manual App. A, ±(% rdg + offset) A) as a rectangular bound, σ = bound/√3; one error per range: calibration on {}, dark on {}, samples on {}",
                        labels(cal_readings),
                        labels(&darks),
                        labels(&of(StepKind::Sample, ch))
                    ),
                ]
            }
            Detector::LockIn => vec![
                format!(
                    "the lock-in's noise, {} (variance of a mean of correlated snapshots, ρ = e^−(1 + {:.4} s/T))",
                    match noise.lines.values().next() {
                        None => "each reading's own snapshot scatter".to_string(),
                        Some(l) if l.spans_time_constants => format!(
                            "pooled over the run's readings and their time constants as a + b·R per snapshot at T = {} s, a = {:.3e} V², b = {:.3e} V, scaled to each reading's T by the filter's ENBW (∝ 1/T)",
                            gonio_core::limits::num(l.t_ref),
                            l.a,
                            l.b
                        ),
                        Some(l) => format!(
                            "pooled over the run's readings as a + b·R per snapshot, a = {:.3e} V², b = {:.3e} V",
                            l.a, l.b
                        ),
                    },
                    opts.snapshot_gap_s
                ) + &capped_note,
                "the lock-in's six-digit replies (step/√12)".into(),
                format!(
                    "the dark vector's noise ({} reading(s), σ {:.3e} V per component, from half their mean R²)",
                    darks.len(),
                    dark_sigma
                ),
                calibration_source,
                format!("the source's drift: {drift_source}"),
                standard_source,
            ],
        };
        let interpolated = matches!(flux, Flux::Interpolated(_));
        let c_rel = if interpolated {
            // The interpolated calibrations' own uncertainty, as the samples carry it.
            median_max(rels[3].clone()).0
        } else {
            c_rel
        };
        let budget = sources
            .into_iter()
            .enumerate()
            .map(|(k, source)| {
                let (rel_median, rel_max) = median_max(std::mem::take(&mut rels[k]));
                BudgetTerm {
                    term: DC_TERMS[k],
                    source,
                    correlation: DC_CORRELATIONS[k],
                    rel_median,
                    rel_max,
                }
            })
            .collect();
        reports.push(ChannelReport {
            channel: name,
            calibration: if use_standard { "standard" } else { "incident" },
            unit: match detector {
                Detector::LockIn => "V",
                Detector::Dc => "A",
            },
            dark_v: dark,
            incident_v: c_mean,
            incident_rel_sigma: c_rel,
            calibration_readings: cal.len(),
            drift_readings: n_refs,
            drift_max,
            samples: count,
            budget,
        });
    }
    let unmeasured = groups.unmeasured();
    let mut samples = Vec::new();
    let mut budget = Vec::new();
    let mut incomplete = 0;
    for (pair, v, fl) in values.into_values() {
        if v.iter().any(Option::is_none) {
            incomplete += 1;
            continue;
        }
        let (value, mut terms): (Vec<f64>, Vec<[f64; N_TERMS]>) = v.into_iter().flatten().unzip();
        if let (Some(b), Channels::Wavelengths(w)) = (&bandpass, &channels) {
            for (t, x) in terms.iter_mut().zip(b.terms(w, &value)) {
                t[N_TERMS - 1] = x;
            }
        }
        let sigma = terms
            .iter()
            .map(|t| t.iter().map(|x| x * x).sum::<f64>().sqrt())
            .collect();
        samples.push(Sample {
            pair,
            value,
            sigma: Some(sigma),
            flags: fl,
        });
        budget.push(terms);
    }
    if incomplete > 0 {
        rejected.insert("missing-channel".into(), incomplete);
    }
    if let (Some(b), Channels::Wavelengths(w)) = (&bandpass, &channels)
        && w.len() >= 2
    {
        for (c, report) in reports.iter_mut().enumerate() {
            let rels = samples
                .iter()
                .zip(&budget)
                .filter(|(s, _)| s.value[c] > 0.0)
                .map(|(s, t)| t[c][N_TERMS - 1] / s.value[c])
                .collect();
            let (rel_median, rel_max) = median_max(rels);
            report.budget.push(BudgetTerm {
                term: spectral::TERM,
                source: b.source(),
                correlation: spectral::CORRELATION,
                rel_median,
                rel_max,
            });
        }
    }
    if samples.is_empty() {
        return Err(missing("no sample readings to reduce".into()));
    }
    Ok(Reduction {
        samples: Samples {
            channels,
            samples,
            isotropic,
        },
        report: Report {
            channels: reports,
            solid_angle_sr: omega,
            rejected,
            max_position_error_deg: max_pos,
            unmeasured,
            capped,
        },
        budget,
        detector,
    })
}

/// The 6485 ranges of readings, as a list of their labels (`2 µA`, `200 nA`).
fn ranges_label(indices: impl Iterator<Item = u8>) -> String {
    let set: std::collections::BTreeSet<u8> = indices.collect();
    if set.is_empty() {
        return "none".into();
    }
    set.into_iter()
        .map(|k| match gonio_proto::k6485::Range::new(k) {
            Some(r) => r.to_string(),
            None => format!("range {k}"),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

fn position_error(a: &PairDeg, b: &PairDeg) -> f64 {
    let d = |x: gonio_core::SphericalDeg, y: gonio_core::SphericalDeg| {
        gonio_core::Dir::from(x)
            .angle_to(gonio_core::Dir::from(y))
            .to_degrees()
    };
    d(a.incident, b.incident).max(d(a.outgoing, b.outgoing))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disagreeing_readings_scale_the_mean_s_uncertainty_by_the_birge_ratio() {
        let m = |v: f64| Measured { t: 0.0, v, s: 1.0 };
        // Within their noise: 1/√2.
        let (mean, s) = weighted_mean(&[m(0.0), m(1.0)]);
        assert_eq!(mean, 0.5);
        assert!((s - 0.5f64.sqrt()).abs() < 1e-15);
        // 10σ apart: χ² = 50 on one degree of freedom, σ × √50.
        let (_, s) = weighted_mean(&[m(0.0), m(10.0)]);
        assert!((s - 0.5f64.sqrt() * 50f64.sqrt()).abs() < 1e-12, "{s}");
    }

    #[test]
    fn the_picoammeter_s_rounding_is_a_seventh_digit_of_the_raw_reading() {
        // +1.234567E-08A: a step of 1e-14 A, over the signal 1e-8 A.
        let r = dc_resolution_rel(1.234567e-8, 1e-8);
        assert!((r - 1e-14 / 12f64.sqrt() / 1e-8).abs() < 1e-22, "{r}");
        // A negative dark-sized reading rounds on its magnitude.
        let r = dc_resolution_rel(-2.5e-12, 1e-9);
        assert!((r - 1e-18 / 12f64.sqrt() / 1e-9).abs() < 1e-24, "{r}");
        assert_eq!(dc_resolution_rel(0.0, 1e-9), 0.0);
        assert_eq!(dc_resolution_rel(1e-9, -1e-12), 0.0);
    }

    #[test]
    fn the_range_accuracy_is_the_bound_over_root_three() {
        let r = crate::test_support::reading();
        // 200 nA: 0.2 % + 10 pA of 100 nA is 210 pA, /√3.
        let (k, u) = range_sigma(&r).expect("a range");
        assert_eq!(k, 2);
        assert!((u - 210e-12 / 3f64.sqrt()).abs() < 1e-24, "{u}");
        assert!(
            range_sigma(&ReadingRecord {
                sensitivity: 8,
                ..r
            })
            .is_none()
        );
    }

    #[test]
    fn the_reply_rounding_is_a_sixth_digit_over_root_twelve() {
        assert!((resolution_rel(1.5e-3) - 1e-8 / 12f64.sqrt() / 1.5e-3).abs() < 1e-18);
        assert_eq!(resolution_rel(0.0), 0.0);
    }
}

/// What the modules' unit tests share.
#[cfg(test)]
mod test_support {
    use gonio_core::dirfile::PairDeg;
    use gonio_run::ReadingRecord;

    /// A reading of 100 nA on the 6485's 200 nA range (index 2), five samples of
    /// scatter 1 pA, at instrument time 0: the fields a test does not set.
    pub(crate) fn reading() -> ReadingRecord {
        ReadingRecord {
            step_id: 1,
            commanded: None,
            position: [0.0; 4],
            read_pair: PairDeg {
                incident: gonio_core::SphericalDeg::new(0.0, 0.0),
                outgoing: gonio_core::SphericalDeg::new(0.0, 0.0),
            },
            sensitivity: 2,
            sensitivity_v: 2e-7,
            time_constant: 0,
            time_constant_s: 0.1,
            slope_db: 0,
            r_mean: 1e-7,
            r_std: 1e-12,
            x_mean: 1e-7,
            y_mean: 0.0,
            n: 5,
            autorange_steps: 0,
            lias: 0,
            flags: 0,
            retries: 0,
            physical_s: 0.0,
            wall_s: 0.0,
        }
    }
}
