#![allow(missing_docs)] // criterion_group! generates undocumented functions
//! Software overhead per point of a complete acquisition on the in-process simulator
//! at time scale 0: plan → prepared schedule → run file → engine session. The
//! simulator answers at once, so the wall time is the software's own: drivers,
//! protocol codecs, simulator, engine, and one SQLite commit (WAL,
//! `synchronous = FULL`) per step.
//!
//! `cargo bench -p gonio-acquire --bench engine -- --warm-up-time 2 --measurement-time 10`;
//! criterion times whole runs of a few hundred steps with the run file on the
//! workspace's disk (cargo's target tmp) and on /dev/shm (tmpfs, where an fsync costs
//! nothing), and the same steps through the drivers and the simulator alone. Stderr
//! gets the plan's size, a per-phase breakdown in ms per step (also for a plan of
//! ~1 700 steps, whose log SQLite checkpoints and rewinds as a long run's), and the
//! cost of the engine's per-step hand-off to tokio's blocking pool; BENCHMARKS.md
//! quotes them.

use std::hint::black_box;
use std::path::Path;
use std::time::{Duration, Instant};

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use gonio_acquire::engine::{Outcome, SessionReport, setup_for};
use gonio_driver::InstrumentConfig;
use gonio_driver::bench::Bench;
use gonio_plan::{Plan, Step};
use gonio_sim::SimBench;

#[path = "sim_run.rs"]
mod sim_run;

use sim_run::{LONG_PLAN, PLAN, SimEngine, fresh, instrument, remove, sim};

/// A directory for run files, removed when dropped: on /work's disk (cargo's target
/// tmp) or on tmpfs.
fn scratch(base: &Path) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("gonio-acquire-bench-engine-")
        .tempdir_in(base)
        .expect("scratch dir")
}

/// Wall time of each phase of one run, and what the run did.
struct Timed {
    prepare: Duration,
    create: Duration,
    connect: Duration,
    session: Duration,
    report: SessionReport,
}

impl Timed {
    fn total(&self) -> Duration {
        self.prepare + self.create + self.connect + self.session
    }
}

/// One complete acquisition into `out`, phase by phase.
fn acquire(
    rt: &tokio::runtime::Runtime,
    inst: &(InstrumentConfig, String),
    plan_text: &str,
    out: &Path,
) -> Timed {
    let t = Instant::now();
    let (plan, mech, prepared) = sim_run::prepare(inst, plan_text);
    let prepare = t.elapsed();

    let t = Instant::now();
    let s = sim();
    let store = sim_run::create(inst, plan_text, (&plan, &prepared), &s, out);
    let create = t.elapsed();

    let t = Instant::now();
    let engine: SimEngine = sim_run::connect(inst, mech, &s, store);
    let connect = t.elapsed();

    let t = Instant::now();
    let (report, store) = rt.block_on(engine.run()).expect("engine runs");
    drop(store);
    let session = t.elapsed();
    assert_eq!(report.outcome, Outcome::Complete);
    assert_eq!(report.measured, report.total);
    Timed {
        prepare,
        create,
        connect,
        session,
        report,
    }
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime")
}

/// The same steps through the drivers and the simulator alone, as the engine takes
/// them (bench set-up, start-up and homing, each move or position read-back, the
/// simulator's per-step hook, a reading, a flagged reading read again), without the
/// engine's task hand-offs and without the run file.
fn drive(inst: &InstrumentConfig, steps: &[Step], transmittance: f64) -> Duration {
    let (mut g, shared) = gonio_sim::connect(inst, &sim()).expect("sim");
    let mut bench = SimBench::new(shared, None);
    let axes = inst.mechanics().expect("mechanics").axes;
    let t = Instant::now();
    g.start().expect("starts");
    g.home().expect("homes");
    let mut setup = None;
    for (id, s) in steps.iter().enumerate() {
        let want = setup_for(s.kind, transmittance);
        if setup != Some(want) {
            bench.set_up(want).expect("bench");
            setup = Some(want);
        }
        let positions = match &s.stages {
            Some(t) => {
                let targets: Vec<(&str, f64)> = axes
                    .iter()
                    .map(String::as_str)
                    .zip(t.iter().copied())
                    .collect();
                g.motion.move_to(&targets)
            }
            None => axes.iter().map(|a| g.motion.position(a)).collect(),
        }
        .expect("moves");
        bench.at_step(id as i64, None);
        g.detector.input_changed();
        let mut r = g.detector.read().expect("reads");
        for _ in 0..2 {
            if r.is_valid() {
                break;
            }
            r = g.detector.read().expect("reads");
        }
        black_box((positions, r));
    }
    t.elapsed()
}

