//! `gonio plan check`: what a plan measures on an instrument, what it cannot and
//! why, and how long it takes.

use std::io::Write;
use std::path::{Path, PathBuf};

use gonio_plan::rejection_counts;
use serde_json::json;

use crate::cmd::prepare::{hms, load_and_prepare};
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
    #[command(flatten)]
    json: JsonFlag,
}

/// Runs `gonio plan …`.
pub fn run(c: Command) -> CliResult<()> {
    match c {
        Command::Check(a) => plan_check(&a.plan, &a.instrument, a.json.json),
        Command::Compare(a) => crate::cmd::compare::compare(a),
    }
}

/// `gonio plan check PLAN --instrument INSTR [--json]`.
fn plan_check(plan: &Path, instrument: &Path, json: bool) -> CliResult<()> {
    let p = load_and_prepare(instrument, plan)?.prepared;
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
