//! Writing to an open run file: metadata, sessions, events, each measured step
//! in one transaction, an adaptive plan's batches, and failed steps.

use rusqlite::params;
use rusqlite::types::Value;

use gonio_plan::schedule::Step;

use crate::error::StoreError;
use crate::integrity::{self, ReadingsRecord, meta_digest, reading_term};
use crate::meta::keys;
use crate::records::{
    Batch, DecisionRecord, EventRecord, ReadingRecord, StoredStep, decision_values, reading_values,
    row_crc, step_values,
};
use crate::schema::{
    CREATE_DECISIONS, DECISION_COLUMNS, INSERT_EVENT, READING_COLUMNS, SET_STATUS, STEP_COLUMNS,
};
use crate::time::wall_now;

use super::RunStore;

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
pub(super) fn write_record(tx: &rusqlite::Transaction<'_>) -> rusqlite::Result<()> {
    let present = integrity::present_readings(tx)?;
    put_meta(tx, keys::INTEGRITY_READINGS, &present.to_text())?;
    let digest = meta_digest(&integrity::meta_map(tx)?);
    put_meta(tx, keys::INTEGRITY_META, &format!("{digest:016x}"))
}

/// Inserts `steps` as pending, with ids from `first` on and their row checksums:
/// the one way steps enter a run file (at creation, and in an adaptive plan's
/// batches).
pub(super) fn insert_steps(
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

impl RunStore {
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
}
