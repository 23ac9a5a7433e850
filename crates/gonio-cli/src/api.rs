//! What the Python package (`gonio-py`) calls: the commands' own computations, on
//! the command's own arguments, without printing.
//!
//! Each function takes the words a command line would (`["check", "run.gonio",
//! "--k", "1,5"]`, without `gonio`), parsed by the command's own parser, so a value
//! is checked and refused with the command's message. Data already in memory (a
//! DataFrame's samples, a model) is `given`: the input word then only names it in
//! messages. Nothing here writes a file the command would write unless asked to
//! (`export`, `report`: the file is their purpose, and it is then written as the
//! command writes it): the caller gets the values the command would have written,
//! and the `--json` object it would have printed. Long calls report how far they
//! are through a [`Watch`], which also carries the caller's stop.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use clap::{CommandFactory, FromArgMatches};
use gonio_dataset::Dataset;
use gonio_process::file::{Content, Meta};
use gonio_process::{Samples, Table};
use serde_json::Value;

use crate::cmd;
pub use crate::error::{CliError, CliResult};
pub use crate::watch::{Progress, Watch};
use crate::{Cli, Command};

/// The words parsed as `gonio WORDS…`.
fn parse(words: &[String]) -> CliResult<(Command, clap::ArgMatches)> {
    let argv = std::iter::once("gonio".to_string()).chain(words.iter().cloned());
    let matches = Cli::command()
        .try_get_matches_from(argv)
        .map_err(clap_error)?;
    let cli = Cli::from_arg_matches(&matches).map_err(clap_error)?;
    Ok((cli.command, matches))
}

/// A parse failure as one line: clap's first, without its `error: ` prefix.
fn clap_error(e: clap::Error) -> CliError {
    let text = e.render().to_string();
    let line = text.lines().next().unwrap_or_default();
    CliError::Input(line.trim_start_matches("error: ").to_string())
}

/// The words were not the command expected: a caller's mistake.
fn wrong(words: &[String]) -> CliError {
    CliError::Runtime(format!("api: not the expected command: {words:?}"))
}

/// Removes `out` from a `--json` object, for a result that was not written.
fn without_out(mut v: Value) -> Value {
    if let Some(o) = v.as_object_mut() {
        o.remove("out");
    }
    v
}

/// Logs to stderr as `-v` (1) or `-vv` (2) would, `RUST_LOG` overriding; once a
/// process (later calls change nothing).
pub fn init_logging(verbose: u8) {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        if let Err(e) = crate::logging::init(verbose, None) {
            eprintln!("gonio: logging: {e}");
        }
    });
}

/// `gonio check`: the `--json` object.
pub fn check(words: &[String], given: Option<Dataset>) -> CliResult<Value> {
    match parse(words)?.0 {
        Command::Check(a) => Ok(cmd::check::compute(&a, given)?.json()),
        _ => Err(wrong(words)),
    }
}

/// `gonio correct`: the corrected table, the sidecar its CSV would have, and the
/// `--json` object (without `out`). The words still need an `--out`, which is not
/// written.
pub fn correct(words: &[String], given: Option<Dataset>) -> CliResult<(Table, Meta, Value)> {
    let (command, matches) = parse(words)?;
    let Command::Correct(a) = command else {
        return Err(wrong(words));
    };
    let steps = a.steps(matches.subcommand_matches("correct"))?;
    let c = cmd::correct::compute(&a, &steps, given, false)?;
    let json = without_out(c.json(&steps, Path::new("")));
    let meta = crate::csvout::tabulated_meta(&c.table, &c.tab);
    Ok((c.table, meta, json))
}

/// `gonio harmonics`: the file `--out` would receive (TOML) and the `--json`
/// object (without `out`).
pub fn harmonics(words: &[String], given: Option<Dataset>) -> CliResult<(String, Value)> {
    match parse(words)?.0 {
        Command::Harmonics(a) => {
            let h = cmd::harmonics::compute(&a, given)?;
            let json = without_out(h.json(h.sh.l_max, Path::new("")));
            Ok((h.file, json))
        }
        _ => Err(wrong(words)),
    }
}

/// What `gonio fit` gives.
#[derive(Clone, Debug)]
pub struct Fit {
    /// The model file `--out` would receive (TOML).
    pub model_file: String,
    /// The `--json` object.
    pub json: Value,
    /// The text the command prints.
    pub report: String,
}

/// `gonio fit` (no `--out` needed; none is written).
pub fn fit(words: &[String], given: Option<Samples>) -> CliResult<Fit> {
    let Command::Fit(a) = parse(words)?.0 else {
        return Err(wrong(words));
    };
    let f = cmd::fit::compute(&a, given)?;
    let mut report = Vec::new();
    cmd::fit::write_report(&mut report, &a, &f)
        .map_err(|e| CliError::Runtime(format!("fit report: {e}")))?;
    Ok(Fit {
        model_file: f.model_file(&a),
        json: f.json(&a),
        report: String::from_utf8_lossy(&report).into_owned(),
    })
}

