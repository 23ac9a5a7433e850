//! The planner's time of each part of a run against the simulated instrument's clock
//! (`config/instrument-sim.toml` on `config/sim-example.toml`), the real drivers doing
//! the work: the start-up and homing, moves and position reads
//! (`Mechanics::move_s`), a fixed reading (`Sr830Config::read_s`) and the range
//! changes autoranging makes on its way to a signal (`ranging::fixed_changes`).

use std::path::Path;

use gonio_driver::InstrumentConfig;
use gonio_driver::sr830::{Sensitivity, ranging, timing};
use gonio_sim::{LightPath, SimConfig, lock};

fn cfgs() -> (InstrumentConfig, SimConfig) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config");
    (
        InstrumentConfig::load(&root.join("instrument-sim.toml")).expect("instrument config"),
        SimConfig::load(&root.join("sim-example.toml")).expect("sim config"),
    )
}

#[test]
fn start_up_moves_and_readings_take_what_the_planner_says() {
    let (icfg, scfg) = cfgs();
    let mech = icfg.mechanics().expect("mechanics");
    let (mut g, sim) = gonio_sim::connect(&icfg, &scfg).expect("connects");
    let now = || lock(&sim).clock().seconds();

    // Start-up: identification, the lock-in's set-up, every axis homed from where the
    // simulator stands it.
    let t0 = now();
    g.start().expect("starts");
    g.home().expect("homes");
    let search = |a: &gonio_driver::smc100::AxisConfig| {
        let c = scfg.controller(a.address);
        gonio_driver::smc100::timing::home_search_s(
            c.start_position,
            c.home_switch,
            c.home_velocity,
            c.acceleration.min(c.max_acceleration),
        )
    };
    let (took, planned) = (now() - t0, icfg.startup_seconds(&search));
    // The detector arm's search from −40° at 10 °/s is most of it.
    assert!(planned > 4.1 && planned < 4.8, "{planned}");
    assert!(
        (took - planned).abs() < 0.005,
        "took {took} s, planned {planned} s"
    );

    // Moves: short and long, one axis and all four, and one that goes nowhere.
    let axes = mech.axes.clone();
    let mut at = [0.0; 4];
    for to in [
        [10.0, -20.0, 0.0, 0.0],
        [10.0, -20.0, 0.0, 0.0],
        [11.0, -19.0, 15.0, 5.0],
        [-60.0, 75.0, 90.0, 40.0],
        [-60.0, 75.0, 92.0, 40.0],
    ] {
        let targets: Vec<(&str, f64)> = axes.iter().map(String::as_str).zip(to).collect();
        let t = now();
        g.motion.move_to(&targets).expect("moves");
        let (took, planned) = (now() - t, mech.move_s(&at, Some(&to)));
        // The model writes positions and times of a typical length: the real lines'
        // numbers are a few characters longer or shorter (0.17 ms each at 57 600 baud).
        assert!(
            (took - planned).abs() < 0.015,
            "{at:?} → {to:?}: took {took} s, planned {planned} s"
        );
        at = to;
    }
    // A step without stages (a dark reading) reads where they stand.
    let t = now();
    for a in &axes {
        g.motion.position(a).expect("position");
    }
    let (took, planned) = (now() - t, mech.move_s(&at, None));
    assert!(
        (took - planned).abs() < 0.003,
        "took {took} s, planned {planned} s"
    );

    // A fixed reading: one cycle when it needs no range change, one cycle and a
    // `SENS` more per range change, as many changes as the rule makes of its value:
    // the sample, then the source blocked (down to the noise), then the sample again
    // (up through overloads).
    let lockin = icfg.lockin();
    let mut changed = 0;
    for path in [LightPath::Sample, LightPath::Dark, LightPath::Sample] {
        lock(&sim).set_light_path(path);
        let from = Sensitivity::new(g.detector.range()).expect("range");
        let t = now();
        g.detector.input_changed();
        let r = g.detector.read().expect("reads").columns();
        let took = now() - t;
        let (changes, to) = ranging::fixed_changes(from, r.mean, lockin.min_fraction);
        assert_eq!(
            changes, r.autorange_steps,
            "from {from} to {to}: R {}",
            r.mean
        );
        assert_eq!(to.index(), r.range);
        let n = r.autorange_steps as f64;
        let planned = (n + 1.0) * lockin.read_s() + n * timing::range_change_s(lockin.baud);
        // The snapshots' answers are a few characters longer or shorter than the
        // model's (1 ms each at 9600 baud): an overloaded cycle's clipped values print
        // short, 37 ms a cycle less.
        assert!(
            (took - planned).abs() < 0.04 * (n + 1.0),
            "{} range changes: took {took} s, planned {planned} s",
            r.autorange_steps
        );
        changed += r.autorange_steps;
    }
    assert!(changed > 20, "{changed}");
}
