//! Acquisition and the simulated goniometer.
//!
//! `acquire` and `resume` run the command's own engine; Ctrl-C (KeyboardInterrupt)
//! raises the engine's stop flag, as SIGINT does for the command, and the call
//! returns only once the stages have stopped and the run is resumable. The
//! simulator serves the same bytes as `gonio sim`, on two pseudo-terminals, in
//! this process, until closed.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use gonio_cli::api::Watch;
use gonio_sim::serve::{ServeError, ServeOptions, Served, serve};
use pyo3::prelude::*;

use crate::errors::{self, Domain};
use crate::interrupt::{self, OnInterrupt};

/// Registers the functions and the class.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(acquire, m)?)?;
    m.add_function(wrap_pyfunction!(resume, m)?)?;
    m.add_class::<NativeSimulator>()?;
    Ok(())
}

/// `gonio acquire WORDS…`: the session's `--json` object (JSON text) and the live
/// page's address when it was served. `progress` draws the command's bar on
/// stderr; `report` is handed the session's progress (`interrupt::run_watched`).
#[pyfunction]
#[pyo3(signature = (words, out, progress = false, report = None))]
fn acquire(
    py: Python<'_>,
    words: Vec<String>,
    out: String,
    progress: bool,
    report: Option<Bound<'_, PyAny>>,
) -> PyResult<(String, Option<String>)> {
    session(py, words, &out, progress, report, gonio_cli::api::acquire)
}

/// `gonio resume WORDS…` (the words name the run): as [`acquire`].
#[pyfunction]
#[pyo3(signature = (words, progress = false, report = None))]
fn resume(
    py: Python<'_>,
    words: Vec<String>,
    progress: bool,
    report: Option<Bound<'_, PyAny>>,
) -> PyResult<(String, Option<String>)> {
    let run = words.get(1).cloned().unwrap_or_default();
    session(py, words, &run, progress, report, gonio_cli::api::resume)
}

/// The signature of `api::acquire` and `api::resume`.
type SessionFn = fn(&[String], Arc<Watch>, bool) -> gonio_cli::api::CliResult<serde_json::Value>;

/// Runs a session (`acquire` or `resume`), Ctrl-C raising its stop flag.
fn session(
    py: Python<'_>,
    words: Vec<String>,
    run: &str,
    progress: bool,
    report: Option<Bound<'_, PyAny>>,
    f: SessionFn,
) -> PyResult<(String, Option<String>)> {
    let watch = Watch::new();
    let w = watch.clone();
    let result = interrupt::run_session(
        py,
        OnInterrupt::Stop(watch.stop_flag()),
        move || f(&words, w, progress),
        report.as_ref().map(|r| (&*watch, r)),
    )?;
    let url = watch.progress().url;
    result
        .map(|v| (v.to_string(), url))
        .map_err(|e| errors::to_py(e, Domain::Instrument, Some(run)))
}

/// The simulated goniometer served on two pseudo-terminals in this process.
#[pyclass(module = "gonio._native", name = "NativeSimulator")]
pub struct NativeSimulator {
    served: Mutex<Option<Served>>,
    ports: (String, String),
    seed: u64,
    time_scale: f64,
}

#[pymethods]
impl NativeSimulator {
    /// Starts serving: `config` a simulator config file (none: the embedded
    /// default), `seed` and `time_scale` overriding it.
    #[new]
    #[pyo3(signature = (config = None, seed = None, time_scale = None))]
    fn new(
        py: Python<'_>,
        config: Option<PathBuf>,
        seed: Option<u64>,
        time_scale: Option<f64>,
    ) -> PyResult<NativeSimulator> {
        let opts = ServeOptions {
            config,
            seed,
            time_scale,
        };
        let served = py.detach(|| serve(&opts)).map_err(serve_err)?;
        Ok(NativeSimulator {
            ports: (
                served.pty.motion.display().to_string(),
                served.pty.detector.display().to_string(),
            ),
            seed: served.seed,
            time_scale: served.time_scale,
            served: Mutex::new(Some(served)),
        })
    }

    /// `(motion port, detector port)`.
    #[getter]
    fn ports(&self) -> (String, String) {
        self.ports.clone()
    }

    /// The seed in use.
    #[getter]
    fn seed(&self) -> u64 {
        self.seed
    }

    /// Wall seconds per physical second.
    #[getter]
    fn time_scale(&self) -> f64 {
        self.time_scale
    }

    /// Whether it still serves.
    #[getter]
    fn serving(&self) -> bool {
        self.served.lock().map(|s| s.is_some()).unwrap_or(false)
    }

    /// Stops serving: the pseudo-terminals close. Idempotent.
    fn close(&self, py: Python<'_>) {
        let served = self.served.lock().ok().and_then(|mut s| s.take());
        py.detach(move || drop(served));
    }
}

fn serve_err(e: ServeError) -> PyErr {
    let code = e.exit_code();
    errors::to_py(
        gonio_cli::api::CliError::classify(code == 2, e),
        Domain::Instrument,
        None,
    )
}
