//! Every fault the simulator can produce, against the real driver: each asserts the
//! typed error (or the recovery), that the stages are stopped, and that nothing is
//! returned as a valid reading.

use std::path::Path;
use std::time::Duration;

use gonio_driver::smc100::{AxisError, MotionError};
use gonio_driver::{GoniometerError, InstrumentConfig, TransportError};
use gonio_sim::faults::{PortOutage, PowerLoss, Stall, Window};
use gonio_sim::{Port, SharedSim, SimConfig, SimGoniometer, lock};

fn rig(seed: u64) -> (SimGoniometer, SharedSim) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config");
    let icfg = InstrumentConfig::load(&root.join("instrument-sim.toml")).expect("instrument");
    let mut scfg = SimConfig::load(&root.join("sim-example.toml")).expect("sim");
    scfg.seed = seed;
    let (mut g, sim) = gonio_sim::connect(&icfg, &scfg).expect("connects");
    g.start().expect("starts");
    g.home().expect("homes");
    (g, sim)
}

fn now(sim: &SharedSim) -> f64 {
    lock(sim).clock().seconds()
}

fn axis_error(e: GoniometerError) -> AxisError {
    match e {
        GoniometerError::Motion(MotionError::AtAxis { source, .. }) => source,
        other => panic!("expected an axis error, got {other}"),
    }
}

/// Every stage at rest (the stop reached every controller).
fn all_stopped(sim: &SharedSim) -> bool {
    let mut s = lock(sim);
    let t = s.clock().seconds() + 10.0;
    (1..=4).all(|a| {
        s.controller_mut(a)
            .map(|c| !c.state(t).is_moving())
            .unwrap_or(false)
    })
}

const POINT: [(&str, f64); 4] = [
    ("source", 30.0),
    ("detector", -40.0),
    ("sample_rot", 10.0),
    ("sample_tilt", 5.0),
];

#[test]
fn no_reply_is_a_timeout_and_stops() {
    let (mut g, sim) = rig(1);
    lock(&sim).faults_mut().silent.push("1TP".into());
    let e = g.measure_at(&POINT).expect_err("no reply");
    assert_eq!(
        axis_error(e),
        AxisError::Transport(TransportError::Timeout(Duration::from_millis(100)))
    );
    assert!(all_stopped(&sim));
}

#[test]
fn dropped_replies_are_retried() {
    let (mut g, sim) = rig(2);
    lock(&sim).faults_mut().drop_reply = 0.05;
    let (pos, reading) = g.measure_at(&POINT).expect("retries get through");
    assert!((pos[0] - 30.0).abs() < 0.01);
    assert!(reading.is_valid());
    assert!(lock(&sim).stats().dropped > 0, "the fault fired");
}

