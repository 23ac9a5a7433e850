//! Long work off the interpreter's lock, interruptible by Ctrl-C.
//!
//! The work runs on a thread of its own while the calling thread, without the lock,
//! waits for it in short slices; between slices it takes the lock back just long
//! enough to let Python run its signal handlers (and, for a call that reports its
//! progress, a callable that draws a notebook's bar). A KeyboardInterrupt then either
//! abandons computation (its thread finishes alone and its result is dropped:
//! nothing it touches is shared) or, for an acquisition, raises the stop flag and
//! waits for the stages to stop before it is re-raised.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use gonio_cli::api::Watch;
use pyo3::prelude::*;

/// How often Python's signal handlers get to run while work goes on.
const SLICE: Duration = Duration::from_millis(50);

/// How the work reacts to Ctrl-C.
pub enum OnInterrupt {
    /// Return at once; the work's thread finishes unobserved.
    Abandon,
    /// Raise this flag, wait for the work to end, then re-raise.
    Stop(Arc<AtomicBool>),
}

/// Runs `work` without the lock, on `threads` worker threads for its parallel parts
/// (rayon; `None`: the global pool, one thread a core), and returns its result.
pub fn run<T, F>(py: Python<'_>, threads: Option<usize>, on: OnInterrupt, work: F) -> PyResult<T>
where
    T: Send + 'static,
    F: FnOnce() -> T + Send + 'static,
{
    run_watched(py, threads, on, work, None)
}

/// A long call's progress, handed to Python: the call's [`Watch`], and the callable
/// that is given its state.
pub type Report<'a, 'py> = Option<(&'a Watch, &'a Bound<'py, PyAny>)>;

/// The state a report callable gets: `(seq, stage, done, total, unit, message,
/// url)`; `seq` changes whenever anything else does.
type State = (
    u64,
    String,
    u64,
    Option<u64>,
    String,
    String,
    Option<String>,
);

/// Hands `f` each stage that ended since it was last called, then the one going on.
fn tell(w: &Watch, f: &Bound<'_, PyAny>) -> PyResult<()> {
    let (ended, now) = w.take();
    for p in ended.into_iter().chain([now]) {
        let s: State = (p.seq, p.stage, p.done, p.total, p.unit, p.message, p.url);
        f.call1((s,))?;
    }
    Ok(())
}

/// As [`run`], handing the work's progress to `report`'s callable between slices
/// and once at the end, on the calling thread with the lock held (so that a
/// notebook's progress bar is drawn where the call was made). A callable that
/// raises ends the call as Ctrl-C does, with its exception.
pub fn run_watched<T, F>(
    py: Python<'_>,
    threads: Option<usize>,
    on: OnInterrupt,
    work: F,
    report: Report<'_, '_>,
) -> PyResult<T>
where
    T: Send + 'static,
    F: FnOnce() -> T + Send + 'static,
{
    let pool = match threads {
        Some(n) => Some(
            rayon::ThreadPoolBuilder::new()
                .num_threads(n.max(1))
                .build()
                .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?,
        ),
        None => None,
    };
    let (tx, rx) = mpsc::channel();
    // The work runs on a worker of the pool its parallel parts use: handed to a pool
    // from a thread outside it, each parallel step would wait on a cross-thread
    // wake-up (twice the time of a small fit, BENCHMARKS.md).
    let job = move || {
        // A panic must not unwind into the pool (rayon aborts the process then): it
        // drops the sender instead, and the caller reports it.
        if let Ok(r) = std::panic::catch_unwind(std::panic::AssertUnwindSafe(work)) {
            // The receiver is gone only when the caller abandoned the work.
            let _ = tx.send(r);
        }
    };
    match pool {
        Some(p) => {
            // The pool lives until its last job ends, then its threads exit.
            p.spawn(job);
        }
        None => rayon::spawn(job),
    }
    wait(py, rx, on, report)
}

/// As [`run_watched`], the work on a thread of its own rather than a worker of the
/// pool: for a session (an acquisition, `plan compare`'s runs), which waits on the
/// instrument for minutes. On a worker it would hold one the adaptive planner's and
/// the reduction's parallel parts need (all of them, on a pool of one thread: they
/// would never run).
pub fn run_session<T, F>(
    py: Python<'_>,
    on: OnInterrupt,
    work: F,
    report: Report<'_, '_>,
) -> PyResult<T>
where
    T: Send + 'static,
    F: FnOnce() -> T + Send + 'static,
{
    let (tx, rx) = mpsc::channel();
    std::thread::Builder::new()
        .name("gonio-session".into())
        .spawn(move || {
            // A panic drops the sender; the caller reports it.
            if let Ok(r) = std::panic::catch_unwind(std::panic::AssertUnwindSafe(work)) {
                let _ = tx.send(r);
            }
        })
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    wait(py, rx, on, report)
}

/// Waits for the work's result in slices, running the signal handlers and the
/// report callable between them.
fn wait<T>(
    py: Python<'_>,
    rx: mpsc::Receiver<T>,
    on: OnInterrupt,
    report: Report<'_, '_>,
) -> PyResult<T>
where
    T: Send + 'static,
{
    let mut interrupted: Option<PyErr> = None;
    let mut rx = rx;
    loop {
        // The receiver goes with the wait (it may not be shared across threads).
        let (got, back) = py.detach(move || (rx.recv_timeout(SLICE), rx));
        rx = back;
        match got {
            Ok(r) => {
                if let (None, Some((w, f))) = (&interrupted, report) {
                    // The end, as the work left it: a bar then shows it complete.
                    tell(w, f)?;
                }
                return match interrupted {
                    Some(e) => Err(e),
                    None => Ok(r),
                };
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                return Err(pyo3::exceptions::PyRuntimeError::new_err(
                    "gonio: the work's thread ended without a result (a panic)",
                ));
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {}
        }
        if interrupted.is_some() {
            continue;
        }
        let told = match report {
            Some((w, f)) => tell(w, f),
            None => Ok(()),
        };
        if let Err(e) = told.and_then(|()| py.check_signals()) {
            match &on {
                OnInterrupt::Abandon => return Err(e),
                OnInterrupt::Stop(flag) => {
                    flag.store(true, Ordering::Relaxed);
                    interrupted = Some(e);
                }
            }
        }
    }
}
