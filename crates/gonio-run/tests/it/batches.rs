//! An adaptive plan's batches in the run file: appended whole with their decision,
//! read back, checked, and absent from the files of runs that never append one.

use std::collections::BTreeMap;
use std::path::Path;

use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use gonio_plan::schedule::{Step, StepKind};
use gonio_run::{Batch, Decision, DecisionRecord, ReadingRecord, RunStore, StoreError};

/// Sample steps at θi = 30°, θo = `from`, `from + 1`, … (`n` of them).
fn steps(from: usize, n: usize) -> Vec<Step> {
    (from..from + n)
        .map(|i| Step {
            kind: StepKind::Sample,
            channel: None,
            repeat: 0,
            pair: Some(PairDeg {
                incident: SphericalDeg::new(30.0, 0.0),
                outgoing: SphericalDeg::new(i as f64, 180.0),
            }),
            stages: Some([-30.0, i as f64, 90.0, 0.0]),
            plan_index: Some(i),
        })
        .collect()
}

fn reading(step_id: i64) -> ReadingRecord {
    let r = 1e-3 * (step_id + 1) as f64;
    ReadingRecord {
        step_id,
        commanded: Some([-30.0, step_id as f64, 90.0, 0.0]),
        position: [-30.0, step_id as f64, 90.0, 0.0],
        read_pair: PairDeg {
            incident: SphericalDeg::new(30.0, 0.0),
            outgoing: SphericalDeg::new(step_id as f64, 180.0),
        },
        sensitivity: 17,
        sensitivity_v: 1e-3,
        time_constant: 8,
        time_constant_s: 0.1,
        slope_db: 24,
        r_mean: r,
        r_std: r * 1e-3,
        x_mean: r,
        y_mean: 1e-9,
        n: 10,
        autorange_steps: 0,
        lias: 0,
        flags: 0,
        retries: 0,
        physical_s: 3.5 * step_id as f64,
        wall_s: 1.8e9 + step_id as f64,
    }
}

