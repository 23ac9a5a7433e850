#![allow(missing_docs)] // criterion_group! generates undocumented functions
//! Software overhead per step of a spectral run on the in-process simulator at time
//! scale 0, beside the instrument time the simulator clocks for the same steps: the
//! simulated goniometer behind a simulated Cornerstone 130
//! (`config/instrument-spectral.toml`, `config/sim-spectral.toml`), a 16-wavelength
//! in-plane plan. The reference is the same plan with one band on the plain
//! simulated goniometer (`config/instrument-sim.toml`), measured in the same run.
//!
//! `cargo bench -p gonio-acquire --bench spectral -- --warm-up-time 1 --measurement-time 5`;
//! stderr gets the steps, the instrument time per step and the schedule's inner loop.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use criterion::{Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use gonio_acquire::engine::{Engine, EngineConfig, Outcome, SessionReport};
use gonio_driver::InstrumentConfig;
use gonio_plan::Plan;
use gonio_run::Inputs;
use gonio_sim::{SimBench, SimConfig};

const POINTS: &str = r#"
[points]
kind = "in-plane"
phi_i = 0
theta_i = [20, 50]
theta_o = { from = -70, to = 70, step = 10 }
[calibration]
dark = true
incident = { transmittance = 1e-3 }
"#;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// One complete run of `plan_text` on `instrument` + `sim` into a fresh file under
/// /dev/shm; its wall time and report.
fn run(instrument: &str, sim: &str, plan_text: &str) -> (Duration, SessionReport, Option<String>) {
    let dir = tempfile::Builder::new()
        .prefix("gonio-bench-spectral-")
        .tempdir_in("/dev/shm")
        .expect("tmpfs");
    let t = Instant::now();
    let (inst, inst_text) =
        InstrumentConfig::load_with_text(&root().join(instrument)).expect("instrument");
    let sim_cfg = SimConfig::load(&root().join(sim)).expect("sim");
    let plan = Plan::from_toml(plan_text, Some(&root().join("config/plan.toml"))).expect("plan");
    let mech = inst.mechanics().expect("mechanics");
    let prepared = gonio_plan::prepare(&mech, inst.reading_seconds(), &plan).expect("prepares");
    let inputs = Inputs {
        instrument_text: inst_text,
        plan_text: plan_text.into(),
        sim: Some((
            std::fs::read_to_string(root().join(sim)).expect("sim text"),
            sim_cfg.sample_model_text().expect("sample"),
        )),
        seed: Some(3),
        software: "bench".into(),
        ..Inputs::default()
    };
    let store =
        gonio_run::create(&dir.path().join("run.gonio"), &plan, &prepared, &inputs).expect("run");
    let (g, shared) = gonio_sim::connect(&inst, &sim_cfg).expect("sim");
    let stored = gonio_acquire::stored(&store).expect("stored");
    let cfg = EngineConfig {
        incident_transmittance: stored.transmittance,
        ..EngineConfig::default()
    };
    let engine = Engine::new(g, SimBench::new(shared, None), store, mech, cfg);
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime");
    let (report, store) = rt.block_on(engine.run()).expect("runs");
    drop(store);
    assert_eq!(report.outcome, Outcome::Complete);
    let reason = prepared
        .schedule
        .spectral
        .as_ref()
        .map(|s| s.reason.clone());
    (t.elapsed(), report, reason)
}

fn bench(c: &mut Criterion) {
    let spectral_plan = format!(
        "name = \"bench spectral\"\nwavelengths = {{ from = 400, to = 700, step = 20 }}\n{POINTS}"
    );
    let single_plan = format!("name = \"bench one band\"\n{POINTS}");
    let cases = [
        (
            "spectral run (16 wavelengths), per step",
            "config/instrument-spectral.toml",
            "config/sim-spectral.toml",
            spectral_plan,
        ),
        (
            "one band, per step (reference)",
            "config/instrument-sim.toml",
            "config/sim-example.toml",
            single_plan,
        ),
    ];
    let mut g = c.benchmark_group("spectral");
    g.sample_size(10);
    g.sampling_mode(SamplingMode::Flat);
    for (name, inst, sim, plan) in &cases {
        let (_, report, reason) = run(inst, sim, plan);
        eprintln!(
            "{name}: {} steps, {:.3} s of instrument time per step; {}",
            report.measured,
            report.physical_s / report.measured as f64,
            reason.as_deref().unwrap_or("one band")
        );
        g.throughput(Throughput::Elements(report.measured as u64));
        g.bench_function(*name, |b| {
            b.iter_custom(|iters| (0..iters).map(|_| run(inst, sim, plan).0).sum())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
