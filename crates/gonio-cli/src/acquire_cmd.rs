//! `gonio plan check`, `gonio acquire`, `gonio resume`, `gonio runs`, `gonio show`.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;

use gonio_acquire::engine::{Engine, EngineConfig, Event, Outcome, SessionReport};
use gonio_driver::{Bench, Clock, Goniometer, InstrumentConfig, OperatorBench, Transport};
use gonio_plan::{Plan, Prepared, rejection_counts};
use gonio_run::{Inputs, RunStore, StoreError};
use gonio_sim::SimBench;
use serde_json::json;

use crate::error::{CliError, CliResult};
use crate::instrument_cmd::{is_simulated, sim_config};
use crate::output;

/// The software name and version written into run files.
pub const SOFTWARE: &str = concat!("gonio ", env!("CARGO_PKG_VERSION"));

fn input(e: impl std::fmt::Display) -> CliError {
    CliError::Input(e.to_string())
}

fn store_err(e: StoreError) -> CliError {
    if e.is_bad_input() {
        CliError::Input(e.to_string())
    } else {
        CliError::Runtime(e.to_string())
    }
}

/// Loads an instrument and a plan and prepares the plan on it.
fn load_and_prepare(
    instrument: &Path,
    plan: &Path,
) -> CliResult<(InstrumentConfig, String, Plan, String, Prepared)> {
    let (inst, inst_text) = InstrumentConfig::load_with_text(instrument).map_err(input)?;
    let (plan_cfg, plan_text) = Plan::load(plan).map_err(input)?;
    let mech = inst
        .mechanics()
        .map_err(|e| input(format!("{}: {e}", instrument.display())))?;
    let prepared = gonio_plan::prepare(&mech, inst.reading_seconds(), &plan_cfg).map_err(input)?;
    Ok((inst, inst_text, plan_cfg, plan_text, prepared))
}

/// Seconds as `1h02m03s`.
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

/// `gonio plan check PLAN --instrument INSTR [--json]`.
pub fn plan_check(plan: &Path, instrument: &Path, json: bool) -> CliResult<()> {
    let (_, _, _, _, p) = load_and_prepare(instrument, plan)?;
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
                "total_s": s.duration_s(),
            },
        }));
    }
    let mut w = output::open(None)?;
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
            "{} steps; motion {} ({} in plan order, {:.0}% less), detector {}, total {}",
            s.steps.len(),
            hms(s.motion_s),
            hms(s.raster_motion_s),
            100.0 * gain,
            hms(s.detector_s),
            hms(s.duration_s())
        )?;
        w.flush()
    })())
}

/// What `acquire` and `resume` print at the end.
fn report_session(path: &Path, r: &SessionReport, json: bool) -> CliResult<()> {
    if json {
        output::json(&json!({
            "run": path.display().to_string(),
            "status": r.outcome.status(),
            "fault": match &r.outcome { Outcome::Faulted(m) => Some(m.clone()), _ => None },
            "measured": r.measured, "skipped": r.skipped,
            "finished": r.finished, "total": r.total,
            "physical_s": r.physical_s,
        }))?;
    } else {
        eprintln!(
            "gonio: {}: {} — {} of {} steps finished ({} measured, {} skipped this session, \
             {} of instrument time)",
            path.display(),
            r.outcome.status(),
            r.finished,
            r.total,
            r.measured,
            r.skipped,
            hms(r.physical_s)
        );
    }
    match &r.outcome {
        Outcome::Complete => Ok(()),
        Outcome::Interrupted => Err(CliError::Interrupted(format!(
            "{}: interrupted; `gonio resume {}` continues it",
            path.display(),
            path.display()
        ))),
        Outcome::Faulted(m) => Err(CliError::Runtime(format!(
            "{}: stopped by a fault ({m}); fix it, then `gonio resume {}`",
            path.display(),
            path.display()
        ))),
    }
}

