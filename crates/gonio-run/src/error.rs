//! Why a run file cannot be used.

use std::path::PathBuf;

/// Why a run file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// SQLite failed (I/O, a full disk, a locked file).
    #[error("{path}: {source}")]
    Sqlite {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: rusqlite::Error,
    },
    /// A file operation failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The file exists already (a new run never overwrites one).
    #[error("{0}: exists already; choose another name, or `gonio resume` it")]
    Exists(PathBuf),
    /// No such file.
    #[error("{0}: no such run file")]
    Missing(PathBuf),
    /// Not an SQLite database, or not a Gonio run file.
    #[error("{path}: not a Gonio run file ({why})")]
    NotARunFile {
        /// The file.
        path: PathBuf,
        /// What gave it away.
        why: String,
    },
    /// Written by a newer Gonio.
    #[error(
        "{path}: schema version {found} is newer than this build reads ({supported}); \
         use a newer gonio"
    )]
    NewerSchema {
        /// The file.
        path: PathBuf,
        /// Its version.
        found: i32,
        /// The newest this build reads.
        supported: i32,
    },
    /// A step was committed twice (two processes on one run file).
    #[error("{path}: step {step} is not pending; is another process working on this run?")]
    NotPending {
        /// The file.
        path: PathBuf,
        /// The step.
        step: i64,
    },
    /// Another process is measuring into the run.
    #[error(
        "{path}: {holder} is working on this run (it holds the run's lock); wait for it \
         to stop, or stop it (Ctrl-C) first"
    )]
    Busy {
        /// The file.
        path: PathBuf,
        /// Who, as far as the file tells.
        holder: String,
    },
    /// A `meta` row every run file has is gone (the file was edited or damaged).
    #[error(
        "{path}: the run's meta row `{key}` is missing (the file was edited or damaged); \
         `gonio verify` lists every fault"
    )]
    MissingMeta {
        /// The file.
        path: PathBuf,
        /// The key.
        key: String,
    },
    /// A batch of steps cannot be appended as given (no steps: a planner with
    /// nothing to add ends the run instead).
    #[error("{path}: cannot append the batch: {why}")]
    BadBatch {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        why: String,
    },
    /// A write only the run's lock holder may make (appending steps), asked of a
    /// store that does not hold the lock ([`crate::RunStore::lock`]).
    #[error(
        "{path}: this store does not hold the run's lock; only the process measuring the run appends to its schedule"
    )]
    NotLocked {
        /// The file.
        path: PathBuf,
    },
    /// Damaged: structure or content fails its checks.
    #[error("{path}: corrupted: {why}")]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// What failed.
        why: String,
    },
}

impl StoreError {
    /// True for faults of the file given (exit status 2), rather than of the machine.
    pub fn is_bad_input(&self) -> bool {
        !matches!(
            self,
            StoreError::Sqlite { .. }
                | StoreError::Io { .. }
                | StoreError::NotPending { .. }
                | StoreError::MissingMeta { .. }
                | StoreError::Busy { .. }
                | StoreError::BadBatch { .. }
                | StoreError::NotLocked { .. }
        )
    }
}
