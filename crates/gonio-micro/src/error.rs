//! The crate's error type.

use std::path::PathBuf;

use gonio_core::tomlfile::FileError;

/// Why a surface, a material or a simulation request was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MicroError {
    /// Stopped by its cancel flag (`Simulation::cancel_on`).
    #[error("cancelled")]
    Cancelled,
    /// A surface file that could not be used: `FILE:LINE:COL: field `NAME`: why`.
    #[error("{0}")]
    File(Box<FileError>),
    /// A height-map file (or its data) that could not be read.
    #[error("{}", located(path, *line, message))]
    HeightMap {
        /// The height-map file.
        path: PathBuf,
        /// 1-based line of the fault, for text formats.
        line: Option<usize>,
        /// What is wrong.
        message: String,
    },
    /// A gonio-brdf model file named by a `model` material that could not be used.
    #[error("{surface}: field `{field}`: {source}")]
    Model {
        /// The surface file that names the model.
        surface: String,
        /// The field that names it (`materials.paint.file`).
        field: String,
        /// The model file's own error (it names the model file, line and field).
        source: Box<gonio_brdf::ModelError>,
    },
    /// A parameter of the API that cannot be used (`what` names it).
    #[error("{what}: {why}")]
    Invalid {
        /// The parameter (`rms_height`, `grid`, `rays`).
        what: String,
        /// What is wrong with it.
        why: String,
    },
    /// The processing crate refused a table or a representation.
    #[error(transparent)]
    Process(#[from] gonio_process::ProcessError),
}

impl From<FileError> for MicroError {
    fn from(e: FileError) -> Self {
        MicroError::File(Box::new(e))
    }
}

impl MicroError {
    pub(crate) fn invalid(what: impl Into<String>, why: impl Into<String>) -> MicroError {
        MicroError::Invalid {
            what: what.into(),
            why: why.into(),
        }
    }
}

fn located(path: &std::path::Path, line: Option<usize>, message: &str) -> String {
    match line {
        Some(l) => format!("{}:{l}: {message}", path.display()),
        None => format!("{}: {message}", path.display()),
    }
}
