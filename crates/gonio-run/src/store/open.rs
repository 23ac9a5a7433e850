//! Creating and opening a run file: the atomic creation, the checks on opening
//! (header, schema version, integrity), migrations, and the run's lock.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rusqlite::{Connection, OpenFlags, OptionalExtension, params};

use gonio_plan::schedule::Step;

use crate::error::StoreError;
use crate::integrity::{self, Integrity, ReadingsRecord, meta_digest};
use crate::lock::{LockError, RunLock};
use crate::meta::keys;
use crate::schema::{APPLICATION_ID, INSERT_EVENT, MIGRATIONS, SCHEMA_VERSION};
use crate::time::wall_now;

use super::RunStore;
use super::write::{insert_steps, write_record};

/// A read-only connection to `path` (see [`RunStore::open_read_only`]).
fn open_read_only(path: &Path) -> rusqlite::Result<Connection> {
    let flags = OpenFlags::SQLITE_OPEN_READ_ONLY
        | OpenFlags::SQLITE_OPEN_NO_MUTEX
        | OpenFlags::SQLITE_OPEN_URI;
    let immutable = !wal_of(path).exists();
    let uri = format!(
        "file:{}?mode=ro{}",
        uri_path(path),
        if immutable { "&immutable=1" } else { "" }
    );
    Connection::open_with_flags(uri, flags)
}

/// The write-ahead log beside the run file at `path`.
fn wal_of(path: &Path) -> PathBuf {
    let mut wal = path.as_os_str().to_owned();
    wal.push("-wal");
    PathBuf::from(wal)
}

