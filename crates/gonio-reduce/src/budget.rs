//! The uncertainty budget's terms: a reading's own (the reply rounding,
//! [`resolution_rel`] and [`dc_resolution_rel`]; a picoammeter's range accuracy,
//! [`range_sigma`] and [`range_rel`]), and a channel's report of them
//! ([`report`]): per term of [`DC_TERMS`] the source the reduction took it from,
//! how it is shared between samples ([`DC_CORRELATIONS`]), and its median and
//! largest value relative to the samples' f ([`median_max`]).
//!
//! The report is assembled from a plain record of what the channel's steps found
//! ([`Channel`]): the steps use this module's reading terms, so it cannot use
//! theirs without an import loop.

use gonio_process::reduction::{BudgetTerm, ChannelReport};
use gonio_run::ReadingRecord;

use crate::group::Read;
use crate::noise::Noise;
use crate::{DC_CORRELATIONS, DC_TERMS, Detector, N_TERMS, Run};

/// The 6485's ranges (2 nA … 20 mA), the range-accuracy coefficients' length.
pub(crate) const RANGES: usize = gonio_proto::k6485::Range::COUNT as usize;

/// The lock-in's reply rounding, relative: six significant digits, a step of
/// 10^(⌊log₁₀ v⌋ − 5), uniformly distributed (σ = step/√12). Not averaged down by
/// the snapshots: without noise they all round alike.
pub(crate) fn resolution_rel(v: f64) -> f64 {
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
pub(crate) fn dc_resolution_rel(i: f64, v: f64) -> f64 {
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
pub(crate) fn range_sigma(r: &ReadingRecord) -> Option<(usize, f64)> {
    let range = gonio_proto::k6485::Range::new(r.sensitivity)?;
    let bound = gonio_proto::k6485::accuracy_a(range, r.x_mean);
    Some((usize::from(r.sensitivity), bound / 3f64.sqrt()))
}

/// [`range_sigma`], or why the reduction stops: a DC reading on a range the 6485
/// has not cannot be given its accuracy.
pub(crate) fn range_of(r: &ReadingRecord) -> Result<(usize, f64), String> {
    range_sigma(r).ok_or_else(|| {
        format!(
            "step {}: range index {} is not a 6485 range",
            r.step_id, r.sensitivity
        )
    })
}

/// A reading's range-accuracy error relative to its signal `v`, per range: its
/// range's σ over `v` (0 elsewhere, and everywhere for a lock-in or a signal not
/// above 0).
pub(crate) fn range_rel(
    r: &ReadingRecord,
    v: f64,
    detector: Detector,
) -> Result<[f64; RANGES], String> {
    let mut out = [0.0; RANGES];
    if detector == Detector::Dc && v > 0.0 {
        let (k, u) = range_of(r)?;
        out[k] = u / v;
    }
    Ok(out)
}

/// The median and the largest of values (0 for none).
pub(crate) fn median_max(mut v: Vec<f64>) -> (f64, f64) {
    if v.is_empty() {
        return (0.0, 0.0);
    }
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[v.len() - 1])
}

/// The 6485 ranges of readings, as a list of their labels (`2 µA`, `200 nA`).
pub(crate) fn ranges_label(indices: impl Iterator<Item = u8>) -> String {
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

/// What a channel's steps found, as its report states it.
pub(crate) struct Channel<'a> {
    /// The channel's name.
    pub name: String,
    /// Whether the reference standard calibrates (else the incident beam).
    pub use_standard: bool,
    /// The dark readings.
    pub darks: &'a [Read<'a>],
    /// The dark subtracted: a lock-in's vector (X, Y), a picoammeter's [I, 0].
    pub dark: [f64; 2],
    /// The σ of each component of the dark's mean.
    pub dark_sigma: f64,
    /// The readings of the calibration used (their ranges are reported).
    pub calibrations: &'a [Read<'a>],
    /// How many of them estimated the incident flux.
    pub n_cal: usize,
    /// The channel's sample readings, rejected ones too (their ranges).
    pub samples: &'a [Read<'a>],
    /// How the source's level is followed (the `drift` term's source).
    pub drift_source: &'a str,
    /// Whether the calibrations are interpolated in time (their uncertainty then
    /// differs from sample to sample).
    pub interpolated: bool,
    /// The incident flux C at the run's mean level.
    pub c_mean: f64,
    /// C's relative standard uncertainty.
    pub c_rel: f64,
    /// The drift references used.
    pub n_refs: usize,
    /// The references' largest relative departure from their mean.
    pub drift_max: f64,
    /// The samples reduced.
    pub count: usize,
    /// Per term, each reduced sample's σ relative to its f.
    pub rels: [Vec<f64>; N_TERMS],
}