/// Shows the engine's events on a progress bar (when stderr is a terminal).
async fn progress(mut rx: tokio::sync::broadcast::Receiver<Event>, quiet: bool) {
    let bar = if quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(0)
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{bar:30} {pos}/{len} steps  ETA {prefix} (instrument time)  {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut first_done = 0usize;
    loop {
        match rx.recv().await {
            Ok(Event::Started { done, total, .. }) => {
                bar.set_length(total as u64);
                bar.set_position(done as u64);
                first_done = done;
            }
            Ok(Event::Measured {
                done,
                total,
                r_mean,
                r_std,
                flags,
                physical_s,
                kind,
                ..
            }) => {
                bar.set_position(done as u64);
                let this_session = done.saturating_sub(first_done).max(1);
                let eta = physical_s / this_session as f64 * (total - done) as f64;
                bar.set_prefix(hms(eta));
                bar.set_message(format!(
                    "{}: R = {:.4e} ± {:.1e} V{}",
                    kind.as_str(),
                    r_mean,
                    r_std,
                    if flags != 0 { " (flagged)" } else { "" }
                ));
            }
            Ok(Event::Fault {
                message,
                recovering,
                ..
            }) => bar.println(format!(
                "gonio: fault: {message}{}",
                if recovering { " (recovering)" } else { "" }
            )),
            Ok(Event::Homed { axes }) => bar.println(format!("gonio: homed {}", axes.join(", "))),
            Ok(Event::Bench { what }) => bar.println(format!("gonio: bench: {what}")),
            Ok(Event::Skipped { step_id, reason }) => {
                bar.println(format!("gonio: step {step_id} skipped: {reason}"));
            }
            Ok(Event::Finished { .. }) | Err(tokio::sync::broadcast::error::RecvError::Closed) => {
                bar.finish_and_clear();
                return;
            }
            Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => {}
        }
    }
}

/// Runs one session of `engine`, with Ctrl-C: the first stops the stages and ends
/// the session `interrupted`; a second exits at once, after a moment for the stop to
/// reach the stages.
fn drive<M, D, C, B>(
    engine: Engine<M, D, C, B>,
    quiet: bool,
) -> CliResult<(SessionReport, RunStore)>
where
    M: Transport + Send + 'static,
    D: Transport + Send + 'static,
    C: Clock + Send + 'static,
    B: Bench + 'static,
{
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| CliError::Runtime(format!("starting the runtime: {e}")))?;
    let stopper = engine.stopper();
    let rx = engine.subscribe();
    rt.block_on(async move {
        tokio::spawn(async move {
            if tokio::signal::ctrl_c().await.is_ok() {
                eprintln!("\ngonio: stopping the stages (Ctrl-C again to quit at once)");
                stopper.stop();
                if tokio::signal::ctrl_c().await.is_ok() {
                    stopper.stop();
                    // The abort flag stops the stages at the driver's next poll.
                    tokio::time::sleep(Duration::from_millis(300)).await;
                    eprintln!("gonio: aborted");
                    std::process::exit(130);
                }
            }
        });
        let listener = tokio::spawn(progress(rx, quiet));
        let r = engine.run().await;
        let _ = listener.await;
        r
    })
    .map_err(|e| CliError::Runtime(e.to_string()))
}

/// Where a run's instrument lives.
pub(crate) enum Rig {
    /// The in-process simulator, built from these configs.
    Sim(Box<gonio_sim::SimConfig>),
    /// Real ports.
    Real,
}

/// Builds the engine for `store` on `instrument` and runs a session.
pub(crate) fn session(
    store: RunStore,
    instrument: &InstrumentConfig,
    instrument_name: &str,
    rig: Rig,
    standard: Option<String>,
    transmittance: f64,
    quiet: bool,
) -> CliResult<(SessionReport, RunStore)> {
    let mech = instrument
        .mechanics()
        .map_err(|e| input(format!("{instrument_name}: {e}")))?;
    let cfg = EngineConfig {
        incident_transmittance: transmittance,
        software: SOFTWARE.into(),
        ..EngineConfig::default()
    };
    match rig {
        Rig::Sim(sim) => {
            let (g, shared) = gonio_sim::connect(instrument, &sim).map_err(|e| match e {
                gonio_sim::SimError::Mismatch(m) => input(format!("{instrument_name}: {m}")),
                other => CliError::Runtime(other.to_string()),
            })?;
            let standard = match standard {
                Some(text) => {
                    let m = gonio_brdf::Model::from_toml(&text, None)
                        .map_err(|e| input(format!("reference standard model: {e}")))?;
                    Some((Box::new(m) as Box<dyn gonio_brdf::Brdf>, 0))
                }
                None => None,
            };
            drive(
                Engine::new(g, SimBench::new(shared, standard), store, mech, cfg),
                quiet,
            )
        }
        Rig::Real => {
            let g = Goniometer::open(instrument).map_err(|e| CliError::Runtime(e.to_string()))?;
            let bench =
                OperatorBench::new(std::io::BufReader::new(std::io::stdin()), std::io::stderr());
            drive(Engine::new(g, bench, store, mech, cfg), quiet)
        }
    }
}

/// `gonio acquire --instrument INSTR --plan PLAN --out RUN [--sim SIM] [--seed N]`.
pub struct AcquireArgs {
    /// Instrument config.
    pub instrument: PathBuf,
    /// Plan.
    pub plan: PathBuf,
    /// Run file to create.
    pub out: PathBuf,
    /// Simulator config for "sim" ports.
    pub sim: Option<PathBuf>,
    /// Seed override.
    pub seed: Option<u64>,
    /// Operator notes.
    pub notes: Option<String>,
    /// JSON report.
    pub json: bool,
}

