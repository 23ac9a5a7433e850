//! `gonio acquire` and `gonio resume`: a plan measured into a run file, and a run
//! continued where it stopped.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use gonio_acquire::engine::{Engine, EngineConfig, Event, Outcome, SessionReport};
use gonio_driver::{Bench, Clock, Goniometer, InstrumentConfig, OperatorBench};
use gonio_run::{Inputs, RunStore};
use gonio_sim::SimBench;
use serde_json::json;

use crate::cmd::estimate::RunEstimate;
use crate::cmd::instrument::{SimFlag, is_simulated, sim_config};
use crate::cmd::prepare::{Loaded, hms, load_and_prepare};
use crate::cmd::reading_time::Source;
use crate::error::{CliError, CliResult};
use crate::output;

/// The software name and version written into run files.
pub const SOFTWARE: &str = concat!("gonio ", env!("CARGO_PKG_VERSION"));

/// `gonio acquire`: measure a plan into a new run file (`.gonio`).
#[derive(clap::Args)]
pub struct AcquireArgs {
    /// The instrument config (TOML).
    #[arg(long)]
    instrument: PathBuf,
    /// The plan (TOML).
    #[arg(long)]
    plan: PathBuf,
    /// The run file to create.
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    sim: SimFlag,
    /// Seed of the simulator's random draws (overrides its config).
    #[arg(long)]
    seed: Option<u64>,
    /// Operator notes stored with the run.
    #[arg(long)]
    notes: Option<String>,
    #[command(flatten)]
    log: LogFlag,
    #[command(flatten)]
    serve: ServeFlag,
    /// Print one JSON object at the end instead of progress and text.
    #[arg(long)]
    json: bool,
}

/// `gonio resume`: continue an interrupted or killed run.
impl AcquireArgs {
    /// The arguments of a quiet acquisition on the simulator: `sim` (the embedded
    /// default when none) with `seed`.
    pub(crate) fn simulated(
        instrument: PathBuf,
        plan: PathBuf,
        out: PathBuf,
        sim: Option<PathBuf>,
        seed: Option<u64>,
    ) -> AcquireArgs {
        AcquireArgs {
            instrument,
            plan,
            out,
            sim: SimFlag { sim },
            seed,
            notes: None,
            log: LogFlag { log: None },
            serve: ServeFlag::default(),
            json: true,
        }
    }
}

#[derive(clap::Args)]
pub struct ResumeArgs {
    /// The run file.
    run: PathBuf,
    #[command(flatten)]
    log: LogFlag,
    #[command(flatten)]
    serve: ServeFlag,
    /// Print one JSON object at the end instead of progress and text.
    #[arg(long)]
    json: bool,
}

/// `--serve [ADDR]` and `--control`: the run's live page (docs/live.md).
#[derive(Clone, Debug, Default, clap::Args)]
pub struct ServeFlag {
    /// Serve the run's live page while measuring, at ADDR: IP:PORT, a port, or an
    /// IP (default 127.0.0.1 at a free port); its address is printed on stderr.
    /// After a session that ends by itself or by the page's Stop, the page stays up,
    /// showing how it ended, until Ctrl-C.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "")]
    pub serve: Option<String>,
    /// Put Stop and Pause buttons on the page, allowed only with the random token
    /// printed in the page's address.
    #[arg(long, requires = "serve")]
    pub control: bool,
}

/// A live page about to be served: its address listened on, before the run exists.
#[derive(Debug)]
pub(crate) struct Serve {
    listener: std::net::TcpListener,
    control: bool,
}

impl ServeFlag {
    /// Listens on the address, if serving: before anything is created, so that a
    /// bad or busy address refuses the command whole (exit 2).
    pub(crate) fn bind(&self) -> CliResult<Option<Serve>> {
        let Some(text) = &self.serve else {
            return Ok(None);
        };
        let listener = gonio_live::bind(gonio_live::parse_addr(text)?)?;
        Ok(Some(Serve {
            listener,
            control: self.control,
        }))
    }
}

/// `/report.html` of the live page: `gonio report`'s page, made in memory.
pub(crate) fn live_report() -> gonio_live::ReportFn {
    Arc::new(|run: &Path| {
        crate::cmd::report::build_report(run, &crate::flags::ReduceFlags::default())
            .map(|c| gonio_io::report::html(&c))
            .map_err(|e| e.to_string())
    })
}

/// `--log FILE`.
#[derive(Clone, Debug, clap::Args)]
pub struct LogFlag {
    /// Also write the session's log (spans and events, serial exchanges with -vv) to
    /// FILE as JSON lines; the file must not exist. The run file's event log stays the
    /// record of the run.
    #[arg(long, value_name = "FILE")]
    pub log: Option<PathBuf>,
}

