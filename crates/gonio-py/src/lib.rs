//! The Python package `gonio`: its native module `gonio._native`.
//!
//! A thin layer: every computation is the command line's own (`gonio_cli::api`) or
//! a library crate's, so a notebook gets the numbers `gonio` prints. What this
//! crate adds is the crossing: numpy arrays in and out without a Python object per
//! element, errors as Python exceptions carrying the command's message and exit
//! status, the interpreter's lock released during long work, and Ctrl-C honoured
//! (`interrupt`). The pure-Python side (`python/gonio/`) shapes the results into
//! DataFrames and objects.

mod batch;
mod columns;
mod commands;
mod errors;
mod instrument;
mod interrupt;
mod model;
mod process;
mod run;

use pyo3::prelude::*;

/// The native module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    errors::register(py, m)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(init_logging, m)?)?;
    run::register(m)?;
    model::register(m)?;
    process::register(m)?;
    instrument::register(m)?;
    batch::register(m)?;
    commands::register(m)?;
    Ok(())
}

/// Logs to stderr at warn (0), debug (1) or trace (2, every serial exchange);
/// `RUST_LOG` overrides. Takes effect once a process.
#[pyfunction]
#[pyo3(signature = (verbose = 0))]
fn init_logging(verbose: u8) {
    gonio_cli::api::init_logging(verbose);
}
