//! What the benches of a complete simulated acquisition share (gonio-acquire's
//! `engine`, gonio-live's `load`, which includes this file by path): the plans, the
//! simulated instrument at time scale 0, run files made and removed, and each phase
//! of setting up a run as `gonio acquire --sim` does.

#![allow(dead_code)] // each bench uses its own part

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use gonio_acquire::engine::{Engine, EngineConfig};
use gonio_core::goniometer::Mechanics;
use gonio_driver::InstrumentConfig;
use gonio_plan::{Plan, Prepared};
use gonio_run::{Inputs, RunStore};
use gonio_sim::{SimBench, SimClock, SimConfig};

/// 3 incidence angles × 7 polar × 13 azimuthal outgoing angles, with a drift reference
/// every 50 pairs, a dark and an incident-beam reading: a few hundred steps (279).
pub const PLAN: &str = r#"
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
pub const LONG_PLAN: &str = r#"
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

/// The simulator's seed.
pub const SEED: u64 = 7;

/// An engine on the in-process simulator.
pub type SimEngine = Engine<SimClock, SimBench>;

/// The repository's root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The simulated instrument's config and its text.
pub fn instrument() -> (InstrumentConfig, String) {
    InstrumentConfig::load_with_text(&root().join("config/instrument-sim.toml"))
        .expect("example instrument")
}

/// The simulator's default config with [`SEED`], at time scale 0 (checked).
pub fn sim() -> SimConfig {
    let mut s = SimConfig::default_config().expect("embedded sim");
    s.seed = SEED;
    assert_eq!(
        s.time_scale, 0.0,
        "the bench needs the simulator at time scale 0"
    );
    s
}

/// A fresh run file path in `dir`.
pub fn fresh(dir: &Path) -> PathBuf {
    static N: AtomicU64 = AtomicU64::new(0);
    dir.join(format!("run-{}.gonio", N.fetch_add(1, Ordering::Relaxed)))
}

/// Removes a run file with its WAL and shared-memory files.
pub fn remove(path: &Path) {
    for suffix in ["", "-wal", "-shm"] {
        let mut p = path.as_os_str().to_owned();
        p.push(suffix);
        let _ = std::fs::remove_file(PathBuf::from(p));
    }
}

/// The plan checked, ordered and scheduled on the instrument.
pub fn prepare(inst: &(InstrumentConfig, String), plan_text: &str) -> (Plan, Mechanics, Prepared) {
    let plan =
        Plan::from_toml(plan_text, Some(&root().join("config/bench-plan.toml"))).expect("plan");
    let mech = inst.0.mechanics().expect("mechanics");
    let prepared = gonio_plan::prepare(&mech, inst.0.reading_seconds(), &plan).expect("prepares");
    (plan, mech, prepared)
}

/// The run file at `out`, with the simulator's config `s` recorded.
pub fn create(
    inst: &(InstrumentConfig, String),
    plan_text: &str,
    (plan, prepared): (&Plan, &Prepared),
    s: &SimConfig,
    out: &Path,
) -> RunStore {
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
    gonio_run::create(out, plan, prepared, &inputs).expect("creates")
}

/// An engine on a fresh simulator `s`, ready to measure `store`.
pub fn connect(
    inst: &(InstrumentConfig, String),
    mech: Mechanics,
    s: &SimConfig,
    store: RunStore,
) -> SimEngine {
    let (g, shared) = gonio_sim::connect(&inst.0, s).expect("sim");
    let stored = gonio_acquire::stored(&store).expect("stored");
    let cfg = EngineConfig {
        incident_transmittance: stored.transmittance,
        ..EngineConfig::default()
    };
    Engine::new(g, SimBench::new(shared, None), store, mech, cfg)
}
