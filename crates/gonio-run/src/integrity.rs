//! The run file's integrity record, and the check of a file against it.
//!
//! Row checksums catch a damaged value; they cannot catch a row that is gone, or a
//! value edited by someone who also recomputed its checksum. So the file also
//! records, in two `meta` rows written in the same transactions as what they cover:
//!
//! - `integrity_meta`: a digest of every `meta` row fixed at creation (the verbatim
//!   configs, the seed, the geometry…), i.e. all but `status` and the two
//!   integrity rows. An edited config changes it.
//! - `integrity_readings`: `COUNT:DIGEST`, the number of readings committed and the
//!   wrapping sum of one mixed word per reading (its step and its checksum). The sum
//!   does not depend on the order of commits, so a re-measured step replaces its
//!   term; a deleted or altered reading changes it.
//!
//! An adaptive run's `decisions` rows carry checksums too, and account for every
//! step appended after the schedule (`check_batches`); a file without the table is
//! checked as before.
//!
//! Files written before the record existed carry neither row: they are checked as
//! before (row checksums, counts), and get the record when next resumed.

use std::collections::BTreeMap;

use rusqlite::types::Value;
use rusqlite::{Connection, OptionalExtension};
use serde::Serialize;

use gonio_core::rng::{GOLDEN_GAMMA, splitmix64};

use crate::meta::keys;
use crate::records::row_crc;
use crate::schema::{DECISION_COLUMNS, READING_COLUMNS, STEP_COLUMNS, has_decisions};

/// `meta` rows that change during a run, and so are outside `integrity_meta`.
pub(crate) const MUTABLE_META: [&str; 3] =
    [keys::STATUS, keys::INTEGRITY_META, keys::INTEGRITY_READINGS];

/// `meta` rows every run file has.
const REQUIRED_META: [&str; 4] = [keys::INSTRUMENT, keys::PLAN, keys::STATUS, keys::STEP_COUNT];

/// At most this many row ids are listed in one finding.
const LISTED: usize = 10;

/// The digest of the `meta` rows fixed at creation.
pub(crate) fn meta_digest(meta: &BTreeMap<String, String>) -> u64 {
    let values: Vec<Value> = meta
        .iter()
        .filter(|(k, _)| !MUTABLE_META.contains(&k.as_str()))
        .flat_map(|(k, v)| [Value::Text(k.clone()), Value::Text(v.clone())])
        .collect();
    row_crc(&values) as u64
}

/// One reading's term of the readings digest: its step and checksum, mixed.
pub(crate) fn reading_term(step_id: i64, crc: i64) -> u64 {
    splitmix64((step_id as u64).wrapping_mul(GOLDEN_GAMMA) ^ splitmix64(crc as u64))
}

/// The readings a run file records: how many, and their digest.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct ReadingsRecord {
    /// Readings committed.
    pub count: u64,
    /// Wrapping sum of their [`reading_term`]s.
    pub digest: u64,
}

impl ReadingsRecord {
    /// Parses `COUNT:DIGEST` (the digest in 16 hexadecimal digits).
    pub fn parse(s: &str) -> Option<ReadingsRecord> {
        let (n, d) = s.split_once(':')?;
        Some(ReadingsRecord {
            count: n.parse().ok()?,
            digest: u64::from_str_radix(d, 16).ok()?,
        })
    }

    /// As stored.
    pub fn to_text(self) -> String {
        format!("{}:{:016x}", self.count, self.digest)
    }

    /// With one more reading.
    pub fn add(&mut self, term: u64) {
        self.count += 1;
        self.digest = self.digest.wrapping_add(term);
    }
}

/// What checking a run file found.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Integrity {
    /// The file carries an integrity record (files written before it existed do not;
    /// they are checked by row checksums and counts alone).
    pub recorded: bool,
    /// Readings the file holds.
    pub readings: u64,
    /// Steps committed once whose readings are gone. `gonio resume` measures them
    /// again.
    pub missing: Vec<i64>,
    /// Required `meta` rows that are gone (also listed in `damage`).
    pub missing_meta: Vec<&'static str>,
    /// Everything else that is wrong, one sentence each.
    pub damage: Vec<String>,
}

impl Integrity {
    /// Nothing is wrong.
    pub fn is_intact(&self) -> bool {
        self.missing.is_empty() && self.damage.is_empty()
    }