/// The channel's report: its calibration, dark and drift, and per term of its
/// detector's budget the source, the correlation and the relative σ's median and
/// largest value.
pub(crate) fn report(run: &Run, mut c: Channel) -> ChannelReport {
    let sources = match run.detector {
        Detector::Dc => dc_sources(run, &c),
        Detector::LockIn => lockin_sources(run, &c),
    };
    let c_rel = if c.interpolated {
        // The interpolated calibrations' own uncertainty, as the samples carry it.
        median_max(c.rels[3].clone()).0
    } else {
        c.c_rel
    };
    let budget = sources
        .into_iter()
        .enumerate()
        .map(|(k, source)| {
            let (rel_median, rel_max) = median_max(std::mem::take(&mut c.rels[k]));
            BudgetTerm {
                term: DC_TERMS[k],
                source,
                correlation: DC_CORRELATIONS[k],
                rel_median,
                rel_max,
            }
        })
        .collect();
    ChannelReport {
        channel: c.name,
        calibration: if c.use_standard {
            "standard"
        } else {
            "incident"
        },
        unit: match run.detector {
            Detector::LockIn => "V",
            Detector::Dc => "A",
        },
        dark_v: c.dark,
        incident_v: c.c_mean,
        incident_rel_sigma: c_rel,
        calibration_readings: c.n_cal,
        drift_readings: c.n_refs,
        drift_max: c.drift_max,
        samples: c.count,
        budget,
    }
}

/// The sources of the terms both detectors' budgets share: `calibration`,
/// `drift` and `standard`.
fn shared_sources(c: &Channel) -> [String; 3] {
    let calibration = format!(
        "the {} calibration reading(s)' noise (scaled by their Birge ratio when they disagree), and the source's level at their time",
        c.n_cal
    );
    let standard = if c.use_standard {
        "the reference standard's BRDF (its stated relative uncertainty)".to_string()
    } else {
        "the reference standard: not used (incident-beam calibration)".to_string()
    };
    [
        calibration,
        format!("the source's drift: {}", c.drift_source),
        standard,
    ]
}

/// What the noise term's source adds when readings were capped.
fn capped_note(capped: usize) -> String {
    if capped > 0 {
        format!(
            "; {capped} reading(s) reached the plan's reading.max_s before their target precision (flagged capped) and carry the precision they reached"
        )
    } else {
        String::new()
    }
}

/// The sources of a lock-in run's terms, [`crate::TERMS`].
fn lockin_sources(run: &Run, c: &Channel) -> Vec<String> {
    let [calibration, drift, standard] = shared_sources(c);
    vec![
        format!(
            "the lock-in's noise, {} (variance of a mean of correlated snapshots, ρ = e^−(1 + {:.4} s/T))",
            lockin_noise(&run.noise),
            run.opts.snapshot_gap_s
        ) + &capped_note(run.capped),
        "the lock-in's six-digit replies (step/√12)".into(),
        format!(
            "the dark vector's noise ({} reading(s), σ {:.3e} V per component, {})",
            c.darks.len(),
            c.dark_sigma,
            if run.noise.lines.is_empty() {
                "from half their mean R²"
            } else {
                "from the pooled noise law at R = 0"
            }
        ),
        calibration,
        drift,
        standard,
    ]
}

