//! The mixed-family instrument (`config/instrument-mixed.toml` on
//! `config/sim-mixed.toml`): SMC100 arms, a KDC101 + PRM1-Z8 and a K10CR1 on APT
//! lines of their own, a K6485 picoammeter. The real drivers, in memory and through
//! real pseudo-terminals.

use std::path::Path;

use gonio_core::kinematics::Layout;
use gonio_core::{DirPair, SphericalDeg};
use gonio_driver::config::LineKind;
use gonio_driver::detector::Reading;
use gonio_driver::{Clock, Goniometer, InstrumentConfig, PortUse, SerialTransport};
use gonio_sim::SimConfig;
use gonio_sim::lock;

fn cfgs() -> (InstrumentConfig, SimConfig) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config");
    (
        InstrumentConfig::load(&root.join("instrument-mixed.toml")).expect("instrument config"),
        SimConfig::load(&root.join("sim-mixed.toml")).expect("sim config"),
    )
}

/// Trapezoid time of a move of `d` at velocity `v`, acceleration `a`.
fn trapezoid(d: f64, v: f64, a: f64) -> f64 {
    let d = d.abs();
    if d * a > v * v {
        d / v + v / a
    } else {
        2.0 * (d / a).sqrt()
    }
}

/// Axes on different lines move together: a move of an SMC100 arm and of the APT
/// rotation stage takes the longer of the two trapezoids, not their sum, and the
/// stages end where they were sent, as the simulated stages agree.
#[test]
fn axes_on_different_lines_move_together() {
    let (icfg, scfg) = cfgs();
    let (mut g, sim) = gonio_sim::connect(&icfg, &scfg).expect("connects");
    let report = g.start().expect("starts");
    let fams: Vec<&str> = report.axes.iter().map(|(_, i)| i.family).collect();
    assert_eq!(fams, ["smc100", "smc100", "kdc101", "k10cr1"]);
    assert!(
        report.detector.contains("MODEL 6485"),
        "{}",
        report.detector
    );
    assert!(report.axes.iter().all(|(_, i)| !i.referenced));
    g.home().expect("homes");
    let t0 = lock(&sim).clock().seconds();
    let got = g
        .motion
        .move_to(&[("source", 30.0), ("sample_rot", 60.0)])
        .expect("moves");
    let took = lock(&sim).clock().seconds() - t0;
    let smc = trapezoid(30.0, 20.0, 80.0);
    let apt = trapezoid(60.0, 20.0, 20.0);
    assert!((smc - 1.75).abs() < 1e-12 && (apt - 4.0).abs() < 1e-12);
    // The longer move plus the polling and the exchanges, far below the sum (5.75 s).
    assert!(took >= apt && took < apt + 0.5, "took {took} s");
    assert!(
        (got[0] - 30.0).abs() < 0.01 && (got[1] - 60.0).abs() < 0.01,
        "{got:?}"
    );
    let now = lock(&sim).clock().seconds();
    let angles = lock(&sim).stage_angles(now);
    assert!(
        (angles[0] - 30.0).abs() < 0.01 && (angles[2] - 60.0).abs() < 0.01,
        "{angles:?}"
    );
    // A target outside an APT axis' limits refuses the whole move before any byte.
    let before = lock(&sim).clock().seconds();
    let e = g
        .motion
        .move_to(&[("source", 0.0), ("sample_tilt", 90.0)])
        .expect_err("out of limits");
    assert!(e.to_string().contains("sample_tilt"), "{e}");
    assert_eq!(lock(&sim).clock().seconds(), before);
    let now = lock(&sim).clock().seconds();
    assert!((lock(&sim).stage_angles(now)[0] - 30.0).abs() < 0.01);
}

