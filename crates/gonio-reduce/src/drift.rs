//! The drift: how the incident flux Φ(t) follows the source through the run
//! ([`IncidentFlux::of`]).
//!
//! The drift reference pair is re-measured every N points. Its readings,
//! normalised to their mean, define the source's relative level g(t)
//! ([`Level::from_refs`]): a straight line fitted to them when it explains their
//! scatter, else linear in instrument time between them ([`interp`], continued
//! along the first and last segments beyond them). Every calibration reading k
//! then estimates the same constant C = Φ_k / g(t_k); their inverse-variance mean C
//! gives Φ(t) = C g(t) for every sample ([`Flux::Drift`]). Without references,
//! calibrations repeated in time are interpolated instead
//! ([`Flux::Interpolated`]); a single calibration, or calibrations all at one
//! time, is held constant ([`Flux::Constant`]).

use gonio_plan::StepKind;

use crate::calibration::{Measured, weighted_mean};
use crate::correlations::Shared;
use crate::dark::Dark;
use crate::{Drift, Run};

/// Linear interpolation in time of measured values, with the interpolated
/// uncertainty. Beyond the ends the value holds, or with `extend` the first or last
/// segment's line continues (a drifting source keeps drifting past the last
/// reference, to the end-of-run calibrations a little later).
pub(crate) fn interp(m: &[Measured], t: f64, extend: bool) -> (f64, f64) {
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

/// The weights [`interp`] gives the values at `t`: (index, weight) of the one or
/// two values it combines (none for no values). Its σ is the quadrature sum of
/// weight × σ over them.
pub(crate) fn interp_weights(m: &[Measured], t: f64, extend: bool) -> Vec<(usize, f64)> {
    let line = |a: usize, b: usize| {
        let w = if m[b].t > m[a].t {
            (t - m[a].t) / (m[b].t - m[a].t)
        } else {
            0.0
        };
        vec![(a, 1.0 - w), (b, w)]
    };
    match m.len() {
        0 => Vec::new(),
        1 => vec![(0, 1.0)],
        n => {
            if t <= m[0].t {
                return if extend { line(0, 1) } else { vec![(0, 1.0)] };
            }
            if t >= m[n - 1].t {
                return if extend {
                    line(n - 2, n - 1)
                } else {
                    vec![(n - 1, 1.0)]
                };
            }
            let k = m.partition_point(|x| x.t <= t).max(1);
            line(k - 1, k)
        }
    }
}

/// The source's relative level g(t) from the drift references.
pub(crate) enum Level {
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

    /// The `drift` term ([`Level::ratio_rel`]) as its shared parts: f's relative
    /// coefficient on each independent error behind it, signed. A line's is its
    /// slope's error, which moves samples before and after the calibrations' time
    /// oppositely; interpolated references' are each reference's noise, shared by
    /// the samples between it and its neighbours (f ∝ 1/g: a reference read high
    /// lowers them). Their quadrature sum is `ratio_rel`.
    fn ratio_parts(&self, t: f64, t_c: f64) -> Vec<(Shared, f64)> {
        match self {
            Level::Line { p0, s1, .. } => vec![(Shared::DriftSlope, (t - t_c) * s1 / p0)],
            Level::Piecewise(m) => {
                let (g, _) = self.at(t);
                if g <= 0.0 {
                    return Vec::new();
                }
                interp_weights(m, t, true)
                    .into_iter()
                    .map(|(k, w)| (Shared::DriftReference(k), -(w * m[k].s) / g))
                    .collect()
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

    /// How the level is followed, as the `drift` term's source says it.
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

/// The incident flux Φ(t) a sample reading is divided by.
pub(crate) enum Flux {
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
    pub(crate) fn at(&self, t: f64) -> (f64, f64, f64) {
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

impl Flux {
    /// The `drift` term at instrument time `t` as its shared parts
    /// ([`Level::ratio_parts`]); none without drift references.
    pub(crate) fn drift_parts(&self, t: f64) -> Vec<(Shared, f64)> {
        match self {
            Flux::Drift { level, t_c, .. } => level.ratio_parts(t, *t_c),
            _ => Vec::new(),
        }
    }
}

/// A channel's incident flux through the run.
pub(crate) struct IncidentFlux {
    /// Φ(t).
    pub flux: Flux,
    /// C: Φ at the references' mean level (the calibrations' mean, without
    /// references).
    pub c: f64,
    /// C's relative standard uncertainty, the level at the calibrations' times
    /// included.
    pub c_rel: f64,
    /// How the source's level is followed (the `drift` term's source).
    pub source: String,
    /// The drift references used.
    pub n_refs: usize,
    /// The references' largest relative departure from their mean.
    pub drift_max: f64,
}

impl IncidentFlux {
    /// The incident flux of the channel `ch` (named `name`) from its calibration
    /// estimates `cal` (sorted by time, at least one) and, with
    /// [`Drift::Auto`], its drift references' signals less `dark`. `Err` when C is
    /// not above 0.
    pub(crate) fn of(
        run: &Run,
        ch: &Option<String>,
        name: &str,
        dark: &Dark,
        cal: &[Measured],
    ) -> Result<IncidentFlux, String> {
        let refs = if run.opts.drift == Drift::Auto {
            references(run, ch, dark)
        } else {
            Vec::new()
        };
        let drift_max = refs.iter().map(|m| (m.v - 1.0).abs()).fold(0.0, f64::max);
        let n_refs = refs.len();
        let (flux, c, c_rel, source) = if refs.is_empty() {
            without_references(cal, run.opts.drift)
        } else {
            by_references(refs, cal)
        };
        if c.is_nan() || c <= 0.0 {
            return Err(format!(
                "channel {name}: the calibration reading is not above the dark"
            ));
        }
        Ok(IncidentFlux {
            flux,
            c,
            c_rel,
            source,
            n_refs,
            drift_max,
        })
    }

    /// Whether the calibrations are interpolated in time.
    pub(crate) fn interpolated(&self) -> bool {
        matches!(self.flux, Flux::Interpolated(_))
    }
}

/// The drift references' signals above 0, sorted by time and normalised to their
/// mean: g, so that C is in volts (amps) at the run's mean level.
fn references(run: &Run, ch: &Option<String>, dark: &Dark) -> Vec<Measured> {
    let mut refs: Vec<Measured> = run
        .groups
        .of(StepKind::Reference, ch)
        .iter()
        .map(|(_, r)| {
            let sig = dark.signal(r, &run.noise);
            Measured {
                t: run.groups.time_of(r),
                v: sig.v,
                s: sig.sigma,
            }
        })
        .filter(|m| m.v > 0.0)
        .collect();
    refs.sort_by(|a, b| a.t.total_cmp(&b.t));
    normalise(&mut refs);
    refs
}

/// Divides values and uncertainties by the values' mean (nothing for none).
fn normalise(refs: &mut [Measured]) {
    if !refs.is_empty() {
        let mean = refs.iter().map(|m| m.v).sum::<f64>() / refs.len() as f64;
        for m in refs {
            m.v /= mean;
            m.s /= mean;
        }
    }
}

/// Φ(t), C, its relative uncertainty and the drift's source without references:
/// calibrations spread in time (more than 1 s apart) are interpolated unless
/// `drift` is [`Drift::None`]; else their weighted mean holds for the run.
fn without_references(cal: &[Measured], drift: Drift) -> (Flux, f64, f64, String) {
    let (c, cs) = weighted_mean(cal);
    let spread = drift != Drift::None && cal.iter().any(|m| (m.t - cal[0].t).abs() > 1.0);
    if spread {
        (
            Flux::Interpolated(cal.to_vec()),
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
}

/// Φ(t) = C g(t), C the weighted mean of the calibrations' Φ_k / g(t_k), and its
/// relative uncertainty with that of g at the calibrations' times.
fn by_references(refs: Vec<Measured>, cal: &[Measured]) -> (Flux, f64, f64, String) {
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
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(t: f64, v: f64, s: f64) -> Measured {
        Measured { t, v, s }
    }

    #[test]
    fn interpolation_is_exact_at_the_knots_and_linear_between() {
        let k = [m(0.0, 1.0, 0.1), m(10.0, 2.0, 0.2), m(20.0, 4.0, 0.0)];
        assert_eq!(interp(&k, 10.0, false), (2.0, 0.2));
        assert_eq!(interp(&k, 0.0, true), (1.0, 0.1));
        // A quarter of the way from the first knot: ¾·1 + ¼·2, σ (¾·0.1) ⊕ (¼·0.2).
        let (v, s) = interp(&k, 2.5, false);
        assert_eq!(v, 1.25);
        assert!((s - 0.075f64.hypot(0.05)).abs() < 1e-15, "{s}");
        assert_eq!(interp(&k, 15.0, false).0, 3.0);
        // Beyond the ends: held, or the end segment continued.
        assert_eq!(interp(&k, -10.0, false), (1.0, 0.1));
        assert_eq!(interp(&k, 30.0, false), (4.0, 0.0));
        assert_eq!(interp(&k, 30.0, true).0, 6.0);
        assert_eq!(interp(&k, -10.0, true).0, 0.0);
        // Nothing to interpolate: 1; one value: itself.
        assert_eq!(interp(&[], 3.0, true), (1.0, 0.0));
        assert_eq!(interp(&k[1..2], 3.0, true), (2.0, 0.2));
    }

    /// References on a line within their noise keep the line; one far off it
    /// makes them interpolated; fewer than three are always interpolated.
    #[test]
    fn the_level_is_a_line_only_when_the_line_explains_the_references() {
        let on_line: Vec<Measured> = (0..5)
            .map(|k| m(f64::from(k) * 100.0, 1.0 + 1e-3 * f64::from(k), 1e-3))
            .collect();
        let Level::Line { t_mean, p0, p1, s1 } = Level::from_refs(on_line.clone()) else {
            panic!("a line");
        };
        assert!((t_mean - 200.0).abs() < 1e-12);
        assert!((p0 - 1.002).abs() < 1e-12 && (p1 - 1e-5).abs() < 1e-15);
        // Σ w (t − t̄)² = 1e6 × 1e5: s1 = 1/√(1e11).
        assert!((s1 - 1e11f64.sqrt().recip()).abs() < 1e-18);
        let level = Level::from_refs(on_line.clone());
        assert!((level.at(300.0).0 - 1.003).abs() < 1e-12);
        assert_eq!(level.calibration_rel(&[0.0, 400.0]), 0.0);
        let mut kinked = on_line.clone();
        kinked[2].v += 0.05;
        assert!(matches!(Level::from_refs(kinked), Level::Piecewise(_)));
        assert!(matches!(
            Level::from_refs(on_line[..2].to_vec()),
            Level::Piecewise(_)
        ));
    }

    #[test]
    fn references_are_normalised_to_their_mean() {
        let mut refs = [m(0.0, 2.0, 0.2), m(1.0, 6.0, 0.4)];
        normalise(&mut refs);
        assert_eq!((refs[0].v, refs[0].s), (0.5, 0.05));
        assert_eq!((refs[1].v, refs[1].s), (1.5, 0.1));
    }

    /// Without references: calibrations apart in time are interpolated (unless
    /// drift is not followed), one time's are held constant at their mean.
    #[test]
    fn without_references_calibrations_apart_in_time_are_interpolated() {
        let cal = [m(0.0, 1.0, 0.01), m(100.0, 1.1, 0.01)];
        let (flux, c, rel, _) = without_references(&cal, Drift::Auto);
        assert!(matches!(flux, Flux::Interpolated(_)) && rel == 0.0);
        assert!((c - 1.05).abs() < 1e-12);
        assert!((flux.at(50.0).0 - 1.05).abs() < 1e-15);
        let (flux, _, rel, source) = without_references(&cal, Drift::None);
        assert!(matches!(flux, Flux::Constant(_)) && rel > 0.0);
        assert!(source.contains("held constant"), "{source}");
    }
}
