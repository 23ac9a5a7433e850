//! The real driver against the simulator: homing, moves, readings, and the BRDF back
//! within the noise model's bounds; in memory and through real pseudo-terminals.

use std::path::Path;
use std::time::Duration;

use gonio_core::kinematics::Layout;
use gonio_core::{Dir, DirPair, SphericalDeg};
use gonio_driver::{Clock, Goniometer, InstrumentConfig, SerialTransport};
use gonio_sim::{SimConfig, lock};

fn cfgs() -> (InstrumentConfig, SimConfig) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config");
    (
        InstrumentConfig::load(&root.join("instrument-sim.toml")).expect("instrument config"),
        SimConfig::load(&root.join("sim-example.toml")).expect("sim config"),
    )
}

/// Stage targets for a direction pair on the coplanar-arm layout, by axis name.
fn targets(pair: DirPair) -> Vec<(&'static str, f64)> {
    let a = Layout::CoplanarArms
        .inverse(pair, Some([0.0; 4]))
        .expect("reachable");
    vec![
        ("source", a[0]),
        ("detector", a[1]),
        ("sample_rot", a[2]),
        ("sample_tilt", a[3]),
    ]
}

/// The BRDF a reading implies, from the known optics: R = g · R_v · P · f · cos θo · Ω.
fn brdf_from(sim: &SimConfig, omega: f64, r: f64, wo: Dir) -> f64 {
    r / (sim.lockin.chop_gain
        * sim.optics.responsivity_v_per_w
        * sim.optics.source_power_w
        * omega
        * wo.z)
}

fn deg(t: f64, p: f64) -> Dir {
    Dir::from(SphericalDeg::new(t, p))
}

#[test]
fn measures_the_brdf_in_memory() {
    let (icfg, scfg) = cfgs();
    let (mut g, sim) = gonio_sim::connect(&icfg, &scfg).expect("connects");
    let report = g.start().expect("starts");
    assert_eq!(report.axes.len(), 4);
    assert!(report.detector.contains("SR830"));
    g.home().expect("homes");
    let omega = lock(&sim).optics().solid_angle_sr();
    for (wi, wo) in [
        (deg(0.0, 0.0), deg(30.0, 180.0)),
        (deg(35.0, 0.0), deg(35.0, 180.0)),
        (deg(65.0, 0.0), deg(70.0, 180.0)),
        (deg(40.0, 30.0), deg(55.0, 250.0)),
    ] {
        let pair = DirPair::new(wi, wo);
        let t = targets(pair);
        let (_, reading) = g.measure_at(&t).expect("measures");
        assert!(reading.is_valid(), "{reading:?}");
        let now = lock(&sim).clock().seconds();
        // The stages point where asked (positions are quantised to 0.0005°).
        let got = lock(&sim).directions(now);
        assert!(got.wi.angle_to(wi) < 2e-5 && got.wo.angle_to(wo) < 2e-5);
        let truth = {
            let s = lock(&sim);
            let mut f = vec![0.0; s.optics().sample().channels().len()];
            s.optics().sample().eval(wi, wo, &mut f);
            f[0]
        };
        let f = brdf_from(&scfg, omega, reading.columns().mean, wo);
        // Samples are spaced by one time constant, so neighbours correlate (e^-1):
        // the variance of their mean is (1+ρ)/(1−ρ) ≈ 2.2 times σ²/n.
        let sigma = reading.columns().std * (2.2 / reading.columns().n as f64).sqrt();
        let sigma_f = brdf_from(&scfg, omega, sigma, wo);
        assert!(
            (f - truth).abs() < 5.0 * sigma_f + 1e-6 * truth,
            "f {f} vs {truth} ± {sigma_f}"
        );
    }
    // The physical time of the run is accounted: homing, four moves, settling, samples.
    let t = lock(&sim).clock().seconds();
    assert!(t > 10.0 && t < 120.0, "{t}");
}

#[test]
fn measures_through_real_pseudo_terminals() {
    let (icfg, scfg) = cfgs();
    let sim = gonio_sim::instrument(&scfg).expect("sim");
    let clock = lock(&sim).clock().clone();
    let pty = gonio_sim::PtySim::spawn(sim.clone()).expect("ptys");
    let mut m = icfg.motion.clone();
    m.port = pty.motion.display().to_string();
    let mut d = icfg.detector.clone();
    d.port = pty.detector.display().to_string();
    let mt = SerialTransport::open(m.serial()).expect("motion pty opens");
    let dt = SerialTransport::open(d.serial()).expect("detector pty opens");
    let mut g =
        Goniometer::from_transports(&icfg, mt, dt, clock.clone(), clock.clone()).expect("built");
    g.start().expect("starts");
    g.home().expect("homes");
    let (wi, wo) = (deg(35.0, 0.0), deg(35.0, 180.0));
    let (_, reading) = g
        .measure_at(&targets(DirPair::new(wi, wo)))
        .expect("measures");
    assert!(reading.is_valid());
    let omega = lock(&sim).optics().solid_angle_sr();
    let truth = {
        let s = lock(&sim);
        let mut f = vec![0.0; 1];
        s.optics().sample().eval(wi, wo, &mut f);
        f[0]
    };
    let f = brdf_from(&scfg, omega, reading.columns().mean, wo);
    let sigma_f = brdf_from(
        &scfg,
        omega,
        reading.columns().std * (2.2 / reading.columns().n as f64).sqrt(),
        wo,
    );
    assert!(
        (f - truth).abs() < 5.0 * sigma_f + 1e-6 * truth,
        "f {f} vs {truth} ± {sigma_f}"
    );
    assert!(clock.now() > Duration::from_secs(5));
    drop(g);
    drop(pty);
}

