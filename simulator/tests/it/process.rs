//! `gonio-sim` as its own process: the driver in this one talks to it through the
//! pseudo-terminals it announces, in (scaled) real time, like to hardware. It serves
//! with no standard input (as `gonio-sim </dev/null &` or a service manager runs it)
//! until a stop signal.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};

use gonio_driver::{Goniometer, InstrumentConfig, SerialTransport, SystemClock};

#[test]
fn a_driver_in_another_process_measures() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_gonio-sim"))
        .args(["--time-scale", "0.02", "--seed", "7"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .expect("gonio-sim starts");
    let mut first = String::new();
    BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut first)
        .expect("announces its ports");
    let v: serde_json::Value = serde_json::from_str(&first).expect("one JSON line");
    assert_eq!(v["seed"], 7);
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config");
    let mut cfg = InstrumentConfig::load(&root.join("instrument-sim.toml")).expect("config");
    cfg.motion.port = v["motion"].as_str().expect("path").into();
    cfg.detector.port = v["detector"].as_str().expect("path").into();
    // The driver waits in wall time here: start near the signal (0.4 mV) and average
    // few samples, so that autoranging and settling take seconds, not tens.
    cfg.detector.lockin.sensitivity = gonio_proto::sr830::Sensitivity::new(17).expect("1 mV");
    cfg.detector.lockin.samples = 3;
    {
        let mt = SerialTransport::open(cfg.motion.serial()).expect("motion line");
        let dt = SerialTransport::open(cfg.detector.serial()).expect("detector line");
        let mut g =
            Goniometer::from_transports(&cfg, mt, dt, SystemClock::new(), SystemClock::new())
                .expect("built");
        let report = g.start().expect("starts");
        assert_eq!(report.axes.len(), 4);
        g.home().expect("homes");
        let (pos, reading) = g
            .measure_at(&[
                ("source", -35.0),
                ("detector", 35.0),
                ("sample_rot", 0.0),
                ("sample_tilt", 0.0),
            ])
            .expect("measures");
        assert!((pos[0] + 35.0).abs() < 0.01 && (pos[1] - 35.0).abs() < 0.01);
        assert!(reading.is_valid(), "{reading:?}");
        assert!(reading.columns().mean > 0.0);
    }
    assert!(child.try_wait().expect("polls").is_none(), "still serving");
    let sent = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(sent.success());
    let status = child.wait().expect("exits");
    assert!(status.success(), "SIGTERM is a clean stop: {status:?}");
}

#[test]
fn bad_config_exits_2_naming_the_field() {
    let dir = tempfile::tempdir().expect("temp dir");
    let p = dir.path().join("sim.toml");
    std::fs::write(&p, "[kinematics]\nlayout = \"coplanar-arms\"\n[kinematics.addresses]\nsource = 1\ndetector = 2\nsample_rot = 3\nsample_tilt = 40\n").expect("write");
    let out = Command::new(env!("CARGO_BIN_EXE_gonio-sim"))
        .args(["--config", p.to_str().expect("utf-8")])
        .stdin(Stdio::null())
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("field `kinematics.addresses.sample_tilt`: must be in 1..=31"),
        "{err}"
    );
}