/// `gonio acquire`.
pub fn acquire(a: AcquireArgs) -> CliResult<()> {
    let (inst, inst_text, plan, plan_text, prepared) = load_and_prepare(&a.instrument, &a.plan)?;
    let simulated = is_simulated(&inst, &a.instrument)?;
    let mut inputs = Inputs {
        instrument_text: inst_text,
        instrument_path: Some(a.instrument.clone()),
        plan_text,
        plan_path: Some(a.plan.clone()),
        seed: a.seed,
        notes: a.notes.clone(),
        software: SOFTWARE.into(),
        ..Inputs::default()
    };
    let rig = if simulated {
        let mut s = sim_config(a.sim.as_deref())?;
        if let Some(seed) = a.seed {
            s.seed = seed;
        }
        let sim_text = match &a.sim {
            Some(p) => {
                std::fs::read_to_string(p).map_err(|e| input(format!("{}: {e}", p.display())))?
            }
            None => gonio_sim::config::DEFAULT_SIM.to_string(),
        };
        let sample = s.sample_model_text().map_err(input)?;
        // The seed actually used, so that a resume reproduces it.
        inputs.seed = Some(s.seed);
        gonio_sim::check_compatible(&inst, &s)
            .map_err(|e| input(format!("{}: {e}", a.instrument.display())))?;
        inputs.sim = Some((sim_text, sample));
        Rig::Sim(Box::new(s))
    } else {
        Rig::Real
    };
    let store = gonio_run::create(&a.out, &plan, &prepared, &inputs).map_err(|e| match e {
        gonio_run::CreateError::Store(s) => store_err(s),
        other => input(other),
    })?;
    let stored = gonio_acquire::stored(&store).map_err(store_err)?;
    let s = &prepared.schedule;
    if !a.json {
        eprintln!(
            "gonio: {}: {} steps ({} pairs measurable, {} left out); estimated {} \
             (motion {}, detector {})",
            a.out.display(),
            s.steps.len(),
            prepared.checked.accepted.len(),
            prepared.checked.rejected.len(),
            hms(s.duration_s()),
            hms(s.motion_s),
            hms(s.detector_s)
        );
    }
    let (report, _) = session(
        store,
        &inst,
        &a.instrument.display().to_string(),
        rig,
        stored.standard_model,
        stored.transmittance,
        a.json,
    )?;
    report_session(&a.out, &report, a.json)
}

/// `gonio resume RUN [--json]`: continues a run where it stopped, with the
/// instrument (and simulator) its file records.
pub fn resume(path: &Path, json: bool) -> CliResult<()> {
    let store = RunStore::open(path).map_err(store_err)?;
    let status = store
        .meta_value("status")
        .map_err(store_err)?
        .unwrap_or_default();
    if status == "complete" {
        return Err(CliError::Input(format!(
            "{}: the run is complete; nothing to resume",
            path.display()
        )));
    }
    let stored = gonio_acquire::stored(&store).map_err(store_err)?;
    let rig = match &stored.sim {
        Some((sim_text, sample)) => {
            let mut s = gonio_sim::SimConfig::from_toml(sim_text, None)
                .map_err(|e| input(format!("{}: stored simulator config: {e}", path.display())))?;
            s.sample_text = Some(sample.clone());
            if let Some(seed) = stored.seed {
                s.seed = seed;
            }
            // A microgeometry sample's stored text is its table: no re-tracing.
            s.prepare_sample()
                .map_err(|e| input(format!("{}: stored sample: {e}", path.display())))?;
            Rig::Sim(Box::new(s))
        }
        None => Rig::Real,
    };
    let (report, _) = session(
        store,
        &stored.instrument,
        &format!("{} (stored instrument config)", path.display()),
        rig,
        stored.standard_model.clone(),
        stored.transmittance,
        json,
    )?;
    report_session(path, &report, json)
}

/// `gonio show RUN [--json]`.
pub fn show(path: &Path, json: bool) -> CliResult<()> {
    let store = RunStore::open(path).map_err(store_err)?;
    let s = gonio_run::summary(&store).map_err(store_err)?;
    if json {
        return output::json(
            &serde_json::to_value(&s).map_err(|e| CliError::Runtime(e.to_string()))?,
        );
    }
    let mut w = output::open(None)?;
    output::finish((|| {
        writeln!(w, "{}: {}", s.path, s.status)?;
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
        if let Some(t) = s
            .estimate
            .get("motion_s")
            .and_then(serde_json::Value::as_f64)
        {
            let d = s
                .estimate
                .get("detector_s")
                .and_then(serde_json::Value::as_f64)
                .unwrap_or(0.0);
            writeln!(
                w,
                "estimated: {} (motion {}, detector {})",
                hms(t + d),
                hms(t),
                hms(d)
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
pub fn runs(dir: &Path, json: bool) -> CliResult<()> {
    let entries = std::fs::read_dir(dir).map_err(|e| input(format!("{}: {e}", dir.display())))?;
    let mut paths: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "gonio"))
        .collect();
    paths.sort();
    let mut rows = Vec::new();
    for p in &paths {
        let row = match RunStore::open(p).and_then(|s| gonio_run::summary(&s)) {
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
    let mut w = output::open(None)?;
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
