//! The run's exclusive lock: one process at a time measures into a run.
//!
//! The lock is the operating system's advisory lock (`flock`) on a file beside the
//! run, `RUN.gonio.lock`, holding the owner's process id. It is never taken on the
//! run file itself: closing any other descriptor of a database file drops the
//! POSIX locks SQLite holds on it. A killed process loses its lock with its
//! descriptors, so a stale lock file never blocks anyone; the owner removes the file
//! when it lets go, while still holding the lock, and a taker checks that the file
//! it locked is still the one at the name (else it lost a race with a removal and
//! tries again).

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

/// Attempts at taking the lock when its file keeps being replaced under us.
const ATTEMPTS: usize = 16;

/// A held lock, released when dropped.
#[derive(Debug)]
pub(crate) struct RunLock {
    file: File,
    path: PathBuf,
}

/// Why the lock was not taken.
#[derive(Debug)]
pub(crate) enum LockError {
    /// Another process holds it: its process id, when it wrote one.
    Busy(Option<u32>),
    /// The lock file could not be used.
    Io(PathBuf, std::io::Error),
}

/// The lock file of `run`.
pub(crate) fn lock_path(run: &Path) -> PathBuf {
    let mut name = run.file_name().unwrap_or_default().to_os_string();
    name.push(".lock");
    run.with_file_name(name)
}

/// The same file (device and inode) as the one at `path` now.
#[cfg(unix)]
fn same_file(f: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (f.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_: &File, path: &Path) -> bool {
    path.exists()
}

impl RunLock {
    /// Takes the lock of `run`, or says who holds it.
    pub fn acquire(run: &Path) -> Result<RunLock, LockError> {
        let path = lock_path(run);
        let io = |e| LockError::Io(path.clone(), e);
        for _ in 0..ATTEMPTS {
            let mut file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
                .map_err(io)?;
            match file.try_lock() {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => {
                    let mut text = String::new();
                    let _ = file.read_to_string(&mut text);
                    return Err(LockError::Busy(text.trim().parse().ok()));
                }
                Err(TryLockError::Error(e)) => return Err(io(e)),
            }
            if !same_file(&file, &path) {
                // The holder removed it between our open and our lock.
                continue;
            }
            file.set_len(0).map_err(io)?;
            file.rewind().map_err(io)?;
            writeln!(file, "{}", std::process::id()).map_err(io)?;
            return Ok(RunLock { file, path });
        }
        Err(io(std::io::Error::other(
            "the lock file keeps being replaced",
        )))
    }
}

impl Drop for RunLock {
    fn drop(&mut self) {
        // Removed while still held, so that nobody can lock the old file after us
        // and believe it is theirs.
        let _ = std::fs::remove_file(&self.path);
        let _ = self.file.unlock();
    }
}
