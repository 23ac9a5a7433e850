//! `gonio-sim`: the simulated goniometer behind two pseudo-terminals.
//!
//! Prints one JSON line — the paths of the SMC100 and SR830 lines — then serves until
//! its standard input closes (or it is killed). Point an instrument config's ports at
//! those paths and drive it like the real instrument.

use std::process::ExitCode;

use clap::Parser;

#[derive(Parser)]
#[command(
    name = "gonio-sim",
    version,
    about = "The simulated goniometer on pseudo-terminals"
)]
struct Args {
    #[command(flatten)]
    serve: gonio_sim::cli::ServeArgs,
}

fn main() -> ExitCode {
    match gonio_sim::cli::serve(Args::parse().serve, &mut std::io::stdin().lock()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("gonio-sim: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
