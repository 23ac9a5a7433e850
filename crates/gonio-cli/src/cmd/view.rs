//! `gonio view`: the live page of any run file (docs/live.md), measured by another
//! process or finished, read-only.

use std::path::PathBuf;

use gonio_run::RunStore;

use crate::error::{CliError, CliResult};

/// `gonio view`: serve a run's live page.
#[derive(clap::Args)]
pub struct ViewArgs {
    /// The run file (opened read-only; its lock is never taken).
    run: PathBuf,
    /// Where to listen: IP:PORT, a port, or an IP (default 127.0.0.1 at a free
    /// port). The address is printed on stderr.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "")]
    serve: Option<String>,
}

/// `gonio view RUN [--serve ADDR]`: serves until a stop signal, then exits 0.
pub fn run(a: ViewArgs) -> CliResult<()> {
    // Examined before SQLite opens it (a FIFO would hold the open forever), then
    // opened whole with every check: a file that is not a run is refused before
    // anything listens.
    gonio_core::input::regular_file(&a.run).map_err(|e| CliError::Input(e.to_string()))?;
    drop(RunStore::open_read_only(&a.run)?);
    let listener = gonio_live::bind(gonio_live::parse_addr(a.serve.as_deref().unwrap_or(""))?)?;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| CliError::Runtime(format!("starting the runtime: {e}")))?;
    rt.block_on(async {
        let mut signals = crate::signals::StopSignals::new()
            .map_err(|e| CliError::Runtime(format!("catching the stop signals: {e}")))?;
        let srv = gonio_live::Server::start(
            listener,
            &a.run,
            gonio_live::Options {
                control: None,
                report: Some(crate::cmd::acquire::live_report()),
                events: None,
            },
        )?;
        eprintln!("gonio: live view at {}", srv.url());
        let sig = signals.next().await;
        eprintln!("gonio: {sig}: the view stops");
        srv.stop().await;
        Ok(())
    })
}