/// `gonio micro`: the table and the `--json` object (without `out`). `theta_i`
/// replaces the grid's incident polar axis (degrees: first node, step, count).
/// Raising `cancel` stops the tracing within a round of blocks (an error then).
/// The words still need an `--out`, which is not written.
pub fn micro(
    words: &[String],
    theta_i: Option<(f64, f64, usize)>,
    cancel: Arc<AtomicBool>,
) -> CliResult<(Table, Value)> {
    let started = std::time::Instant::now();
    let (a, mut sim, grid) = micro_setup(words, theta_i, None)?;
    sim.cancel_on(cancel);
    let r = cmd::micro::trace(&a, &sim, &grid)?;
    let json = cmd::micro::json(&a, &r, &[], None, started.elapsed().as_secs_f64());
    Ok((r.table, without_out(json)))
}

/// The words of `gonio micro` parsed, the surface loaded (from `surface`, the
/// file's text as a sweep edited it, when given) and the grid made, `theta_i`
/// replacing its incident polar axis.
fn micro_setup(
    words: &[String],
    theta_i: Option<(f64, f64, usize)>,
    surface: Option<&str>,
) -> CliResult<(
    cmd::micro::MicroArgs,
    gonio_micro::Simulation,
    gonio_process::Grid,
)> {
    let Command::Micro(a) = parse(words)?.0 else {
        return Err(wrong(words));
    };
    let (sim, mut grid) = cmd::micro::load_from(&a, surface)?;
    if let Some((start, step, n)) = theta_i {
        grid.theta_i = gonio_process::Axis::from_deg(start, step, n);
        grid.validate()
            .map_err(|e| CliError::Input(format!("theta_i: {e}")))?;
    }
    Ok((a, sim, grid))
}

/// The incident nodes of `gonio micro`'s table and the segments of rays each is
/// traced in: what a sweep splits into chunks. Loads the surface, so a bad surface
/// or option fails here, before any chunk is traced.
pub fn micro_plan(
    words: &[String],
    theta_i: Option<(f64, f64, usize)>,
    surface: Option<&str>,
) -> CliResult<(usize, usize)> {
    let (a, _, grid) = micro_setup(words, theta_i, surface)?;
    Ok((grid.n_in(), gonio_micro::sim::segments(a.rays())))
}

/// Writes `table` as `gonio micro --out` (and every command writing a table)
/// does: the CSV and its sidecar, each atomically; an existing file is refused
/// unless `force`.
pub fn write_table(table: &Table, out: &Path, force: bool) -> CliResult<()> {
    crate::csvout::CsvTarget::new(out, force)?.write_table(table)?;
    Ok(())
}

/// Checks `gonio WORDS…` as the command would before reading its input (the
/// parser, and every flag's value for `reduce`, `check`, `fit`, `report` and
/// `micro`), running nothing: a batch refuses bad options before it starts any task.
pub fn validate(words: &[String]) -> CliResult<()> {
    match parse(words)?.0 {
        Command::Reduce(a) => cmd::reduce::check_values(&a),
        Command::Check(a) => a.check_values(),
        Command::Fit(a) => cmd::fit::check_values(&a),
        Command::Report(a) => a.check_values(),
        Command::Micro(a) => cmd::micro::check_counts(&a),
        _ => Ok(()),
    }
}

/// A chunk of `gonio micro`'s table: segments `segs` (of
/// [`gonio_micro::SEGMENT_RAYS`] rays) of incident node `incident`, traced with
/// the same random streams as the whole table. `surface` is the surface file's
/// text when a sweep edited it. [`micro_merge`] puts the chunks together.
pub fn micro_part(
    words: &[String],
    theta_i: Option<(f64, f64, usize)>,
    surface: Option<&str>,
    incident: usize,
    segs: std::ops::Range<usize>,
    cancel: Arc<AtomicBool>,
) -> CliResult<gonio_micro::TablePart> {
    let (a, mut sim, grid) = micro_setup(words, theta_i, surface)?;
    sim.cancel_on(cancel);
    cmd::micro::part(&a, &sim, &grid, incident, segs)
}

