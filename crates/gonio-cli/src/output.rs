//! Where a command's results go: stdout or a file, with a closed pipe treated as the
//! reader having had enough (`gonio model eval … | head`), not as a failure.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

use crate::error::{CliError, CliResult};

/// A buffered writer to `path`, or to stdout when `path` is `None`.
pub fn open(path: Option<&Path>) -> CliResult<Box<dyn Write>> {
    Ok(match path {
        Some(p) => Box::new(BufWriter::new(File::create(p).map_err(|e| {
            CliError::Input(format!("{}: cannot create output file: {e}", p.display()))
        })?)),
        None => Box::new(BufWriter::new(io::stdout().lock())),
    })
}

/// Maps the outcome of writing results: a broken pipe is success, anything else a
/// runtime failure.
pub fn finish(r: io::Result<()>) -> CliResult<()> {
    match r {
        Err(e) if e.kind() == io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(CliError::Runtime(format!("writing output: {e}"))),
        Ok(()) => Ok(()),
    }
}

/// Prints one JSON object on stdout.
pub fn json(v: &serde_json::Value) -> CliResult<()> {
    let mut w = open(None)?;
    finish((|| {
        serde_json::to_writer(&mut w, v)?;
        writeln!(w)?;
        w.flush()
    })())
}
