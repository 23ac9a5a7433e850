//! The run file: refuses what it cannot trust (newer schemas, other files, damage),
//! never overwrites a run, and commits a step all or nothing.

use std::collections::BTreeMap;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::Path;

use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use gonio_plan::schedule::{Step, StepKind};
use gonio_run::{self as store, ReadingRecord, RunStore, StoreError};

fn steps(n: usize) -> Vec<Step> {
    (0..n)
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

fn reading(step_id: i64, r: f64) -> ReadingRecord {
    ReadingRecord {
        step_id,
        commanded: Some([-30.0, step_id as f64, 90.0, 0.0]),
        position: [-30.0, step_id as f64, 90.0, -0.0],
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
        wall_s: 1.8e9,
    }
}

/// A run file of `n` steps with the first `done` measured, closed.
fn make(path: &Path, n: usize, done: usize) {
    let mut meta = BTreeMap::new();
    meta.insert("instrument".to_string(), "name = \"x\"".to_string());
    meta.insert("plan".to_string(), "name = \"p\"".to_string());
    let mut s = RunStore::create(path, &meta, &steps(n)).expect("creates");
    s.begin_session("test").expect("session");
    for i in 0..done {
        s.commit(&reading(i as i64, 1e-3 * (i + 1) as f64), &[])
            .expect("commit");
    }
    s.end_session("interrupted").expect("end");
}

#[test]
fn round_trip() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    let p = dir.join("r.gonio");
    make(&p, 5, 3);
    let s = RunStore::open(&p).expect("opens");
    let r = s.readings().expect("readings");
    assert_eq!(r.len(), 3);
    // −0.0 reads back as 0.0 (SQLite stores integral reals as integers); all else exact.
    assert_eq!(
        r[2],
        ReadingRecord {
            position: [-30.0, 2.0, 90.0, 0.0],
            ..reading(2, 3e-3)
        }
    );
    let st = s.steps().expect("steps");
    assert_eq!(st.len(), 5);
    assert_eq!(st[1].step, steps(5)[1]);
    assert_eq!(st.iter().filter(|x| x.state == "done").count(), 3, "{st:?}");
    assert_eq!(
        s.meta_value("status").expect("meta").as_deref(),
        Some("interrupted")
    );
}

#[test]
fn a_run_is_never_overwritten() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    let p = dir.join("r.gonio");
    make(&p, 2, 1);
    let e = RunStore::create(&p, &BTreeMap::new(), &steps(1)).expect_err("exists");
    assert!(matches!(e, StoreError::Exists(_)));
    assert_eq!(
        RunStore::open(&p)
            .expect("intact")
            .readings()
            .expect("r")
            .len(),
        1
    );
}

#[test]
fn a_step_is_committed_once_all_or_nothing() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    let p = dir.join("r.gonio");
    make(&p, 3, 1);
    let mut s = RunStore::open(&p).expect("opens");
    s.begin_session("test").expect("session");
    let ev = store::EventRecord {
        wall_s: 1.0,
        kind: "retry".into(),
        step_id: Some(0),
        message: "x".into(),
    };
    let e = s.commit(&reading(0, 9.0), &[ev]).expect_err("already done");
    assert!(matches!(e, StoreError::NotPending { step: 0, .. }), "{e}");
    // Neither the second reading nor its event was kept.
    assert_eq!(s.readings().expect("r")[0].r_mean, 1e-3);
    assert!(
        s.events()
            .expect("events")
            .iter()
            .all(|e| e.kind != "retry")
    );
}

#[test]
fn a_newer_schema_is_refused() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    let p = dir.join("r.gonio");
    make(&p, 2, 1);
    {
        let c = rusqlite::Connection::open(&p).expect("sqlite");
        c.pragma_update(None, "user_version", 7).expect("bump");
    }
    let e = RunStore::open(&p).expect_err("newer");
    assert!(matches!(
        e,
        StoreError::NewerSchema {
            found: 7,
            supported: 1,
            ..
        }
    ));
    assert!(
        e.to_string()
            .contains("schema version 7 is newer than this build reads (1)")
    );
    assert!(e.is_bad_input());
}

