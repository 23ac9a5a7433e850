#![allow(missing_docs)] // criterion_group! generates undocumented functions
//! The run file's costs: `RunStore::commit` (one reading, its step marked done, one
//! event, one transaction; WAL with `synchronous = FULL`) on /work's disk and on
//! /dev/shm (tmpfs), beside the disk's own sync latency; and `RunStore::open` of a
//! 10 000-step run file, which runs `PRAGMA quick_check` and verifies every row's
//! checksum.
//!
//! `cargo bench -p gonio-run --bench store -- --warm-up-time 1 --measurement-time 3`;
//! figures in BENCHMARKS.md.

use std::collections::BTreeMap;
use std::fs::OpenOptions;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use gonio_plan::schedule::{Step, StepKind};
use gonio_run::{EventRecord, ReadingRecord, RunStore, wall_now};

/// Steps in a run file the commit bench writes into (a fresh file when used up).
const COMMIT_STEPS: usize = 20_000;
/// Steps in the run file the open bench opens.
const OPEN_STEPS: usize = 10_000;

/// Where the files go: /work's disk (cargo's target tmp) and tmpfs.
fn places() -> [(&'static str, PathBuf); 2] {
    let dir = |base: &Path| {
        let d = base.join(format!("gonio-acquire-bench-store-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("scratch dir");
        d
    };
    [
        ("disk", dir(Path::new(env!("CARGO_TARGET_TMPDIR")))),
        ("tmpfs", dir(Path::new("/dev/shm"))),
    ]
}

/// Removes a run file with its WAL and shared-memory files.
fn remove(path: &Path) {
    for suffix in ["", "-wal", "-shm"] {
        let mut p = path.as_os_str().to_owned();
        p.push(suffix);
        let _ = std::fs::remove_file(PathBuf::from(p));
    }
}

/// `n` sample steps over a grid of pairs, with stage targets, as a schedule has them.
fn steps(n: usize) -> Vec<Step> {
    (0..n)
        .map(|i| {
            let (ti, to, dphi) = ((i % 6) as f64 * 15.0, (i / 6 % 9) as f64 * 10.0, i as f64);
            Step {
                kind: StepKind::Sample,
                channel: None,
                repeat: 0,
                pair: Some(PairDeg {
                    incident: SphericalDeg::new(ti, 0.0),
                    outgoing: SphericalDeg::new(to, dphi % 360.0),
                }),
                stages: Some([-ti, to, dphi % 180.0, 10.0]),
                plan_index: Some(i),
            }
        })
        .collect()
}

/// A reading of step `id` as the engine stores it.
fn reading(id: i64) -> ReadingRecord {
    let x = id as f64;
    ReadingRecord {
        step_id: id,
        commanded: Some([-30.0, 40.0 + x * 1e-3, 12.5, 10.0]),
        position: [-30.000_3, 40.000_1 + x * 1e-3, 12.499_8, 10.000_2],
        read_pair: PairDeg {
            incident: SphericalDeg::new(30.000_3, 0.0),
            outgoing: SphericalDeg::new(40.000_1, 180.0),
        },
        sensitivity: 17,
        sensitivity_v: 1e-3,
        time_constant: 8,
        time_constant_s: 0.1,
        slope_db: 24,
        r_mean: 4.5e-4 + x * 1e-9,
        r_std: 2.1e-7,
        x_mean: 4.49e-4,
        y_mean: 1.3e-6,
        n: 10,
        autorange_steps: 0,
        lias: 0,
        flags: 0,
        retries: 1,
        physical_s: 3.5 * x,
        wall_s: wall_now(),
    }
}

fn event(id: i64) -> EventRecord {
    EventRecord {
        wall_s: wall_now(),
        kind: "retry".into(),
        step_id: Some(id),
        message: "1 exchanges retried".into(),
    }
}

/// A new run file of `n` pending steps with a session begun.
fn new_store(path: &Path, n: usize) -> RunStore {
    remove(path);
    // The rows every run file has (the store refuses a file without them).
    let meta = BTreeMap::from([
        ("name".to_string(), "bench".to_string()),
        ("instrument".to_string(), "name = \"bench\"".to_string()),
        ("plan".to_string(), "name = \"bench\"".to_string()),
    ]);
    let mut s = RunStore::create(path, &meta, &steps(n)).expect("creates");
    s.begin_session("bench").expect("session");
    s
}

fn commit(c: &mut Criterion, places: &[(&'static str, PathBuf)]) {
    let mut g = c.benchmark_group("store");
    for (place, dir) in places {
        // Steady state: a long run, whose log SQLite has checkpointed and rewinds;
        // and a run's first 300 steps, whose commits grow a new log.
        for (name, steps) in [("commit", COMMIT_STEPS), ("commit, new run file", 300)] {
            let path = dir.join("commit.gonio");
            let mut store = Some(new_store(&path, steps));
            let mut next = 0i64;
            g.bench_function(BenchmarkId::new(name, place), |b| {
                b.iter_custom(|iters| {
                    let mut total = Duration::ZERO;
                    for _ in 0..iters {
                        if next as usize == steps {
                            drop(store.take());
                            store = Some(new_store(&path, steps));
                            next = 0;
                        }
                        let s = store.as_mut().expect("a store");
                        let (r, e) = (reading(next), [event(next)]);
                        let t = Instant::now();
                        s.commit(&r, &e).expect("commits");
                        total += t.elapsed();
                        next += 1;
                    }
                    total
                })
            });
            drop(store);
            remove(&path);
        }
        // The references: what the disk charges to make 4 KiB durable with `fsync`
        // (SQLite's call), the least a durable commit can cost; overwriting a block
        // of a file (as a rewound log is), and appending to a growing file (as a
        // new log is), which also commits the file system's journal.
        let file = dir.join("sync.bin");
        let f = OpenOptions::new()
            .create(true)
            .truncate(true)
            .read(true)
            .write(true)
            .open(&file)
            .expect("sync file");
        let page = [0x5au8; 4096];
        f.write_all_at(&page, 255 * 4096).expect("writes");
        f.sync_all().expect("syncs");
        let mut k = 0u64;
        g.bench_function(
            BenchmarkId::new("overwrite 4 KiB + File::sync_all", place),
            |b| {
                b.iter(|| {
                    f.write_all_at(&page, (k % 256) * 4096).expect("writes");
                    k += 1;
                    f.sync_all().expect("syncs")
                })
            },
        );
        f.set_len(0).expect("truncates");
        let mut len = 0u64;
        g.bench_function(
            BenchmarkId::new("append 4 KiB + File::sync_all", place),
            |b| {
                b.iter_custom(|iters| {
                    let mut total = Duration::ZERO;
                    for _ in 0..iters {
                        if len == 4096 * 1024 {
                            f.set_len(0).expect("truncates");
                            f.sync_all().expect("syncs");
                            len = 0;
                        }
                        let t = Instant::now();
                        f.write_all_at(&page, len).expect("writes");
                        f.sync_all().expect("syncs");
                        total += t.elapsed();
                        len += 4096;
                    }
                    total
                })
            },
        );
        drop(f);
        let _ = std::fs::remove_file(&file);
    }
    g.finish();
}

/// A run file of `OPEN_STEPS` steps: as created (no readings) or complete (every
/// step done, with its reading; one event in twenty, a retry).
fn open_file(dir: &Path, complete: bool) -> PathBuf {
    let name = if complete { "complete" } else { "created" };
    let path = dir.join(format!("open-{name}.gonio"));
    let mut s = new_store(&path, OPEN_STEPS);
    if complete {
        for id in 0..OPEN_STEPS as i64 {
            let e: &[EventRecord] = if id % 20 == 0 { &[event(id)] } else { &[] };
            s.commit(&reading(id), e).expect("commits");
        }
        s.end_session("complete").expect("ends");
    }
    drop(s);
    path
}

fn open(c: &mut Criterion, places: &[(&'static str, PathBuf)]) {
    let mut g = c.benchmark_group("store");
    g.sample_size(10);
    // Filled on tmpfs (ten thousand durable commits on the disk would take a while),
    // then copied where they are opened.
    let (_, shm) = &places[1];
    let made = [open_file(shm, false), open_file(shm, true)];
    for (place, dir) in places {
        for (kind, src) in ["created", "complete"].into_iter().zip(&made) {
            let path = dir.join(format!("open-{kind}-{place}.gonio"));
            std::fs::copy(src, &path).expect("copies");
            let size = std::fs::metadata(&path).map_or(0, |m| m.len());
            eprintln!("{kind} run file of {OPEN_STEPS} steps: {} KiB", size / 1024);
            g.bench_function(
                BenchmarkId::new(format!("open {OPEN_STEPS} steps, {kind}"), place),
                |b| b.iter(|| RunStore::open(&path).expect("opens")),
            );
            // The reference: SQLite's own structure check alone, on the same file.
            g.bench_function(
                BenchmarkId::new(format!("PRAGMA quick_check only, {kind}"), place),
                |b| {
                    b.iter(|| {
                        let conn = rusqlite::Connection::open(&path).expect("opens");
                        let ok: String = conn
                            .query_row("PRAGMA quick_check", [], |r| r.get(0))
                            .expect("checks");
                        assert_eq!(ok, "ok");
                    })
                },
            );
            remove(&path);
        }
    }
    g.finish();
    for m in &made {
        remove(m);
    }
}

fn bench(c: &mut Criterion) {
    let places = places();
    commit(c, &places);
    open(c, &places);
    for (_, dir) in &places {
        let _ = std::fs::remove_dir_all(dir);
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
