//! Shared set-up of the plan tests: the simulated instrument of
//! `config/instrument-sim.toml`, plans from text.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

use gonio_driver::InstrumentConfig;
use gonio_plan::{Mechanics, Plan, PrepareError, Prepared};

/// The repository's root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The simulated instrument's config.
pub fn instrument() -> (InstrumentConfig, String) {
    let path = root().join("config/instrument-sim.toml");
    InstrumentConfig::load_with_text(&path).expect("example instrument")
}

/// The simulated instrument as planning sees it.
pub fn mechanics() -> Mechanics {
    instrument().0.mechanics().expect("mechanics")
}

/// Prepares `plan` on the simulated instrument.
pub fn prepare(plan: &Plan) -> Result<Prepared, PrepareError> {
    let (inst, _) = instrument();
    gonio_plan::prepare(
        &inst.mechanics().expect("mechanics"),
        inst.reading_seconds(),
        plan,
    )
}

/// A plan from text, anchored in `config/` (for relative paths).
pub fn plan(text: &str) -> Plan {
    Plan::from_toml(text, Some(&root().join("config/test-plan.toml"))).expect("valid plan")
}

/// A fresh directory, removed when dropped.
pub fn scratch() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}
