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
//! - `dark`: the dark vector's noise, subtracted from every reading: one error
//!   shared by all samples, larger for weak signals (it is additive). Each dark
//!   reading's σ is the pooled law's at R = 0 (the floor every reading of the run
//!   speaks of), not its own R²'s two degrees of freedom; plans take four dark
//!   readings by default.
//! - `calibration`: the calibration readings' noise (scaled up when they disagree),
//!   and the drift level at the calibrations' time.
//! - `drift`: the uncertainty of g(t) relative to the calibrations' g.
//! - `standard`: the reference standard's own BRDF uncertainty
//!   ([`Options::standard_rel_sigma`]), when the standard calibrates.
//! - `position` ([`POSITION_TERM`]): the read-back directions' offsets from the
//!   nominal ones times the BRDF's slope there, from the neighbouring samples.
//!
//! **Correlations.** The shared terms are taken apart into the independent errors
//! behind them — the dark's components, the calibration scale, the drift line's
//! slope or each drift reference, the standard, each picoammeter range, each
//! wavelength's scale — each with a signed coefficient per sample
//! ([`Reduction::covariance`]), so that the full covariance D + VVᵀ is known;
//! [`agreement`] compares a simulated run with the sample it measured against it.
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
pub mod agreement;
mod assemble;
mod budget;
mod calibration;
mod correlations;
mod dark;
mod drift;
mod group;
mod noise;
mod position;
pub mod spectral;
mod values;

use gonio_core::radiometry::Aperture;
use gonio_plan::StepKind;
use gonio_process::Samples;
pub use gonio_process::reduction::{BudgetTerm, ChannelReport, Report};
use gonio_run::{RunStore, StoreError, flags};
use serde::Serialize;

use calibration::Calibrations;
use dark::Dark;
use drift::IncidentFlux;
use group::Grouped;
use noise::Noise;
pub use noise::variance_factors;
use values::Values;

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
/// wavelength term of a spectral run ([`spectral::TERM`], at [`WAVELENGTH`]; 0 and
/// not reported otherwise), then the position term ([`POSITION_TERM`], at
/// [`POSITION`]).
pub const N_TERMS: usize = 9;

/// The index of the wavelength term in a sample's budget ([`Reduction::budget`]).
pub const WAVELENGTH: usize = 7;

/// The index of the position term in a sample's budget ([`Reduction::budget`]).
pub const POSITION: usize = 8;

/// The position term's name: the error of reporting a sample at its nominal
/// directions when it was read where the stages stood ([`position`](crate)).
pub const POSITION_TERM: &str = "position";

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
    /// The samples' covariance: each one's independent σ and its coefficient on
    /// every error it shares with others ([`gonio_process::covariance`]); per sample
    /// and channel they add in quadrature to its σ.
    pub covariance: gonio_process::covariance::Covariance,
}

/// The run as every step of a channel's reduction reads it: the options, the
/// detector and its geometry, the readings grouped by step, the fitted noise and
/// the stored reference standard.
struct Run<'a> {
    /// The reduction's options.
    opts: &'a Options,
    /// What the readings are.
    detector: Detector,
    /// A spectral run's bandpass (for the wavelength term).
    bandpass: Option<spectral::Bandpass>,
    /// Whether the plan is isotropic (its samples say so).
    isotropic: bool,
    /// The detector's solid angle Ω, sr.
    omega: f64,
    /// The transmittance of the filter in the incident beam.
    transmittance: f64,
    /// The readings that count, by step, with their instrument times.
    groups: Grouped<'a>,
    /// The noise law fitted to the kept readings.
    noise: Noise,
    /// The stored reference standard's model.
    standard: Option<gonio_brdf::Model>,
    /// The readings kept although capped.
    capped: usize,
}

/// Reduces a run to BRDF samples, in steps: the readings grouped by step, the
/// noise law pooled over them, then per channel its dark, its calibration, its
/// incident flux through the run, its samples' values and its report, and last
/// the samples and the report assembled (the crate's modules `group`, `noise`,
/// `dark`, `calibration`, `drift`, `values`, `budget` and `assemble`).
pub fn reduce(store: &RunStore, opts: &Options) -> Result<Reduction, ReduceError> {
    let path = store.path().display().to_string();
    let missing = |why: String| ReduceError::Missing {
        path: path.clone(),
        why,
    };
    let stored = store.run_meta()?;
    let detector = Detector::of_instrument(&stored.instrument);
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
    let capped = groups.capped(opts.reject_flags);
    let names = groups.channel_names();
    let channels = group::channels(&names).map_err(&missing)?;
    let standard =
        calibration::standard_model(stored.standard_model.as_deref()).map_err(&missing)?;
    let run = Run {
        opts,
        detector,
        bandpass: spectral::Bandpass::of_instrument(&stored.instrument),
        isotropic,
        omega,
        transmittance: stored.transmittance,
        groups,
        noise,
        standard,
        capped,
    };
    let mut values = Values::new(channels.len());
    let mut reports = Vec::new();
    for (ci, ch) in names.iter().enumerate() {
        let report = channel(&run, ci, ch, channels.name(ci), &mut values);
        reports.push(report.map_err(&missing)?);
    }
    assemble::reduction(&run, channels, values, reports).map_err(missing)
}

/// Reduces the channel `ch` (index `ci`, named `name`): its dark, its calibration,
/// the incident flux through the run, its samples' values (into `values`), and
/// its report. `Err` says what the channel lacks.
fn channel(
    run: &Run,
    ci: usize,
    ch: &Option<String>,
    name: String,
    values: &mut Values,
) -> Result<ChannelReport, String> {
    let dark = Dark::of(run.groups.of(StepKind::Dark, ch), &run.noise, run.detector)?;
    let cal = Calibrations::of(run, ch, &name, &dark)?;
    let flux = IncidentFlux::of(run, ch, &name, &dark, &cal.measured)?;
    let samples = run.groups.of(StepKind::Sample, ch);
    let reduced = values.add(
        run,
        &samples,
        &values::Channel {
            ci,
            dark: &dark,
            cal: &cal,
            flux: &flux,
            standard_rel: cal.standard_rel(run.opts),
        },
    )?;
    Ok(budget::report(
        run,
        budget::Channel {
            name,
            use_standard: cal.use_standard,
            darks: &dark.readings,
            dark: dark.xy,
            dark_sigma: dark.sigma,
            calibrations: &cal.readings,
            n_cal: cal.measured.len(),
            samples: &samples,
            drift_source: &flux.source,
            interpolated: flux.interpolated(),
            c_mean: flux.c,
            c_rel: flux.c_rel,
            n_refs: flux.n_refs,
            drift_max: flux.drift_max,
            count: reduced.count,
            rels: reduced.rels,
        },
    ))
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
