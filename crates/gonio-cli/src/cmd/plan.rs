//! `gonio plan check`: what a plan measures on an instrument, what it cannot and
//! why, and how long it takes.

use std::io::Write;
use std::path::PathBuf;

use gonio_plan::rejection_counts;
use serde_json::json;

use crate::cmd::estimate::RunEstimate;
use crate::cmd::prepare::{hms, load_and_prepare};
use crate::cmd::reading_time::{ReadingTime, Source};
use crate::error::CliResult;
use crate::flags::JsonFlag;
use crate::output;

/// `gonio plan`: check a measurement plan against an instrument.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Map every pair through the instrument's kinematics; list the pairs left out
    /// (outside the limits, shadowed, overfilled, below the horizon, duplicated) and
    /// estimate the motion, band-change and detector time; with several bands, say
    /// which loop (wavelength or geometry) is inside and why.
    Check(CheckArgs),
    /// Measure an adaptive plan and uniform plans of the same number of points on
    /// the simulated instrument, and compare each reconstruction's error against the
    /// simulated sample (cosine-weighted relative RMS on an outgoing grid at the
    /// plan's incidences).
    Compare(crate::cmd::compare::CompareArgs),
}

/// `gonio plan check`.
#[derive(clap::Args)]
pub struct CheckArgs {
    /// The plan (TOML).
    plan: PathBuf,
    /// The instrument config (TOML).
    #[arg(long)]
    instrument: PathBuf,
    /// For a plan with a `[reading]` target: a previous run whose readings give the
    /// signal expected at each step (the nearest reading of the same kind), instead
    /// of the simulated sample.
    #[arg(long, value_name = "RUN")]
    like: Option<PathBuf>,
    #[command(flatten)]
    sim: crate::cmd::instrument::SimFlag,
    #[command(flatten)]
    json: JsonFlag,
}

/// Runs `gonio plan …`.
pub fn run(c: Command) -> CliResult<()> {
    match c {
        Command::Check(a) => plan_check(&a),
        Command::Compare(a) => crate::cmd::compare::compare(a),
    }
}

/// What `plan check` finds: the plan prepared on the instrument and the whole run's
/// estimate, its readings from the signals expected at each step when they are
/// known.
pub(crate) struct PlanCheck {
    prepared: gonio_plan::Prepared,
    estimate: RunEstimate,
    targeted: bool,
    /// The detector is a lock-in that autoranges.
    autoranging: bool,
}

/// What each term shared by every sample will contribute, from the schedule's
/// calibration readings: (term, readings per band each time, what it adds).
fn shared_terms(p: &gonio_plan::Prepared) -> Vec<(&'static str, usize, String)> {
    use gonio_plan::StepKind;
    let s = &p.schedule;
    // The first band's steps stand for every band's; the calibrations before its
    // first sample for each time they are taken.
    let band = s.steps.first().and_then(|x| x.channel.clone());
    let first = s
        .steps
        .iter()
        .position(|x| x.kind == StepKind::Sample)
        .unwrap_or(s.steps.len());
    let count = |k: StepKind| {
        s.steps[..first]
            .iter()
            .filter(|x| x.kind == k && x.channel == band)
            .count()
    };
    let again = s.steps[first..]
        .iter()
        .any(|x| x.kind == StepKind::Incident || x.kind == StepKind::Standard);
    let mut out = Vec::new();
    let dark = count(StepKind::Dark);
    if dark > 0 {
        out.push((
            "dark",
            dark,
            format!(
                "subtracted from every reading: its error is 1/√{dark} = {:.2} of one reading's \
                 noise at the floor, in every sample (a sample at the floor: {:.0}% of its variance)",
                (dark as f64).recip().sqrt(),
                100.0 / (1.0 + dark as f64)
            ),
        ));
    }
    for (term, kind) in [
        ("calibration (incident beam)", StepKind::Incident),
        ("calibration (standard)", StepKind::Standard),
    ] {
        let n = count(kind);
        if n > 0 {
            out.push((
                term,
                n,
                format!(
                    "one scale for every sample: 1/√{n} = {:.2} of one calibration reading's \
                     relative noise{}",
                    (n as f64).recip().sqrt(),
                    if again {
                        "; taken again at the end and interpolated in time"
                    } else {
                        ""
                    }
                ),
            ));
        }
    }
    let refs = s
        .steps
        .iter()
        .filter(|x| x.kind == StepKind::Reference && x.channel == band)
        .count();
    if refs > 0 {
        out.push((
            "drift",
            refs,
            "the source's level between the drift references: each sample carries the \
             interpolated references' noise, shared with the samples of its segment"
                .to_string(),
        ));
    }
    out
}