/// A picoammeter reading of the sample is the photocurrent the optics predict:
/// responsivity × power on the photodiode + the dark current, within its noise.
#[test]
fn the_picoammeter_reads_the_photocurrent() {
    let (icfg, scfg) = cfgs();
    let (mut g, sim) = gonio_sim::connect(&icfg, &scfg).expect("connects");
    g.start().expect("starts");
    g.home().expect("homes");
    let pair = DirPair::new(
        gonio_core::Dir::from(SphericalDeg::new(30.0, 0.0)),
        gonio_core::Dir::from(SphericalDeg::new(30.0, 180.0)),
    );
    let a = Layout::CoplanarArms
        .inverse(pair, Some([0.0; 4]))
        .expect("reachable");
    let targets = [
        ("source", a[0]),
        ("detector", a[1]),
        ("sample_rot", a[2]),
        ("sample_tilt", a[3]),
    ];
    let (_, reading) = g.measure_at(&targets).expect("measures");
    let Reading::Current(r, hz) = &reading else {
        panic!("a DC reading: {reading:?}")
    };
    assert_eq!(*hz, 50);
    assert!(reading.is_valid(), "{reading:?}");
    let now = lock(&sim).clock().seconds();
    let power_w = lock(&sim).signal(now) / scfg.optics.responsivity_v_per_w;
    let pico = scfg.picoammeter.as_ref().expect("picoammeter");
    let want = pico.responsivity_a_per_w * power_w + pico.dark_current_a;
    let sigma = r.std_a / (r.n as f64).sqrt();
    assert!(
        (r.mean_a - want).abs() < 5.0 * sigma + r.accuracy_a() * 1e-3,
        "read {} A, expected {want} A (σ {sigma})",
        r.mean_a
    );
    assert!(
        want > 1e-9 && want < r.range.amps(),
        "{want} on {}",
        r.range
    );
}

/// The same instrument through real pseudo-terminals: every line a `SerialTransport`
/// with its family's framing (APT binary messages on two of them).
#[test]
fn mixed_lines_through_real_pseudo_terminals() {
    let (icfg, scfg) = cfgs();
    let sim = gonio_sim::instrument(&scfg).expect("sim");
    let clock = lock(&sim).clock().clone();
    let pty = gonio_sim::PtySim::spawn(sim.clone()).expect("ptys");
    assert_eq!(pty.apt.len(), 2);
    let roles = scfg.apt_roles();
    let mut g = Goniometer::from_ports(
        &icfg,
        |use_, mut settings| {
            settings.path = match use_ {
                PortUse::Detector(_) => pty.detector.display().to_string(),
                PortUse::Monochromator(_) | PortUse::FilterWheel(_) => {
                    unreachable!("the mixed instrument selects no wavelengths")
                }
                PortUse::Motion(line) => match &line.kind {
                    LineKind::Smc100(_) => pty.motion.display().to_string(),
                    LineKind::Apt(axis, _) => {
                        let n = roles
                            .iter()
                            .position(|r| *r == axis.name)
                            .expect("a simulated APT role");
                        pty.apt[n].display().to_string()
                    }
                },
            };
            Ok(Box::new(SerialTransport::open(settings)?))
        },
        clock,
    )
    .expect("built");
    g.start().expect("starts");
    g.home().expect("homes");
    let got = g
        .motion
        .move_to(&[
            ("detector", -20.0),
            ("sample_rot", 45.0),
            ("sample_tilt", 10.0),
        ])
        .expect("moves");
    for (p, want) in got.iter().zip([-20.0, 45.0, 10.0]) {
        assert!((p - want).abs() < 0.01, "{got:?}");
    }
    let now = lock(&sim).clock().seconds();
    let angles = lock(&sim).stage_angles(now);
    assert!((angles[1] + 20.0).abs() < 0.01, "{angles:?}");
    assert!((angles[2] - 45.0).abs() < 0.01 && (angles[3] - 10.0).abs() < 0.01);
    let r = g.detector.read().expect("reads");
    assert!(r.is_valid(), "{r:?}");
    assert!(r.columns().mean > 0.0);
}

/// What the APT twins saw of the server-alive messages (APT manual p. 130), by role.
fn keepalive_records(sim: &gonio_sim::SharedSim, n: usize) -> Vec<gonio_sim::apt::KeepAliveRecord> {
    let mut s = lock(sim);
    (0..n)
        .map(|i| s.apt_mut(i).expect("an APT twin").keepalive().clone())
        .collect()
}

