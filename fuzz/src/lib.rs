//! The bodies of the loader targets: every TOML file a user writes (instrument config,
//! simulator config, plan, model file, surface file) and the run file. None may panic
//! on any input.
//!
//! A TOML target reads its input one of two ways, chosen by the first byte:
//!
//! - even: the rest of the bytes as the file's text (invalid UTF-8 replaced), for
//!   the parser and whatever it lets through;
//! - odd: a shipped file from `config/` (chosen by the second byte) with hostile
//!   changes made by `gonio_core::fuzz::mutate` (a number made `nan`, `inf`, `-0`,
//!   `1e308`, a huge integer; a line deleted, repeated or moved; a BOM; the file cut
//!   short), seeded by the rest eight bytes at a time. Random bytes seldom make a
//!   valid config, so this mode is what reaches the validation and the code behind it.
//!
//! Files named by the inputs (a plan's directions file, a sample's model or table, a
//! surface's height map) resolve against a directory that does not exist, so the
//! targets read nothing but their input.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Duration;

use gonio_brdf::{Brdf, Model};
use gonio_core::{Dir, DirPair, SphericalDeg};

/// Where the inputs' relative paths lead: nowhere.
const NOWHERE: &str = "/nonexistent-gonio-fuzz";

/// The shipped instrument configs.
pub const INSTRUMENTS: &[&str] = &[
    include_str!("../../config/instrument-example.toml"),
    include_str!("../../config/instrument-sim.toml"),
    include_str!("../../config/instrument-spectral.toml"),
];

/// The shipped simulator config.
pub const SIMS: &[&str] = &[
    include_str!("../../config/sim-example.toml"),
    include_str!("../../config/sim-spectral.toml"),
];

/// The shipped plans.
pub const PLANS: &[&str] = &[
    include_str!("../../config/plan-hemisphere.toml"),
    include_str!("../../config/plan-in-plane.toml"),
    include_str!("../../config/plan-list.toml"),
];

/// The shipped model files.
pub const MODELS: &[&str] = &[
    include_str!("../../config/models/blinn-phong-plastic.toml"),
    include_str!("../../config/models/blue-paint-550nm.toml"),
    include_str!("../../config/models/cook-torrance-gold.toml"),
    include_str!("../../config/models/lafortune-fig9.toml"),
    include_str!("../../config/models/minnaert-matte.toml"),
    include_str!("../../config/models/oren-nayar-plaster.toml"),
    include_str!("../../config/models/phong-fig7.toml"),
    include_str!("../../config/models/phong-shading.toml"),
    include_str!("../../config/models/ward-brushed.toml"),
    include_str!("../../config/models/white-reference.toml"),
];

/// The shipped surface files.
pub const SURFACES: &[&str] = &[
    include_str!("../../config/micro-brushed-aluminium.toml"),
    include_str!("../../config/micro-gaussian-gold.toml"),
    include_str!("../../config/micro-sawtooth-deyoung.toml"),
];

/// The text a TOML target reads (module docs).
pub fn text(data: &[u8], shipped: &[&str]) -> String {
    match data.split_first() {
        None => String::new(),
        Some((mode, rest)) if mode % 2 == 0 => String::from_utf8_lossy(rest).into_owned(),
        Some((_, rest)) => {
            let (pick, seeds) = rest.split_first().unwrap_or((&0, &[]));
            let base = shipped[usize::from(*pick) % shipped.len()];
            let seeds: Vec<u64> = seeds
                .chunks(8)
                .map(|c| {
                    let mut b = [0u8; 8];
                    b[..c.len()].copy_from_slice(c);
                    u64::from_le_bytes(b)
                })
                .collect();
            gonio_core::fuzz::mutate(base, &seeds)
        }
    }
}

fn file(name: &str) -> PathBuf {
    Path::new(NOWHERE).join(name)
}

fn pair(ti: f64, pi: f64, to: f64, po: f64) -> DirPair {
    DirPair::new(
        Dir::from(SphericalDeg::new(ti, pi)),
        Dir::from(SphericalDeg::new(to, po)),
    )
}

/// Direction pairs at the corners of the hemisphere and in between.
fn pairs() -> [DirPair; 4] {
    [
        pair(0.0, 0.0, 0.0, 0.0),
        pair(30.0, 0.0, 45.0, 180.0),
        pair(89.0, 90.0, 10.0, -45.0),
        pair(90.0, 0.0, 90.0, 180.0),
    ]
}

