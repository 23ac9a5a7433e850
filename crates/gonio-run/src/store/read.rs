//! Reading an open run file: metadata, sessions, steps, readings, events, decisions
//! and whole columns.

use std::collections::BTreeMap;

use rusqlite::OptionalExtension;

use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use gonio_plan::schedule::{Step, StepKind};

use crate::error::StoreError;
use crate::meta::RunMeta;
use crate::records::{DecisionRecord, EventRecord, ReadingRecord, SessionRow, StoredStep};
use crate::schema::{DECISION_COLUMNS, READING_COLUMNS, STEP_COLUMNS, has_decisions};

use super::{ColumnValues, RunStore};

impl RunStore {
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
