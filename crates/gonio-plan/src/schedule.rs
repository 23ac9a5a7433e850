//! The schedule of a run: the checked pairs ordered for least motion, expanded by
//! channels and repeats, with drift references and calibrations put in place. It is
//! fixed when a run is created and stored in the run file, so that a resumed run
//! follows exactly the same steps.
//!
//! With several bands (`channels` or `wavelengths`) either loop can be inside: a pass
//! over the geometry per band ([`Loop::Geometry`]), or every band at each geometry
//! point ([`Loop::Wavelength`]). The plan's `[spectral] inner` picks one, or (`auto`)
//! the one whose estimate — stage motion, band changes from the instrument's
//! `gonio_core::spectral_timing::WavelengthTiming`, readings — is shorter;
//! [`SpectralDecision`] records both estimates and the reason.

use std::time::Duration;

use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use serde::{Deserialize, Serialize};

use crate::order;
use crate::plan::{Checked, Inner, Mechanics, Plan, Rejection};

/// What a step measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StepKind {
    /// The sample at a pair of the plan.
    Sample,
    /// The drift reference pair, on the sample.
    Reference,
    /// The source blocked.
    Dark,
    /// The sample removed, the detector facing the source through a filter.
    Incident,
    /// The reference standard in place of the sample.
    Standard,
}

impl StepKind {
    /// The name stored in run files.
    pub fn as_str(self) -> &'static str {
        match self {
            StepKind::Sample => "sample",
            StepKind::Reference => "reference",
            StepKind::Dark => "dark",
            StepKind::Incident => "incident",
            StepKind::Standard => "standard",
        }
    }

    /// The kind a stored name means.
    pub fn parse(s: &str) -> Option<StepKind> {
        [
            StepKind::Sample,
            StepKind::Reference,
            StepKind::Dark,
            StepKind::Incident,
            StepKind::Standard,
        ]
        .into_iter()
        .find(|k| k.as_str() == s)
    }
}

/// One reading to take.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    /// What it measures.
    pub kind: StepKind,
    /// The band, when the plan names bands.
    pub channel: Option<String>,
    /// Which of the plan's repeats (0-based).
    pub repeat: u32,
    /// The pair, degrees (none for a dark reading, taken where the stages are).
    pub pair: Option<PairDeg>,
    /// Stage targets, degrees, role order (none: do not move).
    pub stages: Option<[f64; 4]>,
    /// Index of the pair in the plan's own order (sample steps).
    pub plan_index: Option<usize>,
}

/// A run's steps and what they should cost.
#[derive(Clone, Debug, PartialEq)]
pub struct Schedule {
    /// The steps, in the order they are taken.
    pub steps: Vec<Step>,
    /// Each step's band change and motion before its reading, s (what
    /// [`band_s`](Self::band_s) and [`motion_s`](Self::motion_s) add up): the time a
    /// reading's own estimate is added to, step by step.
    pub step_s: Vec<f64>,
    /// Estimated motion time of the schedule, s: the stages' moves with the serial
    /// exchanges that command them and wait for them
    /// ([`Mechanics::move_s`](crate::plan::Mechanics::move_s)).
    pub motion_s: f64,
    /// The same schedule's motion time with the pairs in plan (raster) order, s.
    pub raster_motion_s: f64,
    /// Estimated detector time (settling and sampling, serial traffic), s.
    pub detector_s: f64,
    /// Estimated time of the band changes (the first selection included), s.
    pub band_s: f64,
    /// With several bands: which loop is inside, and why.
    pub spectral: Option<SpectralDecision>,
}

impl Schedule {
    /// Estimated duration, s.
    pub fn duration_s(&self) -> f64 {
        self.motion_s + self.band_s + self.detector_s
    }
}

/// Which loop of a run with several bands is inside.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Loop {
    /// Every band at each geometry point (and each calibration, each reference).
    Wavelength,
    /// A pass over the geometry per band.
    Geometry,
}

