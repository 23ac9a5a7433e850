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
//! define the source's relative level g(t), linear in instrument time between them
//! (and continued along the first and last segments beyond them). Every calibration
//! reading k then estimates the same constant C = Φ_k / g(t_k); their inverse-variance
//! mean C gives Φ(t) = C g(t) for every sample. Without references, calibrations repeated at the end of the run
//! are interpolated linearly in time instead; a single calibration is held constant.
//!
//! **Uncertainty.** A reading's mean has variance c·σ_R²/n, with c = 2.2 because
//! samples taken one time constant apart correlate (e^−1) — the factor the lock-in's
//! sampling in `gonio-driver` is set up for. Relative uncertainties of the signal, of
//! Φ (the calibrations' scatter) and of g(t) add in quadrature; the calibration's
//! share is common to all samples (a systematic) and is also reported on its own.

use std::collections::BTreeMap;

use gonio_core::Channels;
use gonio_core::dirfile::PairDeg;
use gonio_core::radiometry::Aperture;
use gonio_plan::StepKind;
pub use gonio_process::reduction::{ChannelReport, Report};
use gonio_process::{Sample, Samples};
use gonio_run::{ReadingRecord, RunStore, StoreError, StoredStep, flags};
use serde::Serialize;

/// The variance factor of a lock-in mean over samples one time constant apart.
pub const CORRELATION_FACTOR: f64 = 2.2;

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
}

/// A value with its standard uncertainty.
#[derive(Clone, Copy, Debug)]
struct Measured {
    t: f64,
    v: f64,
    s: f64,
}

fn mean_sigma(r: &ReadingRecord) -> f64 {
    r.r_std * (CORRELATION_FACTOR / f64::from(r.n.max(1))).sqrt()
}