/// The fraction of motion time the schedule saves against the plan's order.
fn motion_saving(s: &gonio_plan::Schedule) -> f64 {
    if s.raster_motion_s > 0.0 {
        1.0 - s.motion_s / s.raster_motion_s
    } else {
        0.0
    }
}

/// Checks the plan against the instrument as `plan check` does, printing nothing.
pub(crate) fn compute(a: &CheckArgs) -> CliResult<PlanCheck> {
    let (plan, instrument) = (a.plan.as_path(), a.instrument.as_path());
    let loaded = load_and_prepare(instrument, plan)?;
    // A simulated instrument: the simulator's sample gives the signals, its
    // controllers where the stages stand at power-up.
    let sim = if a.sim.sim.is_some()
        || crate::cmd::instrument::is_simulated(&loaded.instrument, instrument)?
    {
        Some(crate::cmd::instrument::sim_config(a.sim.sim.as_deref())?)
    } else {
        None
    };
    let signals = match (&a.like, &sim) {
        (Some(run), _) => Some(Source::Run(run)),
        (None, Some(cfg)) => Some(Source::Sim(Box::new(cfg.clone()))),
        (None, None) => None,
    };
    let estimate = RunEstimate::of(&loaded, signals, sim.as_ref())?;
    Ok(PlanCheck {
        targeted: loaded.plan.reading.is_some(),
        autoranging: loaded.instrument.detector.kind == gonio_driver::config::DetectorKind::Sr830
            && loaded.instrument.detector.lockin.autorange,
        prepared: loaded.prepared,
        estimate,
    })
}

impl PlanCheck {
    /// An adaptive plan's summary, its time per later point and whole run from the
    /// run's estimate (start-up, exchanges and expected readings included).
    fn adaptive(&self) -> Option<gonio_plan::adaptive::Summary> {
        let mut a = self.prepared.adaptive.clone()?;
        if let Some(x) = &self.estimate.adaptive {
            a.point_s = x.point_s;
            a.estimate_s = x.whole_s;
        }
        Some(a)
    }

    /// The `--json` object.
    pub(crate) fn json(&self, a: &CheckArgs) -> serde_json::Value {
        let (p, e) = (&self.prepared, &self.estimate);
        let s = &p.schedule;
        let rejected: Vec<_> = p
            .checked
            .rejected
            .iter()
            .map(|r| {
                json!({
                    "index": r.index,
                    "theta_i": r.pair.incident.theta_deg, "phi_i": r.pair.incident.phi_deg,
                    "theta_o": r.pair.outgoing.theta_deg, "phi_o": r.pair.outgoing.phi_deg,
                    "reason": r.reason.name(), "detail": r.reason.to_string(),
                })
            })
            .collect();
        json!({
            "plan": a.plan.display().to_string(),
            "instrument": a.instrument.display().to_string(),
            "pairs": p.pairs.len(),
            "accepted": p.checked.accepted.len(),
            "rejected_by_reason": rejection_counts(&p.checked),
            "rejected": rejected,
            "steps": s.steps.len(),
            "estimate": {
                "startup_s": e.startup_s,
                "motion_s": e.motion_s, "raster_motion_s": s.raster_motion_s,
                "motion_saving": motion_saving(s), "detector_s": e.detector_s,
                "fixed_detector_s": s.detector_s,
                "band_s": e.band_s, "total_s": e.total_s,
            },
            "spectral": s.spectral,
            "shared_terms": shared_terms(p)
                .into_iter()
                .map(|(term, readings, effect)| json!({
                    "term": term, "readings": readings, "effect": effect,
                }))
                .collect::<Vec<_>>(),
            "adaptive": self.adaptive(),
            "reading": e.reading,
        })
    }
}

