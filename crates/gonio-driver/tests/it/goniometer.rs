//! The instrument config and the goniometer built from it.

use std::path::Path;

use gonio_driver::script::ScriptHandle;
use gonio_driver::{Goniometer, InstrumentConfig, ManualClock, ScriptedTransport};
use gonio_proto::sr830::FilterSlope;

fn example_path() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/instrument-example.toml")
}

#[test]
fn example_config_loads() {
    let c = InstrumentConfig::load(&example_path()).expect("valid");
    assert_eq!(c.motion.axes.len(), 4);
    assert_eq!(c.motion.baud, 57600);
    let tilt = &c.motion.axes[3];
    assert_eq!(
        (tilt.name.as_str(), tilt.address, tilt.min, tilt.max),
        ("sample_tilt", 4, -5.0, 85.0)
    );
    // Defaults where the file is silent.
    assert_eq!(tilt.units, "deg");
    assert_eq!(tilt.tolerance, 0.01);
    assert_eq!(c.detector.lockin.slope, FilterSlope::Db24);
    assert_eq!(c.detector.lockin.sensitivity.index(), 20);
    assert_eq!(c.detector.lockin.time_constant.index(), 8);
}

fn err(text: &str) -> gonio_driver::ConfigFileError {
    InstrumentConfig::from_toml(text, Some(Path::new("rig.toml"))).expect_err("refused")
}

const BASE: &str = r#"[motion]
port = "/dev/ttyUSB0"
[[motion.axes]]
name = "source"
address = 1
min = -90.0
max = 90.0
[[motion.axes]]
name = "detector"
address = 2
min = -90.0
max = 90.0
[detector]
port = "/dev/ttyUSB1"
"#;

#[test]
fn config_errors_name_file_line_and_field() {
    assert!(InstrumentConfig::from_toml(BASE, None).is_ok());

    let e = err(&BASE.replace("max = 90.0\n[detector]", "max = -95.0\n[detector]"));
    assert_eq!(e.field.as_deref(), Some("motion.axes[1].max"));
    assert_eq!(e.line, Some(12));
    assert_eq!(
        e.to_string(),
        "rig.toml:12:7: field `motion.axes[1].max`: must be finite and greater than `min`"
    );

    let e = err(&BASE.replace("address = 2", "address = 1"));
    assert_eq!(e.field.as_deref(), Some("motion.axes[1].address"));
    assert_eq!(e.line, Some(10));
    assert!(
        e.message.contains("repeats the address of motion.axes[0]"),
        "{e}"
    );

    let e = err(&BASE.replace("address = 2", "address = 40"));
    assert_eq!(e.field.as_deref(), Some("motion.axes[1].address"));

    let e = err(&format!(
        "{BASE}[detector.lockin]\nsensitivity = \"3 mV\"\n"
    ));
    assert_eq!(e.line, Some(16), "{e}");

    let e = err(&format!("{BASE}[detector.lockin]\nmin_fraction = 0.9\n"));
    assert_eq!(e.field.as_deref(), Some("detector.lockin.min_fraction"));
    assert_eq!(e.line, Some(16), "{e}");

    let e = err(&BASE.replace(
        "port = \"/dev/ttyUSB0\"",
        "port = \"/dev/ttyUSB0\"\nspeed = 9600",
    ));
    assert_eq!(e.line, Some(3));
    assert!(e.message.contains("unknown field `speed`"), "{e}");

    let e = err(&BASE.replace(
        "min = -90.0\nmax = 90.0\n[[motion.axes]]",
        "max = 90.0\n[[motion.axes]]",
    ));
    assert!(e.message.contains("missing field `min`"), "{e}");

    let e = InstrumentConfig::load(Path::new("/no/such/rig.toml")).expect_err("missing");
    assert!(e.to_string().starts_with("/no/such/rig.toml: "), "{e}");
}