/// Inverse-variance mean of values (plain mean when any uncertainty is 0), with its
/// uncertainty; the scatter's standard error when that is larger (the readings
/// disagree more than their noise says).
fn weighted_mean(m: &[Measured]) -> (f64, f64) {
    let n = m.len() as f64;
    let (mean, s) = if m.iter().all(|x| x.s > 0.0) {
        let sw: f64 = m.iter().map(|x| x.s.powi(-2)).sum();
        (
            m.iter().map(|x| x.v / (x.s * x.s)).sum::<f64>() / sw,
            sw.sqrt().recip(),
        )
    } else {
        let mean = m.iter().map(|x| x.v).sum::<f64>() / n;
        (mean, 0.0)
    };
    if m.len() < 2 {
        return (mean, s);
    }
    let scatter = (m.iter().map(|x| (x.v - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
    (mean, s.max(scatter))
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

/// The run's instrument time of every reading, s: the instrument clock, continued
/// across sessions (each session's clock starts again at 0, so a session's first
/// reading follows the previous session's last). It is the clock the source drifts
/// by — in the laboratory the system clock, in a simulated run the simulator's.
fn timeline(by_step: &BTreeMap<i64, &ReadingRecord>) -> BTreeMap<i64, f64> {
    let mut out = BTreeMap::new();
    let (mut t, mut last) = (0.0, None::<f64>);
    for (id, r) in by_step {
        if let Some(prev) = last
            && r.physical_s >= prev
        {
            t += r.physical_s - prev;
        }
        last = Some(r.physical_s);
        out.insert(*id, t);
    }
    out
}

/// A pair's directions, its (value, σ) per channel as the channels are reduced, and
/// the union of its readings' flags.
type PerPair = (PairDeg, Vec<Option<(f64, f64)>>, u32);

/// The incident flux Φ(t) a sample reading is divided by.
enum Flux {
    /// C g(t), g from the drift references.
    Drift { c: f64, refs: Vec<Measured> },
    /// The calibration readings interpolated in time.
    Interpolated(Vec<Measured>),
    /// One level for the whole run.
    Constant(f64),
}

impl Flux {
    /// Φ at instrument time `t` and the relative uncertainty of its time dependence.
    fn at(&self, t: f64) -> (f64, f64) {
        let rel = |v: f64, s: f64| if v > 0.0 { s / v } else { 0.0 };
        match self {
            Flux::Drift { c, refs } => {
                let (g, gs) = interp(refs, t, true);
                (c * g, rel(g, gs))
            }
            Flux::Interpolated(m) => {
                let (v, s) = interp(m, t, false);
                (v, rel(v, s))
            }
            Flux::Constant(c) => (*c, 0.0),
        }
    }
}

/// Reduces a run to BRDF samples.
pub fn reduce(store: &RunStore, opts: &Options) -> Result<Reduction, ReduceError> {
    let path = store.path().display().to_string();
    let missing = |why: String| ReduceError::Missing {
        path: path.clone(),
        why,
    };
    let stored = store.run_meta()?;
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
    // The last reading of a step is the one that counts (a step re-measured after a
    // fault keeps only its final reading).
    let mut by_step: BTreeMap<i64, &ReadingRecord> = BTreeMap::new();
    for r in &readings {
        by_step.insert(r.step_id, r);
    }
    let time = timeline(&by_step);
    let channel_names: Vec<Option<String>> = {
        let mut v: Vec<Option<String>> = Vec::new();
        for s in &steps {
            if !v.contains(&s.step.channel) {
                v.push(s.step.channel.clone());
            }
        }
        v
    };
    let channels = if channel_names.iter().all(Option::is_none) {
        Channels::Single
    } else {
        let names: Vec<String> = channel_names.iter().flatten().cloned().collect();
        Channels::from_names(&names).map_err(|e| missing(format!("channels: {e}")))?
    };
    let standard = match &stored.standard_model {
        Some(t) => Some(
            gonio_brdf::Model::from_toml(t, None)
                .map_err(|e| missing(format!("stored reference standard model: {e}")))?,
        ),
        None => None,
    };
    let of = |kind: StepKind, ch: &Option<String>| -> Vec<(&StoredStep, &ReadingRecord)> {
        let pick = |want: &Option<String>| {
            steps
                .iter()
                .filter(|s| s.step.kind == kind && &s.step.channel == want)
                .filter_map(|s| by_step.get(&s.id).map(|r| (s, *r)))
                .collect::<Vec<_>>()
        };
        let v = pick(ch);
        if v.is_empty() && ch.is_some() {
            pick(&None)
        } else {
            v
        }
    };

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
        let dark_sigma = if darks.is_empty() {
            0.0
        } else {
            darks
                .iter()
                .map(|(_, r)| mean_sigma(r).powi(2))
                .sum::<f64>()
                .sqrt()
                / darks.len() as f64
        };
        let signal = |r: &ReadingRecord| {
            let s = (r.x_mean - dark[0]).hypot(r.y_mean - dark[1]);
            (s, mean_sigma(r).hypot(dark_sigma))
        };
        let incident = of(StepKind::Incident, ch);
        let standard_readings = of(StepKind::Standard, ch);
        let use_standard = match opts.calibration {
            Calibration::Incident => false,
            Calibration::Standard => true,
            Calibration::Auto => incident.is_empty(),
        };
        let mut cal: Vec<Measured> = Vec::new();
        if use_standard {
            let model = standard.as_ref().ok_or_else(|| {
                missing(format!("channel {name}: no reference standard in the run"))
            })?;
            let mc = gonio_brdf::Brdf::channels(model);
            let idx = mc
                .index_of(&name)
                .or((mc.len() == 1).then_some(0))
                .ok_or_else(|| {
                    missing(format!(
                        "channel {name}: the standard's model has no such channel"
                    ))
                })?;
            let mut out = vec![0.0; mc.len()];
            for (s, r) in &standard_readings {
                let Some(p) = s.step.pair else { continue };
                let d = p.to_dirs();
                gonio_brdf::Brdf::eval(model, d.wi, d.wo, &mut out);
                let k = out[idx] * omega * d.wo.z;
                if k > 0.0 {
                    let (v, sv) = signal(r);
                    cal.push(Measured {
                        t: time[&r.step_id],
                        v: v / k,
                        s: sv / k,
                    });
                }
            }
        } else {
            for (_, r) in &incident {
                let (v, sv) = signal(r);
                cal.push(Measured {
                    t: time[&r.step_id],
                    v: v / stored.transmittance,
                    s: sv / stored.transmittance,
                });
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
        cal.sort_by(|a, b| a.t.total_cmp(&b.t));
        let mut refs: Vec<Measured> = if opts.drift == Drift::Auto {
            of(StepKind::Reference, ch)
                .iter()
                .map(|(_, r)| {
                    let (v, s) = signal(r);
                    Measured {
                        t: time[&r.step_id],
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
        // Φ(t) and its relative uncertainty.
        let (flux, c_mean, c_sigma) = if refs.is_empty() {
            let (c, cs) = weighted_mean(&cal);
            let spread =
                opts.drift != Drift::None && cal.iter().any(|m| (m.t - cal[0].t).abs() > 1.0);
            let f = if spread {
                Flux::Interpolated(cal.clone())
            } else {
                Flux::Constant(c)
            };
            (f, c, cs)
        } else {
            let per: Vec<Measured> = cal
                .iter()
                .map(|m| {
                    let (g, _) = interp(&refs, m.t, true);
                    Measured {
                        t: m.t,
                        v: m.v / g,
                        s: m.s / g,
                    }
                })
                .collect();
            let (c, cs) = weighted_mean(&per);
            (
                Flux::Drift {
                    c,
                    refs: refs.clone(),
                },
                c,
                cs,
            )
        };
        if c_mean.is_nan() || c_mean <= 0.0 {
            return Err(missing(format!(
                "channel {name}: the calibration reading is not above the dark"
            )));
        }
        let c_rel = c_sigma / c_mean;
        let mut count = 0;
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
            let (v, sv) = signal(r);
            let (phi, phi_rel) = flux.at(time[&r.step_id]);
            let f = v / (phi * omega * cos_o);
            let rel = (if v > 0.0 { sv / v } else { 0.0 })
                .hypot(phi_rel)
                .hypot(c_rel);
            let sigma = if v > 0.0 {
                f * rel
            } else {
                sv / (phi * omega * cos_o)
            };
            let entry = values
                .entry((index, s.step.repeat))
                .or_insert_with(|| (pair, vec![None; nc], 0));
            entry.1[ci] = Some((f, sigma));
            entry.2 |= r.flags;
            count += 1;
        }
        reports.push(ChannelReport {
            channel: name,
            calibration: if use_standard { "standard" } else { "incident" },
            dark_v: dark,
            incident_v: c_mean,
            incident_rel_sigma: c_rel,
            calibration_readings: cal.len(),
            drift_readings: refs.len(),
            drift_max,
            samples: count,
        });
    }
    let unmeasured = steps
        .iter()
        .filter(|s| s.step.kind == StepKind::Sample && !by_step.contains_key(&s.id))
        .count();
    let mut samples = Vec::new();
    let mut incomplete = 0;
    for (pair, v, fl) in values.into_values() {
        if v.iter().any(Option::is_none) {
            incomplete += 1;
            continue;
        }
        let (value, sigma) = v.into_iter().flatten().unzip();
        samples.push(Sample {
            pair,
            value,
            sigma: Some(sigma),
            flags: fl,
        });
    }
    if incomplete > 0 {
        rejected.insert("missing-channel".into(), incomplete);
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
        },
    })
}

fn position_error(a: &PairDeg, b: &PairDeg) -> f64 {
    let d = |x: gonio_core::SphericalDeg, y: gonio_core::SphericalDeg| {
        gonio_core::Dir::from(x)
            .angle_to(gonio_core::Dir::from(y))
            .to_degrees()
    };
    d(a.incident, b.incident).max(d(a.outgoing, b.outgoing))
}

fn flag_reason(f: u32) -> String {
    if f & flags::UNLOCK != 0 {
        "unlock".into()
    } else {
        "overload".into()
    }
}
