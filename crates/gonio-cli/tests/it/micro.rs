//! `gonio micro` end to end: tables that `gonio check` and `gonio fit` take, the same
//! bytes from the same seed, brushed metal measured anisotropic, the SH estimate exactly
//! reciprocal, and a microgeometry sample measured by the simulated goniometer through
//! the real driver stack, reduced and fitted.

use crate::common;

use common::{gonio, ok, ok_json, root, s, scratch};
use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;

/// A rough surface of Lambertian facets (retro-reflective, like a matte paint seen
/// close up), small enough to trace in a blink.
const SURFACE: &str = r#"
channels = ["R", "G", "B"]
[surface]
kind = "gaussian"
size = [96, 96]
spacing = 1.0
rms_height = 1.2
correlation_length = 3.0
seed = 3
material = "paint"
[materials.paint]
kind = "lambert"
albedo = [0.7, 0.5, 0.3]
"#;

/// A table file with its sidecar (which carries the grid).
fn table(path: &std::path::Path) -> gonio_process::Table {
    use gonio_process::file;
    let side = file::sidecar_path(path);
    let meta = file::Meta::from_json(
        &std::fs::read_to_string(&side).expect("sidecar"),
        Some(&side),
    )
    .expect("a sidecar");
    let text = std::fs::read_to_string(path).expect("table");
    match file::read_from(text.as_bytes(), text.len() as u64, Some(&meta), Some(path))
        .expect("a table file")
    {
        gonio_process::file::Content::Table(t) => t,
        gonio_process::file::Content::Samples(_) => panic!("{} is not a table", path.display()),
    }
}

#[test]
fn micro_tables_are_deterministic_checkable_and_fittable() {
    let d = scratch("micro-table");
    let surface = d.join("surface.toml");
    std::fs::write(&surface, SURFACE).expect("surface");
    let run = |seed: &str, out: &str| {
        ok_json(&[
            "micro",
            &s(&surface),
            "--grid",
            "10,30",
            "--isotropic",
            "--rays",
            "20000",
            "--seed",
            seed,
            "--out",
            &s(&d.join(out)),
            "--json",
        ])
    };
    let a = run("4", "a.csv");
    run("4", "b.csv");
    run("5", "c.csv");
    let bytes = |f: &str| std::fs::read(d.join(f)).expect("table");
    assert_eq!(bytes("a.csv"), bytes("b.csv"), "same seed, same bytes");
    assert_ne!(bytes("a.csv"), bytes("c.csv"), "another seed, other rays");
    // Lambert facets of albedo 0.7 lose light between bounces but never gain it.
    for x in a["albedo"].as_array().expect("albedo") {
        let (rho, sd) = (
            x["albedo"][0].as_f64().expect("R"),
            x["sigma"][0].as_f64().expect("σ"),
        );
        assert!(rho < 0.7 + 4.0 * sd && rho > 0.5, "albedo {rho} ± {sd}");
    }
    assert_eq!(a["leaked"], 0);
    // The table is what the processing crate reads: measures and a lobe fit.
    let t = table(&d.join("a.csv"));
    assert!(
        t.sigma.is_some(),
        "Monte Carlo errors travel as sigma columns"
    );
    let c = ok_json(&["check", &s(&d.join("a.csv")), "--json"]);
    assert_eq!(
        c["isotropy"][0], 0.0,
        "an isotropic table is isotropic by construction"
    );
    let (lambert, lobe) = (fit_rms(&d.join("a.csv"), 0), fit_rms(&d.join("a.csv"), 1));
    eprintln!("relative RMS: Lambert {lambert:.3}, Lambert + 1 lobe {lobe:.3}");
    assert!(lobe < 0.8 * lambert && lobe < 0.3, "{lobe} vs {lambert}");
}

/// The relative RMS of a Lambert + `lobes` fit to `input` (red channel).
fn fit_rms(input: &std::path::Path, lobes: usize) -> f64 {
    let out = input.with_extension(format!("fit{lobes}.toml"));
    let fit = ok_json(&[
        "fit",
        &s(input),
        "--lobes",
        &lobes.to_string(),
        "--out",
        &s(&out),
        "--json",
    ]);
    fit["fit"]["channels"][0]["relative_rms"]
        .as_f64()
        .expect("relative RMS")
}

#[test]
fn brushed_metal_is_anisotropic_and_its_harmonics_exactly_reciprocal() {
    let d = scratch("micro-brushed");
    let out = d.join("cyl.csv");
    let sh = d.join("cyl-sh.toml");
    ok(&[
        "micro",
        &s(&root().join("config/micro-brushed-aluminium.toml")),
        "--grid",
        "15,30",
        "--rays",
        "2000",
        "--out",
        &s(&out),
        "--sh",
        "4",
        "--sh-out",
        &s(&sh),
        "--sh-rays",
        "50000",
        "--per-order",
    ]);
    assert!(d.join("cyl.order1.csv").exists() && d.join("cyl.order3plus.csv").exists());
    let c = ok_json(&["check", &s(&out), "--json"]);
    for ch in 0..3 {
        let pi = c["isotropy"][ch].as_f64().expect("P_i");
        assert!(pi > 0.2, "P_i {pi}: parallel cylinders are not isotropic");
    }
    let c = ok_json(&["check", &s(&sh), "--grid", "15,30", "--json"]);
    for ch in 0..3 {
        assert_eq!(
            c["reciprocity"][ch], 0.0,
            "the symmetric matrix is reciprocal"
        );
        assert!(c["isotropy"][ch].as_f64().expect("P_i") > 0.2);
    }
    // Bad input: a clear error naming the file, exit status 2.
    let bad = d.join("bad.toml");
    std::fs::write(&bad, SURFACE.replace("rms_height = 1.2", "rms_height = -1")).expect("bad");
    let o = gonio(&["micro", &s(&bad), "--out", &s(&d.join("x.csv"))]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("bad.toml") && err.contains("rms_height"),
        "{err}"
    );
}