/// `gonio micro`'s table and `--json` object (without `out` and `seconds`) from
/// its chunks ([`micro_part`]): bit for bit the table traced at once.
pub fn micro_merge(
    words: &[String],
    theta_i: Option<(f64, f64, usize)>,
    surface: Option<&str>,
    parts: &[gonio_micro::TablePart],
) -> CliResult<(Table, Value)> {
    let (a, sim, grid) = micro_setup(words, theta_i, surface)?;
    let r = cmd::micro::merge(&a, &sim, &grid, parts)?;
    let mut json = without_out(cmd::micro::json(&a, &r, &[], None, 0.0));
    if let Some(o) = json.as_object_mut() {
        o.remove("seconds");
    }
    Ok((r.table, json))
}

/// `gonio reduce`: what it writes (a table, or the samples) and its `--json`
/// reduction account. The words still need an `--out`, which is not written.
pub fn reduce(words: &[String]) -> CliResult<(Content, Value, String)> {
    let Command::Reduce(a) = parse(words)?.0 else {
        return Err(wrong(words));
    };
    let (red, content, _) = cmd::reduce::compute(&a)?;
    let sidecar = cmd::reduce::sidecar(&red, &content, a.resampled()).to_json();
    Ok((content, cmd::reduce::reduction_json(&red), sidecar))
}

/// Runs an offline command (`reduce`, `check`, `correct`, `harmonics`, `fit`,
/// `micro`, `export`, `plot`, `report`, `model`, `plan`, `show`, `runs`,
/// `verify`) in this process exactly as `gonio WORDS…` would: the same files,
/// written the same way, and what it would print on stdout returned as text.
/// Commands that drive an instrument or wait for signals (`acquire`, `resume`,
/// `sim`, `instrument`, `demo`) are refused: they have their own functions.
pub fn run(words: &[String]) -> CliResult<String> {
    let (command, matches) = parse(words)?;
    if matches!(
        command,
        Command::Acquire(_)
            | Command::Resume(_)
            | Command::Sim(_)
            | Command::Instrument(_)
            | Command::Demo(_)
    ) {
        return Err(CliError::Input(format!(
            "{}: not run in-process (it drives an instrument); use its own function",
            words.first().map_or("", String::as_str)
        )));
    }
    let (result, out) = crate::output::captured(|| crate::dispatch(command, &matches));
    result?;
    Ok(String::from_utf8_lossy(&out).into_owned())
}

/// How a run's readings are reduced, from the values of `--calibration` and
/// `--drift`.
pub fn open_options(calibration: &str, drift: &str) -> CliResult<gonio_dataset::OpenOptions> {
    crate::flags::ReduceFlags {
        calibration: calibration.into(),
        drift: drift.into(),
    }
    .open_options()
}

/// `gonio acquire`: measures a plan into a new run file until done or `watch`'s
/// stop is raised (then the stages stop and the run is left resumable), its steps
/// followed in `watch`; with `--serve`, its live page served while it measures and
/// its address put in `watch`. The progress bar on stderr only when `progress`. The
/// session's `--json` object; an error unless the run completed.
pub fn acquire(words: &[String], watch: Arc<Watch>, progress: bool) -> CliResult<Value> {
    let Command::Acquire(a) = parse(words)?.0 else {
        return Err(wrong(words));
    };
    let out = a.out_path().to_path_buf();
    watch.begin("acquire", "steps");
    let r = cmd::acquire::acquire_with(&a, !progress, &cmd::acquire::StopBy::Caller(watch))?;
    cmd::acquire::session_result(&out, &r)?;
    Ok(cmd::acquire::session_json(&out, &r))
}

/// `gonio resume`: as [`acquire`], continuing the run the words name.
pub fn resume(words: &[String], watch: Arc<Watch>, progress: bool) -> CliResult<Value> {
    let Command::Resume(a) = parse(words)?.0 else {
        return Err(wrong(words));
    };
    watch.begin("resume", "steps");
    let r = cmd::acquire::resume_with(&a, !progress, &cmd::acquire::StopBy::Caller(watch))?;
    cmd::acquire::session_result(a.run_path(), &r)?;
    Ok(cmd::acquire::session_json(a.run_path(), &r))
}

/// `gonio colour`: the `--json` object. `text` is the spectra file's contents when
/// they come from memory (a DataFrame); the input word then only names them.
pub fn colour(words: &[String], text: Option<&str>) -> CliResult<Value> {
    match parse(words)?.0 {
        Command::Colour(a) => Ok(cmd::colour::compute(&a, text)?.json()),
        _ => Err(wrong(words)),
    }
}

/// What `gonio export` gives.
#[derive(Clone, Debug)]
pub struct Export {
    /// The file's contents.
    pub bytes: Vec<u8>,
    /// A CSV's sidecar (JSON text): the grid, isotropy.
    pub sidecar: Option<String>,
    /// The `--json` object (with `out` when written).
    pub json: Value,
}

