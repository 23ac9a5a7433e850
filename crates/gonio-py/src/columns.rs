//! Columns across the boundary: numpy arrays out (one allocation a column, no
//! Python object per element), float64 arrays in; and data from Python (a path, a
//! model, a DataFrame's columns) as a `Dataset` the commands take.

use std::path::{Path, PathBuf};

use gonio_dataset::Dataset;
use gonio_process::columns::{self, Column};
use gonio_process::file::{Content, Meta};
use gonio_process::{Samples, Table};
use gonio_run::ColumnValues;
use numpy::{IntoPyArray, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::{PyList, PyTuple};

use gonio_cli::api::CliError;

/// Named columns as a list of `(name, ndarray)`.
pub fn to_py<'py>(py: Python<'py>, cols: Vec<(String, Column)>) -> PyResult<Bound<'py, PyList>> {
    let items: Vec<Bound<'py, PyTuple>> = cols
        .into_iter()
        .map(|(name, c)| {
            let array = match c {
                Column::F64(v) => v.into_pyarray(py).into_any(),
                Column::U32(v) => v.into_pyarray(py).into_any(),
            };
            PyTuple::new(py, [name.into_pyobject(py)?.into_any(), array])
        })
        .collect::<PyResult<_>>()?;
    PyList::new(py, items)
}

/// A table or samples as `(columns, sidecar)`: the columns of the CSV the command
/// line writes, and its sidecar (JSON text: the grid, isotropy).
pub fn content_to_py<'py>(py: Python<'py>, c: &Content) -> PyResult<(Bound<'py, PyList>, String)> {
    match c {
        Content::Table(t) => table_to_py(py, t),
        Content::Samples(s) => Ok((
            to_py(py, columns::of_samples(s))?,
            Meta::for_samples(s).to_json(),
        )),
    }
}

/// A table as `(columns, sidecar)`.
pub fn table_to_py<'py>(py: Python<'py>, t: &Table) -> PyResult<(Bound<'py, PyList>, String)> {
    Ok((
        to_py(py, columns::of_table(t))?,
        Meta::for_table(t).to_json(),
    ))
}

/// A run file's columns as `(name, ndarray)` for numbers; a TEXT column is a list
/// (of str or None), an INTEGER column `(int64 array, mask of NULLs or None)`.
pub fn run_columns_to_py<'py>(
    py: Python<'py>,
    cols: Vec<(String, ColumnValues)>,
) -> PyResult<Bound<'py, PyList>> {
    let items: Vec<Bound<'py, PyTuple>> = cols
        .into_iter()
        .map(|(name, c)| {
            let value = match c {
                ColumnValues::Real(v) => v.into_pyarray(py).into_any(),
                ColumnValues::Integer(v) => {
                    let nulls = v.iter().any(Option::is_none);
                    let mask: Option<Vec<bool>> =
                        nulls.then(|| v.iter().map(Option::is_none).collect());
                    let values: Vec<i64> = v.into_iter().map(|x| x.unwrap_or(0)).collect();
                    let mask = match mask {
                        Some(m) => m.into_pyarray(py).into_any(),
                        None => py.None().into_bound(py),
                    };
                    PyTuple::new(py, [values.into_pyarray(py).into_any(), mask])?.into_any()
                }
                ColumnValues::Text(v) => PyList::new(py, v)?.into_any(),
            };
            PyTuple::new(py, [name.into_pyobject(py)?.into_any(), value])
        })
        .collect::<PyResult<_>>()?;
    PyList::new(py, items)
}

/// Data handed in from Python: a file, a model, or a DataFrame's columns.
pub enum Source {
    /// A file any command reads (run, table, samples, MERL, ASTM, model, …).
    Path(PathBuf),
    /// Data in memory, and the label that names it in messages.
    Data(Dataset, PathBuf),
    /// A DataFrame's columns (copied out of numpy), whether the samples are
    /// isotropic, and the label.
    Frame(Vec<(String, Vec<f64>)>, bool, PathBuf),
}

impl Source {
    /// The path the command's words name: the file, or the label.
    pub fn word(&self) -> String {
        match self {
            Source::Path(p) | Source::Data(_, p) | Source::Frame(_, _, p) => {
                p.display().to_string()
            }
        }
    }

    /// The data in memory, if any; a frame's samples are read here, as a sample
    /// file's rows are (so off the interpreter's lock when called there).
    pub fn into_data(self) -> Result<Option<Dataset>, CliError> {
        Ok(match self {
            Source::Path(_) => None,
            Source::Data(d, _) => Some(d),
            Source::Frame(cols, isotropic, label) => {
                Some(samples_dataset(frame_samples(&cols, isotropic, &label)?))
            }
        })
    }

    /// The samples in memory, if any (a model is sampled as `gonio fit` samples a
    /// model file).
    pub fn into_samples(self) -> Result<Option<Samples>, CliError> {
        let label = PathBuf::from(self.word());
        Ok(match self {
            Source::Path(_) => None,
            Source::Frame(cols, isotropic, label) => Some(frame_samples(&cols, isotropic, &label)?),
            Source::Data(Dataset::Samples(s), _) => Some(s),
            Source::Data(d, _) => Some(d.to_samples(200_000, &label)?),
        })
    }
}

/// Samples from a frame's columns, refused as a sample file's would be (bad input).
fn frame_samples(
    cols: &[(String, Vec<f64>)],
    isotropic: bool,
    label: &Path,
) -> Result<Samples, CliError> {
    columns::to_samples(cols, isotropic, label).map_err(|e| CliError::Input(e.to_string()))
}

/// A DataFrame's columns (`[(name, float64 array)]`) copied out of numpy: one copy
/// a column, no Python object per element.
pub fn frame_from_py(cols: Vec<(String, PyReadonlyArray1<'_, f64>)>) -> Vec<(String, Vec<f64>)> {
    cols.into_iter()
        .map(|(n, a)| (n, a.as_array().to_vec()))
        .collect()
}

/// Samples as the dataset a file of them opens as: a table when they form a grid
/// (as a run's reduction, or a table file, would be), else scattered samples.
pub fn samples_dataset(s: Samples) -> Dataset {
    match s.to_table() {
        Some(t) => Dataset::Table(t),
        None => Dataset::Samples(s),
    }
}
