//! A first day on real hardware: the checks a lab runs before it trusts a new
//! instrument with a measurement, each answer set beside what the manual says.
//!
//! [`selftest`] identifies every device; reads each controller's configuration back
//! (an SMC100's `ZT` dump, an APT controller's velocity parameters) and the detector's
//! range; homes what needs it; runs short moves on every APT stage, checking that each
//! `MOT_MOVE_COMPLETED` arrives (the controllers stop sending them without the host's
//! keep-alive, manual p. 130) and recording the length of every status message
//! (`0x0481` is 14 data bytes on a K10CR1, 28 in the manual); times one move per axis
//! against the controller's own model (an SMC100's `PT`, the APT trapezoid); and reads
//! the detector's noise floor with the beam blocked (the band selector's shutter, or
//! the bench). No move leaves the configured soft limits, and none brings the arms
//! closer than the geometry's minimum separation. The [`SelftestReport`] keeps what
//! the hardware answered, for the lab to file.

use std::any::Any;
use std::time::Duration;

use gonio_core::motion::trapezoid_time;
use gonio_proto::Unconfirmed;
use serde::Serialize;

use crate::apt::AptAxis;
use crate::bench::{Bench, Setup};
use crate::clock::Clock;
use crate::config::InstrumentConfig;
use crate::goniometer::Goniometer;
use crate::motion::AxisState;
use crate::smc100::{Param, Smc100Chain};
use crate::transport::Transport;

/// How much the self-test does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelftestOptions {
    /// Short moves on each APT stage (more than the ~50 status messages after which
    /// a controller without the keep-alive falls silent).
    pub apt_moves: usize,
    /// Readings of the dark detector for its noise floor.
    pub dark_readings: usize,
}

impl Default for SelftestOptions {
    fn default() -> Self {
        SelftestOptions {
            apt_moves: 60,
            dark_readings: 10,
        }
    }
}

/// One check: what was asked of which device, what it answered, and what the manual
/// says it should.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Check {
    /// The check (`identify`, `configuration`, `apt moves`, `move time`, `noise floor`,
    /// `keep-alive`).
    pub check: &'static str,
    /// The axis or device.
    pub device: String,
    /// Whether the answer is what a working instrument gives.
    pub passed: bool,
    /// What the hardware answered, in words and numbers.
    pub answered: String,
    /// What the manual (or Gonio's config) says it should be.
    pub expected: String,
    /// Where that is written.
    pub source: &'static str,
}

/// How often a status-kind message arrived with a data length.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StatusLength {
    /// The APT axis.
    pub axis: String,
    /// The message.
    pub message: &'static str,
    /// Its data packet, bytes.
    pub data_bytes: usize,
    /// How many arrived.
    pub count: u64,
}

/// The facts about one device family that no manual page confirms.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FamilyFacts {
    /// The family (`smc100`, `apt`, `sr830`, `k6485`, `cs130`, `fw102c`).
    pub family: &'static str,
    /// Its unconfirmed facts and how to check them.
    pub unconfirmed: &'static [Unconfirmed],
}

/// What the self-test found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SelftestReport {
    /// True when every check passed.
    pub passed: bool,
    /// Every check, in the order it ran.
    pub checks: Vec<Check>,
    /// The status messages the APT controllers sent, by length.
    pub status_lengths: Vec<StatusLength>,
    /// Instrument time the test took, s.
    pub duration_s: f64,
    /// What stays to be checked by hand on these families.
    pub unconfirmed: Vec<FamilyFacts>,
}

/// The unconfirmed facts of a family, by the family name [`AxisInfo`](crate::motion::AxisInfo)
/// and the devices report (`kdc101` and `k10cr1` are `apt`).
pub fn unconfirmed(family: &str) -> Option<FamilyFacts> {
    let (family, unconfirmed): (&'static str, &'static [Unconfirmed]) = match family {
        "smc100" => ("smc100", gonio_proto::smc100::UNCONFIRMED),
        "kdc101" | "k10cr1" | "apt" => ("apt", gonio_proto::apt::UNCONFIRMED),
        "sr830" => ("sr830", gonio_proto::sr830::UNCONFIRMED),
        "k6485" => ("k6485", gonio_proto::k6485::UNCONFIRMED),
        "cs130" => ("cs130", gonio_proto::cs130::UNCONFIRMED),
        "fw102c" => ("fw102c", gonio_proto::fw102c::UNCONFIRMED),
        _ => return None,
    };
    Some(FamilyFacts {
        family,
        unconfirmed,
    })
}