impl Loop {
    /// Its name in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Loop::Wavelength => "wavelength",
            Loop::Geometry => "geometry",
        }
    }
}

/// The estimate of a schedule in one loop order.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LoopEstimate {
    /// Stage motion, s.
    pub motion_s: f64,
    /// Band changes, the first selection included.
    pub band_changes: usize,
    /// Their time, s.
    pub band_s: f64,
    /// Readings, s.
    pub detector_s: f64,
    /// All three, s.
    pub total_s: f64,
}

/// Which loop is inside a run with several bands, and why.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SpectralDecision {
    /// What the plan asked for (`spectral.inner`).
    pub requested: Inner,
    /// The loop inside.
    pub inner: Loop,
    /// Number of bands.
    pub bands: usize,
    /// With the wavelength loop inside: whether successive sweeps over the bands
    /// alternate in direction (else each sweep runs in the plan's order, ascending
    /// wavelength). The wavelength timing decides: alternating saves the move back
    /// to the first band, and costs a drive with backlash its overshoot on every
    /// move down.
    pub alternate: bool,
    /// The estimate with the wavelength loop inside.
    pub wavelength_inner: LoopEstimate,
    /// The estimate with the geometry loop inside.
    pub geometry_inner: LoopEstimate,
    /// The decision in words, with both estimates.
    pub reason: String,
}

/// Why a plan cannot be scheduled on an instrument.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScheduleError {
    /// Every pair was rejected.
    #[error("no pair of the plan can be measured on this instrument")]
    NothingToMeasure,
    /// The drift reference pair cannot be measured.
    #[error("field `drift.at`: the reference pair cannot be measured: {0}")]
    Reference(Rejection),
    /// A pair of the reference standard cannot be measured.
    #[error("field `calibration.standard.at[{index}]`: cannot be measured: {reason}")]
    Standard {
        /// Index in `at`.
        index: usize,
        /// Why.
        reason: Rejection,
    },
    /// The incident-beam reading has no usable stage positions.
    #[error("field `calibration.incident.stages`: {0}")]
    Incident(String),
    /// The bands cannot be named (a plan built in code that skipped validation).
    #[error("{0}")]
    Bands(String),
}

fn pair_of(p: [f64; 4]) -> PairDeg {
    PairDeg {
        incident: SphericalDeg::new(p[0], p[1]),
        outgoing: SphericalDeg::new(p[2], p[3]),
    }
}

/// The incident-beam stages: the plan's, or (coplanar arms) source at −90°, detector
/// at +90°; checked against the limits and for the detector facing the source.
fn incident_stages(
    mech: &Mechanics,
    given: Option<[f64; 4]>,
    half_angle_deg: f64,
) -> Result<[f64; 4], ScheduleError> {
    let stages = match (given, mech.layout) {
        (Some(s), _) => s,
        (None, gonio_core::kinematics::Layout::CoplanarArms) => [-90.0, 90.0, 0.0, 0.0],
        (None, gonio_core::kinematics::Layout::Spherical) => {
            return Err(ScheduleError::Incident(
                "the spherical layout has no default; give the stage positions that put \
                 the detector in the beam"
                    .into(),
            ));
        }
    };
    for ((axis, (lo, hi)), x) in mech.axes.iter().zip(mech.limits).zip(stages) {
        if !(lo..=hi).contains(&x) {
            return Err(ScheduleError::Incident(format!(
                "axis {axis} at {x} is outside [{lo}, {hi}]"
            )));
        }
    }
    let d = mech.layout.forward(stages);
    let off = 180.0 - d.wi.angle_to(d.wo).to_degrees();
    if off.is_nan() || off > half_angle_deg {
        return Err(ScheduleError::Incident(format!(
            "the detector is {off:.2}° off the beam's axis; its aperture takes {half_angle_deg:.2}°"
        )));
    }
    Ok(stages)
}

/// A band: its channel name and its wavelength, when it is one.
struct Band {
    name: String,
    nm: Option<f64>,
}

