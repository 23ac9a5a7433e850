//! `gonio plan check`: what a plan measures on an instrument, what it cannot and
//! why, and how long it takes.

use std::io::Write;
use std::path::PathBuf;

use gonio_plan::rejection_counts;
use serde_json::json;

use crate::cmd::prepare::{hms, load_and_prepare};
use crate::cmd::reading_time::{ReadingTime, Source, estimate_plan};
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

/// `gonio plan check PLAN --instrument INSTR [--like RUN] [--sim SIM] [--json]`.
fn plan_check(a: &CheckArgs) -> CliResult<()> {
    let (plan, instrument, json) = (a.plan.as_path(), a.instrument.as_path(), a.json.json);
    let loaded = load_and_prepare(instrument, plan)?;
    let reading = match (&loaded.plan.reading, &a.like) {
        (None, _) => None,
        (Some(_), Some(run)) => estimate_plan(&loaded, Source::Run(run))?,
        (Some(_), None) => {
            if a.sim.sim.is_some()
                || crate::cmd::instrument::is_simulated(&loaded.instrument, instrument)?
            {
                let cfg = crate::cmd::instrument::sim_config(a.sim.sim.as_deref())?;
                estimate_plan(&loaded, Source::Sim(Box::new(cfg)))?
            } else {
                None
            }
        }
    };
    let targeted = loaded.plan.reading.is_some();
    let p = loaded.prepared;
    let s = &p.schedule;
    let gain = if s.raster_motion_s > 0.0 {
        1.0 - s.motion_s / s.raster_motion_s
    } else {
        0.0
    };
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
    if json {
        return output::json(&json!({
            "plan": plan.display().to_string(),
            "instrument": instrument.display().to_string(),
            "pairs": p.pairs.len(),
            "accepted": p.checked.accepted.len(),
            "rejected_by_reason": rejection_counts(&p.checked),
            "rejected": rejected,
            "steps": s.steps.len(),
            "estimate": {
                "motion_s": s.motion_s, "raster_motion_s": s.raster_motion_s,
                "motion_saving": gain, "detector_s": s.detector_s,
                "band_s": s.band_s, "total_s": s.duration_s(),
            },
            "spectral": s.spectral,
            "adaptive": p.adaptive,
            "reading": reading,
        }));
    }
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
            "{} steps; motion {} ({} in plan order, {:.0}% less), detector {}, {}total {}",
            s.steps.len(),
            hms(s.motion_s),
            hms(s.raster_motion_s),
            100.0 * gain,
            hms(s.detector_s),
            if s.band_s > 0.0 {
                format!("band changes {}, ", hms(s.band_s))
            } else {
                String::new()
            },
            hms(s.duration_s())
        )?;
        if let Some(a) = &p.adaptive {
            adaptive_summary(&mut w, a)?;
        }
        if let Some(r) = &reading {
            reading_summary(&mut w, r, s)?;
        } else if targeted {
            writeln!(
                w,
                "reading to a target: the detector time above is the fixed reading's; the \
                 targeted estimate needs an SR830 with `noise` in [detector.lockin] and the \
                 signals to expect (--like RUN, or --sim SIM for a simulated instrument)"
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
/// fixed reading's, and the run's total with it.
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
         averaging {}, serial {}) against {} for fixed readings; total {}",
        r.sigma_relative,
        r.sigma_absolute,
        r.source,
        hms(r.detector_s),
        hms(r.settle_s),
        hms(r.averaging_s),
        hms(r.serial_s),
        hms(s.detector_s),
        hms(s.duration_s() - s.detector_s + r.detector_s),
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