/// One `spawn_blocking` round trip on the engine's kind of runtime: the hand-off each
/// step makes to the blocking pool and back.
fn handoff(rt: &tokio::runtime::Runtime) -> Duration {
    let n = 20_000;
    let t = Instant::now();
    rt.block_on(async {
        for _ in 0..n {
            tokio::task::spawn_blocking(|| ()).await.expect("joins");
        }
    });
    t.elapsed() / n
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

/// Median of each phase over `n` runs of `plan_text`, printed per measured step.
fn breakdown(
    rt: &tokio::runtime::Runtime,
    inst: &(InstrumentConfig, String),
    plan_text: &str,
    n: usize,
    dir: &Path,
    label: &str,
) {
    let runs: Vec<Timed> = (0..n)
        .map(|_| {
            let out = fresh(dir);
            let t = acquire(rt, inst, plan_text, &out);
            remove(&out);
            t
        })
        .collect();
    let steps = runs[0].report.measured as f64;
    let ms = |f: fn(&Timed) -> Duration| {
        1e3 * median(runs.iter().map(f).collect()).as_secs_f64() / steps
    };
    eprintln!(
        "{steps} steps, run file on {label}: median of {n} runs, ms per step: total {:.3} \
         = plan + check + order {:.3} + create run file {:.3} + connect sim {:.3} + \
         engine session {:.3}",
        ms(Timed::total),
        ms(|t| t.prepare),
        ms(|t| t.create),
        ms(|t| t.connect),
        ms(|t| t.session),
    );
}

fn bench(c: &mut Criterion) {
    let inst = instrument();
    let rt = runtime();
    let disk = scratch(Path::new(env!("CARGO_TARGET_TMPDIR")));
    let shm = scratch(Path::new("/dev/shm"));
    let disk_label = format!("{} (disk)", disk.path().display());

    let plan = Plan::from_toml(PLAN, None).expect("plan");
    let mech = inst.0.mechanics().expect("mechanics");
    let prepared = gonio_plan::prepare(&mech, inst.0.reading_seconds(), &plan).expect("prepares");
    let transmittance = plan
        .calibration
        .incident
        .as_ref()
        .map_or(1.0, |i| i.transmittance);
    let probe = fresh(shm.path());
    let first = acquire(&rt, &inst, PLAN, &probe);
    remove(&probe);
    let steps = first.report.measured;
    assert_eq!(steps, prepared.schedule.steps.len());
    eprintln!(
        "engine plan: {} pairs, {} accepted, {steps} steps (sample, drift, dark, incident); \
         {:.2} s of instrument time per step",
        prepared.pairs.len(),
        prepared.checked.accepted.len(),
        first.report.physical_s / steps as f64,
    );
    breakdown(&rt, &inst, PLAN, 7, disk.path(), &disk_label);
    breakdown(&rt, &inst, PLAN, 7, shm.path(), "/dev/shm (tmpfs)");
    let driven = median(
        (0..7)
            .map(|_| drive(&inst.0, &prepared.schedule.steps, transmittance))
            .collect(),
    );
    eprintln!(
        "of which drivers + simulator alone, same steps: {:.3} ms per step; \
         one spawn_blocking round trip: {:.1} µs",
        1e3 * driven.as_secs_f64() / steps as f64,
        1e6 * handoff(&rt).as_secs_f64(),
    );
    breakdown(&rt, &inst, LONG_PLAN, 3, disk.path(), &disk_label);
    breakdown(&rt, &inst, LONG_PLAN, 3, shm.path(), "/dev/shm (tmpfs)");

    let mut g = c.benchmark_group("engine");
    g.sample_size(10);
    g.sampling_mode(SamplingMode::Flat);
    g.throughput(Throughput::Elements(steps as u64));
    for (name, dir) in [
        ("complete run, disk", disk.path()),
        ("complete run, tmpfs", shm.path()),
    ] {
        g.bench_function(name, |b| {
            b.iter_custom(|iters| {
                let mut total = Duration::ZERO;
                for _ in 0..iters {
                    let out = fresh(dir);
                    total += acquire(&rt, &inst, PLAN, &out).total();
                    remove(&out);
                }
                total
            })
        });
    }
    g.bench_function("drivers + simulator only", |b| {
        b.iter_custom(|iters| {
            (0..iters)
                .map(|_| drive(&inst.0, &prepared.schedule.steps, transmittance))
                .sum()
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