/// Time to change from band `from` (`None`: unknown) to band `to`, s.
fn band_move_s(mech: &Mechanics, bands: &[Band], from: Option<usize>, to: usize) -> f64 {
    if from == Some(to) {
        return 0.0;
    }
    match bands[to].nm {
        Some(nm) => mech.wavelength_move_s(from.and_then(|f| bands[f].nm), nm),
        None => mech.named_band_change_s(),
    }
}

/// A step before its band is named.
#[derive(Clone, Copy)]
struct Proto {
    kind: StepKind,
    band: Option<usize>,
    repeat: u32,
    pair: Option<PairDeg>,
    stages: Option<[f64; 4]>,
    plan_index: Option<usize>,
}

/// Where each kind of step is taken: what both loop orders lay out.
struct Layout<'a> {
    checked: &'a Checked,
    repeats: u32,
    /// Dark readings each time the calibrations are taken.
    darks: u32,
    incident: Option<(PairDeg, [f64; 4])>,
    standard: Vec<(PairDeg, [f64; 4])>,
    reference: Option<(PairDeg, [f64; 4])>,
    every: usize,
    repeat_at_end: bool,
    /// The bands in plan order (`[None]`: one unnamed band).
    bands: Vec<Option<usize>>,
}

/// One configuration to measure: kind, pair, stages, plan index, readings per band.
type At = (
    StepKind,
    Option<PairDeg>,
    Option<[f64; 4]>,
    Option<usize>,
    u32,
);

impl Layout<'_> {
    /// The configurations of one pass over the geometry, in order: the calibrations,
    /// the reference, the pairs of `ord` (backwards with `reverse`) with the
    /// reference after every `every` and after the last, the calibrations again.
    fn sequence(&self, ord: &[usize], reverse: bool, at: &mut dyn FnMut(At)) {
        let calibrations = |at: &mut dyn FnMut(At)| {
            if self.darks > 0 {
                at((StepKind::Dark, None, None, None, self.darks));
            }
            if let Some((p, s)) = self.incident {
                at((StepKind::Incident, Some(p), Some(s), None, self.repeats));
            }
            for (p, s) in &self.standard {
                at((StepKind::Standard, Some(*p), Some(*s), None, self.repeats));
            }
        };
        calibrations(at);
        let reference = |at: &mut dyn FnMut(At)| {
            if let Some((p, s)) = self.reference {
                at((StepKind::Reference, Some(p), Some(s), None, 1));
            }
        };
        reference(at);
        let n = ord.len();
        for k in 0..n {
            let i = if reverse { ord[n - 1 - k] } else { ord[k] };
            let a = &self.checked.accepted[i];
            at((
                StepKind::Sample,
                Some(a.pair),
                Some(a.stages),
                Some(a.index),
                self.repeats,
            ));
            if (k + 1) % self.every == 0 || k + 1 == n {
                reference(at);
            }
        }
        if self.repeat_at_end {
            calibrations(at);
        }
    }

    /// Every step of the schedule in `inner` order, to `emit`. With the wavelength
    /// loop inside, each configuration is measured in every band, the sweeps
    /// alternating in direction with `alternate` (the first one ascending, so that
    /// the bands first appear in the plan's order).
    fn walk(&self, ord: &[usize], inner: Loop, alternate: bool, emit: &mut dyn FnMut(Proto)) {
        let one = |emit: &mut dyn FnMut(Proto), band: Option<usize>, at: At| {
            let (kind, pair, stages, plan_index, repeats) = at;
            for repeat in 0..repeats {
                emit(Proto {
                    kind,
                    band,
                    repeat,
                    pair,
                    stages,
                    plan_index,
                });
            }
        };
        match inner {
            Loop::Geometry => {
                for (pass, &band) in self.bands.iter().enumerate() {
                    self.sequence(ord, pass % 2 == 1, &mut |at| one(emit, band, at));
                }
            }
            Loop::Wavelength => {
                let mut up = true;
                self.sequence(ord, false, &mut |at| {
                    let n = self.bands.len();
                    for k in 0..n {
                        one(emit, self.bands[if up { k } else { n - 1 - k }], at);
                    }
                    if alternate {
                        up = !up;
                    }
                });
            }
        }
    }
}

