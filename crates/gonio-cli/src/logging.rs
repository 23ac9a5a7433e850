//! Logs: `tracing` events to stderr (warnings by default, `-v` debug, `-vv` every
//! serial exchange at trace, or `RUST_LOG`), and with `--log FILE` the same events as
//! JSON lines in a file. Progress bars and log lines share the terminal: a line is
//! written with the bar suspended, so neither tears the other.

use std::io::{IsTerminal, Write};
use std::path::Path;
use std::sync::{Mutex, MutexGuard};

use tracing_subscriber::filter::Targets;
use tracing_subscriber::fmt::MakeWriter;
use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::util::SubscriberInitExt;
use tracing_subscriber::{Layer, fmt};

use crate::error::{CliError, CliResult};

/// The progress bar on screen, if any: log lines are written around it.
static BAR: Mutex<Option<indicatif::ProgressBar>> = Mutex::new(None);

fn bar() -> MutexGuard<'static, Option<indicatif::ProgressBar>> {
    BAR.lock().unwrap_or_else(|p| p.into_inner())
}

/// Puts `pb` on screen for the log to write around (`None` when it is gone).
pub fn set_bar(pb: Option<indicatif::ProgressBar>) {
    *bar() = pb;
}

/// Stderr, written with the progress bar (if any) suspended.
#[derive(Clone, Copy, Debug, Default)]
pub struct Stderr;

impl Write for Stderr {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let pb = bar().clone();
        match pb {
            Some(pb) if !pb.is_hidden() => pb.suspend(|| std::io::stderr().write_all(buf))?,
            _ => std::io::stderr().write_all(buf)?,
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        std::io::stderr().flush()
    }
}

impl<'a> MakeWriter<'a> for Stderr {
    type Writer = Stderr;
    fn make_writer(&'a self) -> Stderr {
        Stderr
    }
}

/// The filter of a log: `RUST_LOG` when set (`LEVEL` and `TARGET=LEVEL` directives,
/// comma-separated, as `tracing_subscriber`'s `Targets` reads them), else `default`.
/// A `RUST_LOG` that does not parse is said once on stderr and `default` used.
fn filter(default: &str) -> Targets {
    let fallback = || default.parse().unwrap_or_default();
    match std::env::var("RUST_LOG") {
        Ok(s) if !s.trim().is_empty() => s.parse().unwrap_or_else(|e| {
            eprintln!("gonio: RUST_LOG={s:?} ignored: {e} (directives are LEVEL or TARGET=LEVEL)");
            fallback()
        }),
        _ => fallback(),
    }
}

/// The filter of the terminal's log: `RUST_LOG` when set, else by `-v` count.
fn terminal_filter(verbose: u8) -> Targets {
    filter(match verbose {
        0 => "warn",
        1 => "debug",
        _ => "trace",
    })
}

/// Installs the logs for this process. With `file`, the same events also go to it
/// as JSON lines (at least at `debug`, so the file is the full account whatever the
/// terminal shows); the file is created, never overwritten.
pub fn init(verbose: u8, file: Option<&Path>) -> CliResult<()> {
    let terminal = fmt::layer()
        .with_writer(Stderr)
        .with_target(verbose > 0)
        .with_ansi(std::io::stderr().is_terminal())
        .without_time()
        .with_filter(terminal_filter(verbose));
    let json = match file {
        Some(path) => {
            let f = std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(path)
                .map_err(|e| {
                    CliError::Input(format!(
                        "{}: cannot create the log file: {e}",
                        path.display()
                    ))
                })?;
            let level = filter(if verbose >= 2 { "trace" } else { "debug" });
            Some(
                fmt::layer()
                    .json()
                    .with_writer(Mutex::new(f))
                    .with_current_span(true)
                    .with_span_list(true)
                    .with_filter(level),
            )
        }
        None => None,
    };
    // A second initialisation (tests calling in-process) keeps the first.
    let _ = tracing_subscriber::registry()
        .with(terminal)
        .with(json)
        .try_init();
    Ok(())
}
