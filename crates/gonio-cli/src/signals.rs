//! The signals that stop Gonio safely: SIGINT (Ctrl-C), SIGTERM (`kill`, a service
//! manager) and SIGHUP (the terminal went away). Each stops the stages and leaves a
//! run resumable, as Ctrl-C does; none kills a measurement mid-move.

use tokio::signal::unix::{Signal, SignalKind, signal};

/// The three stop signals, caught from the moment this is made (they no longer kill
/// the process).
pub struct StopSignals {
    int: Signal,
    term: Signal,
    hup: Signal,
}

impl StopSignals {
    /// Catches the stop signals; must be called inside a tokio runtime.
    pub fn new() -> std::io::Result<StopSignals> {
        Ok(StopSignals {
            int: signal(SignalKind::interrupt())?,
            term: signal(SignalKind::terminate())?,
            hup: signal(SignalKind::hangup())?,
        })
    }

    /// The next stop signal, by name.
    pub async fn next(&mut self) -> &'static str {
        tokio::select! {
            _ = self.int.recv() => "SIGINT",
            _ = self.term.recv() => "SIGTERM",
            _ = self.hup.recv() => "SIGHUP",
        }
    }
}

/// Blocks until a stop signal arrives, and names it.
pub fn wait() -> std::io::Result<&'static str> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    rt.block_on(async {
        let mut s = StopSignals::new()?;
        Ok(s.next().await)
    })
}