/// 220 moves of the two APT stages, detector readings between them, a pause of ten
/// minutes of instrument time with nothing moving: the keep-alive goes out on both APT
/// lines at least once a second throughout (the twins record every gap), no status
/// message is ever withheld, and the stages move again after the pause.
#[test]
fn apt_lines_are_kept_alive_through_moves_readings_and_a_ten_minute_pause() {
    let (icfg, scfg) = cfgs();
    let (mut g, sim) = gonio_sim::connect(&icfg, &scfg).expect("connects");
    g.start().expect("starts");
    g.home().expect("homes");
    let t0 = lock(&sim).clock().seconds();
    for i in 0..220 {
        let (rot, tilt) = if i % 2 == 0 {
            (12.0, 6.0)
        } else {
            (-12.0, 1.0)
        };
        g.motion
            .move_to(&[("sample_rot", rot), ("sample_tilt", tilt)])
            .unwrap_or_else(|e| panic!("move {i}: {e}"));
        if i % 10 == 0 {
            g.detector.read().expect("reads");
        }
        if i == 100 {
            let now = g.motion.clock().now();
            g.idle_until(now + std::time::Duration::from_secs(600));
        }
    }
    let t1 = lock(&sim).clock().seconds();
    assert!(t1 - t0 > 600.0 + 220.0, "{}", t1 - t0);
    for (role, k) in ["sample_rot", "sample_tilt"]
        .iter()
        .zip(keepalive_records(&sim, 2))
    {
        assert_eq!(k.late, 0, "{role}: {k:?}");
        assert!(k.longest_gap_until(t1) <= 1.0, "{role}: {k:?}");
        assert_eq!(k.withheld, 0, "{role}: {k:?}");
        // One every 0.5 s of the session, give or take the waits' granularity.
        let expect = (t1 / 0.5) as u64;
        assert!(
            k.acks + 5 >= expect && k.acks <= expect + 5,
            "{role}: {} vs {expect}",
            k.acks
        );
    }
    // The driver's side of the same count.
    let now = g.motion.clock().now();
    let report = g.heartbeat().report(std::time::Duration::ZERO, now);
    assert_eq!(report.len(), 2, "{report:?}");
    for (port, sent, gap) in &report {
        assert!(*sent > 1000, "{port}: {sent}");
        assert!(*gap <= std::time::Duration::from_secs(1), "{port}: {gap:?}");
    }
}

#[test]
fn without_the_keepalive_the_k10cr1_falls_silent_within_a_run() {
    // The same run with the keep-alive turned off on the APT axes: the controllers
    // count their move completions (the manual's example) and stop talking after 50.
    let (mut icfg, scfg) = cfgs();
    for a in &mut icfg.motion.axes {
        if a.apt_stage().is_some() {
            a.keepalive = false;
        }
    }
    let (mut g, sim) = gonio_sim::connect(&icfg, &scfg).expect("connects");
    g.start().expect("starts");
    g.home().expect("homes");
    let mut failed = None;
    for i in 0..220 {
        let tilt = if i % 2 == 0 { 6.0 } else { 1.0 };
        if let Err(e) = g.motion.move_to(&[("sample_tilt", tilt)]) {
            failed = Some((i, e.to_string()));
            break;
        }
    }
    let (i, e) = failed.expect("a controller without the keep-alive falls silent");
    assert!((45..=50).contains(&i), "failed at move {i}: {e}");
    assert!(e.contains("sample_tilt") && e.contains("no reply"), "{e}");
    let k = &keepalive_records(&sim, 2)[1];
    assert_eq!(k.acks, 0);
    assert!(k.withheld > 0, "{k:?}");
}

#[test]
fn the_manual_read_literally_and_its_28_byte_stepper_status_are_survived() {
    // Every status message counted, the replies to status requests too, and the
    // K10CR1 sending the manual's 28-byte 0x0481 (p. 123) rather than the 14 bytes
    // real K10CR1s send: the keep-alive and the framer take both.
    let (icfg, mut scfg) = cfgs();
    for a in scfg.apt.values_mut() {
        a.keepalive_rule = gonio_sim::apt::KeepAliveRule::All;
        a.stepper_status_bytes = 28;
    }
    let (mut g, sim) = gonio_sim::connect(&icfg, &scfg).expect("connects");
    g.start().expect("starts");
    g.home().expect("homes");
    for i in 0..220 {
        let (rot, tilt) = if i % 2 == 0 {
            (12.0, 6.0)
        } else {
            (-12.0, 1.0)
        };
        let got = g
            .motion
            .move_to(&[("sample_rot", rot), ("sample_tilt", tilt)])
            .unwrap_or_else(|e| panic!("move {i}: {e}"));
        assert!((got[1] - tilt).abs() < 0.01, "{got:?}");
    }
    for k in keepalive_records(&sim, 2) {
        assert_eq!((k.late, k.withheld), (0, 0), "{k:?}");
    }
}
