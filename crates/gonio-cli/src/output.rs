//! Where a command's results go: stdout or a file, with a closed pipe treated as the
//! reader having had enough (`gonio model eval … | head`), not as a failure.
//!
//! Output files are never written in place. A [`Target`] is checked before the
//! command does any work (an existing file is refused without `--force`, a run file
//! always), and its bytes are written to a temporary file in the same directory,
//! synced, and renamed into place: a kill or a full disk leaves the old file whole
//! or no file, never half of one.

use std::cell::RefCell;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{CliError, CliResult};

/// `--force`: replace an existing output file.
#[derive(Clone, Copy, Debug, Default, clap::Args)]
pub struct ForceFlag {
    /// Replace an existing output file (never a run file: those are only ever
    /// created by `gonio acquire`).
    #[arg(long)]
    pub force: bool,
}

/// An output file, checked before any work is done, written whole or not at all.
#[derive(Clone, Debug)]
pub struct Target {
    path: PathBuf,
    force: bool,
}

impl Target {
    /// Checks that `path` may be written: its directory exists, it is not a
    /// directory, a device or a run file, and it does not exist unless `force`.
    pub fn new(path: &Path, force: bool) -> CliResult<Target> {
        let refuse = |why: &str| CliError::Input(format!("{}: {why}", path.display()));
        if path.as_os_str().is_empty() {
            return Err(CliError::Input("the output path is empty".into()));
        }
        let dir = parent(path);
        if !dir.is_dir() {
            return Err(CliError::Input(format!(
                "{}: the directory {} does not exist",
                path.display(),
                dir.display()
            )));
        }
        match std::fs::symlink_metadata(path) {
            Err(e) if e.kind() == io::ErrorKind::NotFound => {}
            Err(e) => return Err(refuse(&format!("cannot use as an output: {e}"))),
            Ok(m) if m.is_dir() => return Err(refuse("is a directory, not an output file")),
            Ok(_) if gonio_run::is_run_file(path) => {
                return Err(refuse(
                    "is a Gonio run file; an output never replaces a run file \
                     (choose another name)",
                ));
            }
            Ok(m) if !m.is_file() => {
                return Err(refuse(
                    "exists and is not a regular file (a device, FIFO or link); \
                     choose another name",
                ));
            }
            Ok(_) if !force => {
                return Err(refuse("exists already; give --force to replace it"));
            }
            Ok(_) => {}
        }
        Ok(Target {
            path: path.to_path_buf(),
            force,
        })
    }

