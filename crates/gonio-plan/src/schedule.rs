//! The schedule of a run: the checked pairs ordered for least motion, expanded by
//! channels and repeats, with drift references and calibrations put in place. It is
//! fixed when a run is created and stored in the run file, so that a resumed run
//! follows exactly the same steps.

use std::time::Duration;

use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use serde::{Deserialize, Serialize};

use crate::order;
use crate::plan::{Checked, Mechanics, Plan, Rejection};

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
    /// Estimated motion time of the schedule, s.
    pub motion_s: f64,
    /// The same schedule's motion time with the pairs in plan (raster) order, s.
    pub raster_motion_s: f64,
    /// Estimated detector time (settling and sampling, serial traffic), s.
    pub detector_s: f64,
}

impl Schedule {
    /// Estimated duration, s.
    pub fn duration_s(&self) -> f64 {
        self.motion_s + self.detector_s
    }
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

/// Builds the schedule of `plan` from its checked pairs, starting from `start`
/// (stage positions, role order).
///
/// Order of a pass: the calibrations (dark, incident, standard), the drift
/// reference, then the sample pairs in the optimised order with the reference after
/// every `drift.every` pairs and once more at the end; with `repeat_at_end` the
/// calibrations again. One pass per channel; every other pass runs the pairs
/// backwards, so that no pass starts with a long move back.
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
    let points: Vec<[f64; 4]> = checked.accepted.iter().map(|a| a.stages).collect();
    let optimised = if plan.order.optimise {
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
    };
    let reference = match &plan.drift {
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
    };
    let c = &plan.calibration;
    let half_angle = mech
        .geometry
        .detector_radius_m
        .atan2(mech.geometry.detector_distance_m)
        .to_degrees();
    let incident = match &c.incident {
        Some(i) => Some(incident_stages(mech, i.stages, half_angle)?),
        None => None,
    };
    let mut standard = Vec::new();
    if let Some(s) = &c.standard {
        for (index, at) in s.at.iter().enumerate() {
            let pair = pair_of(*at);
            let stages = mech
                .accept(pair.to_dirs())
                .map_err(|reason| ScheduleError::Standard { index, reason })?;
            standard.push((pair, stages));
        }
    }
    let channels: Vec<Option<String>> = match &plan.channels {
        Some(c) => c.iter().cloned().map(Some).collect(),
        None => vec![None],
    };
    let every = plan.drift.as_ref().map_or(usize::MAX, |d| d.every);

    let build_with = |ord: &[usize]| {
        let mut steps = Vec::new();
        for (pass, channel) in channels.iter().enumerate() {
            let push = |steps: &mut Vec<Step>, kind, pair, stages, plan_index, repeats| {
                for repeat in 0..repeats {
                    steps.push(Step {
                        kind,
                        channel: channel.clone(),
                        repeat,
                        pair,
                        stages,
                        plan_index,
                    });
                }
            };
            let calibrations = |steps: &mut Vec<Step>| {
                if c.dark {
                    push(steps, StepKind::Dark, None, None, None, plan.repeats);
                }
                if let Some(s) = incident {
                    let wi_wo = mech.layout.forward(s);
                    let pair = PairDeg {
                        incident: SphericalDeg::from(wi_wo.wi),
                        outgoing: SphericalDeg::from(wi_wo.wo),
                    };
                    push(
                        steps,
                        StepKind::Incident,
                        Some(pair),
                        Some(s),
                        None,
                        plan.repeats,
                    );
                }
                for (p, s) in &standard {
                    push(
                        steps,
                        StepKind::Standard,
                        Some(*p),
                        Some(*s),
                        None,
                        plan.repeats,
                    );
                }
            };
            calibrations(&mut steps);
            if let Some((p, s)) = reference {
                push(&mut steps, StepKind::Reference, Some(p), Some(s), None, 1);
            }
            let mut this_pass: Vec<usize> = ord.to_vec();
            if pass % 2 == 1 {
                this_pass.reverse();
            }
            for (k, &i) in this_pass.iter().enumerate() {
                let a = &checked.accepted[i];
                push(
                    &mut steps,
                    StepKind::Sample,
                    Some(a.pair),
                    Some(a.stages),
                    Some(a.index),
                    plan.repeats,
                );
                let last = k + 1 == this_pass.len();
                if let Some((p, s)) = reference
                    && ((k + 1) % every == 0 || last)
                {
                    push(&mut steps, StepKind::Reference, Some(p), Some(s), None, 1);
                }
            }
            if c.repeat_at_end {
                calibrations(&mut steps);
            }
        }
        steps
    };
    let steps = build_with(&optimised);
    let motion = |steps: &[Step]| {
        let mut at = start;
        let mut t = 0.0;
        for s in steps {
            if let Some(p) = s.stages {
                t += mech.motion.step_time(&at, &p);
                at = p;
            }
        }
        t
    };
    let motion_s = motion(&steps);
    let raster_motion_s = motion(&build_with(&order::raster(points.len())));
    let detector_s = steps.len() as f64 * reading_s;
    Ok(Schedule {
        steps,
        motion_s,
        raster_motion_s,
        detector_s,
    })
}
