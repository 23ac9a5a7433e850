//! The remaining commands: `colour`, `export`, `verify`, `report`, `plan check`,
//! `plan compare` and `instrument check`, each the command's own computation
//! (`gonio_cli::api`) on the command's words. Where the command writes a file
//! (`export`, `report`), so does the call when asked, as the command writes it.

use std::path::Path;

use gonio_cli::api::{self, CliError, Watch};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use crate::errors::{self, Domain};
use crate::interrupt::{self, OnInterrupt};
use crate::process::{source, with_input};

/// Registers the functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(colour, m)?)?;
    m.add_function(wrap_pyfunction!(export, m)?)?;
    m.add_function(wrap_pyfunction!(verify, m)?)?;
    m.add_function(wrap_pyfunction!(report, m)?)?;
    m.add_function(wrap_pyfunction!(plan_check, m)?)?;
    m.add_function(wrap_pyfunction!(plan_compare, m)?)?;
    m.add_function(wrap_pyfunction!(instrument_check, m)?)?;
    Ok(())
}

/// The value of `flag` in `words`, if given.
fn flag_value(words: &[String], flag: &str) -> Option<String> {
    let i = words.iter().position(|w| w == flag)?;
    words.get(i + 1).cloned()
}

/// The exception for `e`: bad input about the output `out` (it exists, its
/// directory does not) is a plain `InputError`, neither the data's fault nor a
/// config's; anything else as [`errors::to_py`] maps it.
fn to_py_out(e: CliError, domain: Domain, run: Option<&str>, out: Option<&str>) -> PyErr {
    match (&e, out) {
        (CliError::Input(m), Some(o)) if !o.is_empty() && m.starts_with(o) => {
            errors::to_py(e, Domain::Output, None)
        }
        _ => errors::to_py(e, domain, run),
    }
}

/// A run file checked first, as `Run` opens it: what a command refuses afterwards
/// is then the data (or the options), not the file.
fn check_run(py: Python<'_>, path: &Path) -> PyResult<()> {
    let path = path.to_path_buf();
    py.detach(move || crate::run::open(&path).map(drop))
}

/// `gonio colour WORDS…`: the `--json` object (JSON text). `text` is the spectra
/// file's contents from memory (a DataFrame's CSV), which the input word names.
#[pyfunction]
#[pyo3(signature = (words, text = None))]
fn colour(py: Python<'_>, words: Vec<String>, text: Option<String>) -> PyResult<String> {
    interrupt::run(py, None, OnInterrupt::Abandon, move || {
        api::colour(&words, text.as_deref())
    })?
    .map(|v| v.to_string())
    .map_err(|e| errors::to_py(e, Domain::Data, None))
}

/// `gonio export` of `input` (a path, a model or a DataFrame's columns) with the
/// words `[export, flags…]`: `(bytes, CSV sidecar or None, --json object)`. With
/// `write`, the file is written as the command writes it (`--out`, refused if it
/// exists unless `--force`); without, nothing is.
#[pyfunction]
fn export<'py>(
    py: Python<'py>,
    input: &Bound<'py, PyAny>,
    words: Vec<String>,
    write: bool,
) -> PyResult<(Bound<'py, PyBytes>, Option<String>, String)> {
    let src = source(input)?;
    let word = src.word();
    let run = gonio_run::is_run_file(Path::new(&word)).then(|| word.clone());
    if let Some(r) = &run {
        check_run(py, Path::new(r))?;
    }
    let out = write.then(|| flag_value(&words, "--out")).flatten();
    let words = with_input(words, word);
    let e = interrupt::run(py, None, OnInterrupt::Abandon, move || {
        api::export(&words, src.into_data()?, write)
    })?
    .map_err(|e| to_py_out(e, Domain::Data, run.as_deref(), out.as_deref()))?;
    Ok((PyBytes::new(py, &e.bytes), e.sidecar, e.json.to_string()))
}

/// `gonio verify WORDS…`: `(--json object, exception or None)`, the exception
/// (a `RunFileError`, exit status 1) when the file is damaged. A file that cannot
/// be checked at all raises.
#[pyfunction]
fn verify(py: Python<'_>, words: Vec<String>) -> PyResult<(String, Option<Py<PyAny>>)> {
    let (json, failed) =
        interrupt::run(py, None, OnInterrupt::Abandon, move || api::verify(&words))?
            .map_err(|e| errors::to_py(e, Domain::RunFile, None))?;
    let failed = failed.map(|e| {
        errors::to_py(e, Domain::RunFile, None)
            .into_value(py)
            .into_any()
    });
    Ok((json.to_string(), failed))
}

/// `gonio report WORDS…`: with `write`, DIR/report.html written as the command
/// writes it and `(--json object, None)`; without, nothing written and `(--json
/// object without out, the page's HTML)`.
#[pyfunction]
fn report(py: Python<'_>, words: Vec<String>, write: bool) -> PyResult<(String, Option<String>)> {
    let run = words.get(1).cloned().unwrap_or_default();
    check_run(py, Path::new(&run))?;
    let out = write.then(|| flag_value(&words, "--out")).flatten();
    let (json, html) = interrupt::run(py, None, OnInterrupt::Abandon, move || {
        api::report(&words, write)
    })?
    .map_err(|e| to_py_out(e, Domain::Data, Some(&run), out.as_deref()))?;
    Ok((json.to_string(), html))
}

/// `gonio plan check WORDS…` (`[plan, check, PLAN, flags…]`): the `--json` object.
/// A `--like` run that cannot be used is a `RunFileError`.
#[pyfunction]
fn plan_check(py: Python<'_>, words: Vec<String>) -> PyResult<String> {
    let like = flag_value(&words, "--like");
    interrupt::run(py, None, OnInterrupt::Abandon, move || {
        api::plan_check(&words)
    })?
    .map(|v| v.to_string())
    .map_err(|e| errors::to_py(e, Domain::Config, like.as_deref()))
}

/// `gonio plan compare WORDS…`: the `--json` object. The three runs are measured in
/// turn, Ctrl-C stopping the stages as in `acquire`; `report` is handed each run's
/// progress (a stage a run).
#[pyfunction]
#[pyo3(signature = (words, report = None))]
fn plan_compare(
    py: Python<'_>,
    words: Vec<String>,
    report: Option<Bound<'_, PyAny>>,
) -> PyResult<String> {
    let keep = flag_value(&words, "--keep");
    let watch = Watch::new();
    let w = watch.clone();
    interrupt::run_session(
        py,
        OnInterrupt::Stop(watch.stop_flag()),
        move || api::plan_compare(&words, w),
        report.as_ref().map(|r| (&*watch, r)),
    )?
    .map(|v| v.to_string())
    .map_err(|e| to_py_out(e, Domain::Instrument, None, keep.as_deref()))
}

/// `gonio instrument check WORDS…` (with `--connect`, the ports opened and the
/// instruments identified; nothing moves): the `--json` object.
#[pyfunction]
fn instrument_check(py: Python<'_>, words: Vec<String>) -> PyResult<String> {
    interrupt::run(py, None, OnInterrupt::Abandon, move || {
        api::instrument_check(&words)
    })?
    .map(|v| v.to_string())
    .map_err(|e| errors::to_py(e, Domain::Instrument, None))
}