#[test]
fn other_files_are_not_run_files() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    let text = dir.join("notes.gonio");
    std::fs::write(&text, "just some text, long enough for a header\n").expect("write");
    let e = RunStore::open(&text).expect_err("text");
    assert!(matches!(e, StoreError::NotARunFile { .. }), "{e}");
    let empty = dir.join("empty.gonio");
    std::fs::write(&empty, "").expect("write");
    assert!(matches!(
        RunStore::open(&empty).expect_err("empty"),
        StoreError::NotARunFile { .. }
    ));
    let other = dir.join("other.gonio");
    {
        let c = rusqlite::Connection::open(&other).expect("sqlite");
        c.execute_batch("CREATE TABLE t (x); INSERT INTO t VALUES (1);")
            .expect("table");
    }
    let e = RunStore::open(&other).expect_err("foreign database");
    assert!(e.to_string().contains("application_id 0x00000000"), "{e}");
    assert!(matches!(
        RunStore::open(&dir.join("missing.gonio")).expect_err("missing"),
        StoreError::Missing(_)
    ));
    // Judged without being opened: a FIFO (opening it would block for ever), a device
    // that never ends, a directory.
    let fifo = dir.join("fifo.gonio");
    assert!(
        std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .expect("mkfifo runs")
            .success()
    );
    for (p, why) in [
        (fifo.as_path(), "not a regular file"),
        (Path::new("/dev/zero"), "not a regular file"),
        (dir, "a directory"),
    ] {
        let e = RunStore::open(p).expect_err("not a run");
        assert!(matches!(e, StoreError::NotARunFile { .. }), "{e}");
        assert!(e.to_string().contains(why), "{e}");
    }
}

/// Finds the 8 bytes of `x` (big-endian, as SQLite stores a REAL) in the file.
fn find_f64(bytes: &[u8], x: f64) -> Option<usize> {
    let pat = x.to_be_bytes();
    bytes.windows(8).position(|w| w == pat)
}

#[test]
fn a_damaged_value_is_detected() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    let p = dir.join("r.gonio");
    make(&p, 4, 3);
    let mut bytes = Vec::new();
    std::fs::File::open(&p)
        .and_then(|mut f| f.read_to_end(&mut bytes))
        .expect("read");
    // Change one reading's R in place: the file stays valid SQLite, only the row's
    // checksum can tell.
    let at = find_f64(&bytes, 2e-3).expect("the value is stored");
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .open(&p)
        .expect("open");
    f.seek(SeekFrom::Start(at as u64)).expect("seek");
    f.write_all(&2.5e-3f64.to_be_bytes()).expect("write");
    drop(f);
    let e = RunStore::open(&p).expect_err("damaged");
    assert!(
        e.to_string().contains("readings row 1 fails its checksum"),
        "{e}"
    );
}

#[test]
fn structural_damage_is_detected() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let dir = scratch.path();
    let p = dir.join("r.gonio");
    make(&p, 200, 150);
    let len = std::fs::metadata(&p).expect("meta").len();
    // Overwrite a page in the middle with garbage.
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .open(&p)
        .expect("open");
    f.seek(SeekFrom::Start(len / 2)).expect("seek");
    f.write_all(&[0xA5; 4096]).expect("write");
    drop(f);
    let e = RunStore::open(&p).expect_err("damaged");
    assert!(matches!(e, StoreError::Corrupt { .. }), "{e}");
    // A truncated file.
    let q = dir.join("t.gonio");
    make(&q, 200, 150);
    let f = std::fs::OpenOptions::new()
        .write(true)
        .open(&q)
        .expect("open");
    f.set_len(len / 3).expect("truncate");
    drop(f);
    let e = RunStore::open(&q).expect_err("truncated");
    assert!(matches!(e, StoreError::Corrupt { .. }), "{e}");
}

