//! Reading an input file without trusting it: every loader in Gonio reads through
//! here, so that no path a user types can block the process, exhaust its memory or
//! be mistaken for a file.
//!
//! - The path is examined (`stat`, following symbolic links) before anything is
//!   opened, and only a regular file is read. A FIFO would block `open` until a
//!   writer appears, `/dev/zero` and `/dev/urandom` never end, a directory is not a
//!   file: each is refused with what it is, and a FIFO is never opened.
//! - The open itself does not block either (`O_NONBLOCK` on Linux and macOS), and the
//!   handle is examined again, so a file swapped for a FIFO or a device between the
//!   two looks is refused too.
//! - At most `max + 1` bytes are read, whatever the file claims its size is, and a
//!   file longer than `max` is refused: a file that grows while it is read cannot
//!   take more memory than its cap.
//!
//! The caps are the callers' (each names its own, next to the format it bounds);
//! [`MAX_CONFIG_BYTES`] is the one the small TOML files share.

use std::fs::{File, Metadata};
use std::io::Read;
use std::path::{Path, PathBuf};

/// The most bytes an instrument config, plan, simulator config, surface file or model
/// file may have: 16 MiB. The largest real ones are a few kilobytes (a plan that lists
/// its angles one by one up to its point cap is about 10 MB).
pub const MAX_CONFIG_BYTES: u64 = 16 << 20;

/// Why an input file was not read.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The path could not be examined, opened or read (missing, no permission).
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// The path names something other than a regular file.
    #[error("{}: {}", path.display(), not_regular(what))]
    NotRegular {
        /// The path.
        path: PathBuf,
        /// What it is: `a directory`, `a FIFO (named pipe)`, `a character device`, ….
        what: &'static str,
    },
    /// The file is longer than the cap for its kind.
    #[error("{}: {}", path.display(), too_large(*max))]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// The cap, bytes.
        max: u64,
    },
    /// A text input that is not UTF-8.
    #[error("{}: {}", path.display(), NOT_UTF8)]
    NotUtf8 {
        /// The file.
        path: PathBuf,
    },
}

const NOT_UTF8: &str = "not UTF-8 text";

fn not_regular(what: &str) -> String {
    format!("{what}, not a regular file (Gonio reads its inputs from regular files only)")
}

fn too_large(max: u64) -> String {
    format!("larger than {max} bytes, the most this kind of file may have")
}

impl InputError {
    /// The reason alone, without the path (for errors that place the path
    /// themselves, like the TOML loaders' `FileError`).
    pub fn reason(&self) -> String {
        match self {
            InputError::Io { source, .. } => source.to_string(),
            InputError::NotRegular { what, .. } => not_regular(what),
            InputError::TooLarge { max, .. } => too_large(*max),
            InputError::NotUtf8 { .. } => NOT_UTF8.to_string(),
        }
    }

    /// The file.
    pub fn path(&self) -> &Path {
        match self {
            InputError::Io { path, .. }
            | InputError::NotRegular { path, .. }
            | InputError::TooLarge { path, .. }
            | InputError::NotUtf8 { path } => path,
        }
    }
}

/// What `meta` describes, when it is not a regular file.
fn kind_of(meta: &Metadata) -> Option<&'static str> {
    let t = meta.file_type();
    if t.is_file() {
        return None;
    }
    if t.is_dir() {
        return Some("a directory");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return Some("a FIFO (named pipe)");
        }
        if t.is_char_device() {
            return Some("a character device");
        }
        if t.is_block_device() {
            return Some("a block device");
        }
        if t.is_socket() {
            return Some("a socket");
        }
    }
    Some("not a file of any kind Gonio knows")
}

/// The metadata of `path` (following symbolic links) when it is a regular file; the
/// reason otherwise. Opens nothing, so it never blocks on a FIFO.
pub fn regular_file(path: &Path) -> Result<Metadata, InputError> {
    let meta = std::fs::metadata(path).map_err(|source| InputError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    match kind_of(&meta) {
        None => Ok(meta),
        Some(what) => Err(InputError::NotRegular {
            path: path.to_path_buf(),
            what,
        }),
    }
}

/// Whether `path` is a regular file (following symbolic links), without opening it.
pub fn is_regular_file(path: &Path) -> bool {
    regular_file(path).is_ok()
}

/// Opens a regular file for reading, never blocking: examined first, opened without
/// waiting (a FIFO swapped in after the first look cannot hold the open), and
/// examined again through the handle.
fn open_regular(path: &Path) -> Result<File, InputError> {
    regular_file(path)?;
    let io = |source| InputError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut opts = std::fs::OpenOptions::new();
    opts.read(true);
    // O_NONBLOCK: `open` of a FIFO returns at once instead of waiting for a writer.
    // Its value is 0o4000 on Linux on these architectures (not on MIPS, SPARC or
    // Alpha, which keep only the look before the open).
    #[cfg(all(
        any(target_os = "linux", target_os = "android"),
        any(
            target_arch = "x86",
            target_arch = "x86_64",
            target_arch = "arm",
            target_arch = "aarch64",
            target_arch = "riscv64",
            target_arch = "powerpc",
            target_arch = "powerpc64",
            target_arch = "s390x",
            target_arch = "loongarch64"
        )
    ))]
    {
        use std::os::unix::fs::OpenOptionsExt;
        opts.custom_flags(0o4000);
    }
    #[cfg(target_os = "macos")]
    {
        use std::os::unix::fs::OpenOptionsExt;
        opts.custom_flags(0x0004);
    }
    let file = opts.open(path).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    match kind_of(&meta) {
        None => Ok(file),
        Some(what) => Err(InputError::NotRegular {
            path: path.to_path_buf(),
            what,
        }),
    }
}

