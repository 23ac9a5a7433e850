//! Long work off the interpreter's lock, interruptible by Ctrl-C.
//!
//! The work runs on a thread of its own while the calling thread, without the lock,
//! waits for it in short slices; between slices it takes the lock back just long
//! enough to let Python run its signal handlers. A KeyboardInterrupt then either
//! abandons computation (its thread finishes alone and its result is dropped:
//! nothing it touches is shared) or, for an acquisition, raises the stop flag and
//! waits for the stages to stop before it is re-raised.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::Duration;

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
    let mut interrupted: Option<PyErr> = None;
    let mut rx = rx;
    loop {
        // The receiver goes with the wait (it may not be shared across threads).
        let (got, back) = py.detach(move || (rx.recv_timeout(SLICE), rx));
        rx = back;
        match got {
            Ok(r) => {
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
        if let Err(e) = py.check_signals() {
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
