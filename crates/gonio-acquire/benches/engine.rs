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
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use gonio_acquire::engine::{Engine, EngineConfig, Outcome, SessionReport, setup_for};
use gonio_driver::InstrumentConfig;
use gonio_driver::bench::Bench;
use gonio_plan::{Plan, Prepared, Step};
use gonio_run::Inputs;
use gonio_sim::{SimBench, SimClock, SimConfig};

/// 3 incidence angles × 7 polar × 13 azimuthal outgoing angles, with a drift reference
/// every 50 pairs, a dark and an incident-beam reading: a few hundred steps.
const PLAN: &str = r#"
name = "bench: isotropic, a few hundred pairs"
[points]
kind = "isotropic"
phi_i = 0
theta_i = [0, 30, 60]
theta_o = { from = 10, to = 70, step = 10 }
delta_phi = { from = 0, to = 180, step = 15 }
[drift]
every = 50
[calibration]
dark = true
incident = { transmittance = 1e-3 }
"#;

/// The same with θo up to 80° and 5° steps: 1 685 steps, long enough for SQLite to
/// checkpoint its log (after ~490 commits) and rewind it, as a long run does.
const LONG_PLAN: &str = r#"
name = "bench: isotropic, long"
[points]
kind = "isotropic"
phi_i = 0
theta_i = [0, 30, 60]
theta_o = { from = 10, to = 80, step = 5 }
delta_phi = { from = 0, to = 180, step = 5 }
[drift]
every = 50
[calibration]
dark = true
incident = { transmittance = 1e-3 }
"#;

const SEED: u64 = 7;

type SimEngine = Engine<SimClock, SimBench>;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn instrument() -> (InstrumentConfig, String) {
    InstrumentConfig::load_with_text(&root().join("config/instrument-sim.toml"))
        .expect("example instrument")
}

fn sim() -> SimConfig {
    let mut s = SimConfig::default_config().expect("embedded sim");
    s.seed = SEED;
    assert_eq!(
        s.time_scale, 0.0,
        "the bench needs the simulator at time scale 0"
    );
    s
}

/// A directory for run files, removed when dropped: on /work's disk (cargo's target
/// tmp) or on tmpfs.
fn scratch(base: &Path) -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("gonio-acquire-bench-engine-")
        .tempdir_in(base)
        .expect("scratch dir")
}

/// A fresh run file path in `dir`.
fn fresh(dir: &Path) -> PathBuf {
    static N: AtomicU64 = AtomicU64::new(0);
    dir.join(format!("run-{}.gonio", N.fetch_add(1, Ordering::Relaxed)))
}

/// Removes a run file with its WAL and shared-memory files.
fn remove(path: &Path) {
    for suffix in ["", "-wal", "-shm"] {
        let mut p = path.as_os_str().to_owned();
        p.push(suffix);
        let _ = std::fs::remove_file(PathBuf::from(p));
    }
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
    let plan =
        Plan::from_toml(plan_text, Some(&root().join("config/bench-plan.toml"))).expect("plan");
    let mech = inst.0.mechanics().expect("mechanics");
    let prepared: Prepared =
        gonio_plan::prepare(&mech, inst.0.reading_seconds(), &plan).expect("prepares");
    let prepare = t.elapsed();

    let t = Instant::now();
    let s = sim();
    let inputs = Inputs {
        instrument_text: inst.1.clone(),
        plan_text: plan_text.to_string(),
        sim: Some((
            gonio_sim::config::DEFAULT_SIM.to_string(),
            s.sample_model_text().expect("sample"),
        )),
        seed: Some(SEED),
        software: "bench".into(),
        ..Inputs::default()
    };
    let store = gonio_run::create(out, &plan, &prepared, &inputs).expect("creates");
    let create = t.elapsed();

    let t = Instant::now();
    let (g, shared) = gonio_sim::connect(&inst.0, &s).expect("sim");
    let stored = gonio_acquire::stored(&store).expect("stored");
    let cfg = EngineConfig {
        incident_transmittance: stored.transmittance,
        ..EngineConfig::default()
    };
    let engine: SimEngine = Engine::new(g, SimBench::new(shared, None), store, mech, cfg);
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
        bench.at_step(id as i64);
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