/// The bytes of the regular file `path`, at most `max` of them: a longer file (or one
/// that grows past `max` while it is read) is refused, and no more than `max + 1`
/// bytes are ever read.
pub fn read_bounded(path: &Path, max: u64) -> Result<Vec<u8>, InputError> {
    let file = open_regular(path)?;
    let too_large = || InputError::TooLarge {
        path: path.to_path_buf(),
        max,
    };
    let claimed = file.metadata().map(|m| m.len()).unwrap_or(0);
    if claimed > max {
        return Err(too_large());
    }
    let mut bytes = Vec::with_capacity(usize::try_from(claimed).unwrap_or(0));
    file.take(max.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|source| InputError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    if bytes.len() as u64 > max {
        return Err(too_large());
    }
    Ok(bytes)
}

/// The text of the regular file `path`, at most `max` bytes of UTF-8 (see
/// [`read_bounded`]).
pub fn read_text(path: &Path, max: u64) -> Result<String, InputError> {
    let bytes = read_bounded(path, max)?;
    String::from_utf8(bytes).map_err(|_| InputError::NotUtf8 {
        path: path.to_path_buf(),
    })
}

/// The first `n` bytes of the regular file `path` (fewer when it is shorter), for
/// recognising what it is.
pub fn read_head(path: &Path, n: u64) -> Result<Vec<u8>, InputError> {
    let file = open_regular(path)?;
    let mut bytes = Vec::new();
    file.take(n)
        .read_to_end(&mut bytes)
        .map_err(|source| InputError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("gonio-core-input-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("scratch dir");
        d
    }

    #[test]
    fn reads_a_file_up_to_its_cap_and_refuses_one_byte_more() {
        let d = scratch("cap");
        let p = d.join("f.txt");
        std::fs::write(&p, "abcd").expect("write");
        assert_eq!(read_text(&p, 4).expect("4 bytes fit"), "abcd");
        let e = read_text(&p, 3).expect_err("4 > 3");
        assert!(matches!(e, InputError::TooLarge { max: 3, .. }), "{e}");
        assert!(
            e.to_string()
                .ends_with("f.txt: larger than 3 bytes, the most this kind of file may have"),
            "{e}"
        );
        std::fs::write(&p, [0xff, 0xfe]).expect("write");
        assert!(matches!(read_text(&p, 10), Err(InputError::NotUtf8 { .. })));
        assert_eq!(read_head(&p, 1).expect("head"), vec![0xff]);
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn directories_and_missing_files_are_refused() {
        let d = scratch("dir");
        let e = read_bounded(&d, 10).expect_err("a directory");
        assert!(
            e.to_string().contains("a directory, not a regular file"),
            "{e}"
        );
        assert_eq!(e.path(), d.as_path());
        assert!(!is_regular_file(&d));
        let e = read_bounded(&d.join("missing"), 10).expect_err("missing");
        assert!(matches!(e, InputError::Io { .. }), "{e}");
        let _ = std::fs::remove_dir_all(&d);
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_is_refused_without_blocking() {
        let d = scratch("fifo");
        let p = d.join("pipe");
        let made = std::process::Command::new("mkfifo")
            .arg(&p)
            .status()
            .is_ok_and(|s| s.success());
        if !made {
            return; // no mkfifo on this system: nothing to test
        }
        let (tx, rx) = std::sync::mpsc::channel();
        let q = p.clone();
        std::thread::spawn(move || {
            let _ = tx.send(read_bounded(&q, 10).map_err(|e| e.reason()));
        });
        let got = rx
            .recv_timeout(std::time::Duration::from_secs(10))
            .expect("read_bounded returns at once on a FIFO");
        assert_eq!(
            got.expect_err("a FIFO"),
            "a FIFO (named pipe), not a regular file (Gonio reads its inputs from regular files only)"
        );
        assert!(matches!(
            read_head(&p, 16),
            Err(InputError::NotRegular { .. })
        ));
        let _ = std::fs::remove_dir_all(&d);
    }

    #[cfg(unix)]
    #[test]
    fn devices_are_refused_without_reading_them() {
        let e = read_bounded(Path::new("/dev/zero"), 1 << 20).expect_err("/dev/zero");
        assert_eq!(
            e.reason(),
            "a character device, not a regular file (Gonio reads its inputs from regular files only)"
        );
    }
}
