//! The calibration: a channel's estimates of the incident flux Φ, one per
//! calibration reading ([`Calibrations::of`]), with what the samples' budget needs
//! of them — how a dark error, the reply rounding and the range accuracy move
//! them.
//!
//! Either calibration estimates the same Φ: the incident-beam reading divided by
//! the transmittance T of the filter in the beam during it, or the reference
//! standard's reading divided by its known BRDF, the detector's solid angle and
//! the projection cos θo (Eq. A.15 solved for the incident flux). Which one is
//! used is the choice of [`Options::calibration`](crate::Options::calibration)
//! ([`uses_standard`]). Their values are combined by [`weighted_mean`].

use gonio_plan::StepKind;
use gonio_run::ReadingRecord;

use crate::budget::{self, RANGES};
use crate::dark::{Dark, Signal};
use crate::group::Read;
use crate::{Calibration, Detector, Options, Run};

/// A value with its standard uncertainty, at an instrument time.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Measured {
    /// The instrument time, s.
    pub t: f64,
    /// The value.
    pub v: f64,
    /// Its standard uncertainty.
    pub s: f64,
}

/// A channel's calibration.
pub(crate) struct Calibrations<'a> {
    /// Whether the reference standard calibrates (else the incident beam).
    pub use_standard: bool,
    /// The channel's readings of the calibration used.
    pub readings: Vec<Read<'a>>,
    /// The estimates of Φ, sorted by time.
    pub measured: Vec<Measured>,
    /// The calibration signals' dark sensitivity: the mean of u/S over them.
    pub dark: [f64; 2],
    /// Their reply rounding, relative: the root of the sum of squares over their
    /// count.
    pub res: f64,
    /// Their relative range-accuracy error per range, the dark's included.
    pub acc: [f64; RANGES],
}

/// The reference standard's model a run stores, parsed (`None` without one).
pub(crate) fn standard_model(text: Option<&str>) -> Result<Option<gonio_brdf::Model>, String> {
    text.map(|t| {
        gonio_brdf::Model::from_toml(t, None)
            .map_err(|e| format!("stored reference standard model: {e}"))
    })
    .transpose()
}

/// Whether the standard calibrates: as asked, or with [`Calibration::Auto`] when
/// the channel has no incident-beam reading.
pub(crate) fn uses_standard(choice: Calibration, has_incident: bool) -> bool {
    match choice {
        Calibration::Incident => false,
        Calibration::Standard => true,
        Calibration::Auto => !has_incident,
    }
}

impl<'a> Calibrations<'a> {
    /// The calibration of the channel `ch` (named `name`), its signals less
    /// `dark`. `Err` when the calibration asked for has no reading, or the
    /// standard's model no value for the channel.
    pub(crate) fn of(
        run: &Run<'a>,
        ch: &Option<String>,
        name: &str,
        dark: &Dark,
    ) -> Result<Calibrations<'a>, String> {
        let incident = run.groups.of(StepKind::Incident, ch);
        let standard = run.groups.of(StepKind::Standard, ch);
        let use_standard = uses_standard(run.opts.calibration, !incident.is_empty());
        let (readings, sums) = if use_standard {
            let sums = from_standard(run, &standard, ch, name, dark)?;
            (standard, sums)
        } else {
            let sums = from_incident(run, &incident, dark)?;
            (incident, sums)
        };
        if sums.measured.is_empty() {
            return Err(format!(
                "channel {name}: no {} reading to calibrate with",
                if use_standard {
                    "reference-standard"
                } else {
                    "incident-beam"
                }
            ));
        }
        Ok(sums.finish(use_standard, readings, &dark.acc))
    }

    /// The budget's `standard` term, relative: the standard's stated uncertainty
    /// when it calibrates.
    pub(crate) fn standard_rel(&self, opts: &Options) -> f64 {
        if self.use_standard {
            opts.standard_rel_sigma.max(0.0)
        } else {
            0.0
        }
    }
}

/// The estimates of Φ from the standard's readings: each signal over the
/// standard's f_std Ω cos θo at the reading's pair.
fn from_standard(
    run: &Run,
    readings: &[Read],
    ch: &Option<String>,
    name: &str,
    dark: &Dark,
) -> Result<Sums, String> {
    let model = run
        .standard
        .as_ref()
        .ok_or_else(|| format!("channel {name}: no reference standard in the run"))?;
    let mc = gonio_brdf::Brdf::channels(model);
    let mut out = vec![0.0; mc.len()];
    let mut sums = Sums::default();
    for (s, r) in readings {
        let Some(p) = s.step.pair else { continue };
        let d = p.to_dirs();
        gonio_brdf::Brdf::eval(model, d.wi, d.wo, &mut out);
        // An unnamed channel takes a spectrally flat standard's one value.
        let idx = match mc.index_of(name).or((mc.len() == 1).then_some(0)) {
            Some(i) => i,
            None if ch.is_none() && out.iter().all(|v| *v == out[0]) => 0,
            None => {
                return Err(format!(
                    "channel {name}: the standard's model has no such channel"
                ));
            }
        };
        let k = out[idx] * run.omega * d.wo.z;
        if k > 0.0 {
            let sig = dark.signal(r, &run.noise);
            sums.add(run.groups.time_of(r), k, &sig, r, run.detector)?;
        }
    }
    Ok(sums)
}

/// The estimates of Φ from the incident-beam readings: each signal over the
/// transmittance of the filter in the beam.
fn from_incident(run: &Run, readings: &[Read], dark: &Dark) -> Result<Sums, String> {
    let mut sums = Sums::default();
    for (_, r) in readings {
        let sig = dark.signal(r, &run.noise);
        sums.add(
            run.groups.time_of(r),
            run.transmittance,
            &sig,
            r,
            run.detector,
        )?;
    }
    Ok(sums)
}

