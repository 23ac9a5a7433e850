//! An open run file.
//!
//! Crash safety comes from SQLite: write-ahead log, `synchronous = FULL` (a commit
//! is on the disk when it returns), and one transaction per measured step (its
//! reading, its state, its events). A kill at any instant leaves every committed
//! step whole and the step in flight absent.
//!
//! Corruption is detected, not trusted: opening checks the file is SQLite, that its
//! `application_id` is Gonio's, that its schema version is one this build reads,
//! runs `PRAGMA quick_check`, and verifies a checksum stored with every step and
//! reading row (which catches damaged values SQLite's structure checks cannot).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rusqlite::types::Value;
use rusqlite::{Connection, OpenFlags, OptionalExtension, params};

use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use gonio_plan::schedule::{Step, StepKind};

pub use crate::error::StoreError;
use crate::integrity::{self, Integrity, ReadingsRecord, meta_digest, reading_term};
use crate::lock::{LockError, RunLock};
use crate::meta::{RunMeta, keys};
use crate::records::{
    Batch, DecisionRecord, EventRecord, ReadingRecord, SessionRow, StoredStep, decision_values,
    reading_values, row_crc, step_values,
};
use crate::schema::{
    APPLICATION_ID, CREATE_DECISIONS, DECISION_COLUMNS, INSERT_EVENT, MIGRATIONS, READING_COLUMNS,
    SCHEMA_VERSION, SET_STATUS, STEP_COLUMNS, has_decisions,
};
use crate::time::wall_now;

/// True when `path` is a Gonio run file by its header: SQLite, with Gonio's
/// `application_id` (big-endian at byte 68). Only a regular file is read: a FIFO
/// would block the open.
pub fn is_run_file(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 72];
    std::fs::metadata(path).is_ok_and(|m| m.is_file())
        && std::fs::File::open(path)
            .and_then(|mut f| f.read_exact(&mut head))
            .is_ok()
        && &head[..16] == b"SQLite format 3\0"
        && i32::from_be_bytes([head[68], head[69], head[70], head[71]]) == APPLICATION_ID
}

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

/// Sets one `meta` row (inside a transaction).
fn put_meta(tx: &rusqlite::Transaction<'_>, key: &str, value: &str) -> rusqlite::Result<()> {
    tx.execute(
        "INSERT INTO meta (key, value) VALUES (?1, ?2) \
         ON CONFLICT(key) DO UPDATE SET value = excluded.value",
        params![key, value],
    )?;
    Ok(())
}

/// Writes the integrity record as the file now stands: the digest of its `meta`
/// rows, and its readings.
fn write_record(tx: &rusqlite::Transaction<'_>) -> rusqlite::Result<()> {
    let present = integrity::present_readings(tx)?;
    put_meta(tx, keys::INTEGRITY_READINGS, &present.to_text())?;
    let digest = meta_digest(&integrity::meta_map(tx)?);
    put_meta(tx, keys::INTEGRITY_META, &format!("{digest:016x}"))
}

/// Inserts `steps` as pending, with ids from `first` on and their row checksums:
/// the one way steps enter a run file (at creation, and in an adaptive plan's
/// batches).
fn insert_steps(
    tx: &rusqlite::Transaction<'_>,
    first: i64,
    steps: &[Step],
) -> rusqlite::Result<()> {
    let mut s = tx.prepare(&format!(
        "INSERT INTO steps ({STEP_COLUMNS}, crc) VALUES \
         (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14)"
    ))?;
    for (i, step) in steps.iter().enumerate() {
        let mut v = step_values(first + i as i64, step);
        let crc = row_crc(&v);
        v.push(Value::Integer(crc));
        s.execute(rusqlite::params_from_iter(v))?;
    }
    Ok(())
}

/// One column of a table of the run file.
#[derive(Clone, Debug, PartialEq)]
pub enum ColumnValues {
    /// A REAL column (NULL as NaN).
    Real(Vec<f64>),
    /// An INTEGER column.
    Integer(Vec<Option<i64>>),
    /// A TEXT column.
    Text(Vec<Option<String>>),
}

/// An open run file.
pub struct RunStore {
    conn: Connection,
    path: PathBuf,
    session: Option<i64>,
    /// The run's exclusive lock, when this store holds it (dropped after `conn`).
    lock: Option<RunLock>,
    /// Opened read-only as `immutable` (no write-ahead log beside the file then).
    immutable: bool,
}

impl std::fmt::Debug for RunStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RunStore")
            .field("path", &self.path)
            .field("session", &self.session)
            .finish()
    }
}

