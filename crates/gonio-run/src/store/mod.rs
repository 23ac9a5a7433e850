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

use std::path::{Path, PathBuf};

use rusqlite::Connection;

pub use crate::error::StoreError;
use crate::lock::RunLock;
use crate::schema::APPLICATION_ID;

mod open;
mod read;
mod write;

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

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }
}