/// An instrument config: parsed and validated; if accepted, its policy, ports,
/// reading time and mechanics, the mechanics checking pairs, and the SMC100 chain,
/// SR830 driver and band selector (Cornerstone 130, FW102C) built from it.
pub fn instrument_config(data: &[u8]) {
    use gonio_driver::smc100::Smc100Chain;
    use gonio_driver::sr830::Sr830;
    use gonio_driver::{InstrumentConfig, ManualClock, ScriptedTransport};

    let text = text(data, INSTRUMENTS);
    let c = match InstrumentConfig::from_toml(&text, Some(&file("instrument.toml"))) {
        Ok(c) => c,
        Err(e) => {
            let _ = e.to_string();
            return;
        }
    };
    let _ = (c.motion.policy(), c.motion.serial(), c.detector.serial());
    let _ = (c.stages(), c.reading_seconds());
    if let Ok(m) = c.mechanics() {
        for p in pairs() {
            let _ = m.accept(p);
        }
    }
    let clock = ManualClock::new();
    let (t, _) = ScriptedTransport::new(b'\r', 64, clock.clone());
    let chain = Smc100Chain::new(t, clock.clone(), c.motion.smc100_axes(), c.motion.policy());
    assert!(
        chain.is_ok(),
        "an accepted config's axes: {:?}",
        chain.err()
    );
    let (t, _) = ScriptedTransport::new(b'\r', 64, clock.clone());
    let lockin = Sr830::new(t, clock.clone(), c.detector.lockin.clone());
    assert!(
        lockin.is_ok(),
        "an accepted config's lock-in: {:?}",
        lockin.err()
    );
    let _ = (
        c.wavelength_timing(),
        c.check_bands(&[450.0, 550.0, 1500.0]),
    );
    if let Some(m) = &c.monochromator {
        let (t, _) = ScriptedTransport::new(b'\n', 64, clock.clone());
        let mono = gonio_driver::cs130::Cs130::new(t, clock.clone(), m.cs130.clone());
        assert!(
            mono.is_ok(),
            "an accepted config's monochromator: {:?}",
            mono.err()
        );
    }
    if let Some(w) = &c.filter_wheel {
        let (t, _) = ScriptedTransport::new(b'\r', 64, clock.clone());
        let wheel = gonio_driver::fw102c::Fw102c::new(t, clock, w.fw102c.clone());
        assert!(
            wheel.is_ok(),
            "an accepted config's filter wheel: {:?}",
            wheel.err()
        );
    }
}

/// A simulator config: parsed and validated; if accepted (with the embedded sample,
/// the only one it can load here), the instrument built from it answering a homing,
/// a move, position and state queries and lock-in readings.
pub fn sim_config(data: &[u8]) {
    use gonio_sim::{SimClock, SimConfig, SimInstrument};

    let text = text(data, SIMS);
    let cfg = match SimConfig::from_toml(&text, Some(&file("sim.toml"))) {
        Ok(c) => c,
        Err(e) => {
            let _ = e.to_string();
            return;
        }
    };
    let addrs = cfg.role_addresses();
    assert!(addrs.is_ok(), "validated: {addrs:?}");
    let Ok(mut sim) = SimInstrument::new(&cfg, SimClock::driven(0.0)) else {
        return;
    };
    let a = addrs.unwrap_or_default()[0];
    let _ = sim.motion_bytes(format!("{a}OR\r\n").as_bytes());
    sim.clock().advance(Duration::from_secs(100));
    let _ = sim.motion_bytes(format!("{a}PA10\r\n").as_bytes());
    sim.clock().advance(Duration::from_secs(100));
    let _ = sim.motion_bytes(format!("{a}TP\r\n{a}TS\r\n").as_bytes());
    let _ = sim.lockin_bytes(b"*IDN?\nOUTX 0\nSNAP?1,2\n");
    sim.clock().advance(Duration::from_secs(1));
    let _ = sim.lockin_bytes(b"SNAP?1,2\nLIAS?\n");
    // A band selector, when the config has one (nothing happens otherwise).
    let _ = sim.port_bytes(
        gonio_sim::Port::Monochromator,
        b"FILTER 3\r\nGOWAVE 650\r\n*WAI\r\nWAVE?\r\n",
    );
    let _ = sim.port_bytes(gonio_sim::Port::FilterWheel, b"pos=2\rpos?\r");
    sim.clock().advance(Duration::from_secs(30));
    let _ = sim.spectrum_at(sim.clock().seconds());
    let _ = sim.signal(sim.clock().seconds());
}

/// The simulated instrument as planning sees it.
fn mechanics() -> &'static gonio_plan::Mechanics {
    static M: OnceLock<gonio_plan::Mechanics> = OnceLock::new();
    M.get_or_init(|| {
        let c = gonio_driver::InstrumentConfig::from_toml(INSTRUMENTS[1], None)
            .unwrap_or_else(|e| panic!("the shipped simulated instrument: {e}"));
        c.mechanics()
            .unwrap_or_else(|e| panic!("the shipped simulated instrument: {e}"))
    })
}

/// A plan: parsed and validated; if accepted, expanded and (up to 20 000 pairs, so
/// that an input runs in milliseconds) prepared on the simulated instrument with the
/// ordering off (its wall-time budget is no part of the target).
pub fn plan(data: &[u8]) {
    let text = text(data, PLANS);
    let mut plan = match gonio_plan::Plan::from_toml(&text, Some(&file("plan.toml"))) {
        Ok(p) => p,
        Err(e) => {
            let _ = e.to_string();
            return;
        }
    };
    plan.order.optimise = false;
    let Ok(pairs) = plan.pairs() else { return };
    assert!(pairs.len() <= gonio_plan::plan::MAX_POINTS);
    if pairs.len() <= 20_000 {
        let _ = gonio_plan::prepare(mechanics(), 1.0, &plan);
    }
}

