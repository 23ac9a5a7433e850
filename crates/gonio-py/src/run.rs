//! Run files: opened with their integrity check, read as columns, reduced as
//! `gonio reduce` reduces them.

use std::path::PathBuf;

use gonio_run::RunStore;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::columns;
use crate::errors::{self, Domain};
use crate::interrupt::{self, OnInterrupt};

/// Registers the functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(run_open, m)?)?;
    m.add_function(wrap_pyfunction!(run_readings, m)?)?;
    m.add_function(wrap_pyfunction!(run_events, m)?)?;
    m.add_function(wrap_pyfunction!(run_reduce, m)?)?;
    m.add_function(wrap_pyfunction!(toml_to_json, m)?)?;
    m.add_function(wrap_pyfunction!(json_to_toml, m)?)?;
    Ok(())
}

/// Opens a run file as `gonio show` does: examined before SQLite opens it (a FIFO
/// would hold the open forever), then checked whole.
pub(crate) fn open(path: &std::path::Path) -> Result<RunStore, PyErr> {
    gonio_core::input::regular_file(path).map_err(|e| {
        errors::to_py(
            gonio_cli::api::CliError::Input(e.to_string()),
            Domain::RunFile,
            None,
        )
    })?;
    RunStore::open_read_only(path).map_err(store_err)
}

fn store_err(e: gonio_run::StoreError) -> PyErr {
    errors::to_py(
        gonio_cli::api::CliError::classify(e.is_bad_input(), e),
        Domain::RunFile,
        None,
    )
}

/// Opens a run file the way `gonio show` does: refused unless it is an intact run
/// file (SQLite's check, row checksums, the integrity record). Returns the summary
/// (`gonio show --json`, as JSON text) and every `meta` row.
#[pyfunction]
fn run_open(py: Python<'_>, path: PathBuf) -> PyResult<(String, Bound<'_, PyDict>)> {
    let (summary, meta) = py.detach(|| -> Result<_, PyErr> {
        let store = open(&path)?;
        let s = gonio_run::summary(&store).map_err(store_err)?;
        let meta = store.meta().map_err(store_err)?;
        Ok((s, meta))
    })?;
    let json = serde_json::to_string(&summary).map_err(|e| {
        errors::to_py(
            gonio_cli::api::CliError::Runtime(e.to_string()),
            Domain::RunFile,
            None,
        )
    })?;
    let d = PyDict::new(py);
    for (k, v) in meta {
        d.set_item(k, v)?;
    }
    Ok((json, d))
}

/// The readings as columns (`RunStore::reading_columns`).
#[pyfunction]
fn run_readings(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyList>> {
    let cols = py.detach(|| open(&path)?.reading_columns().map_err(store_err))?;
    columns::run_columns_to_py(py, cols)
}

/// The events: `[(wall_s, kind, step_id or None, message)]`.
#[pyfunction]
#[allow(clippy::type_complexity)]
fn run_events(py: Python<'_>, path: PathBuf) -> PyResult<Vec<(f64, String, Option<i64>, String)>> {
    let events = py.detach(|| open(&path)?.events().map_err(store_err))?;
    Ok(events
        .into_iter()
        .map(|e| (e.wall_s, e.kind, e.step_id, e.message))
        .collect())
}

/// `gonio reduce WORDS…` (the words name the run and carry the flags; their `--out`
/// is not written): `(columns, sidecar JSON, reduction JSON)`.
#[pyfunction]
fn run_reduce(py: Python<'_>, words: Vec<String>) -> PyResult<(Bound<'_, PyList>, String, String)> {
    // The file is checked first, so that what the reduction refuses afterwards is
    // the data (or the options), not the file.
    if let Some(run) = words.get(1) {
        let path = PathBuf::from(run);
        py.detach(|| open(&path).map(drop))?;
    }
    let (content, report, sidecar) = interrupt::run(py, None, OnInterrupt::Abandon, move || {
        gonio_cli::api::reduce(&words)
    })?
    .map_err(|e| errors::to_py(e, Domain::Data, None))?;
    // The columns as the command line writes them; the sidecar as it writes it too,
    // the reduction's covariance included.
    let (cols, _) = columns::content_to_py(py, &content)?;
    Ok((cols, sidecar, report.to_string()))
}

/// TOML text (a config the run file keeps) as JSON text, for `json.loads`: every
/// Python reads it, tomllib or not.
#[pyfunction]
fn toml_to_json(text: &str) -> PyResult<String> {
    let v: toml::Value = toml::from_str(text).map_err(|e| errors::input(e.to_string()))?;
    serde_json::to_string(&v).map_err(|e| errors::input(e.to_string()))
}

/// JSON text (a dict from Python) as TOML text, for a model file from a dict.
#[pyfunction]
fn json_to_toml(text: &str) -> PyResult<String> {
    let v: toml::Value = serde_json::from_str(text).map_err(|e| errors::input(e.to_string()))?;
    toml::to_string(&v).map_err(|e| errors::input(e.to_string()))
}
