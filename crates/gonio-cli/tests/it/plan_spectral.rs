//! Spectral plans as processes: `gonio plan check` reports which loop is inside and
//! why, and a simulated run with the wavelength loop inside (channels interleaved at
//! every point, a drift reference at every wavelength) reduces to the sample's
//! BRDF at every wavelength.

use crate::common;

use common::{config, ok, ok_json, s, scratch};

#[test]
fn plan_check_reports_the_spectral_decision() {
    let args = [
        "plan",
        "check",
        &config("plan-spectral.toml"),
        "--instrument",
        &config("instrument-sim.toml"),
    ];
    let mut json_args = args.to_vec();
    json_args.push("--json");
    let v = ok_json(&json_args);
    let d = &v["spectral"];
    assert_eq!(d["bands"], 16);
    assert_eq!(d["requested"], "auto");
    // No wavelength timing on the simulated instrument: an operator's minute per
    // change, 16 of them with the geometry loop inside (one per pass).
    assert_eq!(d["inner"], "geometry");
    assert_eq!(d["alternate"], false);
    let g = &d["geometry_inner"];
    assert_eq!(g["band_changes"], 16);
    assert_eq!(g["band_s"], 960.0);
    let e = &v["estimate"];
    assert_eq!(e["band_s"], g["band_s"]);
    assert_eq!(e["motion_s"], g["motion_s"]);
    let sum = |x: &serde_json::Value| {
        x["motion_s"].as_f64().expect("motion")
            + x["band_s"].as_f64().expect("band")
            + x["detector_s"].as_f64().expect("detector")
    };
    // The run's total adds the session's start-up to the schedule's.
    let startup = e["startup_s"].as_f64().expect("startup");
    assert!((sum(e) + startup - e["total_s"].as_f64().expect("total")).abs() < 1e-6);
    let w = &d["wavelength_inner"];
    assert!((sum(w) - w["total_s"].as_f64().expect("total")).abs() < 1e-6);
    assert!(w["total_s"].as_f64() > g["total_s"].as_f64());
    // The text says the same, with the reason verbatim.
    let text = String::from_utf8(ok(&args).stdout).expect("UTF-8");
    let reason = d["reason"].as_str().expect("reason");
    assert!(reason.starts_with("geometry inner: "), "{reason}");
    assert!(text.contains(&format!("\n16 bands, {reason}\n")), "{text}");
}

#[test]
fn a_wavelength_inner_run_reduces_at_every_wavelength() {
    let dir = scratch("spectral");
    // The simulated white reference (ρ = 0.99 at 450, 550 and 650 nm) on the stage.
    let sim = std::fs::read_to_string(config("sim-example.toml")).expect("sim config");
    let model = config("models/white-reference.toml");
    let sim = sim.replace(
        "# model = \"models/blue-paint-550nm.toml\"",
        &format!("model = {model:?}"),
    );
    assert!(sim.contains("white-reference"), "the sample line moved");
    std::fs::write(dir.join("sim.toml"), sim).expect("sim");
    std::fs::write(
        dir.join("plan.toml"),
        r#"
wavelengths = [450, 550, 650]
[spectral]
inner = "wavelength"
[points]
kind = "in-plane"
theta_i = [30]
theta_o = { from = -60, to = 70, step = 10 }
[drift]
every = 4
[calibration]
dark = true
dark_readings = 1
incident = { transmittance = 1e-3 }
repeat_at_end = true
"#,
    )
    .expect("plan");
    let run = dir.join("run.gonio");
    let v = ok_json(&[
        "acquire",
        "--instrument",
        &config("instrument-sim.toml"),
        "--plan",
        &s(&dir.join("plan.toml")),
        "--sim",
        &s(&dir.join("sim.toml")),
        "--out",
        &s(&run),
        "--json",
    ]);
    assert_eq!(v["status"], "complete");
    // The run file keeps the decision in its check.
    let db = rusqlite::Connection::open(&run).expect("opens");
    let check: String = db
        .query_row("SELECT value FROM meta WHERE key = 'check'", [], |r| {
            r.get(0)
        })
        .expect("check meta");
    let check: serde_json::Value = serde_json::from_str(&check).expect("JSON");
    assert_eq!(check["spectral"]["inner"], "wavelength");
    assert_eq!(check["spectral"]["alternate"], true);
    // Every wavelength has its own dark, incident and drift references, though they
    // interleave: each channel's reduction follows its own source level.
    let csv = dir.join("f.csv");
    let r = ok_json(&["reduce", &s(&run), "--out", &s(&csv), "--json"]);
    // Per channel: the 2 incident readings (start and end) and 5 references (the
    // first, after pairs 4, 8 and 12, after the last of 13).
    let channels = r["reduction"]["channels"].as_array().expect("channels");
    assert_eq!(channels.len(), 3);
    for (c, band) in channels.iter().zip(["450nm", "550nm", "650nm"]) {
        assert_eq!(c["channel"], band);
        assert_eq!(c["calibration_readings"], 2, "{band}");
        assert_eq!(c["drift_readings"], 5, "{band}");
    }
    let text = std::fs::read_to_string(&csv).expect("samples");
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().expect("header").split(',').collect();
    let col = |name: &str| {
        head.iter()
            .position(|h| *h == name)
            .unwrap_or_else(|| panic!("no column {name} in {head:?}"))
    };
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().expect("a number")).collect())
        .collect();
    assert_eq!(rows.len(), 13, "{r}");
    let truth = 0.99 / std::f64::consts::PI;
    for band in ["450nm", "550nm", "650nm"] {
        let (f, sg) = (
            col(&format!("f_r_{band}_per_sr")),
            col(&format!("sigma_{band}_per_sr")),
        );
        let mut chi2 = 0.0;
        for row in &rows {
            let z = (row[f] - truth) / row[sg];
            assert!(z.abs() < 4.0, "{band}: f_r {} σ {}", row[f], row[sg]);
            chi2 += z * z;
        }
        // Deterministic (the simulator's seed); the calibration and dark errors are
        // shared by a channel's samples, so χ²/n sits below 1 here.
        assert!(chi2 / 13.0 < 2.0, "{band}: χ²/n {}", chi2 / 13.0);
    }
}