/// A model file: parsed and validated; if accepted, evaluated at pairs over the
/// hemisphere, and written to a file that reads back to the same model.
pub fn model_file(data: &[u8]) {
    let text = text(data, MODELS);
    let m = match Model::from_toml(&text, Some(&file("model.toml"))) {
        Ok(m) => m,
        Err(e) => {
            let _ = e.to_string();
            return;
        }
    };
    let mut out = vec![0.0; m.channels().len()];
    for p in pairs() {
        m.eval(p.wi, p.wo, &mut out);
        m.mirror(p.wi, &mut out);
    }
    let back = Model::from_toml(&m.to_toml(), None);
    assert_eq!(back.as_ref(), Ok(&m), "a written model reads back");
}

/// A surface file (`gonio micro`): parsed, validated and its height field built.
pub fn surface(data: &[u8]) {
    let text = text(data, SURFACES);
    if let Err(e) = gonio_micro::Sample::from_toml(&text, Some(&file("surface.toml"))) {
        let _ = e.to_string();
    }
}

/// A small, valid run file (schedule, metadata, a session), as bytes.
fn seed_run() -> &'static [u8] {
    static RUN: OnceLock<Vec<u8>> = OnceLock::new();
    RUN.get_or_init(|| {
        use gonio_plan::schedule::{Step, StepKind};
        let dir = tempfile::tempdir().expect("a temporary directory");
        let path = dir.path().join("seed.gonio");
        let steps: Vec<Step> = (0..3)
            .map(|i| Step {
                kind: StepKind::Sample,
                channel: None,
                repeat: 0,
                pair: Some(gonio_core::dirfile::PairDeg {
                    incident: SphericalDeg::new(30.0, 0.0),
                    outgoing: SphericalDeg::new(f64::from(i) * 10.0, 180.0),
                }),
                stages: Some([-30.0, f64::from(i) * 10.0, 90.0, 0.0]),
                plan_index: Some(i as usize),
            })
            .collect();
        let mut meta = std::collections::BTreeMap::new();
        meta.insert("instrument".to_string(), INSTRUMENTS[1].to_string());
        meta.insert("plan".to_string(), PLANS[1].to_string());
        let mut s = gonio_run::RunStore::create(&path, &meta, &steps).expect("creates");
        s.begin_session("fuzz").expect("session");
        s.end_session("interrupted").expect("session end");
        drop(s);
        std::fs::read(&path).expect("reads")
    })
}

/// A run file: the bytes (first byte even), or a valid run file with the rest of the
/// bytes as edits `(offset: u32 LE, byte)` (first byte odd), written to a file and
/// opened as every reader opens it; if it opens, its metadata, steps, readings,
/// events and sessions read and it summarises, and the processing commands' opening
/// (which reduces it) ends in a dataset or an error, never a panic.
pub fn run_file(data: &[u8]) {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    let dir = DIR.get_or_init(|| tempfile::tempdir().expect("a temporary directory"));
    let bytes = match data.split_first() {
        None => Vec::new(),
        Some((mode, rest)) if mode % 2 == 0 => rest.to_vec(),
        Some((_, rest)) => {
            let mut b = seed_run().to_vec();
            for e in rest.chunks_exact(5) {
                let at = u32::from_le_bytes([e[0], e[1], e[2], e[3]]) as usize;
                let len = b.len();
                b[at % len] = e[4];
            }
            b
        }
    };
    let path = dir.path().join("run.gonio");
    for extra in ["-journal", "-wal", "-shm"] {
        let _ = std::fs::remove_file(dir.path().join(format!("run.gonio{extra}")));
    }
    std::fs::write(&path, &bytes).expect("writes the input");
    // What `gonio verify` does: every check, whatever the damage.
    if let Ok(s) = gonio_run::RunStore::open_unverified(&path)
        && let Ok(found) = s.integrity(true)
    {
        let _ = (found.faults(), found.is_intact());
        let _ = s.refuse_unless_intact(&found);
    }
    match gonio_run::RunStore::open(&path) {
        Ok(s) => {
            let _ = (s.run_meta(), s.meta(), s.steps(), s.readings());
            let _ = (
                s.events(),
                s.sessions(),
                s.session_readings(),
                s.state_counts(),
            );
            let _ = gonio_run::summary(&s);
        }
        Err(e) => {
            let _ = (e.to_string(), e.is_bad_input());
        }
    }
    match gonio_dataset::open(&path, &gonio_dataset::OpenOptions::default()) {
        Ok(o) => {
            let _ = o.data.channels();
        }
        Err(e) => {
            let _ = (e.to_string(), e.is_bad_input());
        }
    }
}
