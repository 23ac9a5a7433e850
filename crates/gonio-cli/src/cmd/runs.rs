//! `gonio runs` and `gonio show`: what run files hold.

use std::io::Write;
use std::path::PathBuf;

use gonio_run::RunStore;
use serde_json::json;

use crate::cmd::prepare::hms;
use crate::error::{CliError, CliResult};
use crate::flags::JsonFlag;
use crate::output;

/// `gonio runs`: list the run files in a directory.
#[derive(clap::Args)]
pub struct RunsArgs {
    /// The directory.
    dir: PathBuf,
    #[command(flatten)]
    json: JsonFlag,
}

/// `gonio show`: a run's status, counts, durations and configs.
#[derive(clap::Args)]
pub struct ShowArgs {
    /// The run file.
    run: PathBuf,
    #[command(flatten)]
    json: JsonFlag,
}

fn input(e: impl std::fmt::Display) -> CliError {
    CliError::Input(e.to_string())
}

/// `gonio show RUN [--json]`.
pub fn show(a: ShowArgs) -> CliResult<()> {
    let (path, json) = (a.run.as_path(), a.json.json);
    // Examined before SQLite opens it: a FIFO would hold the open forever.
    gonio_core::input::regular_file(path).map_err(input)?;
    let store = RunStore::open_read_only(path)?;
    let s = gonio_run::summary(&store)?;
    if json {
        return output::json(
            &serde_json::to_value(&s).map_err(|e| CliError::Runtime(e.to_string()))?,
        );
    }
    let mut w = output::stdout();
    output::finish((|| {
        writeln!(w, "{}: {}", s.path, s.status)?;
        if let Some(note) = &s.status_note {
            writeln!(w, "  {note}")?;
        }
        if let Some(n) = &s.name {
            writeln!(w, "name: {n}")?;
        }
        writeln!(
            w,
            "created {} by {}{}",
            s.created.as_deref().unwrap_or("?"),
            s.software.as_deref().unwrap_or("?"),
            s.seed
                .as_ref()
                .map(|x| format!(", seed {x}"))
                .unwrap_or_default()
        )?;
        if let Some(n) = &s.notes {
            writeln!(w, "notes: {n}")?;
        }
        let states: Vec<String> = s.states.iter().map(|(k, v)| format!("{v} {k}")).collect();
        writeln!(w, "steps: {} ({})", s.steps, states.join(", "))?;
        let kinds: Vec<String> = s
            .done_by_kind
            .iter()
            .map(|(k, v)| format!("{v} {k}"))
            .collect();
        writeln!(
            w,
            "readings: {} ; {} flagged, {} exchanges retried",
            kinds.join(", "),
            s.flagged,
            s.retries
        )?;
        // The whole estimate (start-up and band changes included, as `plan check`
        // totals it); files written before those were estimated lack them: 0.
        let part = |k: &str| s.estimate.get(k).and_then(serde_json::Value::as_f64);
        if let Some(t) = part("motion_s") {
            let (d, b, u) = (
                part("detector_s").unwrap_or(0.0),
                part("band_s").unwrap_or(0.0),
                part("startup_s").unwrap_or(0.0),
            );
            let bands = if b > 0.0 {
                format!(", band changes {}", hms(b))
            } else {
                String::new()
            };
            writeln!(
                w,
                "estimated: {} (start-up {}, motion {}{bands}, detector {})",
                hms(u + t + b + d),
                hms(u),
                hms(t),
                hms(d)
            )?;
        }
        if let Some(b) = &s.batches {
            writeln!(
                w,
                "adaptive: {} batches decided during the run, {} points in {} steps (the \
                 estimate above is the coarse pass's)",
                b.decided, b.points, b.steps
            )?;
        }
        for (k, x) in s.sessions.iter().enumerate() {
            writeln!(
                w,
                "session {}: {} → {} {}; {} readings, {} instrument time",
                k + 1,
                x.started,
                x.ended.as_deref().unwrap_or("(no clean stop)"),
                x.outcome.as_deref().unwrap_or(""),
                x.readings,
                hms(x.physical_s)
            )?;
        }
        let ev: Vec<String> = s.events.iter().map(|(k, v)| format!("{v} {k}")).collect();
        writeln!(w, "events: {}", ev.join(", "))?;
        writeln!(w, "--- instrument config ---\n{}", s.instrument.trim_end())?;
        writeln!(w, "--- plan ---\n{}", s.plan.trim_end())?;
        if let Some(sim) = &s.sim {
            writeln!(w, "--- simulator config ---\n{}", sim.trim_end())?;
        }
        w.flush()
    })())
}

/// `gonio runs DIR [--json]`: every `.gonio` file in DIR, damaged ones included.
pub fn runs(a: RunsArgs) -> CliResult<()> {
    let (dir, json) = (a.dir.as_path(), a.json.json);
    let entries = std::fs::read_dir(dir).map_err(|e| input(format!("{}: {e}", dir.display())))?;
    // Only regular files, told by their metadata before anything is opened: a FIFO
    // named `x.gonio` would block the open, a device would never end.
    let mut paths: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "gonio"))
        .filter(|p| match gonio_core::input::regular_file(p) {
            Ok(_) => true,
            Err(e) => {
                tracing::warn!("skipped: {e}");
                false
            }
        })
        .collect();
    paths.sort();
    let mut rows = Vec::new();
    for p in &paths {
        let row = match RunStore::open_read_only(p).and_then(|s| gonio_run::summary(&s)) {
            Ok(s) => json!({
                "path": p.display().to_string(), "name": s.name, "status": s.status,
                "steps": s.steps,
                "done": s.states.get("done").copied().unwrap_or(0),
                "failed": s.states.get("failed").copied().unwrap_or(0),
                "created": s.created, "sessions": s.sessions.len(),
            }),
            Err(e) => json!({
                "path": p.display().to_string(), "status": "unreadable", "error": e.to_string(),
            }),
        };
        rows.push(row);
    }
    if json {
        return output::json(&json!({ "dir": dir.display().to_string(), "runs": rows }));
    }
    let mut w = output::stdout();
    output::finish((|| {
        for r in &rows {
            let name = r["path"].as_str().unwrap_or("");
            match r.get("error") {
                Some(e) => writeln!(w, "{name}  unreadable: {}", e.as_str().unwrap_or(""))?,
                None => writeln!(
                    w,
                    "{name}  {:<11} {}/{} steps  {}  {}",
                    r["status"].as_str().unwrap_or(""),
                    r["done"],
                    r["steps"],
                    r["created"].as_str().unwrap_or(""),
                    r["name"].as_str().unwrap_or("")
                )?,
            }
        }
        if rows.is_empty() {
            writeln!(w, "{}: no run files", dir.display())?;
        }
        w.flush()
    })())
}