/// The cost of a walk, step by step.
struct Cost<'a> {
    mech: &'a Mechanics,
    bands: &'a [Band],
    at: [f64; 4],
    band: Option<usize>,
    motion_s: f64,
    band_s: f64,
    band_changes: usize,
    steps: usize,
}

impl<'a> Cost<'a> {
    fn new(mech: &'a Mechanics, bands: &'a [Band], start: [f64; 4]) -> Cost<'a> {
        Cost {
            mech,
            bands,
            at: start,
            band: None,
            motion_s: 0.0,
            band_s: 0.0,
            band_changes: 0,
            steps: 0,
        }
    }

    /// The engine's order: the band first, then the stages (a step without stages
    /// reads where they stand). Returns the step's band change and motion, s.
    fn take(&mut self, p: &Proto) -> f64 {
        let mut band_s = 0.0;
        if let Some(b) = p.band
            && self.band != Some(b)
        {
            band_s = band_move_s(self.mech, self.bands, self.band, b);
            self.band_s += band_s;
            self.band_changes += 1;
            self.band = Some(b);
        }
        let motion_s = self.mech.move_s(&self.at, p.stages.as_ref());
        self.motion_s += motion_s;
        if let Some(s) = p.stages {
            self.at = s;
        }
        self.steps += 1;
        band_s + motion_s
    }

    fn estimate(&self, reading_s: f64) -> LoopEstimate {
        let detector_s = self.steps as f64 * reading_s;
        LoopEstimate {
            motion_s: self.motion_s,
            band_changes: self.band_changes,
            band_s: self.band_s,
            detector_s,
            total_s: self.motion_s + self.band_s + detector_s,
        }
    }
}

/// Seconds as `1h02m03s` (`?` for a negative or non-finite value), as reasons and
/// reports write durations.
pub fn hms(s: f64) -> String {
    if !s.is_finite() || s < 0.0 {
        return "?".into();
    }
    let t = s.round() as u64;
    match (t / 3600, t % 3600 / 60, t % 60) {
        (0, 0, s) => format!("{s}s"),
        (0, m, s) => format!("{m}m{s:02}s"),
        (h, m, s) => format!("{h}h{m:02}m{s:02}s"),
    }
}

/// An estimate in words: `2h06m (motion 10m00s, 3100 band changes of 2.0 s, 1h43m;
/// readings 13m)`.
fn describe(e: &LoopEstimate) -> String {
    let each = if e.band_changes > 0 {
        e.band_s / e.band_changes as f64
    } else {
        0.0
    };
    format!(
        "{} (motion {}, {} band changes of {:.1} s, {}; readings {})",
        hms(e.total_s),
        hms(e.motion_s),
        e.band_changes,
        each,
        hms(e.band_s),
        hms(e.detector_s)
    )
}

/// Whether sweeps over the bands should alternate in direction: when a sweep down
/// and one up cost less than two sweeps up, each after a move back to the first band.
fn alternates(mech: &Mechanics, bands: &[Band]) -> bool {
    let n = bands.len();
    if n < 2 {
        return false;
    }
    let up: f64 = (1..n)
        .map(|k| band_move_s(mech, bands, Some(k - 1), k))
        .sum();
    let down: f64 = (1..n)
        .map(|k| band_move_s(mech, bands, Some(k), k - 1))
        .sum();
    let back = band_move_s(mech, bands, Some(n - 1), 0);
    up + down < 2.0 * (back + up)
}

