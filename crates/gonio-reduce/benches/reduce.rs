#![allow(missing_docs)] // criterion_group! generates undocumented functions
//! Throughput of the reduction of a simulated run, against reading the run file's
//! rows (what any reduction must at least do).
//!
//! `cargo bench -p gonio-reduce --bench reduce`; figures and the machine are in
//! BENCHMARKS.md at the repository root.

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Duration;

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use gonio_acquire::engine::{Engine, EngineConfig, Outcome};
use gonio_driver::InstrumentConfig;
use gonio_plan::Plan;
use gonio_reduce::{Options, reduce};
use gonio_run::{Inputs, RunStore};
use gonio_sim::SimBench;
/// An isotropic plan of 1 685 steps (as the acquisition bench's long plan): θi ∈ {0,
/// 30, 60}, θo = 10…80 and Δφ = 0…180 by 5°, drift references every 50 pairs, a dark
/// and an incident-beam reading.
const PLAN: &str = r#"
name = "bench: reduction"
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

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Measures PLAN on the simulator at time scale 0 into a run file in `dir`.
fn simulated_run(dir: &Path) -> RunStore {
    let (inst, inst_text) =
        InstrumentConfig::load_with_text(&root().join("config/instrument-sim.toml"))
            .expect("example instrument");
    let plan = Plan::from_toml(PLAN, Some(&root().join("config/bench-plan.toml"))).expect("plan");
    let mech = inst.mechanics().expect("mechanics");
    let prepared = gonio_plan::prepare(&mech, inst.reading_seconds(), &plan).expect("prepares");
    let mut sim = gonio_sim::SimConfig::default_config().expect("embedded sim");
    sim.seed = 7;
    let inputs = Inputs {
        instrument_text: inst_text,
        plan_text: PLAN.into(),
        sim: Some((
            gonio_sim::config::DEFAULT_SIM.into(),
            sim.sample_model_text().expect("sample"),
        )),
        seed: Some(7),
        software: "bench".into(),
        ..Inputs::default()
    };
    let store =
        gonio_run::create(&dir.join("run.gonio"), &plan, &prepared, &inputs).expect("creates");
    let (g, shared) = gonio_sim::connect(&inst, &sim).expect("sim");
    let cfg = EngineConfig {
        incident_transmittance: 1e-3,
        ..EngineConfig::default()
    };
    let engine = Engine::new(g, SimBench::new(shared, None), store, mech, cfg);
    let (report, store) = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime")
        .block_on(engine.run())
        .expect("engine runs");
    assert_eq!(report.outcome, Outcome::Complete);
    store
}

fn reduction(c: &mut Criterion) {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("gonio-reduce-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    let store = simulated_run(&dir);
    let opts = Options::default();
    let red = reduce(&store, &opts).expect("reduces");
    let n = red.samples.samples.len();
    let readings = store.readings().expect("readings").len();
    eprintln!("reduction: {n} samples from {readings} readings");
    let mut g = c.benchmark_group("reduce a simulated run");
    g.sample_size(10)
        .sampling_mode(SamplingMode::Flat)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("reduce, default options", |b| {
        b.iter(|| black_box(reduce(black_box(&store), &opts).expect("reduces")))
    });
    g.bench_function("reference: read the run's steps, readings and meta", |b| {
        b.iter(|| {
            black_box(store.run_meta().expect("meta"));
            black_box(store.steps().expect("steps"));
            black_box(store.readings().expect("readings"))
        })
    });
    g.finish();
    drop(store);
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, reduction);
criterion_main!(benches);