#[test]
fn utc_dates() {
    assert_eq!(store::utc(0.0), "1970-01-01T00:00:00Z");
    assert_eq!(store::utc(951_782_400.0), "2000-02-29T00:00:00Z");
    assert_eq!(store::utc(1_795_305_599.5), "2026-11-21T23:59:59Z");
}

/// Runs SQL on the file behind Gonio's back, as an editor or a damaged disk would.
fn edit(path: &Path, sql: &str) {
    let c = rusqlite::Connection::open(path).expect("opens");
    c.execute_batch(sql).expect("edits");
}

#[test]
fn a_deleted_reading_is_found_and_its_step_reopened_for_measuring_again() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let p = scratch.path().join("r.gonio");
    make(&p, 5, 4);
    assert!(
        RunStore::open(&p)
            .expect("intact")
            .integrity(true)
            .expect("checks")
            .is_intact()
    );
    edit(&p, "DELETE FROM readings WHERE step_id = 2");
    let e = RunStore::open(&p).expect_err("a reading is gone");
    assert_eq!(
        e.to_string(),
        format!(
            "{}: corrupted: 1 committed reading(s) missing (steps 2); `gonio resume` measures \
             them again",
            p.display()
        )
    );
    // Hidden better: the step put back to pending too. It was attempted once.
    edit(&p, "UPDATE steps SET state = 'pending' WHERE id = 2");
    let mut s = RunStore::open_unverified(&p).expect("opens");
    let found = s.integrity(false).expect("checks");
    assert_eq!(found.missing, vec![2]);
    assert!(found.damage.is_empty(), "{:?}", found.damage);
    assert_eq!(found.readings, 3);
    assert_eq!(s.reopen_missing().expect("reopens"), vec![2]);
    let ev = s.events().expect("events");
    let last = ev.last().expect("an event");
    assert_eq!((last.kind.as_str(), last.step_id), ("remeasure", Some(2)));
    // Measured again: intact, with all five counted.
    s.begin_session("test").expect("session");
    s.commit(&reading(2, 3e-3), &[]).expect("commit");
    s.commit(&reading(4, 5e-3), &[]).expect("commit");
    s.end_session("complete").expect("end");
    drop(s);
    let s = RunStore::open(&p).expect("intact again");
    let found = s.integrity(true).expect("checks");
    assert!(
        found.is_intact() && found.recorded && found.readings == 5,
        "{found:?}"
    );
}

#[test]
fn a_replaced_reading_an_edited_config_and_a_lost_meta_row_are_found() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let (a, b) = (
        scratch.path().join("a.gonio"),
        scratch.path().join("b.gonio"),
    );
    make(&a, 4, 3);
    // The same steps, other values: a row with a valid checksum but not the one
    // committed.
    {
        let mut meta = BTreeMap::new();
        meta.insert("instrument".to_string(), "name = \"x\"".to_string());
        meta.insert("plan".to_string(), "name = \"p\"".to_string());
        let mut s = RunStore::create(&b, &meta, &steps(4)).expect("creates");
        s.begin_session("test").expect("session");
        s.commit(&reading(1, 7e-3), &[]).expect("commit");
    }
    edit(
        &a,
        &format!(
            "ATTACH '{}' AS b; DELETE FROM readings WHERE step_id = 1; \
             INSERT INTO readings SELECT * FROM b.readings WHERE step_id = 1;",
            b.display()
        ),
    );
    let e = RunStore::open(&a).expect_err("replaced");
    assert!(
        e.to_string()
            .contains("the readings differ from those committed"),
        "{e}"
    );
    // An edited config.
    let c = scratch.path().join("c.gonio");
    make(&c, 4, 3);
    edit(
        &c,
        "UPDATE meta SET value = 'name = \"y\"' WHERE key = 'instrument'",
    );
    let e = RunStore::open(&c).expect_err("edited");
    assert!(
        e.to_string()
            .contains("the metadata (configs, seed, geometry) differ"),
        "{e}"
    );
    // A required meta row gone: named, and a runtime fault (exit 1).
    let d = scratch.path().join("d.gonio");
    make(&d, 4, 3);
    edit(&d, "DELETE FROM meta WHERE key = 'status'");
    let e = RunStore::open(&d).expect_err("no status");
    assert!(
        matches!(e, StoreError::MissingMeta { ref key, .. } if key == "status"),
        "{e}"
    );
    assert!(!e.is_bad_input());
}