    /// Every fault, one per entry: the missing readings first.
    pub fn faults(&self) -> Vec<String> {
        let mut v = Vec::new();
        if !self.missing.is_empty() {
            v.push(format!(
                "{} committed reading(s) missing (steps {}); `gonio resume` measures them again",
                self.missing.len(),
                list(&self.missing)
            ));
        }
        v.extend(self.damage.iter().cloned());
        v
    }
}

/// `ids` for a message: the first few, and how many more.
fn list(ids: &[i64]) -> String {
    let shown: Vec<String> = ids.iter().take(LISTED).map(i64::to_string).collect();
    match ids.len().saturating_sub(LISTED) {
        0 => shown.join(", "),
        more => format!("{} and {more} more", shown.join(", ")),
    }
}

/// The readings a file holds now, as a record.
pub(crate) fn present_readings(conn: &Connection) -> rusqlite::Result<ReadingsRecord> {
    let mut r = ReadingsRecord::default();
    let mut stmt = conn.prepare("SELECT step_id, crc FROM readings")?;
    let mut rows = stmt.query([])?;
    while let Some(row) = rows.next()? {
        r.add(reading_term(row.get(0)?, row.get(1)?));
    }
    Ok(r)
}

/// The `meta` table.
pub(crate) fn meta_map(conn: &Connection) -> rusqlite::Result<BTreeMap<String, String>> {
    let mut stmt = conn.prepare("SELECT key, value FROM meta")?;
    let rows = stmt.query_map([], |r| Ok((r.get(0)?, r.get(1)?)))?;
    rows.collect()
}

/// One `i64` query.
fn count(conn: &Connection, sql: &str) -> rusqlite::Result<i64> {
    conn.query_row(sql, [], |r| r.get(0))
}

/// Checks a run file whole: SQLite's own check (`full`: `integrity_check`, else
/// `quick_check`), every row checksum, the schedule's size, the required `meta`
/// rows, readings against steps, and the integrity record.
pub(crate) fn inspect(conn: &Connection, full: bool) -> rusqlite::Result<Integrity> {
    let mut out = Integrity::default();
    let pragma = if full {
        "integrity_check"
    } else {
        "quick_check"
    };
    let mut stmt = conn.prepare(&format!("PRAGMA {pragma}"))?;
    let lines: Vec<String> = stmt
        .query_map([], |r| r.get(0))?
        .collect::<Result<_, _>>()?;
    if lines != ["ok"] {
        out.damage
            .extend(lines.into_iter().map(|l| format!("{pragma}: {l}")));
        // The tables cannot be trusted to read.
        return Ok(out);
    }
    let mut present = ReadingsRecord::default();
    let adaptive = has_decisions(conn)?;
    let mut tables = vec![
        ("steps", STEP_COLUMNS, "id"),
        ("readings", READING_COLUMNS, "step_id"),
    ];
    if adaptive {
        tables.push(("decisions", DECISION_COLUMNS, "id"));
    }
    for (table, cols, key) in tables {
        let n = cols.split(',').count();
        let mut stmt = conn.prepare(&format!("SELECT {cols}, crc FROM {table} ORDER BY {key}"))?;
        let mut rows = stmt.query([])?;
        let mut bad = Vec::new();
        while let Some(row) = rows.next()? {
            let values: Vec<Value> = (0..n)
                .map(|i| row.get::<_, Value>(i))
                .collect::<Result<_, _>>()?;
            let stored: i64 = row.get(n)?;
            let id = match values[0] {
                Value::Integer(i) => i,
                _ => -1,
            };
            if row_crc(&values) != stored {
                bad.push(id);
            }
            if table == "readings" {
                present.add(reading_term(id, stored));
            }
        }
        match bad.len() {
            0 => {}
            1 => out.damage.push(format!(
                "{table} row {} fails its checksum (a damaged value)",
                bad[0]
            )),
            n => out.damage.push(format!(
                "{n} {table} rows fail their checksums (damaged values): rows {}",
                list(&bad)
            )),
        }
    }
    out.readings = present.count;
    let meta = meta_map(conn)?;
    for key in REQUIRED_META {
        if !meta.contains_key(key) {
            out.damage.push(format!("meta row `{key}` is missing"));
            out.missing_meta.push(key);
        }
    }
    let steps = count(conn, "SELECT count(*) FROM steps")?;
    if let Some(want) = meta.get(keys::STEP_COUNT) {
        match want.parse::<i64>() {
            Ok(w) if adaptive => check_batches(conn, w, steps, &mut out.damage)?,
            Ok(w) if w == steps => {}
            Ok(w) => out
                .damage
                .push(format!("{steps} steps stored, the schedule had {w}")),
            Err(_) => out
                .damage
                .push(format!("meta `step_count` = {want:?} is not a count")),
        }
    }
    let orphans = count(
        conn,
        "SELECT count(*) FROM readings r LEFT JOIN steps s ON s.id = r.step_id \
         WHERE s.id IS NULL OR s.state != 'done'",
    )?;
    if orphans != 0 {
        out.damage
            .push(format!("{orphans} reading(s) without a done step"));
    }
    // A step is attempted only by a commit (pending → done) or a failure (→ failed):
    // a done step, or a pending one attempted before, without a reading has lost it.
    let mut stmt = conn.prepare(
        "SELECT s.id FROM steps s LEFT JOIN readings r ON r.step_id = s.id \
         WHERE r.step_id IS NULL AND (s.state = 'done' OR (s.state = 'pending' AND s.attempts > 0)) \
         ORDER BY s.id",
    )?;
    out.missing = stmt
        .query_map([], |r| r.get(0))?
        .collect::<Result<_, _>>()?;
    if let Some(d) = meta.get(keys::INTEGRITY_META) {
        out.recorded = true;
        if u64::from_str_radix(d, 16).ok() != Some(meta_digest(&meta)) {
            out.damage.push(
                "the metadata (configs, seed, geometry) differ from those recorded at \
                 creation: a meta row was edited, added or deleted"
                    .into(),
            );
        }
    }
    if let Some(r) = meta.get(keys::INTEGRITY_READINGS) {
        out.recorded = true;
        match ReadingsRecord::parse(r) {
            None => out.damage.push(format!(
                "meta `{}` = {r:?} is unreadable",
                keys::INTEGRITY_READINGS
            )),
            Some(rec) => {
                let accounted = present.count + out.missing.len() as u64;
                if rec.count != accounted {
                    out.damage.push(format!(
                        "{} reading(s) recorded, {} present{}",
                        rec.count,
                        present.count,
                        if out.missing.is_empty() {
                            String::new()
                        } else {
                            format!(" and {} known missing", out.missing.len())
                        }
                    ));
                } else if out.missing.is_empty() && rec.digest != present.digest {
                    out.damage.push(
                        "the readings differ from those committed (a value edited with its \
                         checksum recomputed, or a row replaced)"
                            .into(),
                    );
                }
            }
        }
    }
    Ok(out)
}

