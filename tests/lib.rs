//! Shared helpers for Gonio's end-to-end tests, which live beside this file and
//! exercise several crates together (model files → radiometry → instrument signals).

use std::path::{Path, PathBuf};

/// The repository's `config/` directory.
pub fn config_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../config")
}