#[test]
fn a_file_from_before_the_integrity_record_still_opens_and_gets_one_when_resumed() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let p = scratch.path().join("old.gonio");
    make(&p, 4, 2);
    edit(
        &p,
        "DELETE FROM meta WHERE key IN ('integrity_meta', 'integrity_readings')",
    );
    let mut s = RunStore::open(&p).expect("an old file opens");
    let found = s.integrity(true).expect("checks");
    assert!(found.is_intact() && !found.recorded, "{found:?}");
    s.begin_session("test").expect("session");
    s.commit(&reading(2, 3e-3), &[]).expect("commit");
    drop(s);
    let found = RunStore::open(&p)
        .expect("opens")
        .integrity(true)
        .expect("checks");
    assert!(
        found.is_intact() && found.recorded && found.readings == 3,
        "{found:?}"
    );
}

#[test]
fn one_process_at_a_time_holds_a_run_and_a_dead_one_holds_nothing() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let p = scratch.path().join("r.gonio");
    make(&p, 4, 1);
    let mut first = RunStore::open(&p).expect("opens");
    first.lock().expect("locks");
    let lock_file = scratch.path().join("r.gonio.lock");
    assert_eq!(
        std::fs::read_to_string(&lock_file)
            .expect("lock file")
            .trim(),
        std::process::id().to_string()
    );
    first.begin_session("gonio test").expect("session");
    let mut second = RunStore::open(&p).expect("a reader opens");
    let e = second.lock().expect_err("held");
    assert!(matches!(e, StoreError::Busy { .. }), "{e}");
    assert!(
        e.to_string().contains(&format!(
            "process {} (gonio test, session started",
            std::process::id()
        )),
        "{e}"
    );
    drop(first);
    assert!(!lock_file.exists(), "released and removed");
    second.lock().expect("free again");
    drop(second);
    // A lock file left by a killed process (no one holds its lock) is no obstacle.
    std::fs::write(&lock_file, "999999\n").expect("stale");
    let mut third = RunStore::open(&p).expect("opens");
    third.lock().expect("a stale lock file does not block");
}

/// The names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .expect("lists")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn a_read_only_open_writes_nothing_into_the_file_or_beside_it() {
    let scratch = tempfile::tempdir().expect("temp dir");
    // A name an SQLite URI would misread unless encoded.
    let dir = scratch.path().join("a ?#%dir");
    std::fs::create_dir(&dir).expect("dir");
    let p = dir.join("r?x#1%.gonio");
    make(&p, 5, 3);
    let before = std::fs::read(&p).expect("reads");
    let listed = names(&dir);
    assert_eq!(listed, ["r?x#1%.gonio"], "a closed run leaves no log");
    {
        let mut s = RunStore::open_read_only(&p).expect("opens read-only");
        assert_eq!(s.readings().expect("readings").len(), 3);
        let found = s.integrity(true).expect("checks");
        assert!(found.is_intact(), "{found:?}");
        let e = s.begin_session("test");
        assert!(e.is_err(), "a read-only store cannot write");
    }
    assert_eq!(std::fs::read(&p).expect("reads"), before, "bytes unchanged");
    assert_eq!(names(&dir), listed, "no -wal, -shm or lock file made");
}

