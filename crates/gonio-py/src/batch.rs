//! What `gonio.batch` runs on a Dask worker: a whole offline command in-process
//! (the files it writes, written as `gonio` writes them, and what it prints), and
//! chunks of a `gonio micro` table with their exact merge.

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use gonio_micro::TablePart;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyList};

use crate::columns;
use crate::errors::{self, Domain};
use crate::interrupt::{self, OnInterrupt};

/// Registers the functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("SEGMENT_RAYS", gonio_micro::SEGMENT_RAYS)?;
    m.add_function(wrap_pyfunction!(run_command, m)?)?;
    m.add_function(wrap_pyfunction!(validate, m)?)?;
    m.add_function(wrap_pyfunction!(micro_plan, m)?)?;
    m.add_function(wrap_pyfunction!(micro_part, m)?)?;
    m.add_function(wrap_pyfunction!(micro_merge, m)?)?;
    m.add_function(wrap_pyfunction!(micro_part_info, m)?)?;
    Ok(())
}

/// `gonio WORDS…` in this process (an offline command: `reduce`, `check`, `fit`,
/// `report`, …): writes what the command writes and returns what it prints.
/// `threads` bounds the threads its parallel parts use (default: one a core).
#[pyfunction]
#[pyo3(signature = (words, threads = None))]
fn run_command(py: Python<'_>, words: Vec<String>, threads: Option<usize>) -> PyResult<String> {
    let input = words.get(1).cloned();
    interrupt::run(py, threads, OnInterrupt::Abandon, move || {
        gonio_cli::api::run(&words)
    })?
    .map_err(|e| errors::to_py(e, Domain::Data, input.as_deref()))
}

/// Checks `gonio WORDS…` as the command would before reading its input (its
/// parser, and every flag's value), running nothing.
#[pyfunction]
fn validate(words: Vec<String>) -> PyResult<()> {
    gonio_cli::api::validate(&words).map_err(|e| errors::to_py(e, Domain::Data, None))
}

/// `(incident nodes, segments of rays a node)` of the table `gonio WORDS` (a
/// `micro` command) makes: loads the surface (`surface`: its edited text), so a
/// bad one fails here.
#[pyfunction]
#[pyo3(signature = (words, theta_i, surface))]
fn micro_plan(
    py: Python<'_>,
    words: Vec<String>,
    theta_i: Option<(f64, f64, usize)>,
    surface: Option<String>,
) -> PyResult<(usize, usize)> {
    let name = words.get(1).cloned();
    interrupt::run(py, None, OnInterrupt::Abandon, move || {
        gonio_cli::api::micro_plan(&words, theta_i, surface.as_deref())
    })?
    .map_err(|e| micro_err(e, name.as_deref()))
}

/// The error of a micro chunk: the surface's fault when its message names it.
fn micro_err(e: gonio_cli::api::CliError, surface: Option<&str>) -> PyErr {
    let domain = match (&e, surface) {
        (gonio_cli::api::CliError::Input(m), Some(s)) if m.starts_with(s) => Domain::Config,
        _ => Domain::Data,
    };
    errors::to_py(e, domain, None)
}

/// Segments `first..end` of incident node `incident` of the table `gonio WORDS`
/// (a `micro` command) makes, as bytes for [`micro_merge`]. `surface` is the
/// surface file's text when a sweep edited it; `theta_i` = (first, step, count)
/// in degrees replaces the grid's incident polar axis.
#[pyfunction]
#[pyo3(signature = (words, theta_i, surface, incident, first, end, threads = None))]
#[allow(clippy::too_many_arguments)]
fn micro_part(
    py: Python<'_>,
    words: Vec<String>,
    theta_i: Option<(f64, f64, usize)>,
    surface: Option<String>,
    incident: usize,
    first: usize,
    end: usize,
    threads: Option<usize>,
) -> PyResult<Bound<'_, PyBytes>> {
    let name = words.get(1).cloned();
    let cancel = Arc::new(AtomicBool::new(false));
    let flag = cancel.clone();
    let part = interrupt::run(py, threads, OnInterrupt::Stop(cancel), move || {
        gonio_cli::api::micro_part(
            &words,
            theta_i,
            surface.as_deref(),
            incident,
            first..end,
            flag,
        )
    })?
    .map_err(|e| micro_err(e, name.as_deref()))?;
    Ok(PyBytes::new(py, &part.to_bytes()))
}

/// The table of `gonio WORDS` from its chunks ([`micro_part`]'s bytes, in any
/// order): `(columns, sidecar, --json object)`, bit for bit the table traced at
/// once. `out` also writes it (CSV and sidecar) as `gonio micro --out` does.
#[pyfunction]
#[pyo3(signature = (words, theta_i, surface, parts, out = None, force = false))]
fn micro_merge<'py>(
    py: Python<'py>,
    words: Vec<String>,
    theta_i: Option<(f64, f64, usize)>,
    surface: Option<String>,
    parts: Vec<Vec<u8>>,
    out: Option<std::path::PathBuf>,
    force: bool,
) -> PyResult<(Bound<'py, PyList>, String, String)> {
    let name = words.get(1).cloned();
    let parts = parts
        .iter()
        .map(|b| TablePart::from_bytes(b))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| errors::input(format!("micro_merge: {e}")))?;
    let (table, json) = interrupt::run(py, None, OnInterrupt::Abandon, move || {
        let (table, json) =
            gonio_cli::api::micro_merge(&words, theta_i, surface.as_deref(), &parts)?;
        if let Some(out) = &out {
            gonio_cli::api::write_table(&table, out, force)?;
        }
        Ok((table, json))
    })?
    .map_err(|e| micro_err(e, name.as_deref()))?;
    let (cols, sidecar) = columns::table_to_py(py, &table)?;
    Ok((cols, sidecar, json.to_string()))
}

/// `(seed, rays, incident, first, end)` of a part's bytes (checked whole): what a
/// kept chunk is, before it is used again.
#[pyfunction]
fn micro_part_info(part: &[u8]) -> PyResult<(u64, usize, usize, usize, usize)> {
    let p = TablePart::from_bytes(part).map_err(|e| errors::input(format!("micro part: {e}")))?;
    let segs = p.segments();
    Ok((p.seed, p.rays, p.incident, segs.start, segs.end))
}