impl RunStore {
    fn sql(&self, source: rusqlite::Error) -> StoreError {
        StoreError::Sqlite {
            path: self.path.clone(),
            source,
        }
    }

    /// Runs `f` in one transaction, committed only if it succeeds: all or nothing.
    fn in_tx<T>(
        &mut self,
        f: impl FnOnce(&rusqlite::Transaction<'_>) -> rusqlite::Result<T>,
    ) -> Result<T, StoreError> {
        let path = self.path.clone();
        let sql = |source| StoreError::Sqlite {
            path: path.clone(),
            source,
        };
        let tx = self.conn.transaction().map_err(sql)?;
        let t = f(&tx).map_err(sql)?;
        tx.commit().map_err(sql)?;
        Ok(t)
    }

    /// Every row of a query, mapped.
    fn rows<T, P: rusqlite::Params, C: FromIterator<T>>(
        &self,
        query: &str,
        params: P,
        map: impl FnMut(&rusqlite::Row<'_>) -> rusqlite::Result<T>,
    ) -> Result<C, StoreError> {
        let mut stmt = self.conn.prepare(query).map_err(|e| self.sql(e))?;
        let rows = stmt.query_map(params, map).map_err(|e| self.sql(e))?;
        rows.collect::<Result<C, _>>().map_err(|e| self.sql(e))
    }

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

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// One metadata value.
    pub fn meta_value(&self, key: &str) -> Result<Option<String>, StoreError> {
        self.conn
            .query_row("SELECT value FROM meta WHERE key = ?1", [key], |r| r.get(0))
            .optional()
            .map_err(|e| self.sql(e))
    }

    /// All metadata.
    pub fn meta(&self) -> Result<BTreeMap<String, String>, StoreError> {
        self.rows("SELECT key, value FROM meta ORDER BY key", [], |r| {
            Ok((r.get(0)?, r.get(1)?))
        })
    }

    /// All metadata, typed.
    pub fn run_meta(&self) -> Result<RunMeta, StoreError> {
        RunMeta::from_map(&self.meta()?, &self.path)
    }

    /// Sets a metadata value, and the digest that covers it (one transaction).
    pub fn set_meta(&mut self, key: &str, value: &str) -> Result<(), StoreError> {
        self.in_tx(|tx| {
            put_meta(tx, key, value)?;
            if !integrity::MUTABLE_META.contains(&key) {
                let digest = meta_digest(&integrity::meta_map(tx)?);
                put_meta(tx, keys::INTEGRITY_META, &format!("{digest:016x}"))?;
            }
            Ok(())
        })
    }

    /// Starts a session (a process working on the run): status `running`.
    pub fn begin_session(&mut self, software: &str) -> Result<i64, StoreError> {
        let id = self.in_tx(|tx| {
            // A file from before the integrity record gets one, of what it holds now.
            if integrity::stored_record(tx)?.is_none() {
                write_record(tx)?;
            }
            tx.execute(
                "INSERT INTO sessions (started_s, software, pid) VALUES (?1, ?2, ?3)",
                params![wall_now(), software, std::process::id()],
            )?;
            let id = tx.last_insert_rowid();
            tx.execute(SET_STATUS, ["running"])?;
            Ok(id)
        })?;
        self.session = Some(id);
        Ok(id)
    }

    /// Ends the session with `outcome` (`complete`, `interrupted`, `faulted`), which
    /// becomes the run's status.
    pub fn end_session(&mut self, outcome: &str) -> Result<(), StoreError> {
        let session = self.session;
        self.in_tx(|tx| {
            if let Some(s) = session {
                tx.execute(
                    "UPDATE sessions SET ended_s = ?1, outcome = ?2 WHERE id = ?3",
                    params![wall_now(), outcome, s],
                )?;
            }
            tx.execute(SET_STATUS, [outcome])?;
            Ok(())
        })
    }

    /// Sessions, oldest first.
    pub fn sessions(&self) -> Result<Vec<SessionRow>, StoreError> {
        self.rows(
            "SELECT id, started_s, ended_s, outcome FROM sessions ORDER BY id",
            [],
            |r| {
                Ok(SessionRow {
                    id: r.get(0)?,
                    started_s: r.get(1)?,
                    ended_s: r.get(2)?,
                    outcome: r.get(3)?,
                })
            },
        )
    }

    /// Per session: readings taken and the instrument time of the last one.
    pub fn session_readings(&self) -> Result<BTreeMap<i64, (usize, f64)>, StoreError> {
        self.rows(
            "SELECT session, count(*), max(physical_s) FROM readings GROUP BY session",
            [],
            |r| {
                let n: i64 = r.get(1)?;
                let t: Option<f64> = r.get(2)?;
                Ok((r.get::<_, i64>(0)?, (n as usize, t.unwrap_or(f64::NAN))))
            },
        )
    }

    /// Logs an event now (its own transaction).
    pub fn event(
        &mut self,
        kind: &str,
        step_id: Option<i64>,
        message: &str,
    ) -> Result<(), StoreError> {
        self.conn
            .execute(
                INSERT_EVENT,
                params![self.session, wall_now(), kind, step_id, message],
            )
            .map_err(|e| self.sql(e))?;
        Ok(())
    }

    /// Commits a measured step: its reading, its state `done`, and `events`, all or
    /// nothing.
    pub fn commit(
        &mut self,
        reading: &ReadingRecord,
        events: &[EventRecord],
    ) -> Result<(), StoreError> {
        let session = self.session;
        let mut v = reading_values(reading, session.unwrap_or(0));
        let crc = row_crc(&v);
        v.push(Value::Integer(crc));
        // Only the lock holder commits, so the record read here is the one the
        // transaction updates.
        let record = integrity::stored_record(&self.conn)
            .map_err(|e| self.sql(e))?
            .map(|text| {
                ReadingsRecord::parse(&text).ok_or_else(|| StoreError::Corrupt {
                    path: self.path.clone(),
                    why: format!(
                        "meta `{}` = {text:?} is unreadable",
                        keys::INTEGRITY_READINGS
                    ),
                })
            })
            .transpose()?
            .map(|mut r| {
                r.add(reading_term(reading.step_id, crc));
                r.to_text()
            });
        let marked = self.in_tx(|tx| {
            let changed = tx
                .prepare_cached(
                    "UPDATE steps SET state = 'done', attempts = attempts + 1 \
                     WHERE id = ?1 AND state = 'pending'",
                )?
                .execute([reading.step_id])?;
            if changed != 1 {
                // Nothing written: a step is never measured twice.
                return Ok(false);
            }
            let placeholders: Vec<String> = (1..=v.len()).map(|i| format!("?{i}")).collect();
            tx.prepare_cached(&format!(
                "INSERT INTO readings ({READING_COLUMNS}, crc) VALUES ({})",
                placeholders.join(", ")
            ))?
            .execute(rusqlite::params_from_iter(v))?;
            let mut ins = tx.prepare_cached(INSERT_EVENT)?;
            for e in events {
                ins.execute(params![session, e.wall_s, e.kind, e.step_id, e.message])?;
            }
            // The record moves with the reading it counts.
            if let Some(text) = &record {
                put_meta(tx, keys::INTEGRITY_READINGS, text)?;
            }
            Ok(true)
        })?;
        if marked {
            Ok(())
        } else {
            Err(StoreError::NotPending {
                path: self.path.clone(),
                step: reading.step_id,
            })
        }
    }

    /// The integrity record of the readings as the file records it now (what the
    /// readings present make it, for a file from before the record existed).
    fn readings_record(&self) -> Result<ReadingsRecord, StoreError> {
        match integrity::stored_record(&self.conn).map_err(|e| self.sql(e))? {
            Some(text) => ReadingsRecord::parse(&text).ok_or_else(|| StoreError::Corrupt {
                path: self.path.clone(),
                why: format!(
                    "meta `{}` = {text:?} is unreadable",
                    keys::INTEGRITY_READINGS
                ),
            }),
            None => integrity::present_readings(&self.conn).map_err(|e| self.sql(e)),
        }
    }

    /// Appends an adaptive plan's batch: its steps, pending, with ids after the last
    /// step's, and its decision as the next row of the `decisions` table (created
    /// with the first batch), with the readings it was made from (their count and
    /// integrity record) and a `batch` event. One transaction: a kill leaves either
    /// all of it or none. Only the run's lock holder appends ([`RunStore::lock`]);
    /// a batch without steps is refused.
    pub fn append_batch(
        &mut self,
        batch: &Batch,
    ) -> Result<(DecisionRecord, Vec<StoredStep>), StoreError> {
        let bad = |why: String| StoreError::BadBatch {
            path: self.path.clone(),
            why,
        };
        if batch.steps.is_empty() {
            return Err(bad("it has no steps".into()));
        }
        let n_steps = u32::try_from(batch.steps.len())
            .map_err(|_| bad(format!("{} steps are too many", batch.steps.len())))?;
        if self.lock.is_none() {
            return Err(StoreError::NotLocked {
                path: self.path.clone(),
            });
        }
        // Only the lock holder writes, so the record read here is the one the
        // transaction sees.
        let record = self.readings_record()?;
        let session = self.session;
        let decision = &batch.decision;
        let d = self.in_tx(|tx| {
            tx.execute_batch(CREATE_DECISIONS)?;
            let first: i64 =
                tx.query_row("SELECT coalesce(max(id) + 1, 0) FROM steps", [], |r| {
                    r.get(0)
                })?;
            let id: i64 =
                tx.query_row("SELECT coalesce(max(id) + 1, 1) FROM decisions", [], |r| {
                    r.get(0)
                })?;
            insert_steps(tx, first, &batch.steps)?;
            let d = DecisionRecord {
                id,
                session,
                wall_s: wall_now(),
                first_step: first,
                steps: n_steps,
                points: decision.points,
                method: decision.method.clone(),
                readings: record.count,
                digest: record.to_text(),
                detail: decision.detail.clone(),
            };
            let mut v = decision_values(&d);
            let crc = row_crc(&v);
            v.push(Value::Integer(crc));
            let placeholders: Vec<String> = (1..=v.len()).map(|i| format!("?{i}")).collect();
            tx.execute(
                &format!(
                    "INSERT INTO decisions ({DECISION_COLUMNS}, crc) VALUES ({})",
                    placeholders.join(", ")
                ),
                rusqlite::params_from_iter(v),
            )?;
            tx.execute(
                INSERT_EVENT,
                params![
                    session,
                    d.wall_s,
                    "batch",
                    first,
                    format!(
                        "batch {id}: {} points, {n_steps} steps ({})",
                        d.points, d.method
                    )
                ],
            )?;
            Ok(d)
        })?;
        let steps = batch
            .steps
            .iter()
            .enumerate()
            .map(|(i, step)| StoredStep {
                id: d.first_step + i as i64,
                step: step.clone(),
                state: "pending".into(),
                attempts: 0,
            })
            .collect();
        Ok((d, steps))
    }

    /// The adaptive plan's decisions, oldest first: none for a run whose schedule
    /// was all fixed at creation (its file has no `decisions` table).
    pub fn decisions(&self) -> Result<Vec<DecisionRecord>, StoreError> {
        if !has_decisions(&self.conn).map_err(|e| self.sql(e))? {
            return Ok(Vec::new());
        }
        self.rows(
            &format!("SELECT {DECISION_COLUMNS} FROM decisions ORDER BY id"),
            [],
            |r| {
                Ok(DecisionRecord {
                    id: r.get(0)?,
                    session: r.get(1)?,
                    wall_s: r.get::<_, Option<f64>>(2)?.unwrap_or(f64::NAN),
                    first_step: r.get(3)?,
                    steps: r.get(4)?,
                    points: r.get(5)?,
                    method: r.get(6)?,
                    readings: r.get::<_, i64>(7)? as u64,
                    digest: r.get(8)?,
                    detail: r.get(9)?,
                })
            },
        )
    }

    /// Marks a step failed (skipped for good) with the reason as an event.
    pub fn fail_step(&mut self, step_id: i64, reason: &str) -> Result<(), StoreError> {
        let session = self.session;
        self.in_tx(|tx| {
            tx.execute(
                "UPDATE steps SET state = 'failed', attempts = attempts + 1 WHERE id = ?1",
                [step_id],
            )?;
            tx.execute(
                INSERT_EVENT,
                params![session, wall_now(), "skip", step_id, reason],
            )?;
            Ok(())
        })
    }

    /// Every step, in schedule order.
    pub fn steps(&self) -> Result<Vec<StoredStep>, StoreError> {
        self.rows(
            &format!("SELECT {STEP_COLUMNS}, state, attempts FROM steps ORDER BY id"),
            [],
            |r| {
                let kind: String = r.get(1)?;
                let angles: [Option<f64>; 4] = [r.get(5)?, r.get(6)?, r.get(7)?, r.get(8)?];
                let targets: [Option<f64>; 4] = [r.get(9)?, r.get(10)?, r.get(11)?, r.get(12)?];
                let pair = match angles {
                    [Some(a), Some(b), Some(c), Some(d)] => Some(PairDeg {
                        incident: SphericalDeg::new(a, b),
                        outgoing: SphericalDeg::new(c, d),
                    }),
                    _ => None,
                };
                let stages = match targets {
                    [Some(a), Some(b), Some(c), Some(d)] => Some([a, b, c, d]),
                    _ => None,
                };
                let plan_index: Option<i64> = r.get(4)?;
                Ok(StoredStep {
                    id: r.get(0)?,
                    step: Step {
                        // The CHECK constraint admits only the five names.
                        kind: StepKind::parse(&kind).unwrap_or(StepKind::Sample),
                        channel: r.get(2)?,
                        repeat: r.get(3)?,
                        pair,
                        stages,
                        plan_index: plan_index.map(|i| i as usize),
                    },
                    state: r.get(13)?,
                    attempts: r.get(14)?,
                })
            },
        )
    }

    /// Every reading, in step order.
    pub fn readings(&self) -> Result<Vec<ReadingRecord>, StoreError> {
        self.readings_where("1", [])
    }

    /// The readings a condition on the `readings` table selects, in step order.
    fn readings_where<P: rusqlite::Params>(
        &self,
        condition: &str,
        params: P,
    ) -> Result<Vec<ReadingRecord>, StoreError> {
        Ok(self
            .readings_with_session(condition, params)?
            .into_iter()
            .map(|(_, r)| r)
            .collect())
    }

    /// [`RunStore::readings_where`], each reading with its session.
    fn readings_with_session<P: rusqlite::Params>(
        &self,
        condition: &str,
        params: P,
    ) -> Result<Vec<(i64, ReadingRecord)>, StoreError> {
        self.rows(
            &format!("SELECT {READING_COLUMNS} FROM readings WHERE {condition} ORDER BY step_id"),
            params,
            |r| {
                let num = |r: &rusqlite::Row<'_>, i: usize| -> rusqlite::Result<f64> {
                    Ok(r.get::<_, Option<f64>>(i)?.unwrap_or(f64::NAN))
                };
                let cmd: [Option<f64>; 4] = [r.get(2)?, r.get(3)?, r.get(4)?, r.get(5)?];
                let commanded = match cmd {
                    [Some(a), Some(b), Some(c), Some(d)] => Some([a, b, c, d]),
                    _ => None,
                };
                let retries: i64 = r.get(27)?;
                let session: i64 = r.get(1)?;
                Ok((
                    session,
                    ReadingRecord {
                        step_id: r.get(0)?,
                        commanded,
                        position: [num(r, 6)?, num(r, 7)?, num(r, 8)?, num(r, 9)?],
                        read_pair: PairDeg {
                            incident: SphericalDeg::new(num(r, 10)?, num(r, 11)?),
                            outgoing: SphericalDeg::new(num(r, 12)?, num(r, 13)?),
                        },
                        sensitivity: r.get(14)?,
                        sensitivity_v: num(r, 15)?,
                        time_constant: r.get(16)?,
                        time_constant_s: num(r, 17)?,
                        slope_db: r.get(18)?,
                        r_mean: num(r, 19)?,
                        r_std: num(r, 20)?,
                        x_mean: num(r, 21)?,
                        y_mean: num(r, 22)?,
                        n: r.get(23)?,
                        autorange_steps: r.get(24)?,
                        lias: r.get(25)?,
                        flags: r.get(26)?,
                        retries: retries as u64,
                        physical_s: num(r, 28)?,
                        wall_s: num(r, 29)?,
                    },
                ))
            },
        )
    }

    /// The readings committed after wall time `wall_s`, in commit order, each
    /// with the session that took it: what a reader following a run in progress
    /// has not seen yet (a step reopened because its reading went missing is
    /// committed again with a new time, and seen again).
    pub fn readings_since(&self, wall_s: f64) -> Result<Vec<(i64, ReadingRecord)>, StoreError> {
        let mut rows = self.readings_with_session("wall_s > ?1", [wall_s])?;
        rows.sort_by(|a, b| a.1.wall_s.total_cmp(&b.1.wall_s));
        Ok(rows)
    }

    /// The events after the one with row id `id`, with their row ids, in order.
    pub fn events_after(&self, id: i64) -> Result<Vec<(i64, EventRecord)>, StoreError> {
        self.rows(
            "SELECT id, wall_s, kind, step_id, message FROM events WHERE id > ?1 ORDER BY id",
            [id],
            |r| {
                Ok((
                    r.get(0)?,
                    EventRecord {
                        wall_s: r.get(1)?,
                        kind: r.get(2)?,
                        step_id: r.get(3)?,
                        message: r.get(4)?,
                    },
                ))
            },
        )
    }

    /// The reading of the latest done step before `step_id` (the detector's state
    /// to restore on resume), if any.
    pub fn last_reading_before(&self, step_id: i64) -> Result<Option<ReadingRecord>, StoreError> {
        Ok(self
            .readings_where(
                "step_id = (SELECT max(step_id) FROM readings WHERE step_id < ?1)",
                [step_id],
            )?
            .pop())
    }

    /// Every event, in order.
    pub fn events(&self) -> Result<Vec<EventRecord>, StoreError> {
        self.rows(
            "SELECT wall_s, kind, step_id, message FROM events ORDER BY id",
            [],
            |r| {
                Ok(EventRecord {
                    wall_s: r.get(0)?,
                    kind: r.get(1)?,
                    step_id: r.get(2)?,
                    message: r.get(3)?,
                })
            },
        )
    }

    /// The readings as columns, in step order: every column of the `readings` table
    /// but its row checksum, under the run file's own names, then the step each
    /// measures (`kind`, `channel`, `repeat`, `plan_index`, and the planned
    /// directions as `planned_theta_i` … `planned_phi_o`). A REAL column's NULL is
    /// NaN; an INTEGER column's NULL is `None`.
    pub fn reading_columns(&self) -> Result<Vec<(String, ColumnValues)>, StoreError> {
        let declared: Vec<(String, String)> = self.rows(
            "SELECT name, type FROM pragma_table_info('readings') ORDER BY cid",
            [],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )?;
        let mut names: Vec<(String, String)> = declared
            .into_iter()
            .filter(|(n, _)| n != "crc")
            // Quoted: the names are read from the file, not from this build.
            .map(|(n, t)| (format!("r.\"{}\"", n.replace('"', "\"\"")), t))
            .collect();
        for (n, t) in [
            ("kind", "TEXT"),
            ("channel", "TEXT"),
            ("repeat", "INTEGER"),
            ("plan_index", "INTEGER"),
            ("theta_i", "REAL"),
            ("phi_i", "REAL"),
            ("theta_o", "REAL"),
            ("phi_o", "REAL"),
        ] {
            names.push((format!("s.{n}"), t.into()));
        }
        let select: Vec<&str> = names.iter().map(|(n, _)| n.as_str()).collect();
        let mut cols: Vec<ColumnValues> = names
            .iter()
            .map(|(_, t)| match t.to_ascii_uppercase().as_str() {
                "REAL" => ColumnValues::Real(Vec::new()),
                "INTEGER" => ColumnValues::Integer(Vec::new()),
                _ => ColumnValues::Text(Vec::new()),
            })
            .collect();
        let query = format!(
            "SELECT {} FROM readings r JOIN steps s ON s.id = r.step_id ORDER BY r.step_id",
            select.join(", ")
        );
        let mut stmt = self.conn.prepare(&query).map_err(|e| self.sql(e))?;
        let mut rows = stmt.query([]).map_err(|e| self.sql(e))?;
        while let Some(row) = rows.next().map_err(|e| self.sql(e))? {
            for (j, c) in cols.iter_mut().enumerate() {
                match c {
                    ColumnValues::Real(v) => v.push(
                        row.get::<_, Option<f64>>(j)
                            .map_err(|e| self.sql(e))?
                            .unwrap_or(f64::NAN),
                    ),
                    ColumnValues::Integer(v) => {
                        v.push(row.get::<_, Option<i64>>(j).map_err(|e| self.sql(e))?)
                    }
                    ColumnValues::Text(v) => {
                        v.push(row.get::<_, Option<String>>(j).map_err(|e| self.sql(e))?)
                    }
                }
            }
        }
        Ok(names
            .into_iter()
            .map(|(n, _)| match n.strip_prefix("s.") {
                Some(step) if step.starts_with("theta") || step.starts_with("phi") => {
                    format!("planned_{step}")
                }
                Some(step) => step.to_string(),
                None => n
                    .trim_start_matches("r.")
                    .trim_matches('"')
                    .replace("\"\"", "\""),
            })
            .zip(cols)
            .collect())
    }

    /// Counts of steps by state.
    pub fn state_counts(&self) -> Result<BTreeMap<String, u64>, StoreError> {
        self.rows(
            "SELECT state, count(*) FROM steps GROUP BY state",
            [],
            |r| Ok((r.get::<_, String>(0)?, r.get::<_, i64>(1)? as u64)),
        )
    }
}
