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

/// The stop signals caught on a runtime of their own, for a process with nothing
/// else to do than wait for them.
pub struct Waiter {
    rt: tokio::runtime::Runtime,
    signals: StopSignals,
}

impl Waiter {
    /// Catches the stop signals from now on: made before the process tells anyone
    /// it is ready, so that a signal sent at once is not fatal.
    pub fn new() -> std::io::Result<Waiter> {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()?;
        let signals = {
            let _in_runtime = rt.enter();
            StopSignals::new()?
        };
        Ok(Waiter { rt, signals })
    }

    /// Blocks until a stop signal arrives, and names it.
    pub fn wait(mut self) -> &'static str {
        self.rt.block_on(self.signals.next())
    }
}