fn batch(method: &str, points: u32, steps: Vec<Step>) -> Batch {
    Batch {
        decision: Decision {
            method: method.into(),
            points,
            detail: format!(r#"{{"method":"{method}","points":{points}}}"#),
        },
        steps,
    }
}

fn meta() -> BTreeMap<String, String> {
    let mut meta = BTreeMap::new();
    meta.insert("instrument".to_string(), "name = \"x\"".to_string());
    meta.insert("plan".to_string(), "name = \"p\"".to_string());
    meta
}

/// The readings record as the file holds it now.
fn record(s: &RunStore) -> String {
    s.meta_value("integrity_readings")
        .expect("meta")
        .expect("recorded")
}

/// A run of 4 scheduled steps, all measured, then a batch of 3 (two measured) and a
/// batch of 2, closed. Returns the two decisions as `append_batch` returned them.
fn adaptive(path: &Path) -> Vec<DecisionRecord> {
    let mut s = RunStore::create(path, &meta(), &steps(0, 4)).expect("creates");
    s.begin_session("test").expect("session");
    for i in 0..4 {
        s.commit(&reading(i), &[]).expect("commit");
    }
    let before = record(&s);
    let (d1, added) = s
        .append_batch(&batch("variation", 2, steps(4, 3)))
        .expect("appends");
    assert_eq!(
        (d1.id, d1.first_step, d1.steps, d1.points, d1.readings),
        (1, 4, 3, 2, 4)
    );
    assert_eq!(d1.digest, before, "the data the decision was made from");
    assert_eq!(d1.method, "variation");
    assert_eq!(d1.detail, r#"{"method":"variation","points":2}"#);
    assert_eq!(d1.session, Some(1));
    assert_eq!(
        added.iter().map(|a| a.id).collect::<Vec<_>>(),
        [4, 5, 6],
        "ids follow the schedule's"
    );
    assert!(
        added
            .iter()
            .all(|a| a.state == "pending" && a.attempts == 0)
    );
    assert_eq!(
        added.iter().map(|a| a.step.clone()).collect::<Vec<_>>(),
        steps(4, 3)
    );
    s.commit(&reading(4), &[]).expect("commit");
    s.commit(&reading(5), &[]).expect("commit");
    let before = record(&s);
    let (d2, added) = s
        .append_batch(&batch("gradient", 1, steps(7, 2)))
        .expect("appends");
    assert_eq!(
        (d2.id, d2.first_step, d2.steps, d2.points, d2.readings),
        (2, 7, 2, 1, 6)
    );
    assert_eq!(d2.digest, before);
    assert_ne!(d2.digest, d1.digest);
    assert_eq!(added.iter().map(|a| a.id).collect::<Vec<_>>(), [7, 8]);
    // As stored, every step in id order: the schedule's, then each batch's.
    let stored = s.steps().expect("steps");
    assert_eq!(
        stored.iter().map(|a| a.id).collect::<Vec<_>>(),
        (0..9).collect::<Vec<i64>>()
    );
    assert_eq!(
        stored.iter().map(|a| a.step.clone()).collect::<Vec<_>>(),
        steps(0, 9)
    );
    assert_eq!(
        stored.iter().map(|a| a.state.as_str()).collect::<Vec<_>>(),
        [
            "done", "done", "done", "done", "done", "done", "pending", "pending", "pending"
        ]
    );
    s.end_session("interrupted").expect("end");
    vec![d1, d2]
}

#[test]
fn two_batches_are_appended_whole_and_read_back() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let p = scratch.path().join("a.gonio");
    let made = adaptive(&p);
    let s = RunStore::open(&p).expect("intact");
    assert_eq!(s.decisions().expect("decisions"), made);
    let found = s.integrity(true).expect("checks");
    assert!(found.is_intact() && found.readings == 6, "{found:?}");
    // Each batch logged in its transaction, at its first step.
    let logged: Vec<(Option<i64>, String)> = s
        .events()
        .expect("events")
        .into_iter()
        .filter(|e| e.kind == "batch")
        .map(|e| (e.step_id, e.message))
        .collect();
    assert_eq!(
        logged,
        [
            (
                Some(4),
                "batch 1: 2 points, 3 steps (variation)".to_string()
            ),
            (Some(7), "batch 2: 1 points, 2 steps (gradient)".to_string()),
        ]
    );
    // The schedule fixed at creation is still its own count.
    assert_eq!(
        s.meta_value("step_count").expect("meta").as_deref(),
        Some("4")
    );
    // And the appended steps measure like any other.
    drop(s);
    let mut s = RunStore::open(&p).expect("opens");
    s.lock().expect("locks");
    s.begin_session("test").expect("session");
    for i in 6..9 {
        s.commit(&reading(i), &[]).expect("commit");
    }
    let found = s.integrity(true).expect("checks");
    assert!(found.is_intact() && found.readings == 9, "{found:?}");
}

#[test]
fn a_batch_is_refused_without_steps_or_without_the_lock_and_written_all_or_nothing() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let p = scratch.path().join("a.gonio");
    let mut s = RunStore::create(&p, &meta(), &steps(0, 2)).expect("creates");
    s.begin_session("test").expect("session");
    let e = s
        .append_batch(&batch("variation", 0, Vec::new()))
        .expect_err("empty");
    assert!(matches!(e, StoreError::BadBatch { .. }), "{e}");
    assert_eq!(
        e.to_string(),
        format!("{}: cannot append the batch: it has no steps", p.display())
    );
    drop(s);
    let mut unlocked = RunStore::open(&p).expect("opens");
    let e = unlocked
        .append_batch(&batch("variation", 1, steps(2, 1)))
        .expect_err("not the lock holder");
    assert!(matches!(e, StoreError::NotLocked { .. }), "{e}");
    drop(unlocked);
    // A failure inside the transaction (the event's insert, its last write) leaves
    // neither the steps nor the decision, nor the table.
    let c = rusqlite::Connection::open(&p).expect("opens");
    c.execute_batch(
        "CREATE TRIGGER refuse BEFORE INSERT ON events WHEN NEW.kind = 'batch' \
         BEGIN SELECT RAISE(ABORT, 'disk full'); END;",
    )
    .expect("trigger");
    drop(c);
    let mut s = RunStore::open(&p).expect("opens");
    s.lock().expect("locks");
    let e = s
        .append_batch(&batch("variation", 1, steps(2, 1)))
        .expect_err("aborted");
    assert!(e.to_string().contains("disk full"), "{e}");
    assert_eq!(s.steps().expect("steps").len(), 2);
    assert!(s.decisions().expect("decisions").is_empty());
    assert!(s.integrity(true).expect("checks").is_intact());
    let tables: i64 = rusqlite::Connection::open(&p)
        .expect("opens")
        .query_row(
            "SELECT count(*) FROM sqlite_master WHERE name = 'decisions'",
            [],
            |r| r.get(0),
        )
        .expect("counts");
    assert_eq!(tables, 0);
}

