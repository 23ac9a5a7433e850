//! Instrument families from the command line: a mixed config checked, connected to
//! the simulator and refused where wrong; the machine's serial ports listed.

use crate::common;

use common::{config, gonio, ok_json, scratch, stderr};

#[test]
fn a_mixed_instrument_checks_and_connects() {
    let inst = config("instrument-mixed.toml");
    let sim = config("sim-mixed.toml");
    let v = ok_json(&[
        "instrument",
        "check",
        &inst,
        "--connect",
        "--sim",
        &sim,
        "--json",
    ]);
    let kinds: Vec<&str> = v["motion"]["axes"]
        .as_array()
        .expect("axes")
        .iter()
        .map(|a| a["kind"].as_str().expect("kind"))
        .collect();
    assert_eq!(kinds, ["smc100", "smc100", "kdc101", "k10cr1"]);
    assert_eq!(v["detector"]["kind"], "k6485");
    let c = v["connected"]["controllers"]
        .as_array()
        .expect("controllers");
    assert_eq!(c[2]["stage"], "KDC101 s/n 27000001 (Prm1Z8)");
    assert_eq!(c[3]["family"], "k10cr1");
    assert!(
        v["connected"]["detector"]
            .as_str()
            .expect("idn")
            .contains("MODEL 6485")
    );
    // What stays unconfirmed is named for every family found, as its doc lists it.
    let families: Vec<&str> = v["connected"]["unconfirmed"]
        .as_array()
        .expect("unconfirmed")
        .iter()
        .map(|f| f["family"].as_str().expect("family"))
        .collect();
    assert_eq!(families, ["smc100", "apt", "k6485"]);
    let apt = &v["connected"]["unconfirmed"][1]["unconfirmed"];
    assert!(
        apt.as_array().expect("facts").iter().any(|u| u["fact"]
            .as_str()
            .expect("fact")
            .contains("stepper status `0x0481`")),
        "{apt}"
    );
    let o = common::ok(&["instrument", "check", &inst, "--connect", "--sim", &sim]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("unconfirmed for apt"), "{text}");
}

