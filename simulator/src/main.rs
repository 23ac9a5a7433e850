//! `gonio-sim`: the simulated goniometer behind two pseudo-terminals.
//!
//! Prints one JSON line — the paths of the SMC100 and SR830 lines — then serves until
//! SIGINT, SIGTERM or SIGHUP (standard input is left alone, so `gonio-sim &` and
//! service managers work). Point an instrument config's ports at those paths and
//! drive it like the real instrument.

use std::io::Write;
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
    use tokio::signal::unix::{SignalKind, signal};
    // The stop signals are caught before the announcement, so that a signal sent as
    // soon as it is read stops the simulator cleanly.
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let (mut int, mut term, mut hup) = {
        let _in_runtime = rt.enter();
        (
            signal(SignalKind::interrupt())?,
            signal(SignalKind::terminate())?,
            signal(SignalKind::hangup())?,
        )
    };
    let served = serve(&ServeOptions {
        config: a.config,
        seed: a.seed,
        time_scale: a.time_scale,
    })?;
    let mut out = std::io::stdout().lock();
    writeln!(out, "{}", served.announcement())?;
    out.flush()?;
    drop(out);
    rt.block_on(async {
        tokio::select! {
            _ = int.recv() => {}
            _ = term.recv() => {}
            _ = hup.recv() => {}
        }
    });
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