/// Builds the schedule of `plan` from its checked pairs, starting from `start`
/// (stage positions, role order).
///
/// Order of a pass: the calibrations (dark, incident, standard), the drift
/// reference, then the sample pairs in the optimised order with the reference after
/// every `drift.every` pairs and once more at the end; with `repeat_at_end` the
/// calibrations again. With the geometry loop inside, one pass per band; every
/// other pass runs the pairs backwards, so that no pass starts with a long move
/// back. With the wavelength loop inside, one pass in which every step (each
/// calibration, each reference, each pair) is taken in every band before the
/// stages move on. With several bands and `spectral.inner = "auto"`, the order whose
/// estimate is shorter (the geometry loop on a tie).
pub fn build(
    plan: &Plan,
    mech: &Mechanics,
    checked: &Checked,
    start: [f64; 4],
    reading_s: f64,
) -> Result<Schedule, ScheduleError> {
    if checked.accepted.is_empty() {
        return Err(ScheduleError::NothingToMeasure);
    }
    let optimised = point_order(plan, mech, checked, start);
    let reference = reference_point(plan, mech, checked)?;
    let c = &plan.calibration;
    let incident = incident_point(plan, mech)?;
    let standard = standard_points(plan, mech)?;
    let bands = bands_of(plan)?;
    let layout = Layout {
        checked,
        repeats: plan.repeats,
        darks: c.dark_count(plan.repeats),
        incident,
        standard,
        reference,
        every: plan.drift.as_ref().map_or(usize::MAX, |d| d.every.max(1)),
        repeat_at_end: c.repeat_at_end,
        bands: if bands.is_empty() {
            vec![None]
        } else {
            (0..bands.len()).map(Some).collect()
        },
    };
    let estimate = |ord: &[usize], inner: Loop, alternate: bool| {
        let mut cost = Cost::new(mech, &bands, start);
        layout.walk(ord, inner, alternate, &mut |p| {
            cost.take(&p);
        });
        cost.estimate(reading_s)
    };
    let alternate = alternates(mech, &bands);
    let (inner, spectral) = if bands.len() < 2 {
        (Loop::Geometry, None)
    } else {
        let w = estimate(&optimised, Loop::Wavelength, alternate);
        let g = estimate(&optimised, Loop::Geometry, false);
        let decision = decide_inner(plan.spectral.inner, bands.len(), alternate, w, g);
        (decision.inner, Some(decision))
    };
    let alternate = inner == Loop::Wavelength && alternate;
    let mut steps = Vec::new();
    let mut step_s = Vec::new();
    let mut cost = Cost::new(mech, &bands, start);
    layout.walk(&optimised, inner, alternate, &mut |p| {
        step_s.push(cost.take(&p));
        steps.push(Step {
            kind: p.kind,
            channel: p.band.map(|b| bands[b].name.clone()),
            repeat: p.repeat,
            pair: p.pair,
            stages: p.stages,
            plan_index: p.plan_index,
        });
    });
    let raster = estimate(&order::raster(checked.accepted.len()), inner, alternate);
    Ok(Schedule {
        steps,
        step_s,
        motion_s: cost.motion_s,
        raster_motion_s: raster.motion_s,
        detector_s: cost.steps as f64 * reading_s,
        band_s: cost.band_s,
        spectral,
    })
}

/// The order of the accepted pairs: optimised for motion time within the plan's
/// budget, or the plan's own.
fn point_order(plan: &Plan, mech: &Mechanics, checked: &Checked, start: [f64; 4]) -> Vec<usize> {
    let points: Vec<[f64; 4]> = checked.accepted.iter().map(|a| a.stages).collect();
    if plan.order.optimise {
        order::optimise(
            &mech.motion,
            start,
            &points,
            // Validated to [0, 3600] s when read; a plan built in code is held to the
            // same rather than left to panic on a NaN or a 1e20.
            Duration::try_from_secs_f64(plan.order.budget_s.clamp(0.0, crate::plan::BUDGET.max))
                .unwrap_or(Duration::ZERO),
        )
    } else {
        order::raster(points.len())
    }
}