/// A third-party client — a plain POSIX shell script using only `stty`, `printf` and
/// `dd`, no Gonio code — opens the simulator's ptys and gets manual-conformant replies.
#[test]
fn a_shell_script_talks_to_the_simulator() {
    let (_, scfg) = cfgs();
    let sim = gonio_sim::instrument(&scfg).expect("sim");
    let pty = gonio_sim::PtySim::spawn(sim.clone()).expect("ptys");
    let script = r#"
set -e
ask() { # port, command, terminator of the command, bytes to read (at most)
  exec 3<>"$1"
  stty -F "$1" raw -echo 57600
  printf "$2$3" >&3
  timeout 2 dd bs=1 count="$4" <&3 2>/dev/null || true
  exec 3>&-
}
ask "$M" 1TS '\r\n' 11; echo
ask "$M" 1PA10 '\r\n' 0
ask "$M" 1TE '\r\n' 6; echo
ask "$M" 1TP '\r\n' 6; echo
ask "$D" 'OUTX 0' '\n' 0
ask "$D" '*IDN?' '\n' 49; echo
ask "$D" 'OUTP? 3' '\n' 24; echo
"#;
    let out = std::process::Command::new("sh")
        .arg("-c")
        .arg(script)
        .env("M", &pty.motion)
        .env("D", &pty.detector)
        .output()
        .expect("sh runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout).replace('\r', "");
    let lines: Vec<&str> = text.lines().filter(|l| !l.is_empty()).collect();
    // Not referenced after power-up; a move is refused with H; the counter reads 0.
    assert_eq!(lines[0], "1TS00000A", "{text:?}");
    assert_eq!(lines[1], "1TEH");
    assert_eq!(lines[2], "1TP0");
    assert_eq!(lines[3], "Stanford_Research_Systems,SR830,s/n00111,ver1.07");
    // R (volts) at the power-up sensitivity (1 V full scale), barely started settling:
    // a number the SR830 format allows, far below full scale.
    let r: f64 = (lines[4].trim().parse()).unwrap_or_else(|e| panic!("{e}: {text:?}"));
    assert!((0.0..0.01).contains(&r), "{text:?}");
    drop(pty);
}

/// The port closes and reopens through a real pty: the path vanishes and comes back,
/// and the driver reopens it.
#[test]
fn pty_port_closes_and_reopens() {
    use gonio_sim::faults::{PortOutage, Window};
    let (icfg, mut scfg) = cfgs();
    // The driver's reconnection waits must take some wall time for the server thread
    // to notice the outage end: 500 ms of simulated time are 10 ms of wall time here.
    scfg.time_scale = 0.02;
    let sim = gonio_sim::instrument(&scfg).expect("sim");
    let clock = lock(&sim).clock().clone();
    let pty = gonio_sim::PtySim::spawn(sim.clone()).expect("ptys");
    let mut m = icfg.motion.clone();
    m.port = pty.motion.display().to_string();
    let mt = SerialTransport::open(m.serial()).expect("opens");
    let mut chain = gonio_driver::smc100::Smc100Chain::new(
        mt,
        clock.clone(),
        icfg.motion.smc100_axes(),
        gonio_driver::smc100::ChainPolicy {
            // 100 ms of simulated time would be 2 ms of wall time, and five reopening
            // attempts 500 ms apart 50 ms: a busy machine's scheduling would read as a
            // silent controller or a port that never comes back.
            reply_timeout: Duration::from_secs(5),
            reconnect_attempts: 100,
            ..icfg.motion.policy()
        },
    )
    .expect("chain");
    assert_eq!(chain.position("source").expect("before"), 0.0);
    let t = clock.now().as_secs_f64();
    lock(&sim).faults_mut().outage.push(PortOutage {
        port: gonio_sim::Port::Motion,
        window: Window {
            from_s: t,
            to_s: t + 1.0,
        },
    });
    // Let the server notice the outage and close the pty.
    std::thread::sleep(Duration::from_millis(50));
    assert_eq!(chain.position("source").expect("after the outage"), 0.0);
    assert!(clock.now().as_secs_f64() >= t + 1.0);
    drop(chain);
    drop(pty);
}
