//! Spectral acquisition from the command line: a simulated Cornerstone 130 selects
//! each wavelength (and its order filter, and closes its shutter for darks); a
//! simulated FW102C wheel of band-pass filters does the same with filters; the
//! configs that cannot work are refused before anything moves.

use crate::common;

use std::path::Path;

use common::{config, gonio, ok, ok_json, s, scratch, stderr};

const PLAN: &str = r#"
name = "spectral cli"
wavelengths = [450, 550, 650]
[points]
kind = "in-plane"
phi_i = 0
theta_i = [30]
theta_o = { from = -50, to = 50, step = 25 }
[calibration]
dark = true
dark_readings = 1
incident = { transmittance = 1e-3 }
"#;

fn put(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    s(&p)
}

/// The mean signal (R, V) of each reading of `kind` in a run.
fn signals(run: &str, kind: &str) -> Vec<f64> {
    let c = rusqlite::Connection::open_with_flags(run, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
        .expect("open");
    let mut st = c
        .prepare(
            "SELECT r.r_mean FROM readings r JOIN steps s ON s.id = r.step_id \
             WHERE s.kind = ?1 ORDER BY s.id",
        )
        .expect("query");
    st.query_map([kind], |r| r.get::<_, f64>(0))
        .expect("rows")
        .map(|r| r.expect("row"))
        .collect()
}

/// The bench events of a run, in order.
fn bench_events(run: &str) -> Vec<String> {
    let c = rusqlite::Connection::open_with_flags(run, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
        .expect("open");
    let mut st = c
        .prepare("SELECT message FROM events WHERE kind = 'bench' ORDER BY id")
        .expect("query");
    st.query_map([], |r| r.get::<_, String>(0))
        .expect("rows")
        .map(|r| r.expect("row"))
        .collect()
}

#[test]
fn a_monochromator_run_selects_every_wavelength_and_closes_its_shutter_for_darks() {
    let d = scratch("spectral-mono");
    let plan = put(&d, "plan.toml", PLAN);
    let run = s(&d.join("run.gonio"));
    let v = ok_json(&[
        "acquire",
        "--instrument",
        &config("instrument-spectral.toml"),
        "--sim",
        &config("sim-spectral.toml"),
        "--plan",
        &plan,
        "--out",
        &run,
        "--json",
    ]);
    assert_eq!(v["status"], "complete", "{v}");
    let events = bench_events(&run);
    // The first band: the drive reads back 450 nm plus the twin's calibration error
    // (its seed's draw from the 0.1 nm the config states: −0.04 nm),
    // grating 1 and the open position (no second order under 560 nm).
    assert!(
        events.contains(&"band 450nm: cs130 at 449.96 nm (grating 1, order filter 1)".to_string()),
        "{events:?}"
    );
    // 650 nm needs the 590 nm long-pass (position 3) against 325 nm light.
    assert!(
        events
            .iter()
            .any(|e| e.starts_with("band 650nm: cs130 at 649.96 nm (grating 1, order filter 3)")),
        "{events:?}"
    );
    // Darks by the shutter: no operator is asked to block the beam.
    assert!(events.iter().any(|e| e == "shutter closed"), "{events:?}");
    assert!(events.iter().any(|e| e == "shutter open"), "{events:?}");
    assert!(
        !events.iter().any(|e| e.contains("block the source beam")),
        "{events:?}"
    );
    let r = ok_json(&["reduce", &run, "--out", &s(&d.join("t.csv")), "--json"]);
    assert_eq!(
        r["wavelengths_nm"],
        serde_json::json!([450.0, 550.0, 650.0]),
        "{r}"
    );
    for ch in r["reduction"]["channels"].as_array().expect("channels") {
        let terms: Vec<&str> = ch["budget"]
            .as_array()
            .expect("budget")
            .iter()
            .map(|t| t["term"].as_str().expect("term"))
            .collect();
        // The wavelength term, then the position term.
        assert_eq!(
            terms[terms.len() - 2..],
            ["wavelength", "position"],
            "{terms:?}"
        );
    }
}

/// A wheel of three band-pass filters and an opaque blank, on both sides of the
/// simulation.
const WHEEL: &str = r#"
[[filters]]
kind = "bandpass"
position = 1
centre_nm = 450
fwhm_nm = 10
[[filters]]
kind = "bandpass"
position = 2
centre_nm = 550
fwhm_nm = 10
[[filters]]
kind = "bandpass"
position = 3
centre_nm = 650
fwhm_nm = 10
[[filters]]
kind = "dark"
position = 6
"#;

#[test]
fn a_filter_wheel_run_selects_each_band_by_its_filter() {
    let d = scratch("spectral-wheel");
    let plan = put(&d, "plan.toml", PLAN);
    let inst = std::fs::read_to_string(config("instrument-sim.toml")).expect("inst");
    let wheel_inst = WHEEL.replace("[[filters]]", "[[filter_wheel.fw102c.filters]]");
    let inst = put(
        &d,
        "inst.toml",
        &format!("{inst}\n[filter_wheel]\nport = \"sim\"\n\n{wheel_inst}"),
    );
    let sim = std::fs::read_to_string(config("sim-spectral.toml")).expect("sim");
    // The same bench with the monochromator swapped for the wheel.
    let cut = sim
        .find("\n[monochromator]")
        .expect("a [monochromator] section");
    let sample = config("models/spectral-blue-paint.toml");
    let sim = sim[..cut]
        .replace("models/spectral-blue-paint.toml", &sample)
        .to_string()
        + "\n[filter_wheel]\n"
        + &WHEEL.replace("[[filters]]", "[[filter_wheel.filters]]");
    let sim = put(&d, "sim.toml", &sim);
    let run = s(&d.join("run.gonio"));
    let v = ok_json(&[
        "acquire",
        "--instrument",
        &inst,
        "--sim",
        &sim,
        "--plan",
        &plan,
        "--out",
        &run,
        "--json",
    ]);
    assert_eq!(v["status"], "complete", "{v}");
    let events = bench_events(&run);
    assert!(
        events.contains(&"band 550nm: fw102c at 550 nm (position 2, FWHM 10 nm)".to_string()),
        "{events:?}"
    );
    assert!(events.iter().any(|e| e == "shutter closed"), "{events:?}");
    // Band and shutter share the wheel: a dark after a dark at another band stays
    // behind the opaque position (the wheel is not turned to the band until the
    // shutter opens), so every dark reads nothing next to the incident beam.
    assert!(
        events
            .iter()
            .any(|e| e.ends_with("once the shutter opens)")),
        "{events:?}"
    );
    let (darks, incident) = (signals(&run, "dark"), signals(&run, "incident"));
    assert_eq!((darks.len(), incident.len()), (3, 3));
    let lit = incident.iter().copied().fold(f64::INFINITY, f64::min);
    for d in &darks {
        assert!(
            *d < 1e-4 * lit,
            "dark {d} V beside the incident beam's {lit} V"
        );
    }
    // The reduction: the paint's diffuse albedo shows through the lobe-free
    // backscatter side, within the wavelength term the 10 nm filters bring.
    let r = ok_json(&["reduce", &run, "--out", &s(&d.join("t.csv")), "--json"]);
    assert_eq!(
        r["wavelengths_nm"],
        serde_json::json!([450.0, 550.0, 650.0])
    );
    let ch = &r["reduction"]["channels"][0];
    let w = ch["budget"]
        .as_array()
        .expect("budget")
        .iter()
        .find(|t| t["term"] == "wavelength")
        .expect("a wavelength term");
    assert!(
        w["source"]
            .as_str()
            .expect("source")
            .contains("filter wheel")
    );
    // Every value within 4σ of the paint at the filter's centre: the σ carries the
    // 10 nm filters' wavelength term (the lamp's slope moves a filter's effective
    // centre by a fraction of a nanometre, its width averages the spectrum).
    let model = gonio_brdf::Model::load(Path::new(&config("models/spectral-blue-paint.toml")))
        .expect("paint");
    let table = std::fs::read_to_string(d.join("t.csv")).expect("table");
    let mut n = 0;
    let mut out = vec![0.0; 21];
    for line in table.lines().skip(1) {
        let x: Vec<f64> = line
            .split(',')
            .map(|v| v.parse().expect("number"))
            .collect();
        let pair = gonio_core::dirfile::PairDeg {
            incident: gonio_core::SphericalDeg::new(x[0], x[1]),
            outgoing: gonio_core::SphericalDeg::new(x[2], x[3]),
        }
        .to_dirs();
        gonio_brdf::Brdf::eval(&model, pair.wi, pair.wo, &mut out);
        // The paint's channels are 380, 400, … 780 nm: 450 nm lies between 440 and
        // 460, whose values the smooth interpolation of the simulator passes through.
        for (c, nm) in [450.0, 550.0, 650.0].iter().enumerate() {
            let truth = gonio_sim::spectral::interpolate(
                &(0..21).map(|k| 380.0 + 20.0 * k as f64).collect::<Vec<_>>(),
                &out,
                *nm,
            );
            let z = (x[4 + c] - truth) / x[7 + c];
            assert!(z.abs() < 4.0, "{line}: {nm} nm z = {z}");
            n += 1;
        }
    }
    assert_eq!(n, 12);
}

#[test]
fn a_band_selector_the_simulator_lacks_is_refused_before_anything_moves() {
    let d = scratch("spectral-refuse");
    let plan = put(&d, "plan.toml", PLAN);
    let run = d.join("run.gonio");
    let out = gonio(&[
        "acquire",
        "--instrument",
        &config("instrument-spectral.toml"),
        "--sim",
        &config("sim-example.toml"),
        "--plan",
        &plan,
        "--out",
        &s(&run),
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("[monochromator], but the simulator has none"),
        "{}",
        stderr(&out)
    );
    assert!(!run.exists());
    // Both selectors at once: the config names the field.
    let inst = std::fs::read_to_string(config("instrument-spectral.toml")).expect("inst");
    let both = put(
        &d,
        "both.toml",
        &format!("{inst}\n[filter_wheel]\nport = \"sim\"\n"),
    );
    let out = gonio(&["instrument", "check", &both]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("filter_wheel"), "{}", stderr(&out));
    // An approach longer than the drive's range of approach.
    let bad = put(
        &d,
        "bad.toml",
        "[monochromator]\nport = \"sim\"\n[monochromator.cs130]\napproach_nm = 500\n",
    );
    let inst_bad = format!(
        "{}\n{}",
        std::fs::read_to_string(config("instrument-sim.toml")).expect("inst"),
        std::fs::read_to_string(&bad).expect("bad")
    );
    let inst_bad = put(&d, "inst-bad.toml", &inst_bad);
    let out = gonio(&["instrument", "check", &inst_bad]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("monochromator.cs130.approach_nm"),
        "{}",
        stderr(&out)
    );
    let _ = ok(&["instrument", "check", &config("instrument-spectral.toml")]);
    // Wavelengths the monochromator cannot serve, or bands that are not wavelengths:
    // refused before the run file exists.
    for (name, plan_text, why) in [
        (
            "far.toml",
            PLAN.replace("[450, 550, 650]", "[450, 2500]"),
            "field `wavelengths`",
        ),
        (
            "rgb.toml",
            PLAN.replace(
                "wavelengths = [450, 550, 650]",
                "channels = [\"R\", \"G\", \"B\"]",
            ),
            "field `channels`",
        ),
    ] {
        let plan = put(&d, name, &plan_text);
        for args in [
            vec!["plan", "check", &plan, "--instrument"],
            vec![
                "acquire",
                "--plan",
                &plan,
                "--out",
                &s(&run),
                "--instrument",
            ],
        ] {
            let mut args: Vec<&str> = args;
            let inst = config("instrument-spectral.toml");
            args.push(&inst);
            let out = gonio(&args);
            assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
            assert!(stderr(&out).contains(why), "{}", stderr(&out));
            assert!(!run.exists());
        }
    }
}