/// The calibration readings' estimates as they are gathered, with the sums of
/// their sensitivities.
#[derive(Default)]
struct Sums {
    /// The estimates of Φ, in reading order.
    measured: Vec<Measured>,
    /// Σ u/S over the readings.
    dark: [f64; 2],
    /// Σ of the squared relative reply rounding.
    res: f64,
    /// Σ of the relative range-accuracy errors, per range.
    acc: [f64; RANGES],
}

impl Sums {
    /// Adds a reading at instrument time `t` whose signal `sig` estimates Φ as
    /// S/`k`.
    fn add(
        &mut self,
        t: f64,
        k: f64,
        sig: &Signal,
        r: &ReadingRecord,
        detector: Detector,
    ) -> Result<(), String> {
        let v = sig.v;
        self.measured.push(Measured {
            t,
            v: v / k,
            s: sig.sigma / k,
        });
        if v > 0.0 {
            self.dark[0] += sig.u[0] / v;
            self.dark[1] += sig.u[1] / v;
        }
        self.res += sig.res.powi(2);
        for (a, e) in self.acc.iter_mut().zip(budget::range_rel(r, v, detector)?) {
            *a += e;
        }
        Ok(())
    }

    /// The sums as means over the estimates (at least one), sorted by time.
    fn finish<'a>(
        mut self,
        use_standard: bool,
        readings: Vec<Read<'a>>,
        dark_acc: &[f64; RANGES],
    ) -> Calibrations<'a> {
        let ncal = self.measured.len() as f64;
        let dark = [self.dark[0] / ncal, self.dark[1] / ncal];
        let res = self.res.sqrt() / ncal;
        // The calibration's relative range-accuracy error per range: its readings'
        // own (a plain mean over them, as for the dark) less the dark's, which moves
        // every calibration signal by −e_dark.
        let acc: [f64; RANGES] =
            std::array::from_fn(|k| self.acc[k] / ncal - dark_acc[k] * dark[0]);
        self.measured.sort_by(|a, b| a.t.total_cmp(&b.t));
        Calibrations {
            use_standard,
            readings,
            measured: self.measured,
            dark,
            res,
            acc,
        }
    }
}

/// Inverse-variance mean of values, with its uncertainty, scaled by the Birge ratio
/// √(χ²/(n − 1)) when the values disagree beyond their noise (χ² more than three
/// standard deviations above n − 1): the scatter of two or three readings is too
/// uncertain to replace their noise unless it is significant. Without
/// uncertainties (any of them 0), the plain mean and its scatter's standard error.
pub(crate) fn weighted_mean(m: &[Measured]) -> (f64, f64) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::reading;

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

    /// Weights 1/σ²: 4 and 1 (σ ½ and 1) put the mean at (4·1 + 1·2)/5 = 1.2, of
    /// σ 1/√5. Without uncertainties, the plain mean and the standard error of its
    /// scatter.
    #[test]
    fn the_mean_weighs_by_inverse_variance_and_falls_back_to_the_plain_mean() {
        let m = |v: f64, s: f64| Measured { t: 0.0, v, s };
        let (mean, s) = weighted_mean(&[m(1.0, 0.5), m(2.0, 1.0)]);
        assert!((mean - 1.2).abs() < 1e-15 && (s - 0.2f64.sqrt()).abs() < 1e-15);
        let (mean, s) = weighted_mean(&[m(1.0, 0.0), m(3.0, 1.0)]);
        // Scatter √2 about 2, over √2: 1.
        assert_eq!((mean, s), (2.0, 1.0));
        assert_eq!(weighted_mean(&[m(4.0, 0.0)]), (4.0, 0.0));
        assert_eq!(weighted_mean(&[m(4.0, 2.0)]), (4.0, 2.0));
    }

    #[test]
    fn auto_calibrates_by_the_incident_beam_where_the_channel_has_one() {
        assert!(!uses_standard(Calibration::Auto, true));
        assert!(uses_standard(Calibration::Auto, false));
        assert!(uses_standard(Calibration::Standard, true));
        assert!(!uses_standard(Calibration::Incident, false));
    }

    /// Two readings: the dark sensitivity is the mean of u/S, the rounding
    /// √(Σ res²)/n, and the estimates come out sorted by time.
    #[test]
    fn the_sensitivities_are_means_over_the_calibration_readings() {
        let r = reading();
        let sig = |v: f64, u: [f64; 2], res: f64| Signal {
            v,
            sigma: 0.1,
            u,
            res,
        };
        let mut sums = Sums::default();
        sums.add(5.0, 2.0, &sig(2.0, [1.0, 0.0], 0.3), &r, Detector::LockIn)
            .expect("adds");
        sums.add(1.0, 2.0, &sig(4.0, [0.0, 1.0], 0.4), &r, Detector::LockIn)
            .expect("adds");
        let cal = sums.finish(false, Vec::new(), &[0.0; RANGES]);
        assert_eq!(cal.dark, [0.25, 0.125]);
        assert!((cal.res - 0.25).abs() < 1e-15);
        assert_eq!(cal.acc, [0.0; RANGES]);
        let t: Vec<(f64, f64, f64)> = cal.measured.iter().map(|m| (m.t, m.v, m.s)).collect();
        assert_eq!(t, [(1.0, 2.0, 0.05), (5.0, 1.0, 0.05)]);
    }

    #[test]
    fn a_run_without_a_standard_has_no_model() {
        assert!(matches!(standard_model(None), Ok(None)));
        let e = standard_model(Some("kind = \"no such kind\"")).expect_err("refused");
        assert!(e.starts_with("stored reference standard model: "), "{e}");
    }
}
