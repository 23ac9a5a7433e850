//! Shared set-up of the acquisition tests: the simulated instrument of
//! `config/instrument-sim.toml` and `config/sim-example.toml`, plans from text.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

use gonio_acquire::engine::{Engine, EngineConfig, SessionReport};
use gonio_driver::InstrumentConfig;
use gonio_plan::{Plan, Prepared};
use gonio_run::{Inputs, RunStore};
use gonio_sim::{SharedSim, SimBench, SimConfig};

/// The repository's root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The simulated instrument's config.
pub fn instrument() -> (InstrumentConfig, String) {
    let path = root().join("config/instrument-sim.toml");
    InstrumentConfig::load_with_text(&path).expect("example instrument")
}

/// The simulator's default config, with `seed`.
pub fn sim(seed: u64) -> SimConfig {
    let mut s = SimConfig::default_config().expect("embedded sim");
    s.seed = seed;
    s
}

/// A plan from text, anchored in `config/` (for relative paths).
pub fn plan(text: &str) -> Plan {
    Plan::from_toml(text, Some(&root().join("config/test-plan.toml"))).expect("valid plan")
}

/// A fresh directory for run files, removed when dropped.
pub fn scratch() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

/// An instrument and its simulator: config files under `config/`.
#[derive(Clone, Copy)]
pub struct Setup {
    pub instrument: &'static str,
    /// `None`: the embedded default simulator.
    pub sim: Option<&'static str>,
}

/// `config/instrument-sim.toml` on the embedded simulator.
pub const DEFAULT: Setup = Setup {
    instrument: "config/instrument-sim.toml",
    sim: None,
};

/// The mixed-family instrument: SMC100 arms, a KDC101 and a K10CR1 on APT lines, a
/// K6485.
pub const MIXED: Setup = Setup {
    instrument: "config/instrument-mixed.toml",
    sim: Some("config/sim-mixed.toml"),
};

impl Setup {
    fn instrument(self) -> (InstrumentConfig, String) {
        InstrumentConfig::load_with_text(&root().join(self.instrument)).expect("instrument")
    }

    fn sim(self, seed: u64) -> (SimConfig, String) {
        let (mut s, text) = match self.sim {
            None => (
                SimConfig::default_config().expect("embedded sim"),
                gonio_sim::config::DEFAULT_SIM.to_string(),
            ),
            Some(p) => {
                let path = root().join(p);
                let text = std::fs::read_to_string(&path).expect("sim text");
                (SimConfig::load(&path).expect("sim config"), text)
            }
        };
        s.seed = seed;
        (s, text)
    }
}

/// Prepares `plan` and creates its run file at `out`.
pub fn create(out: &Path, plan: &Plan, plan_text: &str, seed: u64) -> (RunStore, Prepared) {
    create_on(DEFAULT, out, plan, plan_text, seed)
}

/// Prepares `plan` for `setup` and creates its run file at `out`.
pub fn create_on(
    setup: Setup,
    out: &Path,
    plan: &Plan,
    plan_text: &str,
    seed: u64,
) -> (RunStore, Prepared) {
    let (inst, inst_text) = setup.instrument();
    let mech = inst.mechanics().expect("mechanics");
    let prepared = gonio_plan::prepare(&mech, inst.reading_seconds(), plan).expect("prepares");
    let (s, sim_text) = setup.sim(seed);
    let inputs = Inputs {
        instrument_text: inst_text,
        plan_text: plan_text.to_string(),
        sim: Some((sim_text, s.sample_model_text().expect("sample"))),
        seed: Some(seed),
        software: "test".into(),
        ..Inputs::default()
    };
    let store = gonio_run::create(out, plan, &prepared, &inputs).expect("creates");
    (store, prepared)
}

/// An engine on a fresh simulator for `store`.
pub fn engine(
    store: RunStore,
    seed: u64,
    tweak: impl FnOnce(&mut SimConfig),
) -> (Engine<gonio_sim::SimClock, SimBench>, SharedSim) {
    engine_on(DEFAULT, store, seed, tweak)
}

/// An engine on a fresh simulator of `setup` for `store`.
pub fn engine_on(
    setup: Setup,
    store: RunStore,
    seed: u64,
    tweak: impl FnOnce(&mut SimConfig),
) -> (Engine<gonio_sim::SimClock, SimBench>, SharedSim) {
    let (inst, _) = setup.instrument();
    let (mut s, _) = setup.sim(seed);
    tweak(&mut s);
    let (g, shared) = gonio_sim::connect(&inst, &s).expect("sim");
    let mech = inst.mechanics().expect("mechanics");
    let stored = gonio_acquire::stored(&store).expect("stored");
    let bench = SimBench::new(shared.clone(), None);
    let cfg = EngineConfig {
        incident_transmittance: stored.transmittance,
        ..EngineConfig::default()
    };
    (Engine::new(g, bench, store, mech, cfg), shared)
}

/// Runs one session to its end.
pub fn run_session(engine: Engine<gonio_sim::SimClock, SimBench>) -> (SessionReport, RunStore) {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime")
        .block_on(engine.run())
        .expect("engine runs")
}