/// The first-day check on the simulated mixed instrument: it passes, with 60 APT
/// moves a stage each answered by its completion, the status lengths recorded and
/// the report written; with the keep-alive removed from the APT axes it fails on the
/// twin, at the moves; an existing report is not overwritten without `--force`.
#[test]
fn selftest_passes_on_the_simulator_and_fails_without_the_keepalive() {
    let dir = scratch("selftest");
    let inst = config("instrument-mixed.toml");
    let sim = config("sim-mixed.toml");
    let out = dir.join("selftest.json");
    let out_s = out.display().to_string();
    let selftest = || {
        gonio(&[
            "instrument",
            "selftest",
            &inst,
            "--sim",
            &sim,
            "--out",
            &out_s,
        ])
    };
    let o = selftest();
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("checks passed"), "{text}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).expect("report")).expect("json");
    let r = &v["report"];
    assert_eq!(r["passed"], true);
    let checks = r["checks"].as_array().expect("checks");
    let by = |check: &str, device: &str| {
        checks
            .iter()
            .find(|c| c["check"] == check && c["device"] == device)
            .unwrap_or_else(|| panic!("{check} {device}: {checks:?}"))
    };
    for axis in ["sample_rot", "sample_tilt"] {
        let m = by("apt moves", axis);
        assert!(
            m["answered"]
                .as_str()
                .expect("text")
                .contains("60 of 60 moves"),
            "{m}"
        );
        assert!(
            m["answered"]
                .as_str()
                .expect("text")
                .contains("60 MOT_MOVE_COMPLETED"),
            "{m}"
        );
        by("move time", axis);
    }
    for axis in ["source", "detector"] {
        by("configuration", axis);
        by("move time", axis);
    }
    by("noise floor", "k6485");
    assert_eq!(
        checks.iter().filter(|c| c["check"] == "keep-alive").count(),
        2
    );
    // The K10CR1 twin sends the 14-byte stepper status, as real K10CR1s do.
    let lengths = r["status_lengths"].as_array().expect("lengths");
    assert!(lengths.iter().any(|l| l["axis"] == "sample_tilt"
        && l["message"] == "MOT_GET_STATUSUPDATE"
        && l["data_bytes"] == 14));
    assert!(lengths.iter().any(|l| l["axis"] == "sample_rot"
        && l["message"] == "MOT_GET_DCSTATUSUPDATE"
        && l["data_bytes"] == 14));

    // The report is not overwritten.
    let o = selftest();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));

    // Without the keep-alive on the APT axes, the controllers fall silent within the
    // 60 moves: the self-test fails there, and says so.
    let text = std::fs::read_to_string(&inst).expect("config");
    let off = text
        .replace("kind = \"kdc101\"", "kind = \"kdc101\"\nkeepalive = false")
        .replace("kind = \"k10cr1\"", "kind = \"k10cr1\"\nkeepalive = false");
    let p = dir.join("no-keepalive.toml");
    std::fs::write(&p, off).expect("write");
    let o = gonio(&[
        "instrument",
        "selftest",
        &p.display().to_string(),
        "--sim",
        &sim,
        "--json",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("the self-test failed: apt moves on sample_rot"),
        "{e}"
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    assert_eq!(v["report"]["passed"], false);

    // Another instrument: SMC100s, an SR830, and a Cornerstone 130 whose shutter
    // blocks the beam for the noise floor. No APT line: no keep-alive to report.
    let o = gonio(&[
        "instrument",
        "selftest",
        &config("instrument-spectral.toml"),
        "--sim",
        &config("sim-spectral.toml"),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    let checks = v["report"]["checks"].as_array().expect("checks");
    let named = |check: &str, device: &str| {
        checks
            .iter()
            .any(|c| c["check"] == check && c["device"] == device && c["passed"] == true)
    };
    assert!(
        named("identify", "cs130") && named("noise floor", "sr830"),
        "{checks:?}"
    );
    assert!(
        !checks
            .iter()
            .any(|c| c["check"] == "keep-alive" || c["check"] == "apt moves")
    );
    let families: Vec<&str> = v["report"]["unconfirmed"]
        .as_array()
        .expect("unconfirmed")
        .iter()
        .map(|f| f["family"].as_str().expect("family"))
        .collect();
    assert_eq!(families, ["smc100", "sr830", "cs130"]);
}

/// Each refusal names the file, line and field, exits 2, and opens no port.
#[test]
fn wrong_family_settings_are_refused_with_the_field() {
    let dir = scratch("families");
    let text = std::fs::read_to_string(config("instrument-mixed.toml")).expect("config");
    let cases = [
        (
            "serial_number = 27000001",
            "serial_number = 27000001\naddress = 3",
            "motion.axes[2].address",
            "no chain address",
        ),
        (
            "kind = \"k10cr1\"",
            "kind = \"k10cr1\"\nstage = \"prm1z8\"",
            "motion.axes[3].stage",
            "its own stage",
        ),
        (
            "name = \"source\"\naddress = 1",
            "name = \"source\"\naddress = 1\nserial_number = 5",
            "motion.axes[0].kind",
            "for APT axes",
        ),
        (
            "[detector.picoammeter]",
            "[detector.lockin]\nsamples = 3\n[detector.picoammeter]",
            "detector.lockin",
            "a K6485 takes [detector.picoammeter]",
        ),
        (
            "nplc = 1.0",
            "nplc = 100.0",
            "detector.picoammeter.nplc",
            "",
        ),
    ];
    for (i, (from, to, field, why)) in cases.iter().enumerate() {
        assert!(text.contains(from), "{from}");
        let bad = dir.join(format!("bad{i}.toml"));
        std::fs::write(&bad, text.replacen(from, to, 1)).expect("write");
        let o = gonio(&["instrument", "check", &bad.display().to_string()]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        let e = stderr(&o);
        assert!(e.contains(&format!("bad{i}.toml:")), "{e}");
        assert!(e.contains(&format!("field `{field}`")), "{e}");
        assert!(e.contains(why), "{e}");
    }
    // Ports named by USB serial numbers nobody has: the config is valid, the
    // connection fails and says which serial number it looked for.
    let lab = text
        .replace(
            "port = \"sim\"                   # in the lab: \"usb:27000001\"",
            "port = \"usb:27000001\"",
        )
        .replace(
            "port = \"sim\"                   # the SMC100",
            "port = \"usb:27000009\" # the SMC100",
        )
        .replace(
            "port = \"sim\"                   # in the lab: \"usb:55000001\"",
            "port = \"/dev/null-tilt\"",
        )
        .replace(
            "port = \"sim\"                   # RS-232",
            "port = \"/dev/null-pico\" # RS-232",
        );
    assert!(
        lab.contains("usb:27000001") && !lab.contains("port = \"sim\""),
        "{lab}"
    );
    let p = dir.join("lab.toml");
    std::fs::write(&p, lab).expect("write");
    let o = gonio(&["instrument", "check", &p.display().to_string()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = gonio(&["instrument", "check", &p.display().to_string(), "--connect"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("opening motion port"), "{e}");
    assert!(
        e.contains("no USB serial device with serial number \"27000009\""),
        "{e}"
    );
}

#[test]
fn ports_are_listed_with_their_usb_identity() {
    let v = ok_json(&["instrument", "ports", "--json"]);
    for p in v["ports"].as_array().expect("ports") {
        let path = p["path"].as_str().expect("path");
        assert!(path.starts_with("/dev/"), "{path}");
        // A USB port with a serial number can be named by it.
        if let Some(s) = p["serial_number"].as_str() {
            assert_eq!(p["name"], format!("usb:{s}"));
            assert_eq!(p["bus"], "usb");
        }
    }
}
