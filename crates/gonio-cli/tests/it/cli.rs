//! The `gonio` binary end to end: outputs, JSON, exit statuses and error messages.

use crate::common;

use common::{config, gonio, scratch, stderr};
use std::path::Path;
use std::process::{Command, Output};

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn demo_prints_the_blue_paint_albedo() {
    let o = gonio(&["demo"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = stdout(&o);
    assert!(s.contains("Table 1"));
    // ρ(0°) = 0.410810984534 (mpmath reference quadrature).
    assert!(
        s.lines().any(|l| l.trim_start().starts_with("0   0.41081")),
        "{s}"
    );
    assert!(s.contains("= 0e0"), "reciprocity must be exact:\n{s}");
    // The closing summary names every driver there is.
    for (family, what) in gonio_driver::DRIVERS {
        assert!(
            s.contains(what),
            "{family} missing from the demo's summary:\n{s}"
        );
    }
}

#[test]
fn demo_json_is_one_object_with_the_reference_values() {
    let o = gonio(&["demo", "--json"]);
    assert!(o.status.success());
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    let a0 = v["albedo"][0]["total"].as_f64().expect("number");
    assert!((a0 - 0.410810984534).abs() < 1e-11, "{a0}");
    let a30 = v["albedo"][3]["total"].as_f64().expect("number");
    assert!((a30 - 0.418024770928).abs() < 1e-11, "{a30}");
    assert_eq!(v["reciprocity_max_relative_difference"].as_f64(), Some(0.0));
    assert!(v["albedo_max_method_difference"].as_f64().expect("number") < 1e-8);
    // The acquisition: 99 pairs, 9 shadowed, 90 measured, plus 8 darks (the plan's
    // default four, at the start and the end), 2 incident readings and 5 drift
    // references; reduced, within 0.1 % of the model everywhere.
    let a = &v["acquisition"];
    assert_eq!(a["steps"], 105);
    assert_eq!(a["rejected"]["shadowed"], 9);
    let points = a["points"].as_array().expect("points");
    assert_eq!(points.len(), 90);
    assert!(a["max_relative_deviation"].as_f64().expect("number") < 1e-3);
    assert!(a["motion_s"].as_f64() <= a["raster_motion_s"].as_f64());
    // The incident beam: R_v P T = 1e4 V/W · 1 mW · 1e-3 = 10 mV, times the lock-in's
    // chop gain 0.45.
    assert!((a["incident_v"].as_f64().expect("number") - 4.5e-3).abs() < 5e-6);
    // The run file is temporary unless asked for.
    assert!(a["run_file"].is_null());
}

#[test]
fn model_eval_writes_the_conventions_csv() {
    let d = scratch("eval");
    let dirs = d.join("dirs.csv");
    std::fs::write(&dirs, "theta_i,phi_i,theta_o,phi_o\n0,0,0,0\n65,0,80,180\n").expect("write");
    let out = d.join("out.csv");
    let o = gonio(&[
        "model",
        "eval",
        &config("models/blue-paint-550nm.toml"),
        &dirs.display().to_string(),
        "--out",
        &out.display().to_string(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(o.stdout.is_empty());
    let text = std::fs::read_to_string(&out).expect("written");
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,f_r_550nm_per_sr")
    );
    // Hand-computed values of Eq. 8 (tests/reference/table1.py in gonio-brdf).
    for (line, want) in lines.zip([0.13777128125142845398, 0.35528470225034492222]) {
        let v: f64 = line
            .rsplit(',')
            .next()
            .expect("value")
            .parse()
            .expect("number");
        assert!((v - want).abs() < 2e-15, "{line}");
    }
}

#[test]
fn model_eval_json_names_channels() {
    let d = scratch("evaljson");
    let dirs = d.join("dirs.csv");
    std::fs::write(&dirs, "theta_i,phi_i,theta_o,phi_o\n10,0,20,90\n").expect("write");
    let o = gonio(&[
        "model",
        "eval",
        &config("models/white-reference.toml"),
        &dirs.display().to_string(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    assert_eq!(
        v["channels"],
        serde_json::json!(["450nm", "550nm", "650nm"])
    );
    let f = v["rows"][0]["values"][1].as_f64().expect("number");
    assert!((f - 0.99 / std::f64::consts::PI).abs() < 1e-16);
}

#[test]
fn model_albedo_json() {
    let o = gonio(&[
        "model",
        "albedo",
        &config("models/white-reference.toml"),
        "--theta-i",
        "0,45,89",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    let rows = v["albedo"].as_array().expect("array");
    assert_eq!(rows.len(), 3);
    for r in rows {
        for x in r["values"].as_array().expect("values") {
            assert!((x.as_f64().expect("number") - 0.99).abs() < 1e-15);
        }
    }
}

#[test]
fn bad_directions_file_exits_2_naming_file_line_and_field() {
    let d = scratch("baddirs");
    let dirs = d.join("dirs.csv");
    std::fs::write(&dirs, "theta_i,phi_i,theta_o,phi_o\n0,0,10,0\n0,0,abc,0\n").expect("write");
    let o = gonio(&[
        "model",
        "eval",
        &config("models/white-reference.toml"),
        &dirs.display().to_string(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(
        e.contains(&format!(
            "{}:3: field `theta_o`: \"abc\" is not a number",
            dirs.display()
        )),
        "{e}"
    );
    assert_eq!(e.lines().count(), 1, "one-line reason: {e}");
}

#[test]
fn bad_model_file_exits_2_naming_file_line_and_field() {
    let d = scratch("badmodel");
    let model = d.join("model.toml");
    std::fs::write(
        &model,
        "kind = \"lafortune\"\nchannels = [\"R\", \"G\", \"B\"]\n\n[[lobes]]\ncx = [-1.0, -1.0, -1.0]\ncz = [0.9, 0.9]\nn = [10, 10, 10]\n",
    )
    .expect("write");
    let o = gonio(&["model", "albedo", &model.display().to_string()]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(
        e.contains(&format!(
            "{}:6:6: field `lobes[0].cz`: expected 3 values (one per channel R,G,B), got 2",
            model.display()
        )),
        "{e}"
    );
}

#[test]
fn bad_arguments_exit_2() {
    let o = gonio(&[
        "model",
        "albedo",
        &config("models/white-reference.toml"),
        "--theta-i",
        "0,95",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("95 is outside [0, 90] degrees"));
    let o = gonio(&["model", "albedo", "/no/such/model.toml"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("/no/such/model.toml"));
    let d = scratch("badout");
    let dirs = d.join("dirs.csv");
    std::fs::write(&dirs, "theta_i,phi_i,theta_o,phi_o\n0,0,0,0\n").expect("write");
    let o = gonio(&[
        "model",
        "eval",
        &config("models/white-reference.toml"),
        &dirs.display().to_string(),
        "--out",
        "/no/such/dir/out.csv",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("/no/such/dir/out.csv"));
}

#[test]
fn instrument_check_validates_configs() {
    let o = gonio(&[
        "instrument",
        "check",
        &config("instrument-example.toml"),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    assert_eq!(v["motion"]["axes"].as_array().expect("axes").len(), 4);
    assert_eq!(v["detector"]["sensitivity_v"].as_f64(), Some(0.01));

    let d = scratch("badinstr");
    let bad = d.join("rig.toml");
    std::fs::write(
        &bad,
        "[motion]\nport = \"/dev/ttyUSB0\"\n[[motion.axes]]\nname = \"a\"\naddress = 1\nmin = 5.0\nmax = 1.0\n[detector]\nport = \"/dev/ttyUSB1\"\n",
    )
    .expect("write");
    let o = gonio(&["instrument", "check", &bad.display().to_string()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains(&format!(
            "{}:7:7: field `motion.axes[0].max`: must be finite and greater than `min`",
            bad.display()
        )),
        "{}",
        stderr(&o)
    );
    // A valid config whose ports are absent is a runtime failure, not bad input.
    let o = gonio(&[
        "instrument",
        "check",
        &config("instrument-example.toml"),
        "--connect",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("/dev/gonio-motion"), "{}", stderr(&o));
}

#[test]
fn sim_announces_its_ptys_and_serves_until_a_stop_signal() {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    // Standard input closed from the start, as `gonio sim </dev/null &` has it.
    let mut child = Command::new(env!("CARGO_BIN_EXE_gonio"))
        .args(["sim", "--seed", "3"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .expect("gonio sim starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("one line");
    let v: serde_json::Value = serde_json::from_str(&line).expect("JSON");
    for k in ["motion", "detector"] {
        let p = v[k].as_str().expect("a path");
        assert!(Path::new(p).exists(), "{p}");
    }
    assert_eq!(v["seed"], 3);
    for sig in ["-INT", "-TERM", "-HUP"] {
        if sig != "-INT" {
            child = Command::new(env!("CARGO_BIN_EXE_gonio"))
                .args(["sim", "--seed", "3"])
                .stdin(Stdio::null())
                .stdout(Stdio::piped())
                .spawn()
                .expect("gonio sim starts");
            let mut line = String::new();
            BufReader::new(child.stdout.take().expect("stdout"))
                .read_line(&mut line)
                .expect("one line");
        }
        std::thread::sleep(std::time::Duration::from_millis(200));
        assert!(
            child.try_wait().expect("polls").is_none(),
            "{sig}: still serving"
        );
        let sent = Command::new("kill")
            .args([sig, &child.id().to_string()])
            .status()
            .expect("kill runs");
        assert!(sent.success());
        assert!(
            child.wait().expect("exits").success(),
            "{sig}: a clean stop"
        );
    }

    let o = gonio(&["sim", "--time-scale", "0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--time-scale"), "{}", stderr(&o));
}