    fn cannot(&self, e: &dyn std::fmt::Display) -> CliError {
        CliError::Runtime(format!(
            "{}: cannot write output file: {e}",
            self.path.display()
        ))
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes `bytes` to the file: to a temporary file beside it, synced, then
    /// renamed into place (linked, when not replacing, so that a file that appeared
    /// meanwhile is not lost).
    pub fn write(&self, bytes: &[u8]) -> CliResult<()> {
        self.write_with(|tmp| {
            std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(tmp)
                .and_then(|mut f| f.write_all(bytes))
                .map_err(|e| self.cannot(&e))
        })
    }

    /// Like [`Target::write`], for writers that want a path: `write` gets the
    /// temporary file's path (with the target's extension) and writes it whole.
    pub fn write_with(&self, write: impl FnOnce(&Path) -> CliResult<()>) -> CliResult<()> {
        let path = &self.path;
        let fail = |e: &dyn std::fmt::Display| self.cannot(e);
        // Re-checked: the file may have appeared while the command worked.
        Target::new(path, self.force)?;
        let tmp = temp_name(path);
        let written = write(&tmp).and_then(|()| {
            // Durable before it takes the name.
            File::open(&tmp)
                .and_then(|f| f.sync_all())
                .map_err(|e| fail(&e))
        });
        let placed = written.and_then(|()| {
            if self.force {
                std::fs::rename(&tmp, path).map_err(|e| fail(&e))
            } else {
                match std::fs::hard_link(&tmp, path) {
                    Ok(()) => Ok(()),
                    Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {
                        Err(CliError::Input(format!(
                            "{}: exists already; give --force to replace it",
                            path.display()
                        )))
                    }
                    // File systems without hard links.
                    Err(_) => std::fs::rename(&tmp, path).map_err(|e| fail(&e)),
                }
            }
        });
        let _ = std::fs::remove_file(&tmp);
        placed?;
        // The new name is durable too (best effort: not every platform syncs
        // directories).
        if let Ok(d) = File::open(parent(path)) {
            let _ = d.sync_all();
        }
        Ok(())
    }
}

/// The directory `path` is in (`.` for a bare name).
pub fn parent(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// A fresh hidden name beside `path`.
fn temp_name(path: &Path) -> PathBuf {
    static SEQ: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .map_or("out".into(), |n| n.to_string_lossy().into_owned());
    // Hidden, and ending in the target's own name so that writers that go by the
    // extension (PNG or SVG) still see it.
    path.with_file_name(format!(
        ".gonio-tmp-{}-{}-{name}",
        std::process::id(),
        SEQ.fetch_add(1, Ordering::Relaxed)
    ))
}

thread_local! {
    /// What a command running under [`captured`] on this thread printed so far.
    static CAPTURE: RefCell<Option<Vec<u8>>> = const { RefCell::new(None) };
}

/// Runs `f` with what it prints on stdout (through [`stdout`], [`json`] and
/// [`Sink`]) collected instead, on this thread: a command run in-process by
/// another program (`api::run`) returns its output instead of printing it.
pub fn captured<T>(f: impl FnOnce() -> T) -> (T, Vec<u8>) {
    /// Puts the previous capture back, even when `f` panics.
    struct Restore(Option<Vec<u8>>);
    impl Drop for Restore {
        fn drop(&mut self) {
            let prev = self.0.take();
            CAPTURE.with(|c| *c.borrow_mut() = prev);
        }
    }
    let restore = Restore(CAPTURE.with(|c| c.replace(Some(Vec::new()))));
    let out = f();
    // Ours taken; the guard then puts the previous capture (if any) back.
    let bytes = CAPTURE.with(|c| c.take());
    drop(restore);
    (out, bytes.unwrap_or_default())
}

/// Stdout, or the capture when one is on.
struct CapturedOut;

impl Write for CapturedOut {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        CAPTURE.with(|c| match c.borrow_mut().as_mut() {
            Some(v) => {
                v.extend_from_slice(buf);
                Ok(buf.len())
            }
            None => io::stdout().write(buf),
        })
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// Where a command's text goes: stdout, or a [`Target`] written whole at
/// [`Sink::finish`].
pub enum Sink {
    /// Standard output.
    Stdout(Box<dyn Write>),
    /// A file, collected in memory and written atomically at the end.
    File(Target, Vec<u8>),
}

impl Write for Sink {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match self {
            Sink::Stdout(w) => w.write(buf),
            Sink::File(_, v) => v.write(buf),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match self {
            Sink::Stdout(w) => w.flush(),
            Sink::File(..) => Ok(()),
        }
    }
}

impl Sink {
    /// A sink to `target`, or to stdout.
    pub fn new(target: Option<Target>) -> Sink {
        match target {
            Some(t) => Sink::File(t, Vec::new()),
            None => Sink::Stdout(stdout()),
        }
    }

    /// Ends the output: `r` (the outcome of writing) mapped by [`finish`], then the
    /// file written.
    pub fn finish(self, r: io::Result<()>) -> CliResult<()> {
        finish(r)?;
        match self {
            Sink::Stdout(mut w) => finish(w.flush()),
            Sink::File(t, bytes) => t.write(&bytes),
        }
    }
}

/// A buffered writer to stdout.
pub fn stdout() -> Box<dyn Write> {
    if CAPTURE.with(|c| c.borrow().is_some()) {
        Box::new(CapturedOut)
    } else {
        Box::new(BufWriter::new(io::stdout().lock()))
    }
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
    let mut w = stdout();
    finish((|| {
        serde_json::to_writer(&mut w, v)?;
        writeln!(w)?;
        w.flush()
    })())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn captures_nest_and_each_gets_its_own_output() {
        let (inner, outer) = captured(|| {
            let _ = write!(stdout(), "outer 1;");
            let inner = captured(|| {
                let _ = write!(stdout(), "inner;");
            });
            let _ = json(&serde_json::json!({"k": 1}));
            inner.1
        });
        assert_eq!(inner, b"inner;");
        assert_eq!(String::from_utf8_lossy(&outer), "outer 1;{\"k\":1}\n");
        // And none is left on afterwards.
        assert!(CAPTURE.with(|c| c.borrow().is_none()));
    }
}