/// `gonio plan check PLAN --instrument INSTR [--like RUN] [--sim SIM] [--json]`.
fn plan_check(a: &CheckArgs) -> CliResult<()> {
    let c = compute(a)?;
    if a.json.json {
        return output::json(&c.json(a));
    }
    let plan = a.plan.as_path();
    let (p, e, targeted) = (&c.prepared, &c.estimate, c.targeted);
    let s = &p.schedule;
    let gain = motion_saving(s);
    let mut w = output::stdout();
    output::finish((|| {
        writeln!(
            w,
            "{}: {} pairs, {} measurable, {} left out",
            plan.display(),
            p.pairs.len(),
            p.checked.accepted.len(),
            p.checked.rejected.len()
        )?;
        for (reason, n) in rejection_counts(&p.checked) {
            writeln!(w, "  {reason}: {n}")?;
        }
        for r in &p.checked.rejected {
            writeln!(
                w,
                "  pair {} (θi {}, φi {}, θo {}, φo {}): {}",
                r.index,
                r.pair.incident.theta_deg,
                r.pair.incident.phi_deg,
                r.pair.outgoing.theta_deg,
                r.pair.outgoing.phi_deg,
                r.reason
            )?;
        }
        writeln!(
            w,
            "{} steps; start-up {}, motion {} ({} in plan order, {:.0}% less), detector {}, \
             {}total {}",
            s.steps.len(),
            hms(e.startup_s),
            hms(e.motion_s),
            hms(s.raster_motion_s),
            100.0 * gain,
            hms(e.detector_s),
            if e.band_s > 0.0 {
                format!("band changes {}, ", hms(e.band_s))
            } else {
                String::new()
            },
            hms(e.total_s)
        )?;
        if let Some(a) = c.adaptive() {
            adaptive_summary(&mut w, &a)?;
        }
        for (term, n, effect) in shared_terms(p) {
            writeln!(w, "shared term {term}: {n} reading(s) a band; {effect}")?;
        }
        match &e.reading {
            Some(r) if r.targeted => reading_summary(&mut w, r, s)?,
            Some(r) => writeln!(
                w,
                "fixed readings, signals from {}: {} range changes expected ({} of the \
                 detector's {})",
                r.source,
                r.range_changes,
                hms(r.ranging_s),
                hms(r.detector_s)
            )?,
            None => {}
        }
        if e.reading.is_none() && targeted {
            writeln!(
                w,
                "reading to a target: the detector time above is the fixed reading's; the \
                 targeted estimate needs an SR830 with `noise` in [detector.lockin] and the \
                 signals to expect (--like RUN, or --sim SIM for a simulated instrument)"
            )?;
        } else if e.reading.is_none() && c.autoranging {
            writeln!(
                w,
                "fixed readings: the range changes autoranging makes are not counted without \
                 the signals to expect (--like RUN, or --sim SIM that stands for the \
                 instrument)"
            )?;
        }
        if let Some(d) = &s.spectral {
            writeln!(
                w,
                "{} bands, {}{}",
                d.bands,
                d.reason,
                if d.alternate {
                    "; the sweeps over the bands alternate up and down"
                } else {
                    ""
                }
            )?;
        }
        w.flush()
    })())
}

/// What `plan check` says of a targeted plan: the detector's time, split, against the
/// fixed reading's (the total above counts the targeted one).
fn reading_summary(
    w: &mut impl Write,
    r: &ReadingTime,
    s: &gonio_plan::Schedule,
) -> std::io::Result<()> {
    let tcs: Vec<String> = r
        .time_constants
        .iter()
        .map(|(tc, n)| format!("{tc} × {n}"))
        .collect();
    writeln!(
        w,
        "reading to σ/f {:e} (floor {:.2e} V), signals from {}: detector {} (settling {}, \
         averaging {}, serial {}; {} range changes) against {} for fixed readings",
        r.sigma_relative,
        r.sigma_absolute,
        r.source,
        hms(r.detector_s),
        hms(r.settle_s),
        hms(r.averaging_s),
        hms(r.serial_s),
        r.range_changes,
        hms(s.detector_s),
    )?;
    writeln!(
        w,
        "  time constants: {}{}",
        tcs.join(", "),
        if r.capped > 0 {
            format!("; {} reading(s) expected to reach the cap", r.capped)
        } else {
            String::new()
        }
    )
}

/// What `plan check` says of an adaptive plan: the budget, the coarse pass (the
/// schedule above), the batches and their candidates, the whole run's estimate.
fn adaptive_summary(w: &mut impl Write, a: &gonio_plan::adaptive::Summary) -> std::io::Result<()> {
    use gonio_plan::adaptive::Budget;
    let budget = match a.budget {
        Budget::Points(p) => format!("{p} points"),
        Budget::Hours(h) => format!(
            "{} of instrument time, about {} points at {:.1} s a point",
            hms(h * 3600.0),
            a.points,
            a.point_s
        ),
    };
    writeln!(
        w,
        "adaptive: budget {budget}; the schedule above is the coarse pass ({} points, {:.0}% \
         of the budget); then batches of {} points chosen by {} among {} measurable \
         candidates ({} refused by the instrument); whole run estimated {}",
        a.coarse,
        100.0 * a.coarse as f64 / a.points.max(1) as f64,
        a.batch,
        a.method.as_str(),
        a.pool,
        a.refused,
        hms(a.estimate_s)
    )
}