#[test]
fn corrupted_replies_are_retried_or_refused() {
    let (mut g, sim) = rig(3);
    lock(&sim).faults_mut().corrupt_reply = 0.05;
    let (pos, _) = g.measure_at(&POINT).expect("retries get through");
    assert!((pos[1] + 40.0).abs() < 0.01);
    assert!(lock(&sim).stats().corrupted > 0);
    // Every reply corrupted: the driver refuses them all rather than use one.
    lock(&sim).faults_mut().corrupt_reply = 1.0;
    let e = g
        .motion
        .position("detector")
        .expect_err("never a clean reply");
    assert!(
        matches!(
            e,
            MotionError::AtAxis {
                source: AxisError::Protocol { .. },
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn delayed_replies() {
    let (mut g, sim) = rig(4);
    // Later than the 100 ms timeout, earlier than the retry's: the driver takes it.
    lock(&sim).faults_mut().reply_delay_s = 0.15;
    let p = g.motion.position("source").expect("late but answered");
    assert!(p.abs() < 1e-9);
    // Later than every attempt: a timeout. (Another axis, so that the late second
    // answer to the first query, still in flight, cannot be mistaken for this one.)
    lock(&sim).faults_mut().reply_delay_s = 1.0;
    let e = g.motion.position("detector").expect_err("too late");
    assert!(
        matches!(
            e,
            MotionError::AtAxis {
                source: AxisError::Transport(TransportError::Timeout(_)),
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn power_loss_mid_move_then_recovery() {
    let (mut g, sim) = rig(5);
    let t = now(&sim);
    lock(&sim).faults_mut().power_loss.push(PowerLoss {
        address: 2,
        at_s: t + 0.5,
    });
    let e = g.measure_at(&POINT).expect_err("power loss");
    assert_eq!(axis_error(e), AxisError::ControllerReset);
    assert!(all_stopped(&sim));
    assert_eq!(lock(&sim).stats().power_losses, 1);
    // Recovery: reset, wait for the boot, home again; then the point measures.
    g.motion.reset_and_home("detector").expect("recovers");
    let (pos, reading) = g.measure_at(&POINT).expect("measures after recovery");
    assert!((pos[1] + 40.0).abs() < 0.01);
    assert!(reading.is_valid());
}

#[test]
fn stalled_stage_is_disabled_and_everything_stops() {
    let (mut g, sim) = rig(6);
    lock(&sim).faults_mut().stall.push(Stall {
        address: 1,
        at: 20.0,
    });
    let e = g.measure_at(&POINT).expect_err("stalled");
    match axis_error(e) {
        AxisError::Disabled { errors, .. } => {
            assert_eq!(errors & 0x0020, 0x0020, "following error bit")
        }
        other => panic!("{other}"),
    }
    assert!(all_stopped(&sim));
    let t = now(&sim);
    let stuck = lock(&sim).stage_angles(t)[0];
    assert!((stuck - 20.0).abs() < 1e-9, "{stuck}");
}

#[test]
fn detector_overload_is_flagged_never_valid() {
    let (mut g, sim) = rig(7);
    let t = now(&sim);
    lock(&sim).faults_mut().overload.push(Window {
        from_s: t,
        to_s: t + 1e6,
    });
    let (_, reading) = g.measure_at(&POINT).expect("a reading, flagged");
    let reading = reading.lockin().expect("a lock-in reading").clone();
    assert!(reading.flags.input_overload);
    assert!(!reading.is_valid());
    assert_eq!(reading.r(), None);
    // Autoranging climbed to the least sensitive range looking for a clean reading.
    assert_eq!(reading.sensitivity.index(), 26);
}

#[test]
fn reference_unlock_is_flagged() {
    let (mut g, sim) = rig(8);
    let t = now(&sim);
    lock(&sim).faults_mut().unlock.push(Window {
        from_s: t,
        to_s: t + 1e6,
    });
    let (_, reading) = g.measure_at(&POINT).expect("a reading, flagged");
    let reading = reading.lockin().expect("a lock-in reading").clone();
    assert!(reading.flags.unlock);
    assert!(!reading.is_valid());
}

#[test]
fn port_closes_and_reopens() {
    let (mut g, sim) = rig(9);
    let t = now(&sim);
    lock(&sim).faults_mut().outage.push(PortOutage {
        port: Port::Motion,
        window: Window {
            from_s: t,
            to_s: t + 1.2,
        },
    });
    // Reopened after three 500 ms waits.
    let p = g.motion.position("source").expect("reconnects");
    assert!(p.abs() < 1e-9);
    assert!(now(&sim) >= t + 1.2);
    // An outage longer than the reconnection budget (5 × 500 ms) is an error.
    let t = now(&sim);
    lock(&sim).faults_mut().outage.push(PortOutage {
        port: Port::Detector,
        window: Window {
            from_s: t,
            to_s: t + 60.0,
        },
    });
    let e = g.detector.read().expect_err("gone for good");
    assert!(e.to_string().contains("unavailable"), "{e}");
}

#[test]
fn same_seed_same_bytes() {
    fn run(seed: u64) -> Vec<f64> {
        let (mut g, _) = rig(seed);
        let mut out = Vec::new();
        for src in [20.0, 30.0] {
            let (pos, r) = g
                .measure_at(&[
                    ("source", src),
                    ("detector", -40.0),
                    ("sample_rot", 0.0),
                    ("sample_tilt", 0.0),
                ])
                .expect("measures");
            out.extend(pos);
            let c = r.columns();
            out.extend([c.mean, c.std, c.x, c.y]);
        }
        out
    }
    let (a, b, c) = (run(11), run(11), run(12));
    assert_eq!(a, b, "same seed, same readings to the last bit");
    assert_ne!(a, c, "another seed, other noise");
}