impl AcquireArgs {
    /// The run file to create.
    pub fn out_path(&self) -> &Path {
        &self.out
    }

    /// Where the log file goes, if any.
    pub fn log_file(&self) -> Option<&Path> {
        self.log.log.as_deref()
    }
}

impl ResumeArgs {
    /// The run file.
    pub fn run_path(&self) -> &Path {
        &self.run
    }

    /// Where the log file goes, if any.
    pub fn log_file(&self) -> Option<&Path> {
        self.log.log.as_deref()
    }
}

fn input(e: impl std::fmt::Display) -> CliError {
    CliError::Input(e.to_string())
}

/// What `acquire` and `resume` print at the end.
fn report_session(path: &Path, r: &SessionReport, json: bool) -> CliResult<()> {
    if json {
        output::json(&session_json(path, r))?;
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
    session_result(path, r)
}

/// The `--json` object of a session.
pub(crate) fn session_json(path: &Path, r: &SessionReport) -> serde_json::Value {
    json!({
        "run": path.display().to_string(),
        "status": r.outcome.status(),
        "fault": match &r.outcome { Outcome::Faulted(m) => Some(m.clone()), _ => None },
        "measured": r.measured, "skipped": r.skipped,
        "finished": r.finished, "total": r.total,
        "physical_s": r.physical_s,
    })
}

/// A session's end as a result: an error unless it completed.
pub(crate) fn session_result(path: &Path, r: &SessionReport) -> CliResult<()> {
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
    // Log lines (faults are logged at warn by the engine) are written around the bar.
    crate::logging::set_bar(Some(bar.clone()));
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
                    if gonio_run::flags::questioned(flags) {
                        " (flagged)"
                    } else {
                        ""
                    }
                ));
            }
            // The engine logs faults (warn); the log writes around the bar.
            Ok(Event::Fault { .. }) => {}
            Ok(Event::Homed { axes }) => bar.println(format!("gonio: homed {}", axes.join(", "))),
            Ok(Event::Bench { what }) => bar.println(format!("gonio: bench: {what}")),
            Ok(Event::Paused) => bar.println("gonio: paused (stages idle)"),
            Ok(Event::Resumed) => bar.println("gonio: pause ended"),
            // An adaptive plan's batch: the run grows.
            Ok(Event::Batch {
                batch,
                points,
                steps,
                total,
            }) => {
                bar.set_length(total as u64);
                bar.println(format!(
                    "gonio: batch {batch}: {points} points, {steps} steps"
                ));
            }
            // Logged by the engine (warn).
            Ok(Event::Skipped { .. }) => {}
            Ok(Event::Finished { .. }) | Err(tokio::sync::broadcast::error::RecvError::Closed) => {
                bar.finish_and_clear();
                crate::logging::set_bar(None);
                return;
            }
            Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => {}
        }
    }
}

