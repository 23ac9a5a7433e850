//! Errors as Python exceptions: `GonioError` and its subclasses, each carrying the
//! command's one-line message (file, line, field) and its exit status
//! (`exit_code`: 2 bad input, 1 runtime failure). An operator's stop is Python's own
//! `KeyboardInterrupt`.

use gonio_cli::api::CliError;
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt};
use pyo3::prelude::*;

create_exception!(
    gonio,
    GonioError,
    PyException,
    "Any failure Gonio reports; `exit_code` is the command line's exit status."
);
create_exception!(
    gonio,
    InputError,
    GonioError,
    "Bad input: an argument, a file or a value (exit status 2)."
);
create_exception!(
    gonio,
    ConfigError,
    InputError,
    "A config, plan, model or surface file is wrong; the message names the file, line and field."
);
create_exception!(
    gonio,
    DataError,
    InputError,
    "Data that cannot be processed as asked (a table, samples, a DataFrame)."
);
create_exception!(
    gonio,
    RunFileError,
    GonioError,
    "A run file is missing, not a run file, damaged, locked or already exists."
);
create_exception!(
    gonio,
    InstrumentError,
    GonioError,
    "The instrument (or the simulator) failed: a port, a timeout, a fault."
);

/// What a call was about, which picks the exception class of its failures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Domain {
    /// Configs, plans, models, surfaces.
    Config,
    /// Data to process.
    Data,
    /// A run file.
    RunFile,
    /// An acquisition.
    Instrument,
    /// A file a call writes (it exists, its directory does not).
    Output,
}

/// Adds the exception classes to the module.
pub fn register(py: Python<'_>, m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("GonioError", py.get_type::<GonioError>())?;
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("ConfigError", py.get_type::<ConfigError>())?;
    m.add("DataError", py.get_type::<DataError>())?;
    m.add("RunFileError", py.get_type::<RunFileError>())?;
    m.add("InstrumentError", py.get_type::<InstrumentError>())?;
    // Class defaults, for errors raised by the package's Python side (the native
    // side sets each instance's own): bad input 2, anything else 1, as `gonio`.
    py.get_type::<GonioError>().setattr("exit_code", 1)?;
    py.get_type::<InputError>().setattr("exit_code", 2)?;
    py.get_type::<RunFileError>().setattr("exit_code", 2)?;
    Ok(())
}

/// The exception for `e` in `domain`. `run` is the run file concerned, if any: bad
/// input about it is a run-file error whatever the domain.
pub fn to_py(e: CliError, domain: Domain, run: Option<&str>) -> PyErr {
    let code = e.exit_code();
    let msg = e.to_string();
    // Bad input about the run file itself (it exists, it is locked, it is damaged)
    // is the file's fault; a failure while measuring into it is the instrument's.
    let about_run = matches!(e, CliError::Input(_)) && run.is_some_and(|r| msg.starts_with(r));
    let err = match (e, domain) {
        (CliError::Interrupted(m), _) => return PyKeyboardInterrupt::new_err(m),
        _ if about_run || domain == Domain::RunFile => RunFileError::new_err(msg),
        (CliError::Input(m), Domain::Config | Domain::Instrument) => ConfigError::new_err(m),
        (CliError::Input(m), Domain::Output) => InputError::new_err(m),
        (CliError::Input(m), _) => DataError::new_err(m),
        (CliError::Runtime(m), Domain::Instrument) => InstrumentError::new_err(m),
        (CliError::Runtime(m), _) => GonioError::new_err(m),
    };
    Python::attach(|py| {
        // The attribute is informative; a failure to set it leaves the exception as is.
        let _ = err.value(py).setattr("exit_code", code);
    });
    err
}

/// A bad argument from Python (exit status 2).
pub fn input(msg: impl Into<String>) -> PyErr {
    to_py(CliError::Input(msg.into()), Domain::Data, None)
}