/// Runs the self-test on `g`, built from `cfg`, asking `bench` to block the beam when
/// there is no shutter. A fault of the instrument is a failed check, not an error:
/// the report says what went wrong where; later checks that need what failed are
/// skipped.
pub fn selftest<C: Clock + Clone + 'static>(
    g: &mut Goniometer<C>,
    cfg: &InstrumentConfig,
    bench: &mut dyn Bench,
    opts: &SelftestOptions,
) -> SelftestReport {
    let t0 = g.motion.clock().now();
    let mut t = Tally::default();
    let families = identify(g, &mut t);
    if t.failed() {
        return t.report(g, t0, &families);
    }
    configuration(g, cfg, &mut t);
    home(g, &mut t);
    let arms = Arms::of(cfg);
    if !t.failed() {
        apt_moves(g, arms.as_ref(), opts, &mut t);
        move_times(g, arms.as_ref(), &mut t);
    }
    noise_floor(g, bench, opts, &mut t);
    keepalive(g, t0, &mut t);
    t.report(g, t0, &families)
}

#[derive(Default)]
struct Tally {
    checks: Vec<Check>,
    lengths: Vec<StatusLength>,
}

impl Tally {
    fn push(
        &mut self,
        check: &'static str,
        device: &str,
        passed: bool,
        answered: String,
        expected: impl Into<String>,
        source: &'static str,
    ) {
        tracing::info!(check, device, passed, %answered, "selftest");
        self.checks.push(Check {
            check,
            device: device.to_string(),
            passed,
            answered,
            expected: expected.into(),
            source,
        });
    }

    fn failed(&self) -> bool {
        self.checks.iter().any(|c| !c.passed)
    }

    fn report<C: Clock + Clone>(
        self,
        g: &Goniometer<C>,
        t0: Duration,
        families: &[&str],
    ) -> SelftestReport {
        let mut facts: Vec<FamilyFacts> = Vec::new();
        for f in families.iter().filter_map(|f| unconfirmed(f)) {
            if !facts.iter().any(|u| u.family == f.family) {
                facts.push(f);
            }
        }
        SelftestReport {
            passed: !self.failed(),
            checks: self.checks,
            status_lengths: self.lengths,
            duration_s: g.motion.clock().now().saturating_sub(t0).as_secs_f64(),
            unconfirmed: facts,
        }
    }
}

fn identify<C: Clock + Clone + 'static>(g: &mut Goniometer<C>, t: &mut Tally) -> Vec<&'static str> {
    let mut families = Vec::new();
    match g.motion.identify() {
        Ok(axes) => {
            for (name, info) in axes {
                families.push(info.family);
                let expected = match info.family {
                    "smc100" => "an SMC100 answering `VE` and `ID?` (manual p. 66, 29)",
                    "kdc101" => {
                        "`HW_GET_INFO`: a KDC101, serial number 27xxxxxx (manual §2.2, p. 32–33)"
                    }
                    "k10cr1" => {
                        "`HW_GET_INFO`: a K10CR1, serial number 55xxxxxx (manual §2.2, p. 32–33)"
                    }
                    _ => "its identity",
                };
                t.push(
                    "identify",
                    &name,
                    true,
                    format!(
                        "{} {}, firmware {}, state {}",
                        info.family, info.stage, info.version, info.state
                    ),
                    expected,
                    "the family's manual",
                );
            }
        }
        Err(e) => t.push(
            "identify",
            "motion",
            false,
            e.to_string(),
            "every controller answers and is the configured one",
            "the families' manuals",
        ),
    }
    let family = g.detector.family();
    families.push(family);
    match g.detector.setup() {
        Ok(id) => t.push(
            "identify",
            family,
            true,
            id,
            "`*IDN?` names the configured model",
            "IEEE 488.2 `*IDN?` (SR830 p. 5-24; 6485 §10)",
        ),
        Err(e) => t.push(
            "identify",
            family,
            false,
            e.to_string(),
            "`*IDN?` names the configured model",
            "IEEE 488.2 `*IDN?`",
        ),
    }
    if let Some(sel) = &mut g.spectral {
        let family = sel.family();
        families.push(family);
        let r = sel.setup();
        let passed = r.is_ok();
        t.push(
            "identify",
            family,
            passed,
            r.unwrap_or_else(|e| e.to_string()),
            "the band selector identifies itself and takes its set-up",
            "CS130B §15.4 `INFO?`; FW102C p. 11 `*idn?`",
        );
    }
    families
}