/// Runs one session of `engine`, with the stop signals (Ctrl-C, SIGTERM, SIGHUP): the
/// first stops the stages and ends the session `interrupted`; a second exits at once,
/// after a moment for the stop to reach the stages.
///
/// With a live page, the page is served from the session's start; after its end
/// it stays up, showing how the session ended, until the next stop signal (unless a
/// stop signal ended the session).
fn drive<C, B>(
    engine: Engine<C, B>,
    run: &Path,
    how: Driving<'_>,
) -> CliResult<(SessionReport, RunStore)>
where
    C: Clock + Clone + Send + 'static,
    B: Bench + 'static,
{
    let Driving { quiet, stop, serve } = how;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| CliError::Runtime(format!("starting the runtime: {e}")))?;
    let stopper = engine.stopper();
    let rx = engine.subscribe();
    let signals = match stop {
        StopBy::Signals => {
            let _in_runtime = rt.enter();
            Some(
                crate::signals::StopSignals::new()
                    .map_err(|e| CliError::Runtime(format!("catching the stop signals: {e}")))?,
            )
        }
        StopBy::Caller(_) => None,
    };
    let caller = match stop {
        StopBy::Caller(w) => Some(w.clone()),
        StopBy::Signals => None,
    };
    // The caller's view of the session: its steps, as the progress bar shows them.
    let followed = caller.as_ref().map(|w| (w.clone(), engine.subscribe()));
    // Set once the session has ended: a signal then ends the live page's stay.
    let ended = Arc::new(AtomicBool::new(false));
    // Set by a stop signal during the session: whoever sent it wants the process to
    // end, so the page does not stay after the session.
    let signalled = Arc::new(AtomicBool::new(false));
    let linger = Arc::new(tokio::sync::Notify::new());
    let controls = gonio_live::Controls {
        stopper: engine.stopper(),
        pauser: engine.pauser(),
    };
    let live_events = serve.as_ref().map(|_| engine.subscribe());
    rt.block_on(async move {
        let server = match serve {
            Some(s) => {
                let srv = gonio_live::Server::start(
                    s.listener,
                    run,
                    gonio_live::Options {
                        control: s.control.then_some(controls),
                        report: Some(live_report()),
                        events: live_events,
                    },
                )?;
                if let Some(w) = &caller {
                    w.set_url(srv.url());
                }
                // A quiet caller shows the address itself, where its user looks.
                let shown_by_caller = quiet && caller.is_some();
                if !shown_by_caller {
                    if srv.token().is_some() {
                        eprintln!(
                            "gonio: live view at {} (the token allows Stop and Pause)",
                            srv.url()
                        );
                    } else {
                        eprintln!("gonio: live view at {}", srv.url());
                    }
                }
                Some(srv)
            }
            None => None,
        };
        if let Some(mut signals) = signals {
            let (ended, linger, signalled) = (ended.clone(), linger.clone(), signalled.clone());
            tokio::spawn(async move {
                let mut stops = 0;
                loop {
                    let sig = signals.next().await;
                    if ended.load(Ordering::SeqCst) {
                        linger.notify_one();
                        return;
                    }
                    signalled.store(true, Ordering::SeqCst);
                    stops += 1;
                    stopper.stop();
                    if stops == 1 {
                        eprintln!("\ngonio: {sig}: stopping the stages (again to quit at once)");
                        continue;
                    }
                    // The abort flag stops the stages at the driver's next poll.
                    tokio::time::sleep(Duration::from_millis(300)).await;
                    eprintln!("gonio: aborted");
                    std::process::exit(130);
                }
            });
        } else if let Some(w) = caller.clone() {
            // Another thread owns the interrupt (Python's KeyboardInterrupt): it
            // raises the flag, and the stop is the same as a signal's.
            tokio::spawn(async move {
                while !w.stopped() {
                    tokio::time::sleep(Duration::from_millis(20)).await;
                }
                stopper.stop();
            });
        }
        let listener = tokio::spawn(progress(rx, quiet));
        let follower = followed.map(|(w, rx)| tokio::spawn(crate::watch::follow(rx, w)));
        let r = engine.run().await;
        let _ = listener.await;
        if let Some(f) = follower {
            let _ = f.await;
        }
        if let Some(srv) = server {
            ended.store(true, Ordering::SeqCst);
            srv.session_ended();
            srv.settled(Duration::from_secs(30)).await;
            if matches!(stop, StopBy::Signals) && !signalled.load(Ordering::SeqCst) {
                let how = match &r {
                    Ok((report, _)) => report.outcome.status(),
                    Err(_) => "failed",
                };
                eprintln!(
                    "gonio: the session ended ({how}); the live view stays at {} until Ctrl-C",
                    srv.url()
                );
                linger.notified().await;
            }
            srv.stop().await;
        }
        r.map_err(|e| CliError::Runtime(e.to_string()))
    })
}

/// Where a run's instrument lives.
/// What stops a session safely: the process's stop signals (the command), or a flag
/// another thread raises (the Python package, whose interpreter owns SIGINT).
#[derive(Clone, Debug)]
pub enum StopBy {
    /// SIGINT, SIGTERM, SIGHUP; a second one quits at once.
    Signals,
    /// The caller's stop flag, polled every 20 ms; the caller also follows the
    /// session's progress and is told the live page's address.
    Caller(Arc<crate::watch::Watch>),
}

/// How a session runs: quietly (no progress bar) or not, what stops it, and
/// whether its live page is served.
#[derive(Debug)]
pub(crate) struct Driving<'a> {
    /// No progress bar.
    pub quiet: bool,
    /// What stops it.
    pub stop: &'a StopBy,
    /// The live page, listening already.
    pub serve: Option<Serve>,
}

/// What a session takes from the run's plan: the reference standard's model text,
/// the incident filter's transmittance, the `[reading]` target.
pub(crate) struct RunSetup {
    /// The reference standard's model text.
    pub standard: Option<String>,
    /// The incident-beam filter's transmittance.
    pub transmittance: f64,
    /// The reading target.
    pub reading: Option<gonio_acquire::engine::ReadTarget>,
}

