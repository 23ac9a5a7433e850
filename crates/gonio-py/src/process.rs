//! `check`, `correct`, `harmonics`, `fit` and `micro`: the commands' own
//! computations (`gonio_cli::api`) on a file, a model or a DataFrame's columns.

use std::path::PathBuf;

use gonio_cli::api::Watch;
use gonio_dataset::Dataset;
use numpy::PyReadonlyArray1;
use pyo3::prelude::*;
use pyo3::types::PyList;
use rayon::prelude::*;

use crate::columns::{self, Source};
use crate::errors::{self, Domain};
use crate::interrupt::{self, OnInterrupt};
use crate::model::NativeModel;

/// Registers the functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(check, m)?)?;
    m.add_function(wrap_pyfunction!(correct, m)?)?;
    m.add_function(wrap_pyfunction!(harmonics, m)?)?;
    m.add_function(wrap_pyfunction!(fit, m)?)?;
    m.add_function(wrap_pyfunction!(micro, m)?)?;
    Ok(())
}

/// A DataFrame's columns as Python hands them over: `(columns, isotropic, label)`.
type Frame<'py> = (Vec<(String, PyReadonlyArray1<'py, f64>)>, bool, PathBuf);

/// The data `source` is: a path (str or os.PathLike), a `NativeModel`, a
/// `NativeBsdf`, or a DataFrame's columns.
pub(crate) fn source(obj: &Bound<'_, PyAny>) -> PyResult<Source> {
    if let Ok(m) = obj.cast::<NativeModel>() {
        let model = m.get().model.clone();
        return Ok(Source::Data(
            Dataset::Model(Box::new(model)),
            PathBuf::from("<model>"),
        ));
    }
    if let Ok(b) = obj.cast::<crate::model::NativeBsdf>() {
        return Ok(Source::Data(
            Dataset::Rgl(Box::new(b.get().bsdf.clone())),
            PathBuf::from("<bsdf>"),
        ));
    }
    if let Ok((cols, isotropic, label)) = obj.extract::<Frame<'_>>() {
        return Ok(Source::Frame(
            columns::frame_from_py(cols),
            isotropic,
            label,
        ));
    }
    match obj.extract::<PathBuf>() {
        Ok(p) => Ok(Source::Path(p)),
        Err(_) => Err(errors::input(
            "the input: a path, a Run, a Model or a DataFrame of samples",
        )),
    }
}

/// `[command, input, flags…]` from `[command, flags…]`.
pub(crate) fn with_input(mut words: Vec<String>, input: String) -> Vec<String> {
    words.insert(1.min(words.len()), input);
    words
}

/// `gonio check`: the `--json` object (JSON text).
#[pyfunction]
fn check(py: Python<'_>, input: &Bound<'_, PyAny>, words: Vec<String>) -> PyResult<String> {
    let src = source(input)?;
    let words = with_input(words, src.word());
    interrupt::run(py, None, OnInterrupt::Abandon, move || {
        gonio_cli::api::check(&words, src.into_data()?)
    })?
    .map(|v| v.to_string())
    .map_err(|e| errors::to_py(e, Domain::Data, None))
}

/// `gonio correct`: `(columns, sidecar, --json object)` of the corrected table.
#[pyfunction]
fn correct<'py>(
    py: Python<'py>,
    input: &Bound<'py, PyAny>,
    words: Vec<String>,
) -> PyResult<(Bound<'py, PyList>, String, String)> {
    let src = source(input)?;
    let words = with_input(words, src.word());
    let (table, meta, json) = interrupt::run(py, None, OnInterrupt::Abandon, move || {
        gonio_cli::api::correct(&words, src.into_data()?)
    })?
    .map_err(|e| errors::to_py(e, Domain::Data, None))?;
    let cols = columns::to_py(py, gonio_process::columns::of_table(&table))?;
    Ok((cols, meta.to_json(), json.to_string()))
}

/// `gonio harmonics`: `(file text, --json object)`.
#[pyfunction]
fn harmonics(
    py: Python<'_>,
    input: &Bound<'_, PyAny>,
    words: Vec<String>,
) -> PyResult<(String, String)> {
    let src = source(input)?;
    let words = with_input(words, src.word());
    interrupt::run(py, None, OnInterrupt::Abandon, move || {
        gonio_cli::api::harmonics(&words, src.into_data()?)
    })?
    .map(|(text, json)| (text, json.to_string()))
    .map_err(|e| errors::to_py(e, Domain::Data, None))
}

/// `gonio fit`: `(model file, --json object, report text)`; the work on `threads`
/// threads (none: one a core). `report` is handed the call's state (stage `fit`,
/// no count: the fitter does not say how far it is).
#[pyfunction]
#[pyo3(signature = (input, words, threads = None, report = None))]
fn fit(
    py: Python<'_>,
    input: &Bound<'_, PyAny>,
    words: Vec<String>,
    threads: Option<usize>,
    report: Option<Bound<'_, PyAny>>,
) -> PyResult<(String, String, String)> {
    let src = source(input)?;
    let words = with_input(words, src.word());
    let watch = Watch::new();
    watch.begin("fit", "");
    interrupt::run_watched(
        py,
        threads,
        OnInterrupt::Abandon,
        move || gonio_cli::api::fit(&words, src.into_samples()?),
        report.as_ref().map(|r| (&*watch, r)),
    )?
    .map(|f| (f.model_file, f.json.to_string(), f.report))
    .map_err(|e| errors::to_py(e, Domain::Data, None))
}

/// `gonio micro SURFACE …`: `(columns, sidecar, --json object)` of the table;
/// `theta_i` = (first, step, count) in degrees replaces the incident polar axis.
/// With `report`, the table is traced an incident node at a time (each node on a
/// thread of the pool, all its rays at once; merged, bit for bit the table traced
/// whole) and `report` is handed the nodes done.
#[pyfunction]
#[pyo3(signature = (words, theta_i = None, threads = None, report = None))]
fn micro<'py>(
    py: Python<'py>,
    words: Vec<String>,
    theta_i: Option<(f64, f64, usize)>,
    threads: Option<usize>,
    report: Option<Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyList>, String, String)> {
    let surface = words.get(1).cloned();
    let watch = Watch::new();
    let w = watch.clone();
    let by_node = report.is_some();
    let work = move || {
        if !by_node {
            return gonio_cli::api::micro(&words, theta_i, w.stop_flag());
        }
        let m = gonio_cli::api::Micro::new(&words, theta_i, w.stop_flag())?;
        let n = m.incidences();
        w.begin("trace", "incidences");
        w.set(0, Some(n as u64));
        let nodes = (0..n)
            .into_par_iter()
            .map(|i| {
                let node = m.node(i);
                w.advance();
                node
            })
            .collect::<Result<Vec<_>, _>>()?;
        m.finish(&nodes)
    };
    let stop = OnInterrupt::Stop(watch.stop_flag());
    let (table, json) = interrupt::run_watched(
        py,
        threads,
        stop,
        work,
        report.as_ref().map(|r| (&*watch, r)),
    )?
    .map_err(|e| {
        let domain = match (&e, &surface) {
            (gonio_cli::api::CliError::Input(m), Some(s)) if m.starts_with(s.as_str()) => {
                Domain::Config
            }
            _ => Domain::Data,
        };
        errors::to_py(e, domain, None)
    })?;
    let (cols, sidecar) = columns::table_to_py(py, &table)?;
    Ok((cols, sidecar, json.to_string()))
}