/// The SMC100 chain or APT axis behind a motion line, for their own operations.
enum Family<'a, C: Clock + Clone + 'static> {
    Smc100(&'a mut Smc100Chain<Box<dyn Transport>, C>),
    Apt(&'a mut AptAxis<Box<dyn Transport>, C>),
}

fn family<C: Clock + Clone + 'static>(line: &mut dyn Any) -> Option<Family<'_, C>> {
    if line.is::<Smc100Chain<Box<dyn Transport>, C>>() {
        return line
            .downcast_mut::<Smc100Chain<Box<dyn Transport>, C>>()
            .map(Family::Smc100);
    }
    line.downcast_mut::<AptAxis<Box<dyn Transport>, C>>()
        .map(Family::Apt)
}

fn configuration<C: Clock + Clone + 'static>(
    g: &mut Goniometer<C>,
    cfg: &InstrumentConfig,
    t: &mut Tally,
) {
    for line in g.motion.lines_mut() {
        match family::<C>(line.as_any_mut()) {
            Some(Family::Smc100(chain)) => {
                let axes: Vec<_> = chain.axes().to_vec();
                for a in axes {
                    match chain.read_config(&a.name) {
                        Ok(p) => {
                            let (sl, sr) = (
                                p.get(Param::NegativeLimit).unwrap_or(f64::NAN),
                                p.get(Param::PositiveLimit).unwrap_or(f64::NAN),
                            );
                            let inside = sl <= a.min && a.max <= sr;
                            t.push(
                                "configuration",
                                &a.name,
                                inside,
                                format!(
                                    "ZT: stage {}, SL {sl}, SR {sr}, VA {}, AC {}, {} lines",
                                    p.stage,
                                    p.get(Param::Velocity).unwrap_or(f64::NAN),
                                    p.get(Param::Acceleration).unwrap_or(f64::NAN),
                                    p.values.len() + p.other.len() + 3
                                ),
                                format!(
                                    "the controller's travel limits [SL, SR] hold Gonio's [{}, {}] (else a move is refused with G)",
                                    a.min, a.max
                                ),
                                "SMC100 manual, ZT p. 67, PA p. 41, SL/SR p. 54–55",
                            );
                        }
                        Err(e) => t.push(
                            "configuration",
                            &a.name,
                            false,
                            e.to_string(),
                            "a whole `ZT` dump",
                            "SMC100 manual, ZT p. 67",
                        ),
                    }
                }
            }
            Some(Family::Apt(axis)) => {
                let name = axis.axis().name.clone();
                let (v, a) = axis.axis().motion();
                match axis.velocity_params() {
                    Ok((gv, ga)) => {
                        let close = |x: f64, y: f64| (x - y).abs() <= 1e-3 * y.abs().max(1e-9);
                        t.push(
                            "configuration",
                            &name,
                            close(gv, v) && close(ga, a),
                            format!("VELPARAMS: {gv:.4} deg/s, {ga:.4} deg/s²"),
                            format!("what set-up wrote: {v} deg/s, {a} deg/s²"),
                            "APT manual, MOT_REQ_VELPARAMS p. 66",
                        );
                    }
                    Err(e) => t.push(
                        "configuration",
                        &name,
                        false,
                        e.to_string(),
                        "`MOT_GET_VELPARAMS`",
                        "APT manual p. 66",
                    ),
                }
            }
            None => {}
        }
    }
    let family = g.detector.family();
    match g.detector.read() {
        Ok(r) => {
            let c = r.columns();
            let (unit, want) = match family {
                "k6485" => ("A", format!("{}", cfg.detector.picoammeter().range)),
                _ => (
                    "V",
                    format!("{} V", cfg.detector.lockin.sensitivity.volts()),
                ),
            };
            t.push(
                "configuration",
                family,
                r.is_valid(),
                format!(
                    "range index {}, full scale {:e} {unit}, integration {} s",
                    c.range, c.full_scale, c.integration_s
                ),
                format!(
                    "a valid reading on the configured range {want} (or where autoranging took it)"
                ),
                "6485 manual p. 4-2, 4-5; SR830 manual p. 5-6",
            );
        }
        Err(e) => t.push(
            "configuration",
            family,
            false,
            e.to_string(),
            "a reading",
            "the detector's manual",
        ),
    }
}

fn home<C: Clock + Clone + 'static>(g: &mut Goniometer<C>, t: &mut Tally) {
    let names = g.motion.axis_names();
    let mut lost = Vec::new();
    for n in &names {
        match g.motion.state(n) {
            Ok(AxisState::Referenced) => {}
            Ok(_) => lost.push(n.clone()),
            Err(e) => {
                t.push(
                    "home",
                    n,
                    false,
                    e.to_string(),
                    "its state",
                    "the family's manual",
                );
                return;
            }
        }
    }
    if lost.is_empty() {
        return;
    }
    let refs: Vec<&str> = lost.iter().map(String::as_str).collect();
    let r = g.motion.home(&refs);
    t.push(
        "home",
        &lost.join(", "),
        r.is_ok(),
        r.map_or_else(|e| e.to_string(), |()| "homed".into()),
        "each axis without its reference homes (as a run does first)",
        "SMC100 OR p. 39; APT MOT_MOVE_HOME p. 80",
    );
}