pub(crate) enum Rig {
    /// The in-process simulator, built from these configs.
    Sim(Box<gonio_sim::SimConfig>),
    /// Real ports.
    Real,
}

/// Connects to `instrument` (and checks the reference standard), then opens the run
/// with `store` — last, so that nothing is created for a rig that cannot be used —
/// and runs a session.
pub(crate) fn session(
    store: impl FnOnce() -> CliResult<RunStore>,
    instrument: &InstrumentConfig,
    instrument_name: &str,
    rig: Rig,
    run: RunSetup,
    how: Driving<'_>,
) -> CliResult<(SessionReport, RunStore)> {
    let RunSetup {
        standard,
        transmittance,
        reading,
    } = run;
    let mech = instrument
        .mechanics()
        .map_err(|e| input(format!("{instrument_name}: {e}")))?;
    let cfg = EngineConfig {
        incident_transmittance: transmittance,
        software: SOFTWARE.into(),
        reading,
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
            let store = store()?;
            let run = store.path().to_path_buf();
            let planner = planner_for(&store, &mech, instrument)?;
            drive(
                with_planner(
                    Engine::new(g, SimBench::new(shared, standard), store, mech, cfg),
                    planner,
                ),
                &run,
                how,
            )
        }
        Rig::Real => {
            let g = Goniometer::open(instrument).map_err(|e| CliError::Runtime(e.to_string()))?;
            let bench =
                OperatorBench::new(std::io::BufReader::new(std::io::stdin()), std::io::stderr());
            let store = store()?;
            let run = store.path().to_path_buf();
            let planner = planner_for(&store, &mech, instrument)?;
            drive(
                with_planner(Engine::new(g, bench, store, mech, cfg), planner),
                &run,
                how,
            )
        }
    }
}

/// The adaptive planner of the run in `store`, if its plan is adaptive: built from
/// the plan the run file records, so that a resumed run decides as the first
/// session would have.
fn planner_for(
    store: &RunStore,
    mech: &gonio_plan::Mechanics,
    instrument: &InstrumentConfig,
) -> CliResult<Option<gonio_reduce::adaptive::Planner>> {
    gonio_reduce::adaptive::Planner::for_run(store, mech, instrument.reading_seconds())
        .map_err(|e| input(format!("{}: {e}", store.path().display())))
}

/// The engine, deciding an adaptive run's batches with `planner` when there is one.
fn with_planner<C, B>(
    engine: Engine<C, B>,
    planner: Option<gonio_reduce::adaptive::Planner>,
) -> Engine<C, B>
where
    C: Clock + Clone + Send + 'static,
    B: Bench + 'static,
{
    match planner {
        Some(mut p) => engine.with_planner(Box::new(move |store: &RunStore| {
            p.next(store).map_err(|e| e.to_string())
        })),
        None => engine,
    }
}

/// `gonio acquire --instrument INSTR --plan PLAN --out RUN [--sim SIM] [--seed N]`.
pub fn acquire(a: AcquireArgs) -> CliResult<()> {
    let report = acquire_with(&a, a.json, &StopBy::Signals)?;
    report_session(&a.out, &report, a.json)
}

