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

impl VerifyArgs {
    /// The run file.
    pub(crate) fn run_path(&self) -> &std::path::Path {
        &self.run
    }
}

/// What `gonio verify` found: its `--json` object, and the command's failure when
/// the file is damaged.
pub(crate) struct Verified {
    /// The `--json` object.
    pub json: serde_json::Value,
    /// Every fault, one line each.
    faults: Vec<String>,
    intact: bool,
    readings: u64,
    recorded: bool,
}

impl Verified {
    /// The command's outcome: an error naming the file unless it is intact.
    pub(crate) fn result(&self, path: &std::path::Path) -> CliResult<()> {
        if self.intact {
            Ok(())
        } else {
            Err(CliError::Runtime(format!(
                "{}: damaged ({} fault(s))",
                path.display(),
                self.faults.len()
            )))
        }
    }
}

/// Checks the run file at `path` whole, read only (a check never changes what it
/// checks). An error only when it cannot be checked at all.
pub(crate) fn verify(path: &std::path::Path) -> CliResult<Verified> {
    let store = RunStore::open_unverified_read_only(path)?;
    let found = store.integrity(true)?;
    let faults = found.faults();
    Ok(Verified {
        json: json!({
            "run": path.display().to_string(),
            "intact": found.is_intact(),
            "recorded": found.recorded,
            "readings": found.readings,
            "missing": found.missing,
            "faults": faults,
        }),
        intact: found.is_intact(),
        readings: found.readings,
        recorded: found.recorded,
        faults,
    })
}

/// `gonio verify RUN [--json]`: exit 0 when intact, 1 with every fault when not.
pub fn run(a: VerifyArgs) -> CliResult<()> {
    let path = a.run.as_path();
    let v = verify(path)?;
    if a.json.json {
        output::json(&v.json)?;
    } else {
        let mut w = output::stdout();
        output::finish((|| {
            if v.faults.is_empty() {
                writeln!(
                    w,
                    "{}: intact ({} readings; {})",
                    path.display(),
                    v.readings,
                    if v.recorded {
                        "integrity record, row checksums and SQLite's integrity_check agree"
                    } else {
                        "no integrity record (written before it existed); row checksums \
                         and SQLite's integrity_check agree"
                    }
                )?;
            }
            for f in &v.faults {
                writeln!(w, "{}: {f}", path.display())?;
            }
            w.flush()
        })())?;
    }
    v.result(path)
}
