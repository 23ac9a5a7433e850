//! The binary's error: a one-line reason and the exit status it maps to
//! (`CONVENTIONS.md`: 2 for bad input, 1 for a runtime failure).

use std::fmt;

/// Why a command failed.
#[derive(Debug)]
pub enum CliError {
    /// Bad arguments, files or configs: exit status 2.
    Input(String),
    /// A failure while running on good input: exit status 1.
    Runtime(String),
    /// Stopped by the operator (Ctrl-C), cleanly and resumably: exit status 130, the
    /// shell's code for an interrupt.
    Interrupted(String),
}

impl CliError {
    /// The process exit status for this error.
    pub fn exit_code(&self) -> i32 {
        match self {
            CliError::Input(_) => 2,
            CliError::Runtime(_) => 1,
            CliError::Interrupted(_) => 130,
        }
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

/// A result whose error is a [`CliError`].
pub type CliResult<T> = Result<T, CliError>;