/// Creates the run file and measures it; `quiet` prints nothing (no progress bar).
pub(crate) fn acquire_with(
    a: &AcquireArgs,
    quiet: bool,
    stop: &StopBy,
) -> CliResult<SessionReport> {
    let loaded = load_and_prepare(&a.instrument, &a.plan)?;
    let Loaded {
        instrument: inst,
        instrument_text: inst_text,
        plan,
        plan_text,
        prepared,
    } = &loaded;
    if a.out.exists() {
        return Err(CliError::from(gonio_run::StoreError::Exists(a.out.clone())));
    }
    let out_dir = output::parent(&a.out);
    if !out_dir.is_dir() {
        return Err(input(format!(
            "{}: the directory {} does not exist",
            a.out.display(),
            out_dir.display()
        )));
    }
    let simulated = is_simulated(inst, &a.instrument)?;
    let mut inputs = Inputs {
        instrument_text: inst_text.clone(),
        instrument_path: Some(a.instrument.clone()),
        plan_text: plan_text.clone(),
        plan_path: Some(a.plan.clone()),
        seed: a.seed,
        notes: a.notes.clone(),
        software: SOFTWARE.into(),
        ..Inputs::default()
    };
    let rig = if simulated {
        let mut s = sim_config(a.sim.sim.as_deref())?;
        if let Some(seed) = a.seed {
            s.seed = seed;
        }
        let sim_text = match &a.sim.sim {
            Some(p) => gonio_core::input::read_text(p, gonio_core::input::MAX_CONFIG_BYTES)
                .map_err(input)?,
            None => gonio_sim::config::DEFAULT_SIM.to_string(),
        };
        let sample = s.sample_model_text().map_err(input)?;
        // The seed actually used, so that a resume reproduces it.
        inputs.seed = Some(s.seed);
        gonio_sim::check_compatible(inst, &s)
            .map_err(|e| input(format!("{}: {e}", a.instrument.display())))?;
        inputs.sim = Some((sim_text, sample));
        Rig::Sim(Box::new(s))
    } else {
        Rig::Real
    };
    // The estimate `plan check` gives, the simulated sample's signals included.
    let estimate = match &rig {
        Rig::Sim(s) => RunEstimate::of(&loaded, Some(Source::Sim(s.clone())), Some(s.as_ref()))?,
        Rig::Real => RunEstimate::of(&loaded, None, None)?,
    };
    // Every referenced file read and checked: the run's whole record, before it
    // exists anywhere.
    let mut meta = gonio_run::create::meta_for(plan, prepared, &inputs).map_err(input)?;
    meta.estimate = Some(estimate.record(&loaded));
    let serve = a.serve.bind()?;
    let create = || {
        let store = RunStore::create(&a.out, &meta.to_map(), &prepared.schedule.steps)?;
        if !quiet {
            let e = &estimate;
            eprintln!(
                "gonio: {}: {} steps ({} pairs measurable, {} left out); estimated {} \
                 (start-up {}, motion {}, detector {}{}){}",
                a.out.display(),
                prepared.schedule.steps.len(),
                prepared.checked.accepted.len(),
                prepared.checked.rejected.len(),
                hms(e.total_s),
                hms(e.startup_s),
                hms(e.motion_s),
                hms(e.detector_s),
                if e.band_s > 0.0 {
                    format!(", band changes {}", hms(e.band_s))
                } else {
                    String::new()
                },
                e.adaptive.map_or(String::new(), |x| format!(
                    "; the whole adaptive run {}",
                    hms(x.whole_s)
                ))
            );
        }
        Ok(store)
    };
    let (report, _) = session(
        create,
        inst,
        &a.instrument.display().to_string(),
        rig,
        RunSetup {
            standard: meta.standard_model.clone(),
            transmittance: meta.transmittance,
            reading: plan
                .reading
                .as_ref()
                .map(gonio_acquire::engine::read_target),
        },
        Driving { quiet, stop, serve },
    )?;
    Ok(report)
}

/// `gonio resume RUN [--json]`: continues a run where it stopped, with the
/// instrument (and simulator) its file records.
pub fn resume(a: ResumeArgs) -> CliResult<()> {
    let report = resume_served(&a.run, a.json, &StopBy::Signals, &a.serve)?;
    report_session(&a.run, &report, a.json)
}

/// Continues the run `a` names, its live page served if `a` asks for it; `quiet`
/// prints nothing (no progress bar).
pub(crate) fn resume_with(a: &ResumeArgs, quiet: bool, stop: &StopBy) -> CliResult<SessionReport> {
    resume_served(&a.run, quiet, stop, &a.serve)
}

/// [`resume_with`], with the live page if `serve` asks for it.
fn resume_served(
    path: &Path,
    quiet: bool,
    stop: &StopBy,
    serve: &ServeFlag,
) -> CliResult<SessionReport> {
    let mut store = RunStore::open_unverified(path)?;
    // Before anything is checked further, let alone a port opened or an axis homed:
    // one process at a time.
    store.lock()?;
    let found = store.integrity(false)?;
    // Missing readings are measured again; any other damage refuses the run.
    store.refuse_damage(&found)?;
    let status = store.meta_value("status")?.unwrap_or_default();
    if status == "complete" && found.missing.is_empty() {
        return Err(CliError::Input(format!(
            "{}: the run is complete; nothing to resume",
            path.display()
        )));
    }
    let stored = gonio_acquire::stored(&store)?;
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
    let serve = serve.bind()?;
    if !found.missing.is_empty() {
        let reopened = store.reopen_missing()?;
        tracing::warn!(
            run = %path.display(),
            steps = ?reopened,
            "committed readings are missing from the run file; measuring those steps again"
        );
    }
    let (report, _) = session(
        || Ok(store),
        &stored.instrument,
        &format!("{} (stored instrument config)", path.display()),
        rig,
        RunSetup {
            standard: stored.standard_model.clone(),
            transmittance: stored.transmittance,
            reading: stored.reading,
        },
        Driving { quiet, stop, serve },
    )?;
    Ok(report)
}