/// Where the arms may not go: the source and detector closer than the geometry's
/// minimum separation, where the detector arm blocks the beam or the arms collide. A
/// move of the self-test is made only where the planner would allow the stages.
struct Arms {
    mech: gonio_core::goniometer::Mechanics,
}

impl Arms {
    fn of(cfg: &InstrumentConfig) -> Option<Arms> {
        cfg.mechanics().ok().map(|mech| Arms { mech })
    }

    /// True when moving `name` to `target`, the other role axes where they stand,
    /// keeps the arms apart, or at least brings them no closer than they are (after
    /// homing, the arms may stand together); always, without kinematics.
    fn allow<C: Clock + Clone + 'static>(
        arms: Option<&Arms>,
        g: &mut Goniometer<C>,
        name: &str,
        target: f64,
    ) -> bool {
        let Some(a) = arms else {
            return true;
        };
        let mut now = [0.0; 4];
        for (i, axis) in a.mech.axes.iter().enumerate() {
            match g.motion.position(axis) {
                Ok(p) => now[i] = p,
                Err(_) => return false,
            }
        }
        let mut then = now;
        for (i, axis) in a.mech.axes.iter().enumerate() {
            if axis == name {
                then[i] = target;
            }
        }
        let sep =
            |s: [f64; 4]| gonio_core::kinematics::arm_separation_deg(a.mech.layout.forward(s));
        let after = sep(then);
        after >= a.mech.geometry.min_arm_separation_deg || after >= sep(now) - 1e-9
    }
}

/// Targets `d` either side of `p` (kept `d` inside the limits where they allow),
/// each within `[min, max]`.
fn targets(p: f64, d: f64, min: f64, max: f64) -> [f64; 2] {
    let margin = ((max - min) / 4.0).min(d.abs());
    let centre = p.clamp(min + margin, max - margin);
    [(centre + d).clamp(min, max), (centre - d).clamp(min, max)]
}

