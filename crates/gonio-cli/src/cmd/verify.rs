//! `gonio verify`: a run file checked whole against its integrity record.

use std::io::Write;
use std::path::PathBuf;

use gonio_run::RunStore;
use serde_json::json;

use crate::error::{CliError, CliResult};
use crate::flags::JsonFlag;
use crate::output;

/// `gonio verify`: check a run file whole.
#[derive(clap::Args)]
pub struct VerifyArgs {
    /// The run file.
    run: PathBuf,
    #[command(flatten)]
    json: JsonFlag,
}

/// `gonio verify RUN [--json]`: exit 0 when intact, 1 with every fault when not.
pub fn run(a: VerifyArgs) -> CliResult<()> {
    let path = a.run.as_path();
    // Read only: a check never changes what it checks.
    let store = RunStore::open_unverified_read_only(path)?;
    let found = store.integrity(true)?;
    let faults = found.faults();
    if a.json.json {
        output::json(&json!({
            "run": path.display().to_string(),
            "intact": found.is_intact(),
            "recorded": found.recorded,
            "readings": found.readings,
            "missing": found.missing,
            "faults": faults,
        }))?;
    } else {
        let mut w = output::stdout();
        output::finish((|| {
            if faults.is_empty() {
                writeln!(
                    w,
                    "{}: intact ({} readings; {})",
                    path.display(),
                    found.readings,
                    if found.recorded {
                        "integrity record, row checksums and SQLite's integrity_check agree"
                    } else {
                        "no integrity record (written before it existed); row checksums \
                         and SQLite's integrity_check agree"
                    }
                )?;
            }
            for f in &faults {
                writeln!(w, "{}: {f}", path.display())?;
            }
            w.flush()
        })())?;
    }
    if found.is_intact() {
        Ok(())
    } else {
        Err(CliError::Runtime(format!(
            "{}: damaged ({} fault(s))",
            path.display(),
            faults.len()
        )))
    }
}
