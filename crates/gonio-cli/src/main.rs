//! `gonio`: the command-line front of the Gonio gonioreflectometer system.
//!
//! Every command that reports numbers takes `--json` and then prints one JSON object on
//! stdout; logs and errors go to stderr. Exit status 0 on success, 1 on a runtime
//! failure, 2 on bad input, with a one-line reason naming the file and line or field.

mod acquire_cmd;
mod demo;
mod error;
mod fit_cmd;
mod instrument_cmd;
mod io_cmd;
mod micro_cmd;
mod model_cmd;
mod output;
mod process_cmd;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use error::CliError;

#[derive(Parser)]
#[command(name = "gonio", version, about = "Measure, model and check BRDFs", long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Show what Gonio does on an embedded default: the blue paint of Lafortune et al.
    /// 1997 (Table 1), its albedo curve and its BRDF in the plane of incidence, and a
    /// complete simulated acquisition of it, reduced and compared with the model.
    Demo {
        /// Print one JSON object instead of tables.
        #[arg(long)]
        json: bool,
        /// Keep the demo's run file here (a temporary file, removed, otherwise).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Evaluate and integrate analytic BRDF model files.
    Model {
        #[command(subcommand)]
        command: ModelCommand,
    },
    /// Check an instrument config, and optionally talk to the instrument.
    Instrument {
        #[command(subcommand)]
        command: InstrumentCommand,
    },
    /// Check a measurement plan against an instrument: what can be measured, what
    /// cannot and why, and how long it will take.
    Plan {
        #[command(subcommand)]
        command: PlanCommand,
    },
    /// Measure a plan into a new run file (`.gonio`). Ctrl-C stops the stages and
    /// leaves the run resumable; a second Ctrl-C quits at once.
    Acquire {
        /// The instrument config (TOML).
        #[arg(long)]
        instrument: PathBuf,
        /// The plan (TOML).
        #[arg(long)]
        plan: PathBuf,
        /// The run file to create.
        #[arg(long)]
        out: PathBuf,
        /// Simulator config for ports named "sim" (the embedded default otherwise).
        #[arg(long)]
        sim: Option<PathBuf>,
        /// Seed of the simulator's random draws (overrides its config).
        #[arg(long)]
        seed: Option<u64>,
        /// Operator notes stored with the run.
        #[arg(long)]
        notes: Option<String>,
        /// Print one JSON object at the end instead of progress and text.
        #[arg(long)]
        json: bool,
    },
    /// Continue an interrupted or killed run where it stopped (re-homing if needed).
    Resume {
        /// The run file.
        run: PathBuf,
        /// Print one JSON object at the end instead of progress and text.
        #[arg(long)]
        json: bool,
    },
    /// List the run files in a directory.
    Runs {
        /// The directory.
        dir: PathBuf,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Show a run: status, counts, durations, configs.
    Show {
        /// The run file.
        run: PathBuf,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Reduce a run's readings to BRDF samples with uncertainties (DeYoung Eq. A.15, or
    /// relative to the run's reference standard), drift-corrected; writes a table when
    /// the samples form a grid, else the samples (CSV).
    Reduce {
        /// The run file.
        run: PathBuf,
        /// The table or sample file to write (CSV).
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        reduction: ReduceFlags,
        /// Resample onto a hemisphere grid of DTHETA,DPHI degrees (nearest-j kernel).
        #[arg(long, value_parser = process_cmd::parse_grid)]
        grid: Option<(f64, f64)>,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Measure reciprocity, energy conservation, isotropy and separability (DeYoung
    /// Ch. 4) of a run, a table, a separable or harmonics file, or a model file.
    Check {
        /// The input.
        input: PathBuf,
        /// The k of P_s^(k), comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "1")]
        k: Vec<usize>,
        /// Resample (or tabulate a model) on a hemisphere grid of DTHETA,DPHI degrees.
        #[arg(long, value_parser = process_cmd::parse_grid)]
        grid: Option<(f64, f64)>,
        #[command(flatten)]
        reduction: ReduceFlags,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Transform a table towards reciprocity, energy conservation, isotropy or
    /// k-separability (DeYoung Ch. 5), the steps in the order given.
    Correct {
        /// The input.
        input: PathBuf,
        /// Reciprocity with δ in [0, 1] (Eq. 5.1–5.2).
        #[arg(long)]
        reciprocity: Vec<String>,
        /// Energy conservation: δ[:per-direction|:global][:tau=T] (Eq. 5.4–5.8).
        #[arg(long)]
        energy: Vec<String>,
        /// Isotropy with δ (Eq. 5.9–5.10).
        #[arg(long)]
        isotropy: Vec<String>,
        /// k-separability: k[:δ] (Eq. 5.15); a last step with δ = 1 and a .toml output
        /// writes the k factor pairs.
        #[arg(long)]
        separable: Vec<String>,
        /// The output (CSV table, or TOML factors).
        #[arg(long)]
        out: PathBuf,
        /// Resample (or tabulate a model) on a hemisphere grid of DTHETA,DPHI degrees.
        #[arg(long, value_parser = process_cmd::parse_grid)]
        grid: Option<(f64, f64)>,
        #[command(flatten)]
        reduction: ReduceFlags,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Represent a table by real spherical harmonics with a symmetric coefficient
    /// matrix (Westin et al. 1992): exactly reciprocal; reports the truncation error.
    Harmonics {
        /// The input.
        input: PathBuf,
        /// The truncation order l_max.
        #[arg(long)]
        order: usize,
        /// Attenuate orders above this one (against ringing); none by default.
        #[arg(long)]
        filter: Option<usize>,
        /// The coefficient file to write (TOML).
        #[arg(long)]
        out: PathBuf,
        /// Resample (or tabulate a model) on a hemisphere grid of DTHETA,DPHI degrees.
        #[arg(long, value_parser = process_cmd::parse_grid)]
        grid: Option<(f64, f64)>,
        #[command(flatten)]
        reduction: ReduceFlags,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Predict a BRDF from microgeometry (the virtual gonioreflectometer of Westin et
    /// al. 1992): trace rays through every bounce on a surface file's height field and
    /// tabulate f_r with its Monte Carlo error (and, with --sh, the symmetric
    /// spherical-harmonic matrix).
    Micro {
        /// The surface file (TOML; docs/micro.md).
        surface: PathBuf,
        /// The grid, DTHETA,DPHI in degrees (polar band midpoints, a full turn).
        #[arg(long, value_parser = process_cmd::parse_grid, default_value = "10,15")]
        grid: (f64, f64),
        /// Tabulate the isotropic form (θi, φo − φi, θo), averaging over the sample's
        /// turns; for anisotropic surfaces leave it off.
        #[arg(long)]
        isotropic: bool,
        /// Rays per incident direction of the grid.
        #[arg(long, default_value_t = 100_000)]
        rays: usize,
        /// Seed of every random draw: the same seed gives the same table bytes.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// The table to write (CSV with a grid header, sigma columns = Monte Carlo
        /// standard errors).
        #[arg(long)]
        out: PathBuf,
        /// Also write one table per bounce order (1, 2, 3+) beside OUT.
        #[arg(long)]
        per_order: bool,
        /// Also estimate the spherical-harmonic matrix to this degree from its own rays.
        #[arg(long)]
        sh: Option<usize>,
        /// Taper SH degrees above this one (Westin et al.'s filtering).
        #[arg(long, requires = "sh")]
        sh_filter: Option<usize>,
        /// Where to write the SH file (TOML); required with --sh.
        #[arg(long, requires = "sh")]
        sh_out: Option<PathBuf>,
        /// Rays of the SH estimate (incident directions drawn over the hemisphere).
        #[arg(long, default_value_t = 1_000_000, requires = "sh")]
        sh_rays: usize,
        /// Bounces after which a ray is stopped (its energy is reported).
        #[arg(long, default_value_t = 100)]
        max_bounces: u32,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Fit sums of generalized cosine lobes (Lafortune et al. 1997) by
    /// Levenberg–Marquardt; write the model file and report parameters with standard
    /// errors. `--compare` also fits Ward, Blinn-Phong and Cook–Torrance.
    Fit {
        /// The input: a run file, a table or sample CSV, a separable file.
        input: PathBuf,
        /// The model fitted: lafortune.
        #[arg(long, default_value = "lafortune")]
        model: String,
        /// Number of lobes.
        #[arg(long, default_value_t = 3)]
        lobes: usize,
        /// The diffuse term: lambert or minnaert.
        #[arg(long, default_value = "lambert")]
        diffuse: String,
        /// Let Cx and Cy differ.
        #[arg(long)]
        anisotropic: bool,
        /// The error measured: lafortune (f cos θi cos θo) or ngan (f cos θi).
        #[arg(long, default_value = "lafortune")]
        metric: String,
        /// Leave out pairs with θi or θo above this, degrees.
        #[arg(long, default_value_t = 90.0)]
        cutoff: f64,
        /// One set of exponents for all channels.
        #[arg(long)]
        share_exponents: bool,
        /// Scale the model down where its directional albedo exceeds 1.
        #[arg(long)]
        conserve_energy: bool,
        /// Ignore the samples' uncertainties (fit the metric unweighted).
        #[arg(long)]
        unweighted: bool,
        /// Also fit Ward, Blinn-Phong and Cook–Torrance on the same data and metric.
        #[arg(long)]
        compare: bool,
        /// The model file to write (TOML).
        #[arg(long)]
        out: Option<PathBuf>,
        #[command(flatten)]
        reduction: ReduceFlags,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Write a run, table or samples as MERL binary, ASTM E1392 text or CSV.
    Export {
        /// The input.
        input: PathBuf,
        /// merl, astm or csv.
        #[arg(long)]
        format: String,
        /// The file to write.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        reduction: ReduceFlags,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Plot a run, table, samples, MERL file or model (PNG or SVG by the extension).
    Plot {
        /// The input.
        input: PathBuf,
        /// A fitted model file drawn against the data.
        #[arg(long)]
        fit: Option<PathBuf>,
        /// polar, hemisphere, albedo, separability or sphere.
        #[arg(long)]
        kind: String,
        /// The image to write (.png or .svg).
        #[arg(long)]
        out: PathBuf,
        /// Incident polar angles, degrees (polar: the curves; hemisphere: the first).
        #[arg(long, value_delimiter = ',', default_value = "0,35,65")]
        theta_i: Vec<f64>,
        /// Only this channel (by name).
        #[arg(long)]
        channel: Option<String>,
        /// Sphere: the light's angle from the view axis, degrees.
        #[arg(long, default_value_t = 45.0)]
        light_theta: f64,
        /// Sphere: the light's azimuth in the image, degrees from +x towards +y.
        #[arg(long, default_value_t = 135.0)]
        light_phi: f64,
        #[command(flatten)]
        reduction: ReduceFlags,
    },
    /// Write the run report: one self-contained HTML page with the run's metadata,
    /// calibration, measures, fit and plots.
    Report {
        /// The run file.
        run: PathBuf,
        /// The directory to write report.html into.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        reduction: ReduceFlags,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Run the simulated goniometer on two pseudo-terminals: prints one JSON line with
    /// their paths, then serves until standard input closes.
    Sim(SimArgs),
}

/// Options of `gonio sim` (the same as `gonio-sim`'s).
#[derive(clap::Args)]
struct SimArgs {
    /// Simulator config (TOML); the embedded default when absent.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Override the config's seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Wall seconds per physical second (> 0; default 1, real time).
    #[arg(long)]
    time_scale: Option<f64>,
}

/// How a run file's readings are reduced.
#[derive(clap::Args)]
struct ReduceFlags {
    /// The calibration giving the incident flux: auto, incident or standard.
    #[arg(long, default_value = "auto")]
    calibration: String,
    /// Drift correction: auto (reference readings), calibrations, none.
    #[arg(long, default_value = "auto")]
    drift: String,
}

impl ReduceFlags {
    fn args(self) -> process_cmd::ReduceArgs {
        process_cmd::ReduceArgs {
            calibration: self.calibration,
            drift: self.drift,
        }
    }
}

#[derive(Subcommand)]
enum PlanCommand {
    /// Map every pair through the instrument's kinematics; list the pairs left out
    /// (outside the limits, shadowed, overfilled, below the horizon, duplicated) and
    /// estimate the motion and detector time.
    Check {
        /// The plan (TOML).
        plan: PathBuf,
        /// The instrument config (TOML).
        #[arg(long)]
        instrument: PathBuf,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Subcommand)]
enum InstrumentCommand {
    /// Validate an instrument config (ports, axes, limits, detector settings); with
    /// `--connect`, open the ports, identify every controller and set the lock-in up.
    /// Nothing moves.
    Check {
        /// The instrument config (TOML).
        config: PathBuf,
        /// Open the ports and identify the instruments.
        #[arg(long)]
        connect: bool,
        /// Simulator config for ports named "sim" (the embedded default otherwise).
        #[arg(long)]
        sim: Option<PathBuf>,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Subcommand)]
enum ModelCommand {
    /// Evaluate a model at the direction pairs of a CSV file
    /// (`theta_i,phi_i,theta_o,phi_o`, degrees); writes the pairs with one column a
    /// channel, in 1/sr.
    Eval {
        /// The model file (TOML).
        model: PathBuf,
        /// The directions file (CSV).
        dirs: PathBuf,
        /// Write the CSV here instead of stdout.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Print one JSON object instead of CSV.
        #[arg(long)]
        json: bool,
    },
    /// Directional–hemispherical reflectance ρ(θi) per channel.
    Albedo {
        /// The model file (TOML).
        model: PathBuf,
        /// Incident polar angles in degrees, comma-separated, each in [0, 90].
        #[arg(long, value_delimiter = ',', default_value = "0,15,30,45,60,75,85",
              value_parser = model_cmd::parse_theta)]
        theta_i: Vec<f64>,
        /// Incident azimuth in degrees (matters for anisotropic models).
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        phi_i: f64,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
    },
}

fn run(cli: Cli) -> Result<(), CliError> {
    match cli.command {
        Command::Demo { json, out } => demo::run(json, out.as_deref()),
        Command::Model { command } => match command {
            ModelCommand::Eval {
                model,
                dirs,
                out,
                json,
            } => model_cmd::eval(&model, &dirs, out.as_deref(), json),
            ModelCommand::Albedo {
                model,
                theta_i,
                phi_i,
                json,
            } => model_cmd::albedo(&model, &theta_i, phi_i, json),
        },
        Command::Instrument { command } => match command {
            InstrumentCommand::Check {
                config,
                connect,
                sim,
                json,
            } => instrument_cmd::check(&config, connect, sim.as_deref(), json),
        },
        Command::Plan {
            command:
                PlanCommand::Check {
                    plan,
                    instrument,
                    json,
                },
        } => acquire_cmd::plan_check(&plan, &instrument, json),
        Command::Acquire {
            instrument,
            plan,
            out,
            sim,
            seed,
            notes,
            json,
        } => acquire_cmd::acquire(acquire_cmd::AcquireArgs {
            instrument,
            plan,
            out,
            sim,
            seed,
            notes,
            json,
        }),
        Command::Resume { run, json } => acquire_cmd::resume(&run, json),
        Command::Runs { dir, json } => acquire_cmd::runs(&dir, json),
        Command::Show { run, json } => acquire_cmd::show(&run, json),
        Command::Reduce {
            run,
            out,
            reduction,
            grid,
            json,
        } => process_cmd::reduce_cmd(&run, &out, &reduction.args(), grid, json),
        Command::Check {
            input,
            k,
            grid,
            reduction,
            json,
        } => process_cmd::check(&input, &k, grid, &reduction.args(), json),
        Command::Correct {
            input,
            reciprocity,
            energy,
            isotropy,
            separable,
            out,
            grid,
            reduction,
            json,
        } => {
            let raw: Vec<String> = std::env::args().collect();
            let steps =
                process_cmd::ordered_steps(&raw, &reciprocity, &energy, &isotropy, &separable)?;
            process_cmd::correct(&input, &steps, &out, grid, &reduction.args(), json)
        }
        Command::Harmonics {
            input,
            order,
            filter,
            out,
            grid,
            reduction,
            json,
        } => process_cmd::harmonics(&input, order, filter, &out, grid, &reduction.args(), json),
        Command::Micro {
            surface,
            grid,
            isotropic,
            rays,
            seed,
            out,
            per_order,
            sh,
            sh_filter,
            sh_out,
            sh_rays,
            max_bounces,
            json,
        } => {
            let sh = match (sh, sh_out) {
                (Some(l), Some(p)) => Some((l, sh_filter, p, sh_rays)),
                (Some(_), None) => {
                    return Err(CliError::Input("--sh needs --sh-out FILE".into()));
                }
                _ => None,
            };
            micro_cmd::micro(micro_cmd::MicroArgs {
                surface,
                grid,
                isotropic,
                rays,
                seed,
                out,
                per_order,
                sh,
                max_bounces,
                json,
            })
        }
        Command::Fit {
            input,
            model,
            lobes,
            diffuse,
            anisotropic,
            metric,
            cutoff,
            share_exponents,
            conserve_energy,
            unweighted,
            compare,
            out,
            reduction,
            json,
        } => fit_cmd::fit(fit_cmd::FitArgs {
            input,
            model,
            lobes,
            diffuse,
            anisotropic,
            metric,
            cutoff,
            share_exponents,
            conserve_energy,
            unweighted,
            compare,
            out,
            reduction: reduction.args(),
            json,
        }),
        Command::Export {
            input,
            format,
            out,
            reduction,
            json,
        } => io_cmd::export(&input, &format, &out, &reduction.args(), json),
        Command::Plot {
            input,
            fit,
            kind,
            out,
            theta_i,
            channel,
            light_theta,
            light_phi,
            reduction,
        } => io_cmd::plot(io_cmd::PlotArgs {
            input,
            fit,
            kind,
            out,
            theta_i,
            channel,
            light_theta,
            light_phi,
            reduction: reduction.args(),
        }),
        Command::Report {
            run,
            out,
            reduction,
            json,
        } => io_cmd::report(&run, &out, &reduction.args(), json).map(|_| ()),
        Command::Sim(args) => instrument_cmd::sim(args.config, args.seed, args.time_scale),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("gonio: {e}");
            ExitCode::from(e.exit_code() as u8)
        }
    }
}