/// The drift reference, with its stages: the plan's `drift.at`, or its first
/// accepted pair; `None` without drift.
fn reference_point(
    plan: &Plan,
    mech: &Mechanics,
    checked: &Checked,
) -> Result<Option<(PairDeg, [f64; 4])>, ScheduleError> {
    Ok(match &plan.drift {
        None => None,
        Some(d) => Some(match d.at {
            Some(at) => {
                let pair = pair_of(at);
                let stages = mech
                    .accept(pair.to_dirs())
                    .map_err(ScheduleError::Reference)?;
                (pair, stages)
            }
            None => (checked.accepted[0].pair, checked.accepted[0].stages),
        }),
    })
}

/// The incident-beam calibration's stages and the pair they face, when the plan
/// asks for one; the detector must take the beam within its aperture.
fn incident_point(
    plan: &Plan,
    mech: &Mechanics,
) -> Result<Option<(PairDeg, [f64; 4])>, ScheduleError> {
    let half_angle = mech
        .geometry
        .detector_radius_m
        .atan2(mech.geometry.detector_distance_m)
        .to_degrees();
    Ok(match &plan.calibration.incident {
        Some(i) => {
            let s = incident_stages(mech, i.stages, half_angle)?;
            let wi_wo = mech.layout.forward(s);
            let pair = PairDeg {
                incident: SphericalDeg::from(wi_wo.wi),
                outgoing: SphericalDeg::from(wi_wo.wo),
            };
            Some((pair, s))
        }
        None => None,
    })
}

/// The reference standard's pairs with their stages, each measurable.
fn standard_points(
    plan: &Plan,
    mech: &Mechanics,
) -> Result<Vec<(PairDeg, [f64; 4])>, ScheduleError> {
    let mut standard = Vec::new();
    if let Some(s) = &plan.calibration.standard {
        for (index, at) in s.at.iter().enumerate() {
            let pair = pair_of(*at);
            let stages = mech
                .accept(pair.to_dirs())
                .map_err(|reason| ScheduleError::Standard { index, reason })?;
            standard.push((pair, stages));
        }
    }
    Ok(standard)
}

/// The plan's bands with their wavelengths; empty for one unnamed band.
fn bands_of(plan: &Plan) -> Result<Vec<Band>, ScheduleError> {
    let names = plan
        .channel_names()
        .map_err(|e| ScheduleError::Bands(e.to_string()))?;
    let nm = plan.band_wavelengths();
    Ok(names
        .iter()
        .flatten()
        .enumerate()
        .map(|(k, name)| Band {
            name: name.clone(),
            nm: nm.as_ref().and_then(|w| w.get(k).copied()),
        })
        .collect())
}

/// Which loop goes inside, from the plan's request and the two estimates (`w`
/// wavelength inner, `g` geometry inner), with the reason in words.
fn decide_inner(
    requested: Inner,
    bands: usize,
    alternate: bool,
    w: LoopEstimate,
    g: LoopEstimate,
) -> SpectralDecision {
    let inner = match requested {
        Inner::Wavelength => Loop::Wavelength,
        Inner::Geometry => Loop::Geometry,
        Inner::Auto if w.total_s < g.total_s => Loop::Wavelength,
        Inner::Auto => Loop::Geometry,
    };
    let (mine, other) = match inner {
        Loop::Wavelength => (&w, &g),
        Loop::Geometry => (&g, &w),
    };
    let other_loop = match inner {
        Loop::Wavelength => Loop::Geometry,
        Loop::Geometry => Loop::Wavelength,
    };
    let reason = match requested {
        Inner::Auto => format!(
            "{} inner: {}, {} than {} inner: {}",
            inner.as_str(),
            describe(mine),
            if mine.total_s < other.total_s {
                "less"
            } else {
                "no more"
            },
            other_loop.as_str(),
            describe(other)
        ),
        _ => format!(
            "{} inner, as spectral.inner asks: {}; {} inner: {}",
            inner.as_str(),
            describe(mine),
            other_loop.as_str(),
            describe(other)
        ),
    };
    SpectralDecision {
        requested,
        inner,
        bands,
        alternate: inner == Loop::Wavelength && alternate,
        wavelength_inner: w,
        geometry_inner: g,
        reason,
    }
}