/// `path` as the path of an SQLite `file:` URI: absolute, with every byte outside
/// the unreserved set and `/` percent-encoded (`?`, `#` and `%` would otherwise
/// end or escape it).
fn uri_path(path: &Path) -> String {
    let abs = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut out = String::new();
    for &b in abs.as_os_str().as_encoded_bytes() {
        if b.is_ascii_alphanumeric() || b"/-_.~".contains(&b) {
            out.push(char::from(b));
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

impl RunStore {
    fn pragmas(conn: &Connection) -> rusqlite::Result<()> {
        conn.pragma_update(None, "journal_mode", "WAL")?;
        conn.pragma_update(None, "synchronous", "FULL")?;
        conn.pragma_update(None, "foreign_keys", "ON")?;
        conn.busy_timeout(std::time::Duration::from_secs(5))?;
        Ok(())
    }

    /// Creates a new run file with its metadata and schedule; refuses to overwrite.
    /// The store returned holds the run's lock ([`RunStore::lock`]).
    ///
    /// Atomic: the file is written whole under a temporary name and linked into place
    /// only when complete, so a kill during creation leaves no run file (and no
    /// half-made one that `resume` would have to refuse).
    pub fn create(
        path: &Path,
        meta: &BTreeMap<String, String>,
        steps: &[Step],
    ) -> Result<RunStore, StoreError> {
        if path.exists() {
            return Err(StoreError::Exists(path.to_path_buf()));
        }
        let name = path
            .file_name()
            .map_or("run".into(), |n| n.to_string_lossy().into_owned());
        let tmp = path.with_file_name(format!(".{name}.partial-{}", std::process::id()));
        let _ = std::fs::remove_file(&tmp);
        let written = Self::write_new(&tmp, meta, steps);
        let placed = written.and_then(|()| {
            let io = |source| StoreError::Io {
                path: path.to_path_buf(),
                source,
            };
            // A hard link never replaces an existing file: two runs racing for one
            // name cannot both win.
            match std::fs::hard_link(&tmp, path) {
                Ok(()) => Ok(()),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    Err(StoreError::Exists(path.to_path_buf()))
                }
                // File systems without hard links: check, then rename.
                Err(_) if path.exists() => Err(StoreError::Exists(path.to_path_buf())),
                Err(_) => std::fs::rename(&tmp, path).map_err(io),
            }
        });
        let _ = std::fs::remove_file(&tmp);
        placed?;
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty())
            && let Ok(d) = std::fs::File::open(dir)
        {
            // The new name is durable too (best effort: not every platform syncs
            // directories).
            let _ = d.sync_all();
        }
        // The creator measures into it: nobody else may until it lets go.
        let mut store = Self::open(path)?;
        store.lock()?;
        Ok(store)
    }

    /// Writes a complete new run file at `path` (rollback journal, closed after).
    fn write_new(
        path: &Path,
        meta: &BTreeMap<String, String>,
        steps: &[Step],
    ) -> Result<(), StoreError> {
        let sql = |source| StoreError::Sqlite {
            path: path.to_path_buf(),
            source,
        };
        let conn = Connection::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_WRITE
                | OpenFlags::SQLITE_OPEN_CREATE
                | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(sql)?;
        conn.pragma_update(None, "synchronous", "FULL")
            .map_err(sql)?;
        let mut store = RunStore {
            conn,
            path: path.to_path_buf(),
            session: None,
            lock: None,
            immutable: false,
        };
        store.migrate(0)?;
        let tx = store.conn.transaction().map_err(sql)?;
        {
            let mut m = tx
                .prepare("INSERT INTO meta (key, value) VALUES (?1, ?2)")
                .map_err(sql)?;
            let mut all: BTreeMap<String, String> = meta
                .iter()
                .filter(|(k, _)| !integrity::MUTABLE_META.contains(&k.as_str()))
                .map(|(k, v)| (k.clone(), v.clone()))
                .collect();
            all.insert(keys::STEP_COUNT.into(), steps.len().to_string());
            all.insert(keys::STATUS.into(), "created".into());
            all.insert(
                keys::INTEGRITY_META.into(),
                format!("{:016x}", meta_digest(&all)),
            );
            all.insert(
                keys::INTEGRITY_READINGS.into(),
                ReadingsRecord::default().to_text(),
            );
            for (k, v) in &all {
                m.execute(params![k, v]).map_err(sql)?;
            }
            insert_steps(&tx, 0, steps).map_err(sql)?;
        }
        tx.commit().map_err(sql)?;
        Ok(())
    }

    /// Opens an existing run file after checking that it is one, that this build
    /// reads its schema (migrating an older one), and that it is intact: every fault
    /// [`RunStore::integrity`] finds refuses it.
    pub fn open(path: &Path) -> Result<RunStore, StoreError> {
        let store = Self::open_unverified(path)?;
        let found = store.integrity(false)?;
        store.refuse_unless_intact(&found)?;
        Ok(store)
    }

    /// The error a damaged file gets: a missing required `meta` row by name, else
    /// every fault.
    pub fn refuse_unless_intact(&self, found: &Integrity) -> Result<(), StoreError> {
        self.refuse_damage(found)?;
        if found.missing.is_empty() {
            return Ok(());
        }
        Err(StoreError::Corrupt {
            path: self.path.clone(),
            why: found.faults().join("; "),
        })
    }

    /// Like [`RunStore::refuse_unless_intact`], but lets missing readings through:
    /// a resume measures them again ([`RunStore::reopen_missing`]).
    pub fn refuse_damage(&self, found: &Integrity) -> Result<(), StoreError> {
        if let Some(key) = found.missing_meta.first() {
            return Err(StoreError::MissingMeta {
                path: self.path.clone(),
                key: key.to_string(),
            });
        }
        if found.damage.is_empty() {
            return Ok(());
        }
        Err(StoreError::Corrupt {
            path: self.path.clone(),
            why: found.damage.join("; "),
        })
    }

    /// Checks the whole file: SQLite's own check (`full`: the slower
    /// `integrity_check`), every row checksum, the schedule, the required metadata,
    /// readings against steps, and the integrity record.
    ///
    /// The checks read one snapshot (a read transaction), so that a run being
    /// measured by another process checks as it stood at one commit.
    pub fn integrity(&self, full: bool) -> Result<Integrity, StoreError> {
        let corrupt = |e: rusqlite::Error| StoreError::Corrupt {
            path: self.path.clone(),
            why: e.to_string(),
        };
        let snapshot = self.conn.unchecked_transaction().map_err(corrupt)?;
        let found = integrity::inspect(&snapshot, full).map_err(corrupt)?;
        // Read only: nothing to commit.
        snapshot.rollback().map_err(corrupt)?;
        Ok(found)
    }

    /// Makes the steps whose committed readings are missing pending again, so that
    /// the next session measures them, with an event for each; rebases the readings
    /// record on the readings present (and writes the integrity record of a file
    /// from before it existed). Returns the steps re-opened. All or nothing.
    pub fn reopen_missing(&mut self) -> Result<Vec<i64>, StoreError> {
        let found = self.integrity(false)?;
        let missing = found.missing.clone();
        let session = self.session;
        self.in_tx(|tx| {
            for id in &missing {
                tx.execute(
                    "UPDATE steps SET state = 'pending' WHERE id = ?1",
                    [id],
                )?;
                tx.execute(
                    INSERT_EVENT,
                    params![
                        session,
                        wall_now(),
                        "remeasure",
                        id,
                        "the committed reading of this step is missing from the file;                          it is measured again"
                    ],
                )?;
            }
            write_record(tx)?;
            Ok(())
        })?;
        Ok(missing)
    }

    /// Opens an existing run file for reading only, after the checks of
    /// [`RunStore::open`]: nothing is ever written into the file.
    ///
    /// A file with no write-ahead log beside it (a finished or archived run) is
    /// opened `immutable`: SQLite then creates no `-wal` or `-shm` file, so an
    /// archive on read-only storage reads too (a writer that starts on the file
    /// after this open is not seen). A file with one (a run being measured, or one
    /// whose writer was killed) is read through it, as it stands at its last
    /// commit; SQLite may then create the `-shm` index beside it, as every reader
    /// of a live database does. A file of an older schema is refused (it needs one
    /// read-write open to be migrated).
    pub fn open_read_only(path: &Path) -> Result<RunStore, StoreError> {
        let store = Self::open_unverified_read_only(path)?;
        let found = store.integrity(false)?;
        store.refuse_unless_intact(&found)?;
        Ok(store)
    }

    /// Opens a run file after checking only that it is one and that this build
    /// reads its schema: for [`RunStore::integrity`] to say what is wrong with it.
    pub fn open_unverified(path: &Path) -> Result<RunStore, StoreError> {
        Self::open_checked(path, false)
    }

    /// [`RunStore::open_unverified`], for reading only (as
    /// [`RunStore::open_read_only`]).
    pub fn open_unverified_read_only(path: &Path) -> Result<RunStore, StoreError> {
        Self::open_checked(path, true)
    }

    /// [`RunStore::open_unverified`], read-write or read-only.
    fn open_checked(path: &Path, read_only: bool) -> Result<RunStore, StoreError> {
        let not_run = |why: String| StoreError::NotARunFile {
            path: path.to_path_buf(),
            why,
        };
        // Judged by its metadata before anything opens it: opening a FIFO would block.
        match std::fs::metadata(path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(StoreError::Missing(path.to_path_buf()));
            }
            Err(e) => return Err(not_run(e.to_string())),
            Ok(m) if m.is_dir() => return Err(not_run("a directory".into())),
            Ok(m) if !m.is_file() => {
                return Err(not_run(
                    "not a regular file (a device, FIFO or socket)".into(),
                ));
            }
            Ok(_) => {}
        }
        let corrupt = |why: String| StoreError::Corrupt {
            path: path.to_path_buf(),
            why,
        };
        let mut head = [0u8; 16];
        {
            use std::io::Read;
            let mut f = std::fs::File::open(path).map_err(|e| not_run(e.to_string()))?;
            f.read_exact(&mut head)
                .map_err(|_| not_run("shorter than an SQLite header".into()))?;
        }
        if &head != b"SQLite format 3\0" {
            return Err(not_run("no SQLite header".into()));
        }
        let conn = if read_only {
            open_read_only(path)
        } else {
            Connection::open_with_flags(
                path,
                OpenFlags::SQLITE_OPEN_READ_WRITE | OpenFlags::SQLITE_OPEN_NO_MUTEX,
            )
        }
        .map_err(|e| corrupt(e.to_string()))?;
        let read_i32 = |name: &str| -> Result<i32, StoreError> {
            conn.pragma_query_value(None, name, |r| r.get(0))
                .map_err(|e| corrupt(e.to_string()))
        };
        let app = read_i32("application_id")?;
        if app != APPLICATION_ID {
            return Err(not_run(format!(
                "application_id {app:#010x}, not Gonio's {APPLICATION_ID:#010x}"
            )));
        }
        let version = read_i32("user_version")?;
        if version > SCHEMA_VERSION {
            return Err(StoreError::NewerSchema {
                path: path.to_path_buf(),
                found: version,
                supported: SCHEMA_VERSION,
            });
        }
        if read_only {
            if version < SCHEMA_VERSION {
                return Err(not_run(format!(
                    "schema version {version}: open it once with a command that writes \
                     (gonio resume) to bring it to version {SCHEMA_VERSION}"
                )));
            }
            conn.busy_timeout(std::time::Duration::from_secs(5))
                .map_err(|e| corrupt(e.to_string()))?;
        } else {
            Self::pragmas(&conn).map_err(|e| corrupt(e.to_string()))?;
        }
        let mut store = RunStore {
            conn,
            path: path.to_path_buf(),
            session: None,
            lock: None,
            immutable: read_only && !wal_of(path).exists(),
        };
        if version < 1 {
            return Err(not_run("schema version 0: never initialised".into()));
        }
        store.migrate(version)?;
        Ok(store)
    }

    /// Brings the schema from `from` to [`SCHEMA_VERSION`], one migration a
    /// transaction.
    fn migrate(&mut self, from: i32) -> Result<(), StoreError> {
        for v in from..SCHEMA_VERSION {
            self.in_tx(|tx| {
                tx.execute_batch(MIGRATIONS[v as usize])?;
                tx.pragma_update(None, "user_version", v + 1)?;
                if v == 0 {
                    tx.pragma_update(None, "application_id", APPLICATION_ID)?;
                }
                Ok(())
            })?;
        }
        Ok(())
    }

    /// True when this read-only store was opened on a finished file (`immutable`,
    /// see [`RunStore::open_read_only`]) and a writer has started on it since: what
    /// it reads no longer follows the file, and a reader that follows the run opens
    /// it again.
    pub fn is_outdated(&self) -> bool {
        self.immutable && wal_of(&self.path).exists()
    }

    /// The process id of whoever measures into the run now (holds its lock), if
    /// anyone; 0 when the holder's id cannot be read. Asked without taking or
    /// touching the lock.
    pub fn measured_by(&self) -> Option<u32> {
        crate::lock::holder(&self.path)
    }

    /// Takes the run's exclusive lock, held until this store is dropped: one
    /// process at a time measures into a run. Readers (`show`, `reduce`) do not take
    /// it. A killed process leaves no lock behind (see `lock.rs`).
    pub fn lock(&mut self) -> Result<(), StoreError> {
        if self.lock.is_some() {
            return Ok(());
        }
        match RunLock::acquire(&self.path) {
            Ok(l) => {
                self.lock = Some(l);
                Ok(())
            }
            Err(LockError::Busy(pid)) => Err(StoreError::Busy {
                path: self.path.clone(),
                holder: self.holder(pid),
            }),
            Err(LockError::Io(path, source)) => Err(StoreError::Io { path, source }),
        }
    }

    /// Who holds the lock: its process, and the session it runs when the file has
    /// one open.
    fn holder(&self, pid: Option<u32>) -> String {
        let Some(pid) = pid else {
            return "another process".into();
        };
        let session: Option<(f64, String)> = self
            .conn
            .query_row(
                "SELECT started_s, software FROM sessions WHERE ended_s IS NULL AND pid = ?1 \
                 ORDER BY id DESC LIMIT 1",
                [pid],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .optional()
            .ok()
            .flatten();
        match session {
            Some((started, software)) => format!(
                "process {pid} ({software}, session started {})",
                crate::time::utc(started)
            ),
            None => format!("process {pid}"),
        }
    }
}