/// `gonio export` of the input, or of `given` data in memory: with `write`, the file
/// (and a CSV's sidecar) written as the command writes it, refused if it exists
/// without `--force`; without, nothing written (the `--out` word not even checked).
pub fn export(words: &[String], given: Option<Dataset>, write: bool) -> CliResult<Export> {
    let Command::Export(a) = parse(words)?.0 else {
        return Err(wrong(words));
    };
    let (e, json) = cmd::export::export(&a, given, write)?;
    Ok(Export {
        sidecar: e.sidecar.as_ref().map(Meta::to_json),
        bytes: e.bytes,
        json,
    })
}

/// `gonio verify`: its `--json` object, and the command's failure when the file is
/// damaged (exit status 1). An error only when the file cannot be checked at all.
pub fn verify(words: &[String]) -> CliResult<(Value, Option<CliError>)> {
    let Command::Verify(a) = parse(words)?.0 else {
        return Err(wrong(words));
    };
    let v = cmd::verify::verify(a.run_path())?;
    let failed = v.result(a.run_path()).err();
    Ok((v.json, failed))
}

/// `gonio report`: with `write`, writes DIR/report.html as the command does and
/// returns its `--json` object; without, writes nothing and returns the object
/// (without `out`) and the page's HTML.
pub fn report(words: &[String], write: bool) -> CliResult<(Value, Option<String>)> {
    let Command::Report(a) = parse(words)?.0 else {
        return Err(wrong(words));
    };
    if write {
        Ok((cmd::report::write(&a)?.0, None))
    } else {
        let (json, html) = cmd::report::page(&a)?;
        Ok((json, Some(html)))
    }
}

/// `gonio plan check`: the `--json` object.
pub fn plan_check(words: &[String]) -> CliResult<Value> {
    match parse(words)?.0 {
        Command::Plan(cmd::plan::Command::Check(a)) => Ok(cmd::plan::compute(&a)?.json(&a)),
        _ => Err(wrong(words)),
    }
}

/// `gonio plan compare`: the `--json` object, the three runs followed in `watch`
/// (a stage each) and stopped when its stop is raised.
pub fn plan_compare(words: &[String], watch: Arc<Watch>) -> CliResult<Value> {
    match parse(words)?.0 {
        Command::Plan(cmd::plan::Command::Compare(a)) => {
            cmd::compare::compare_json(&a, &cmd::acquire::StopBy::Caller(watch))
        }
        _ => Err(wrong(words)),
    }
}

/// `gonio instrument check` (with `--connect`, the instruments identified; nothing
/// moves): the `--json` object.
pub fn instrument_check(words: &[String]) -> CliResult<Value> {
    match parse(words)?.0 {
        Command::Instrument(cmd::instrument::Command::Check(a)) => a.report(),
        _ => Err(wrong(words)),
    }
}

/// `gonio micro` set up once (the words parsed, the surface loaded, the grid made)
/// and traced by incident node: what a caller showing progress runs, each node on
/// a thread of its choosing. The table merged from the nodes is bit for bit the one
/// [`micro`] traces at once.
pub struct Micro {
    args: cmd::micro::MicroArgs,
    sim: gonio_micro::Simulation,
    grid: gonio_process::Grid,
    started: std::time::Instant,
}

impl Micro {
    /// Sets up `gonio WORDS…` (a `micro` command); `theta_i` replaces the grid's
    /// incident polar axis, raising `cancel` stops the tracing within a round of
    /// blocks.
    pub fn new(
        words: &[String],
        theta_i: Option<(f64, f64, usize)>,
        cancel: Arc<AtomicBool>,
    ) -> CliResult<Micro> {
        let started = std::time::Instant::now();
        let (args, mut sim, grid) = micro_setup(words, theta_i, None)?;
        sim.cancel_on(cancel);
        Ok(Micro {
            args,
            sim,
            grid,
            started,
        })
    }

    /// The incident nodes of the table.
    pub fn incidences(&self) -> usize {
        self.grid.n_in()
    }

    /// Incident node `incident`, all its rays.
    pub fn node(&self, incident: usize) -> CliResult<gonio_micro::TablePart> {
        let segs = gonio_micro::sim::segments(self.args.rays());
        cmd::micro::part(&self.args, &self.sim, &self.grid, incident, 0..segs)
    }

    /// The table and the `--json` object (without `out`) from every node.
    pub fn finish(&self, nodes: &[gonio_micro::TablePart]) -> CliResult<(Table, Value)> {
        let r = cmd::micro::merge(&self.args, &self.sim, &self.grid, nodes)?;
        let seconds = self.started.elapsed().as_secs_f64();
        let json = cmd::micro::json(&self.args, &r, &[], None, seconds);
        Ok((r.table, without_out(json)))
    }
}