fn edit(path: &Path, sql: &str) {
    let c = rusqlite::Connection::open(path).expect("opens");
    c.execute_batch(sql).expect("edits");
}

/// The damage `open` reports, one entry per finding.
fn damage(path: &Path) -> Vec<String> {
    let e = RunStore::open(path).expect_err("damaged");
    assert!(matches!(e, StoreError::Corrupt { .. }), "{e}");
    RunStore::open_unverified(path)
        .expect("opens")
        .integrity(true)
        .expect("checks")
        .damage
}

#[test]
fn an_edited_decision_is_damage() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let p = scratch.path().join("a.gonio");
    adaptive(&p);
    edit(
        &p,
        r#"UPDATE decisions SET detail = '{"points":[]}' WHERE id = 2"#,
    );
    assert_eq!(
        damage(&p),
        ["decisions row 2 fails its checksum (a damaged value)"]
    );
}

#[test]
fn a_deleted_appended_step_is_damage() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let p = scratch.path().join("a.gonio");
    adaptive(&p);
    // A pending step: no reading goes missing with it.
    edit(&p, "DELETE FROM steps WHERE id = 8");
    assert_eq!(
        damage(&p),
        ["8 steps stored, the schedule had 4 and 2 batch(es) added 5"]
    );
}

#[test]
fn a_deleted_decision_is_damage() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let p = scratch.path().join("a.gonio");
    adaptive(&p);
    edit(&p, "DELETE FROM decisions WHERE id = 1");
    assert_eq!(
        damage(&p),
        [
            "decisions row 2 is batch 1 (a batch's row was deleted or renumbered)",
            "batch 2 starts at step 7, not at step 4 where the steps before it end",
            "9 steps stored, the schedule had 4 and 1 batch(es) added 2",
            "3 step(s) with ids outside the schedule and its batches (0 to 5)",
        ]
    );
}

#[test]
fn a_read_only_store_sees_the_decisions() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let p = scratch.path().join("a.gonio");
    let made = adaptive(&p);
    let r = RunStore::open_read_only(&p).expect("opens read-only");
    assert_eq!(r.decisions().expect("decisions"), made);
}

#[test]
fn a_run_without_batches_has_no_decisions_table() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let p = scratch.path().join("grid.gonio");
    {
        let mut s = RunStore::create(&p, &meta(), &steps(0, 3)).expect("creates");
        s.begin_session("test").expect("session");
        s.commit(&reading(0), &[]).expect("commit");
        s.end_session("interrupted").expect("end");
    }
    let tables: Vec<String> = {
        let c = rusqlite::Connection::open(&p).expect("opens");
        let mut stmt = c
            .prepare("SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")
            .expect("query");
        stmt.query_map([], |r| r.get(0))
            .expect("rows")
            .collect::<Result<_, _>>()
            .expect("names")
    };
    assert_eq!(tables, ["events", "meta", "readings", "sessions", "steps"]);
    let s = RunStore::open(&p).expect("opens");
    assert!(s.decisions().expect("decisions").is_empty());
    assert!(s.integrity(true).expect("checks").is_intact());
    let r = RunStore::open_read_only(&p).expect("opens read-only");
    assert!(r.decisions().expect("decisions").is_empty());
}
