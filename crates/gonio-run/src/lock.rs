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

/// Who holds the lock of `run`, if anyone: the holder's process id (0 when the lock
/// file does not say). Nothing is locked, created or written to find out, so a
/// process about to take the lock never finds it briefly held by the asker.
///
/// On Linux the kernel's table of `flock` locks (`/proc/locks`) is read for the
/// lock file's inode; elsewhere a lock file that exists is taken as held (its owner
/// removes it when it lets go; only a killed owner leaves one behind).
pub(crate) fn holder(run: &Path) -> Option<u32> {
    let path = lock_path(run);
    let meta = std::fs::metadata(&path).ok()?;
    let pid = || {
        std::fs::read_to_string(&path)
            .ok()
            .and_then(|t| t.trim().parse().ok())
            .unwrap_or(0)
    };
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::fs::MetadataExt;
        // The table is read whole in one call where it fits: the kernel walks it
        // anew at each read, so entries that go between two reads can shift ours
        // past the point already read. A lock seen missing is looked for again
        // (a lock released stays missing; one held is seen at once).
        let found = (0..3).any(|_| lock_table().is_some_and(|t| held_in(&t, meta.ino())));
        found.then(pid)
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = meta;
        Some(pid())
    }
}

/// The kernel's table of locks, read in as few calls as possible.
#[cfg(target_os = "linux")]
fn lock_table() -> Option<String> {
    let mut f = File::open("/proc/locks").ok()?;
    let mut buf = vec![0u8; 1 << 18];
    let mut len = 0;
    loop {
        let n = f.read(&mut buf[len..]).ok()?;
        if n == 0 {
            break;
        }
        len += n;
        if len == buf.len() {
            buf.resize(buf.len() * 2, 0);
        }
    }
    buf.truncate(len);
    String::from_utf8(buf).ok()
}

/// Whether `/proc/locks` text lists a `FLOCK` lock on inode `ino`. Each line reads
/// `N: FLOCK  ADVISORY  WRITE PID MAJ:MIN:INODE START END` (proc(5)); lines of
/// blocked waiters (`N: -> FLOCK …`) hold nothing.
#[cfg_attr(not(target_os = "linux"), allow(dead_code))]
fn held_in(table: &str, ino: u64) -> bool {
    table.lines().any(|line| {
        let mut words = line.split_whitespace().skip(1);
        words.next() == Some("FLOCK")
            && words
                .nth(3)
                .and_then(|dev| dev.rsplit(':').next())
                .and_then(|i| i.parse::<u64>().ok())
                == Some(ino)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lock_table_is_read_by_inode_and_skips_waiters() {
        let table = "1: POSIX  ADVISORY  WRITE 77 08:01:42 0 EOF\n\
                     2: FLOCK  ADVISORY  WRITE 1234 fd:00:9001 0 EOF\n\
                     3: -> FLOCK  ADVISORY  WRITE 99 fd:00:555 0 EOF\n";
        assert!(held_in(table, 9001));
        // A POSIX (fcntl) lock is SQLite's, not the run's lock.
        assert!(!held_in(table, 42));
        assert!(!held_in(table, 555));
        assert!(!held_in(table, 1234));
    }

    #[test]
    fn a_held_lock_names_its_holder_and_a_released_one_nobody() {
        let dir = tempfile::tempdir().expect("dir");
        let run = dir.path().join("r.gonio");
        assert_eq!(holder(&run), None);
        let lock = RunLock::acquire(&run).expect("locks");
        assert_eq!(holder(&run), Some(std::process::id()));
        drop(lock);
        assert_eq!(holder(&run), None);
        // A killed owner's file is left behind, unlocked: nobody holds it.
        std::fs::write(lock_path(&run), "4242\n").expect("write");
        #[cfg(target_os = "linux")]
        assert_eq!(holder(&run), None);
    }
}