fn apt_moves<C: Clock + Clone + 'static>(
    g: &mut Goniometer<C>,
    arms: Option<&Arms>,
    opts: &SelftestOptions,
    t: &mut Tally,
) {
    let clock = g.motion.clock().clone();
    // The APT axes and the ends of their short moves, where both keep the arms apart.
    let mut plans: Vec<(String, Option<[f64; 2]>)> = Vec::new();
    let apt: Vec<(String, f64, f64)> = g
        .motion
        .lines_mut()
        .iter_mut()
        .filter_map(|l| match family::<C>(l.as_any_mut())? {
            Family::Apt(axis) => {
                let a = axis.axis();
                Some((a.name.clone(), a.min, a.max))
            }
            Family::Smc100(_) => None,
        })
        .collect();
    for (name, min, max) in apt {
        let ends = g.motion.position(&name).ok().and_then(|p| {
            // Short moves back and forth, well inside the soft limits.
            let amp = (max - min).min(4.0) / 4.0;
            let ends = targets(p, amp, min, max);
            ends.iter()
                .all(|&x| Arms::allow(arms, g, &name, x))
                .then_some(ends)
        });
        plans.push((name, ends));
    }
    for line in g.motion.lines_mut() {
        let Some(Family::Apt(axis)) = family::<C>(line.as_any_mut()) else {
            continue;
        };
        let name = axis.axis().name.clone();
        let Some(ends) = plans.iter().find(|(n, _)| *n == name).and_then(|p| p.1) else {
            t.push(
                "apt moves",
                &name,
                false,
                "not run: no position, or its short moves would bring the arms too close".into(),
                "moves that keep the arms apart",
                "the instrument config's geometry",
            );
            continue;
        };
        let before = axis.completions_received();
        let t_start = clock.now();
        let mut done = 0u64;
        let mut fault = None;
        for i in 0..opts.apt_moves {
            let moved = axis.move_to(ends[i % 2]).and_then(|_| {
                // A move may end on a settled status before its completion is in.
                if axis.completions_received() - before < done + 1 {
                    axis.await_completion(Duration::from_millis(500))?;
                }
                Ok(())
            });
            match moved {
                Ok(()) => done += 1,
                Err(e) => {
                    fault = Some(e.to_string());
                    break;
                }
            }
        }
        let completions = axis.completions_received() - before;
        let took = clock.now().saturating_sub(t_start).as_secs_f64();
        t.push(
            "apt moves",
            &name,
            fault.is_none() && completions == opts.apt_moves as u64,
            format!(
                "{done} of {} moves between {:.3}° and {:.3}° done in {took:.1} s, {completions} MOT_MOVE_COMPLETED{}",
                opts.apt_moves,
                ends[0],
                ends[1],
                fault.map(|f| format!("; then: {f}")).unwrap_or_default()
            ),
            "every move ends, and each sends MOT_MOVE_COMPLETED; without the host's server-alive at least once a second the controller stops after about 50 status messages",
            "APT manual, MOT_MOVE_COMPLETED p. 83, MOT_ACK_DCSTATUSUPDATE p. 130",
        );
        for (message, data_bytes, count) in axis.status_lengths() {
            t.lengths.push(StatusLength {
                axis: name.clone(),
                message,
                data_bytes,
                count,
            });
        }
    }
}

/// How long a move of `d` takes by the controller's own model: an SMC100's `PT`
/// (manual p. 43, its working velocity, acceleration and jerk time), or the trapezoid
/// of an APT controller's velocity parameters (manual §8, p. 39); with what it rests on.
fn model_time<C: Clock + Clone + 'static>(
    g: &mut Goniometer<C>,
    name: &str,
    d: f64,
) -> Option<(f64, String)> {
    for line in g.motion.lines_mut() {
        if line.limits(name).is_none() {
            continue;
        }
        return match family::<C>(line.as_any_mut())? {
            Family::Smc100(chain) => chain
                .motion_time(name, d)
                .ok()
                .map(|t| (t, format!("the controller's `PT{:.3}`", d.abs()))),
            Family::Apt(axis) => axis.velocity_params().ok().map(|(v, a)| {
                (
                    trapezoid_time(d, v, a),
                    format!("the trapezoid at {v:.3} deg/s and {a:.3} deg/s²"),
                )
            }),
        };
    }
    None
}

