//! `gonio`: the command-line front of the Gonio gonioreflectometer system, as a
//! library: the binary is [`main`], and [`api`] is what the Python package calls so
//! that it computes, reports and refuses exactly as the commands do.
//!
//! Every command that reports numbers takes `--json` and then prints one JSON object on
//! stdout; logs and errors go to stderr. Exit status 0 on success, 1 on a runtime
//! failure, 2 on bad input, 130 when stopped by a signal, with a one-line reason
//! naming the file and line or field. `-v` shows debug logs, `-vv` every serial
//! exchange (or set `RUST_LOG`).

pub mod api;
mod cmd;
mod csvout;
mod error;
mod flags;
mod logging;
mod output;
mod signals;
mod watch;

use std::path::Path;
use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

use error::CliError;

#[derive(Parser)]
#[command(name = "gonio", version, about = "Measure, model and check BRDFs", long_about = None)]
struct Cli {
    /// More log on stderr: -v debug, -vv trace (every serial exchange).
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Show what Gonio does on an embedded default: the blue paint of Lafortune et al.
    /// 1997 (Table 1), its albedo curve and its BRDF in the plane of incidence, and a
    /// complete simulated acquisition of it, reduced and compared with the model.
    Demo(cmd::demo::DemoArgs),
    /// Evaluate and integrate analytic BRDF model files.
    #[command(subcommand)]
    Model(cmd::model::Command),
    /// Check an instrument config, and optionally talk to the instrument.
    #[command(subcommand)]
    Instrument(cmd::instrument::Command),
    /// Check a measurement plan against an instrument: what can be measured, what
    /// cannot and why, and how long it will take.
    #[command(subcommand)]
    Plan(cmd::plan::Command),
    /// Measure a plan into a new run file (`.gonio`). Ctrl-C (or SIGTERM, SIGHUP)
    /// stops the stages and leaves the run resumable; a second one quits at once.
    Acquire(cmd::acquire::AcquireArgs),
    /// Continue an interrupted or killed run where it stopped (re-homing if needed).
    Resume(cmd::acquire::ResumeArgs),
    /// List the run files in a directory.
    Runs(cmd::runs::RunsArgs),
    /// Show a run: status, counts, durations, configs.
    Show(cmd::runs::ShowArgs),
    /// Check a run file whole: SQLite's integrity check, every row checksum, and the
    /// integrity record (readings deleted, replaced or altered, configs edited).
    /// Exit 0 when intact, 1 with every fault when not.
    Verify(cmd::verify::VerifyArgs),
    /// Reduce a run's readings to BRDF samples with uncertainties (DeYoung Eq. A.15, or
    /// relative to the run's reference standard), drift-corrected; writes a table when
    /// the samples form a grid, else the samples (CSV).
    Reduce(cmd::reduce::ReduceArgs),
    /// Measure reciprocity, energy conservation, isotropy and separability (DeYoung
    /// Ch. 4) of a run, a table, a separable or harmonics file, or a model file.
    Check(cmd::check::CheckArgs),
    /// Transform a table towards reciprocity, energy conservation, isotropy or
    /// k-separability (DeYoung Ch. 5), the steps in the order given.
    Correct(cmd::correct::CorrectArgs),
    /// Represent a table by real spherical harmonics with a symmetric coefficient
    /// matrix (Westin et al. 1992): exactly reciprocal; reports the truncation error.
    Harmonics(cmd::harmonics::HarmonicsArgs),
    /// Predict a BRDF from microgeometry (the virtual gonioreflectometer of Westin et
    /// al. 1992): trace rays through every bounce on a surface file's height field and
    /// tabulate f_r with its Monte Carlo error (and, with --sh, the symmetric
    /// spherical-harmonic matrix).
    Micro(cmd::micro::MicroArgs),
    /// Fit sums of generalized cosine lobes (Lafortune et al. 1997) by
    /// Levenberg–Marquardt; write the model file and report parameters with standard
    /// errors. `--compare` also fits Ward, Blinn-Phong and Cook–Torrance.
    Fit(cmd::fit::FitArgs),
    /// Write a run, table, samples, model or RGL material as MERL binary, ASTM E1392
    /// text, CSV or an RGL material (`.bsdf`, for Mitsuba 3).
    Export(cmd::export::ExportArgs),
    /// Plot a run, table, samples, MERL file or model (PNG or SVG by the extension).
    Plot(cmd::plot::PlotArgs),
    /// Spectra (a CSV with a `wavelength_nm` column) to CIE XYZ, chromaticity and sRGB
    /// under a CIE illuminant, for the 1931 or 1964 observer (CIE 015:2018).
    Colour(cmd::colour::ColourArgs),
    /// Write the run report: one self-contained HTML page with the run's metadata,
    /// calibration, measures, fit and plots.
    Report(cmd::report::ReportArgs),
    /// Serve a run's live page (read-only) for any run file, measured by another
    /// process or finished: status, progress, the BRDF filling in, the detector
    /// trace, drift and the event log. Serves until Ctrl-C.
    View(cmd::view::ViewArgs),
    /// Run the simulated goniometer on two pseudo-terminals: prints one JSON line with
    /// their paths, then serves until SIGINT, SIGTERM or SIGHUP.
    Sim(cmd::instrument::SimArgs),
}