#[test]
fn a_read_only_open_sees_a_live_run_at_its_last_commit() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let p = scratch.path().join("live.gonio");
    make(&p, 6, 2);
    let mut writer = RunStore::open(&p).expect("opens");
    writer.lock().expect("locks");
    writer.begin_session("test").expect("session");
    writer.commit(&reading(2, 3e-3), &[]).expect("commit");
    // The writer's log holds the third reading.
    let r = RunStore::open_read_only(&p).expect("a reader opens");
    assert_eq!(r.readings().expect("readings").len(), 3);
    writer.commit(&reading(3, 4e-3), &[]).expect("commit");
    assert_eq!(r.readings().expect("readings").len(), 4, "and the next");
}

#[test]
fn a_reader_following_a_run_sees_each_new_reading_and_event_once() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let p = scratch.path().join("r.gonio");
    let mut meta = BTreeMap::new();
    meta.insert("instrument".to_string(), "name = \"x\"".to_string());
    meta.insert("plan".to_string(), "name = \"p\"".to_string());
    let mut w = RunStore::create(&p, &meta, &steps(4)).expect("creates");
    let s1 = w.begin_session("test").expect("session");
    let at = |i: i64, wall: f64| ReadingRecord {
        wall_s: wall,
        ..reading(i, 1e-3)
    };
    w.commit(&at(0, 100.0), &[]).expect("commit");
    w.event("bench", Some(0), "dark").expect("event");
    // A reader opened while the writer holds the run.
    let r = RunStore::open_read_only(&p).expect("reader");
    let first = r.readings_since(f64::NEG_INFINITY).expect("since");
    assert_eq!(first.len(), 1);
    assert_eq!((first[0].0, first[0].1.step_id), (s1, 0));
    let events = r.events_after(0).expect("events");
    let last_id = events.last().expect("an event").0;
    assert!(
        events
            .iter()
            .any(|(_, e)| e.kind == "bench" && e.message == "dark")
    );
    w.commit(&at(1, 101.0), &[]).expect("commit");
    w.commit(&at(2, 102.0), &[]).expect("commit");
    w.event("fault", Some(1), "lost reply").expect("event");
    let next = r.readings_since(100.0).expect("since");
    let ids: Vec<i64> = next.iter().map(|(_, x)| x.step_id).collect();
    assert_eq!(ids, [1, 2]);
    let new: Vec<String> = r
        .events_after(last_id)
        .expect("events")
        .into_iter()
        .map(|(_, e)| e.kind)
        .collect();
    assert_eq!(new, ["fault"]);
    assert!(r.readings_since(102.0).expect("since").is_empty());
    // The writer measures into it; the reader says who (this process).
    w.lock().expect("locks");
    assert_eq!(r.measured_by(), Some(std::process::id()));
    drop(w);
    assert_eq!(r.measured_by(), None);
}

#[test]
fn flag_bits_are_named() {
    use gonio_run::flags;
    assert_eq!(flags::text(0), "");
    assert_eq!(
        flags::text(flags::UNLOCK | flags::SHADOWED),
        "unlock, shadowed"
    );
}

#[test]
fn a_reader_of_a_finished_run_knows_when_a_writer_starts_on_it() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let p = scratch.path().join("r.gonio");
    make(&p, 4, 2);
    // Closed cleanly: no log beside it, so the reader opens it immutable.
    let r = RunStore::open_read_only(&p).expect("reader");
    assert!(!r.is_outdated());
    let mut w = RunStore::open(&p).expect("writer");
    w.begin_session("resume").expect("session");
    w.commit(&reading(2, 3e-3), &[]).expect("commit");
    // The immutable reader does not see the new reading: it must reopen.
    assert!(r.is_outdated());
    assert_eq!(r.readings().expect("readings").len(), 2);
    let again = RunStore::open_read_only(&p).expect("reopens");
    assert!(!again.is_outdated());
    assert_eq!(again.readings().expect("readings").len(), 3);
}