#[test]
fn the_simulated_goniometer_measures_a_microgeometry_sample() {
    let d = scratch("micro-sim");
    std::fs::write(d.join("surface.toml"), SURFACE).expect("surface");
    let example = std::fs::read_to_string(root().join("config/sim-example.toml")).expect("sim");
    let sim = example.replace(
        "[sample]                       # the embedded blue paint when no model is given\n\
         # model = \"models/blue-paint-550nm.toml\"\n",
        "[sample]\nchannel = \"R\"\n[sample.micro]\nsurface = \"surface.toml\"\n\
         grid = [10.0, 30.0]\nrays = 4000\nseed = 5\n",
    );
    assert_ne!(
        sim, example,
        "the example config's [sample] section was found"
    );
    std::fs::write(d.join("sim.toml"), &sim).expect("sim config");
    std::fs::write(d.join("plan.toml"), common::ISO_PLAN).expect("plan");
    let run = d.join("run.gonio");
    ok_json(&[
        "acquire",
        "--instrument",
        &s(&root().join("config/instrument-sim.toml")),
        "--plan",
        &s(&d.join("plan.toml")),
        "--sim",
        &s(&d.join("sim.toml")),
        "--out",
        &s(&run),
        "--json",
    ]);
    // The same table the simulator precomputed, from the same seed.
    ok(&[
        "micro",
        &s(&d.join("surface.toml")),
        "--grid",
        "10,30",
        "--isotropic",
        "--rays",
        "4000",
        "--seed",
        "5",
        "--out",
        &s(&d.join("truth.csv")),
    ]);
    let truth = table(&d.join("truth.csv"));
    let samples = d.join("samples.csv");
    ok_json(&["reduce", &s(&run), "--out", &s(&samples), "--json"]);
    let text = std::fs::read_to_string(&samples).expect("samples");
    let (mut z2, mut n) = (0.0, 0);
    let mut out = [0.0; 3];
    for line in text.lines().filter(|l| !l.starts_with('#')).skip(1) {
        let f: Vec<f64> = line
            .split(',')
            .map(|x| x.parse().expect("number"))
            .collect();
        let p = PairDeg {
            incident: SphericalDeg::new(f[0], f[1]),
            outgoing: SphericalDeg::new(f[2], f[3]),
        };
        let dirs = p.to_dirs();
        gonio_brdf::Brdf::eval(&truth, dirs.wi, dirs.wo, &mut out);
        // Columns: angles, value, sigma, flags.
        z2 += ((f[4] - out[0]) / f[5]).powi(2);
        n += 1;
    }
    let z = (z2 / f64::from(n)).sqrt();
    eprintln!("{n} readings, normalised RMS residual against the traced table {z:.2}");
    assert!(n >= 30, "{n} readings");
    assert!(z < 2.5, "normalised RMS residual {z}");
    // Rough Lambertian microgeometry is not a sum of cosine lobes: the fit is the
    // closest approximation, better with a lobe (its retro-reflection) than without.
    let (lambert, lobe) = (fit_rms(&run, 0), fit_rms(&run, 1));
    eprintln!("relative RMS of the run's fits: Lambert {lambert:.3}, Lambert + 1 lobe {lobe:.3}");
    assert!(lobe < 0.8 * lambert && lobe < 0.3, "{lobe} vs {lambert}");
}

/// Issue 40: `gonio micro`'s outputs — the table, its sidecar, the per-order tables
/// and the SH file — are the same bytes on one thread and on two, on the issue's
/// gold surface (a conductor: every bounce weighted by Fresnel) with enough rays
/// that both threads trace many blocks and their results arrive out of order.
#[test]
fn micro_outputs_are_the_same_bytes_on_one_and_two_threads() {
    let d = scratch("micro-threads");
    let run = |threads: &str| {
        let out = d.join(format!("t{threads}.csv"));
        let sh = d.join(format!("t{threads}-sh.toml"));
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_gonio"))
            .env("RAYON_NUM_THREADS", threads)
            .args([
                "micro",
                &s(&root().join("config/micro-gaussian-gold.toml")),
                "--grid",
                "30,60",
                "--rays",
                "30000",
                "--seed",
                "9",
                "--per-order",
                "--sh",
                "2",
                "--sh-out",
                &s(&sh),
                "--sh-rays",
                "20000",
                "--out",
                &s(&out),
            ])
            .output()
            .expect("the gonio binary runs");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let files = [
            out.clone(),
            gonio_process::file::sidecar_path(&out),
            d.join(format!("t{threads}.order1.csv")),
            d.join(format!("t{threads}.order2.csv")),
            d.join(format!("t{threads}.order3plus.csv")),
            sh,
        ];
        files
            .iter()
            .map(|f| std::fs::read(f).unwrap_or_else(|e| panic!("{}: {e}", f.display())))
            .collect::<Vec<_>>()
    };
    let (one, two) = (run("1"), run("2"));
    assert_eq!(one.len(), 6);
    for (k, (a, b)) in one.iter().zip(&two).enumerate() {
        assert!(a.len() > 100, "output {k} is a real file");
        assert!(a == b, "output {k} differs between 1 and 2 threads");
    }
}