/// Runs the command `matches` holds (the parsed line: the correction steps' order
/// is read from it).
fn run(cli: Cli, matches: &clap::ArgMatches) -> Result<(), CliError> {
    let log_file = match &cli.command {
        Command::Acquire(a) => a.log_file(),
        Command::Resume(a) => a.log_file(),
        _ => None,
    }
    .map(Path::to_path_buf);
    logging::init(cli.verbose, log_file.as_deref())?;
    let result = dispatch(cli.command, matches);
    // Nothing is left behind by a command refused for bad input: the log file this
    // process created goes too (before any run file exists, it holds nothing).
    if let (Err(CliError::Input(_)), Some(p)) = (&result, &log_file) {
        let _ = std::fs::remove_file(p);
    }
    result
}

/// Runs one command.
pub(crate) fn dispatch(command: Command, matches: &clap::ArgMatches) -> Result<(), CliError> {
    match command {
        Command::Demo(a) => cmd::demo::run(a),
        Command::Model(c) => cmd::model::run(c),
        Command::Instrument(c) => cmd::instrument::run(c),
        Command::Plan(c) => cmd::plan::run(c),
        Command::Acquire(a) => cmd::acquire::acquire(a),
        Command::Resume(a) => cmd::acquire::resume(a),
        Command::Runs(a) => cmd::runs::runs(a),
        Command::Show(a) => cmd::runs::show(a),
        Command::Verify(a) => cmd::verify::run(a),
        Command::View(a) => cmd::view::run(a),
        Command::Reduce(a) => cmd::reduce::run(a),
        Command::Check(a) => cmd::check::run(a),
        Command::Correct(a) => cmd::correct::run(a, matches.subcommand_matches("correct")),
        Command::Harmonics(a) => cmd::harmonics::run(a),
        Command::Micro(a) => cmd::micro::run(a),
        Command::Fit(a) => cmd::fit::run(a),
        Command::Export(a) => cmd::export::run(a),
        Command::Plot(a) => cmd::plot::run(a),
        Command::Colour(a) => cmd::colour::run(a),
        Command::Report(a) => cmd::report::run(a),
        Command::Sim(a) => cmd::instrument::sim(a),
    }
}

/// The `gonio` command: parses the process's arguments, runs the command, prints a
/// failure's one-line reason and returns its exit status.
pub fn main() -> ExitCode {
    let matches = Cli::command().get_matches();
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(c) => c,
        Err(e) => e.exit(),
    };
    match run(cli, &matches) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("gonio: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