fn move_times<C: Clock + Clone + 'static>(
    g: &mut Goniometer<C>,
    arms: Option<&Arms>,
    t: &mut Tally,
) {
    let clock = g.motion.clock().clone();
    let axes: Vec<(String, f64, f64)> = g
        .motion
        .axis_names()
        .into_iter()
        .filter_map(|n| {
            let (min, max, _) = g.motion.lines().iter().find_map(|l| l.limits(&n))?;
            Some((n, min, max))
        })
        .collect();
    for (name, min, max) in axes {
        let Ok(p) = g.motion.position(&name) else {
            continue;
        };
        let d = ((max - min) / 4.0).min(10.0);
        let Some(target) = targets(p, d, min, max)
            .into_iter()
            .find(|&x| Arms::allow(arms, g, &name, x))
        else {
            t.push(
                "move time",
                &name,
                true,
                format!(
                    "not timed: {d:.1}° either way from {p:.3}° would bring the arms too close"
                ),
                "the arms kept apart",
                "the instrument config's geometry",
            );
            continue;
        };
        let Some((model, basis)) = model_time(g, &name, target - p) else {
            t.push(
                "move time",
                &name,
                false,
                "no motion time from the controller".into(),
                "`PT` or the velocity parameters",
                "SMC100 PT p. 43; APT MOT_REQ_VELPARAMS p. 66",
            );
            continue;
        };
        let t0 = clock.now();
        let r = g.motion.move_to(&[(name.as_str(), target)]);
        let took = clock.now().saturating_sub(t0).as_secs_f64();
        // Polling, replies and settling add to the profile: at most the engine's own
        // move allowance (1.5 × the profile + 2 s) is a working stage.
        let passed = r.is_ok() && took >= 0.95 * model && took <= 1.5 * model + 2.0;
        t.push(
            "move time",
            &name,
            passed,
            match r {
                Ok(_) => format!(
                    "{:.3}° in {took:.3} s ({:.2} × the model's {model:.3} s)",
                    target - p,
                    took / model.max(1e-9)
                ),
                Err(e) => e.to_string(),
            },
            format!("{basis}, plus the polling: within 1.5 × + 2 s"),
            "SMC100 PT p. 43; APT §8 p. 39",
        );
    }
}

fn noise_floor<C: Clock + Clone + 'static>(
    g: &mut Goniometer<C>,
    bench: &mut dyn Bench,
    opts: &SelftestOptions,
    t: &mut Tally,
) {
    let family = g.detector.family();
    let shutter = g.spectral.as_ref().is_some_and(|s| s.has_shutter());
    let blocked = if shutter {
        g.spectral
            .as_mut()
            .map(|s| s.set_shutter(false).map_err(|e| e.to_string()))
    } else {
        Some(ask(g, bench, Setup::Dark).map_err(|e| e.to_string()))
    };
    if let Some(Err(e)) = blocked {
        t.push(
            "noise floor",
            family,
            false,
            e,
            "the beam blocked",
            "Gonio's bench",
        );
        return;
    }
    g.detector.input_changed();
    let mut means = Vec::new();
    let mut fault = None;
    for _ in 0..opts.dark_readings.max(2) {
        match g.detector.read() {
            Ok(r) if r.is_valid() => means.push(r.columns().mean),
            Ok(r) => {
                fault = Some(format!("a flagged reading: {}", r.flags_text()));
                break;
            }
            Err(e) => {
                fault = Some(e.to_string());
                break;
            }
        }
    }
    let n = means.len() as f64;
    let mean = means.iter().sum::<f64>() / n.max(1.0);
    let sd = (means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt();
    let unit = if family == "k6485" { "A" } else { "V" };
    t.push(
        "noise floor",
        family,
        fault.is_none(),
        match &fault {
            None => format!(
                "{} dark readings: mean {mean:.3e} {unit}, sd {sd:.3e} {unit}",
                means.len()
            ),
            Some(f) => f.clone(),
        },
        "valid readings with the beam blocked: the floor every reading's uncertainty starts from",
        "6485 manual Appendix A (noise); SR830 manual p. 3-3",
    );
    // The beam back, as a run expects to find it.
    if shutter {
        if let Some(s) = g.spectral.as_mut() {
            let _ = s.set_shutter(true);
        }
    } else {
        let _ = ask(g, bench, Setup::Sample);
    }
    g.detector.input_changed();
}

/// Asks the bench for `setup`, the instrument's lines kept alive while a person
/// answers.
fn ask<C: Clock + Clone + 'static>(
    g: &Goniometer<C>,
    bench: &mut dyn Bench,
    setup: Setup,
) -> Result<(), crate::bench::BenchError> {
    if bench.waits_for_a_person() {
        g.while_a_person_answers(|| bench.set_up(setup))
    } else {
        bench.set_up(setup)
    }
}

fn keepalive<C: Clock + Clone + 'static>(g: &mut Goniometer<C>, t0: Duration, t: &mut Tally) {
    let now = g.motion.clock().now();
    for (port, sent, gap) in g.heartbeat().report(t0, now) {
        t.push(
            "keep-alive",
            &port,
            gap <= Duration::from_secs(1),
            format!(
                "{sent} MOT_ACK_DCSTATUSUPDATE sent, longest gap {:.3} s",
                gap.as_secs_f64()
            ),
            "at least one a second for the whole session",
            "APT manual p. 130",
        );
    }
}
