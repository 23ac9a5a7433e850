//! The binary's one error type: a one-line reason and the exit status it maps to
//! (`docs/CONVENTIONS.md`: 2 for bad input, 1 for a runtime failure, 130 for an
//! interrupt). Every library error becomes one of these here, and only here.

use std::fmt;

/// Why a command failed.
#[derive(Debug)]
pub enum CliError {
    /// Bad arguments, files or configs: exit status 2.
    Input(String),
    /// A failure while running on good input: exit status 1.
    Runtime(String),
    /// Stopped by the operator (Ctrl-C, SIGTERM, SIGHUP), cleanly and resumably: exit
    /// status 130, the shell's code for an interrupt.
    Interrupted(String),
}

impl CliError {
    /// The process exit status for this error.
    pub fn exit_code(&self) -> u8 {
        match self {
            CliError::Input(_) => 2,
            CliError::Runtime(_) => 1,
            CliError::Interrupted(_) => 130,
        }
    }

    /// Bad input when `bad_input`, a runtime failure otherwise.
    pub fn classify(bad_input: bool, message: impl fmt::Display) -> CliError {
        if bad_input {
            CliError::Input(message.to_string())
        } else {
            CliError::Runtime(message.to_string())
        }
    }
}

impl CliError {
    /// Processing refused `path`'s data: bad input, unless the numerics failed.
    pub fn process(path: &std::path::Path, e: gonio_process::ProcessError) -> CliError {
        CliError::classify(
            !matches!(e, gonio_process::ProcessError::Numerics(_)),
            format!("{}: {e}", path.display()),
        )
    }
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CliError::Input(m) | CliError::Runtime(m) | CliError::Interrupted(m) => f.write_str(m),
        }
    }
}

impl From<gonio_brdf::ModelError> for CliError {
    fn from(e: gonio_brdf::ModelError) -> Self {
        CliError::Input(e.to_string())
    }
}

impl From<gonio_core::tomlfile::FileError> for CliError {
    fn from(e: gonio_core::tomlfile::FileError) -> Self {
        CliError::Input(e.to_string())
    }
}

impl From<gonio_dataset::DatasetError> for CliError {
    fn from(e: gonio_dataset::DatasetError) -> Self {
        CliError::classify(e.is_bad_input(), e)
    }
}

impl From<gonio_run::StoreError> for CliError {
    fn from(e: gonio_run::StoreError) -> Self {
        CliError::classify(e.is_bad_input(), e)
    }
}

impl From<gonio_live::LiveError> for CliError {
    fn from(e: gonio_live::LiveError) -> Self {
        CliError::classify(e.is_input(), e)
    }
}

impl From<gonio_sim::serve::ServeError> for CliError {
    fn from(e: gonio_sim::serve::ServeError) -> Self {
        CliError::classify(e.exit_code() == 2, e)
    }
}

/// A result whose error is a [`CliError`].
pub type CliResult<T> = Result<T, CliError>;
