//! `gonio-sim`: the simulated goniometer behind two pseudo-terminals.
//!
//! Prints one JSON line — the paths of the SMC100 and SR830 lines — then serves until
//! its standard input closes (or it is killed). Point an instrument config's ports at
//! those paths and drive it like the real instrument.

use std::io::{Read, Write};
use std::path::PathBuf;
use std::process::ExitCode;

use clap::Parser;
use gonio_sim::serve::{ServeError, ServeOptions, serve};

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
    /// Wall seconds per physical second (> 0; default 1, real time).
    #[arg(long)]
    time_scale: Option<f64>,
}

fn run(a: Args) -> Result<(), ServeError> {
    let served = serve(&ServeOptions {
        config: a.config,
        seed: a.seed,
        time_scale: a.time_scale,
    })?;
    let mut out = std::io::stdout().lock();
    writeln!(out, "{}", served.announcement())?;
    out.flush()?;
    drop(out);
    let mut sink = [0u8; 256];
    let mut stdin = std::io::stdin().lock();
    while stdin.read(&mut sink)? > 0 {}
    Ok(())
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("gonio-sim: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
