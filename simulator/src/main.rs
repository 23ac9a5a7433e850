//! `gonio-sim`: the simulated goniometer behind two pseudo-terminals.
//!
//! Prints one JSON line — the paths of the SMC100 and SR830 lines — then serves until
//! its standard input closes (or it is killed). Point an instrument config's ports at
//! those paths and drive it like the real instrument.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;

#[derive(Parser)]
#[command(
    name = "gonio-sim",
    version,
    about = "The simulated goniometer on pseudo-terminals"
)]
struct Args {
    /// Simulator config (TOML); the embedded default when absent.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Override the config's seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Wall seconds per physical second (> 0; the default 1 is real time).
    #[arg(long)]
    time_scale: Option<f64>,
}

fn main() -> ExitCode {
    let a = Args::parse();
    let args = gonio_sim::cli::ServeArgs {
        config: a.config,
        seed: a.seed,
        time_scale: a.time_scale,
    };
    match gonio_sim::cli::serve(args, &mut std::io::stdin().lock()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("gonio-sim: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