/// The steps of an adaptive run against its schedule and batches: the batches are
/// numbered 1, 2, … and each one's steps follow the schedule's and the earlier
/// batches' without a gap, and the steps stored are the schedule's `scheduled`
/// and every batch's, ids `0 .. total`.
fn check_batches(
    conn: &Connection,
    scheduled: i64,
    stored: i64,
    damage: &mut Vec<String>,
) -> rusqlite::Result<()> {
    let mut stmt = conn.prepare("SELECT id, first_step, steps FROM decisions ORDER BY id")?;
    let batches: Vec<(i64, i64, i64)> = stmt
        .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))?
        .collect::<Result<_, _>>()?;
    let mut next = scheduled;
    for (k, (id, first, n)) in batches.iter().enumerate() {
        if *id != k as i64 + 1 {
            damage.push(format!(
                "decisions row {id} is batch {} (a batch's row was deleted or renumbered)",
                k + 1
            ));
        }
        if *first != next {
            damage.push(format!(
                "batch {id} starts at step {first}, not at step {next} where the steps \
                 before it end"
            ));
        }
        next = first.saturating_add(*n);
    }
    // Saturating: the counts are read from a file that may have been edited.
    let added = batches.iter().fold(0i64, |a, b| a.saturating_add(b.2));
    let want = scheduled.saturating_add(added);
    if stored != want {
        damage.push(format!(
            "{stored} steps stored, the schedule had {scheduled} and {} batch(es) added {added}",
            batches.len()
        ));
    }
    let outside = count(
        conn,
        &format!("SELECT count(*) FROM steps WHERE id < 0 OR id >= {want}"),
    )?;
    if outside != 0 {
        damage.push(format!(
            "{outside} step(s) with ids outside the schedule and its batches (0 to {})",
            want.saturating_sub(1)
        ));
    }
    Ok(())
}

/// The stored readings record, if any.
pub(crate) fn stored_record(conn: &Connection) -> rusqlite::Result<Option<String>> {
    conn.query_row(
        "SELECT value FROM meta WHERE key = ?1",
        [keys::INTEGRITY_READINGS],
        |r| r.get(0),
    )
    .optional()
}