/// Every number of the config has a finite range: a non-finite or absurd value is
/// refused with its field, line and the limit (docs/hardware.md, "Limits").
#[test]
fn config_numbers_outside_their_range_name_the_limit() {
    let cases: &[(&str, &str, usize, &str, &str)] = &[
        (
            "port = \"/dev/ttyUSB0\"",
            "port = \"/dev/ttyUSB0\"\npoll_interval_ms = 18446744073709551615",
            3,
            "motion.poll_interval_ms",
            "must be at most 60000 ms, got 18446744073709551615",
        ),
        (
            "port = \"/dev/ttyUSB0\"",
            "port = \"/dev/ttyUSB0\"\nreply_timeout_ms = 0",
            3,
            "motion.reply_timeout_ms",
            "must be at least 1 ms, got 0",
        ),
        (
            "port = \"/dev/ttyUSB0\"",
            "port = \"/dev/ttyUSB0\"\nretries = 1000000",
            3,
            "motion.retries",
            "must be at most 10, got 1000000",
        ),
        (
            "port = \"/dev/ttyUSB0\"",
            "port = \"/dev/ttyUSB0\"\nbaud = 1000000000",
            3,
            "motion.baud",
            "must be at most 4000000 baud, got 1000000000",
        ),
        (
            "min = -90.0\nmax = 90.0\n[detector]",
            "min = nan\nmax = 90.0\n[detector]",
            11,
            "motion.axes[1].min",
            "must be finite, got NaN",
        ),
        (
            "min = -90.0\nmax = 90.0\n[[motion.axes]]",
            "min = -90.0\nmax = 1e300\n[[motion.axes]]",
            7,
            "motion.axes[0].max",
            "must be at most 1e6 units, got 1e300",
        ),
        (
            "address = 2",
            "address = 2\nvelocity = inf",
            11,
            "motion.axes[1].velocity",
            "must be finite, got inf",
        ),
        (
            "address = 2",
            "address = 2\nhome_timeout_s = 1e308",
            11,
            "motion.axes[1].home_timeout_s",
            "must be at most 3600 s, got 1e308",
        ),
        (
            "address = 2",
            "address = 2\ntolerance = -1.0",
            11,
            "motion.axes[1].tolerance",
            "must be positive, got -1",
        ),
        (
            "[detector]",
            "[geometry]\ndetector_distance_m = 1e20\n[detector]",
            14,
            "geometry.detector_distance_m",
            "must be at most 100 m, got 1e20",
        ),
    ];
    for (from, to, line, field, message) in cases {
        let text = BASE.replacen(from, to, 1);
        let e = err(&text);
        assert_eq!(e.field.as_deref(), Some(*field), "{e}\n{text}");
        assert_eq!(e.line, Some(*line), "{e}\n{text}");
        assert_eq!(e.message, *message, "{text}");
    }
}

/// Start-up, homing and one measurement over scripted lines: the bytes of both
/// protocols in the order the goniometer sends them.
#[test]
fn start_home_and_measure() {
    let cfg = InstrumentConfig::from_toml(
        &format!("{BASE}[detector.lockin]\nsensitivity = 20\ntime_constant = 8\nslope_db = 24\nsamples = 2\n"),
        None,
    )
    .expect("valid");
    let clock = ManualClock::new();
    let (mt, m) = ScriptedTransport::new(b'\n', 128, clock.clone());
    let (dt, d) = ScriptedTransport::new(b'\r', 256, clock.clone());
    let mut g =
        Goniometer::from_transports(&cfg, mt, dt, clock.clone(), clock.clone()).expect("built");

    for a in ["1", "2"] {
        m.exchange(
            format!("{a}VE\r\n"),
            format!("{a}VE SMC_PP - Controller-driver version  3. 1. 2\r\n"),
        )
        .exchange(format!("{a}ID?\r\n"), format!("{a}IDURS100PP\r\n"))
        .exchange(format!("{a}TS\r\n"), format!("{a}TS000033\r\n"));
    }
    d.send("OUTX 0\n")
        .exchange(
            "*IDN?\n",
            "Stanford_Research_Systems,SR830,s/n00111,ver1.000\r",
        )
        .send("*CLS\n")
        .send("SENS 20\n")
        .send("OFLT 8\n")
        .send("OFSL 3\n")
        .exchange("*ESR?\n", "0\r");
    let report = g.start().expect("starts");
    assert_eq!(report.axes.len(), 2);
    assert_eq!(report.axes[1].1.stage, "URS100PP");
    assert!(report.detector.contains("SR830"));

    // Both controllers already READY: homing does nothing.
    m.exchange("1TS\r\n", "1TS000033\r\n")
        .exchange("2TS\r\n", "2TS000033\r\n");
    g.home().expect("ready");

    m.exchange("1TP\r\n", "1TP0\r\n")
        .exchange("1PT30\r\n", "1PT1.5\r\n")
        .send("1PA30\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .exchange("2TP\r\n", "2TP0\r\n")
        .exchange("2PT45\r\n", "2PT2\r\n")
        .send("2PA-45\r\n")
        .exchange("2TE\r\n", "2TE@\r\n")
        .exchange("1TS\r\n", "1TS000033\r\n")
        .exchange("2TS\r\n", "2TS000033\r\n")
        .exchange("1TP\r\n", "1TP30\r\n")
        .exchange("2TP\r\n", "2TP-45\r\n");
    d.exchange("LIAS?\n", "0\r")
        .exchange("SNAP? 1,2\n", "0.003,0.004\r")
        .exchange("SNAP? 1,2\n", "0.006,0.008\r")
        .exchange("LIAS?\n", "0\r");
    let (pos, reading) = g
        .measure_at(&[("source", 30.0), ("detector", -45.0)])
        .expect("measured");
    assert_eq!(pos, vec![30.0, -45.0]);
    assert!(reading.is_valid());
    assert!(
        (reading.columns().mean - 0.0075).abs() < 1e-15,
        "{}",
        reading.columns().mean
    );
    finish(g, &m, &d);
}

fn finish(g: Goniometer<ManualClock>, m: &ScriptHandle, d: &ScriptHandle) {
    m.send("ST\r\n");
    drop(g);
    m.finish().expect("motion transcript");
    d.finish().expect("detector transcript");
}