/// How a lock-in run's noise was taken: the pooled line of its first slope, or
/// each reading's own scatter.
fn lockin_noise(noise: &Noise) -> String {
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
    }
}

/// The sources of a DC run's terms, [`DC_TERMS`].
fn dc_sources(run: &Run, c: &Channel) -> Vec<String> {
    let [calibration, drift, standard] = shared_sources(c);
    let labels = |rs: &[Read]| ranges_label(rs.iter().map(|(_, r)| r.sensitivity));
    vec![
        format!(
            "the picoammeter's noise, {} (a mean of n independent samples: s²/n, ρ = 0)",
            dc_noise(&run.noise)
        ) + &capped_note(run.capped),
        "the 6485's seven-digit replies (step/√12)".into(),
        format!(
            "the dark current's noise ({} reading(s), mean {:.3e} A subtracted as a scalar, σ {:.3e} A from {})",
            c.darks.len(),
            c.dark[0],
            c.dark_sigma,
            if run.noise.lines.is_empty() {
                "s/√n"
            } else {
                "the pooled noise law where its setting has one, else s/√n"
            }
        ),
        calibration,
        drift,
        standard,
        format!(
            "the 6485's 1-year accuracy per range (manual App. A, ±(% rdg + offset) A) as a rectangular bound, σ = bound/√3; one error per range: calibration on {}, dark on {}, samples on {}",
            labels(c.calibrations),
            labels(c.darks),
            labels(c.samples)
        ),
    ]
}

/// How a DC run's noise was taken: its pooled lines, per range, or each reading's
/// own scatter.
fn dc_noise(noise: &Noise) -> String {
    if noise.lines.is_empty() {
        return "each reading's own sample scatter".to_string();
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::reading;

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
        let r = reading();
        // 200 nA: 0.2 % + 10 pA of 100 nA is 210 pA, /√3.
        let (k, u) = range_sigma(&r).expect("a range");
        assert_eq!(k, 2);
        assert!((u - 210e-12 / 3f64.sqrt()).abs() < 1e-24, "{u}");
        let beyond = ReadingRecord {
            sensitivity: 8,
            ..r
        };
        assert!(range_sigma(&beyond).is_none());
        assert_eq!(
            range_of(&beyond),
            Err("step 1: range index 8 is not a 6485 range".to_string())
        );
    }

    /// Relative to the signal, on the reading's own range only, and only for a
    /// picoammeter's signal above 0.
    #[test]
    fn a_reading_s_range_error_is_its_range_s_sigma_over_the_signal() {
        let r = reading();
        let rel = range_rel(&r, 5e-8, Detector::Dc).expect("a range");
        let (_, u) = range_sigma(&r).expect("a range");
        assert_eq!(rel[2], u / 5e-8);
        assert_eq!(rel.iter().filter(|x| **x != 0.0).count(), 1);
        assert_eq!(range_rel(&r, 5e-8, Detector::LockIn), Ok([0.0; RANGES]));
        assert_eq!(range_rel(&r, 0.0, Detector::Dc), Ok([0.0; RANGES]));
    }

    #[test]
    fn the_reply_rounding_is_a_sixth_digit_over_root_twelve() {
        assert!((resolution_rel(1.5e-3) - 1e-8 / 12f64.sqrt() / 1.5e-3).abs() < 1e-18);
        assert_eq!(resolution_rel(0.0), 0.0);
    }

    #[test]
    fn the_median_is_the_upper_middle_value() {
        assert_eq!(median_max(vec![]), (0.0, 0.0));
        assert_eq!(median_max(vec![3.0, 1.0, 2.0]), (2.0, 3.0));
        assert_eq!(median_max(vec![4.0, 1.0, 3.0, 2.0]), (3.0, 4.0));
    }

    #[test]
    fn ranges_are_listed_once_each_by_their_labels() {
        assert_eq!(ranges_label(std::iter::empty()), "none");
        let label = ranges_label([2u8, 0, 2].into_iter());
        assert_eq!(label.matches(", ").count(), 1, "{label}");
        assert!(ranges_label(std::iter::once(9)).contains("range 9"));
    }
}
