//! Spectral data through the outputs: the long-form CSV (`--format csv-long`,
//! `reduce --long`) and its read-back, per-wavelength σ, measures and lobe fits, the
//! ASTM E1392 text with a column per wavelength, and the albedo plotted against
//! wavelength.

use crate::common;

use std::path::{Path, PathBuf};

use common::{gonio, ok, ok_json, root, s, scratch};
use gonio_dataset::{Kind, OpenOptions};
use gonio_io::plot::{self, AlbedoOptions, Source};

/// A one-lobe Lafortune model whose every parameter changes with wavelength: the
/// truth the fits must recover.
const LAFORTUNE3: &str = r#"
kind = "lafortune"
channels = ["450nm", "550nm", "650nm"]

[diffuse]
rho = [0.2, 0.35, 0.5]

[[lobes]]
cx = [-0.8, -0.9, -1.0]
cy = [-0.8, -0.9, -1.0]
cz = [0.7, 0.8, 0.9]
n = [10.0, 15.0, 20.0]
"#;

/// ρd, Cx, Cy, Cz, n of [`LAFORTUNE3`] at each wavelength.
const TRUTH: [[f64; 5]; 3] = [
    [0.2, -0.8, -0.8, 0.7, 10.0],
    [0.35, -0.9, -0.9, 0.8, 15.0],
    [0.5, -1.0, -1.0, 0.9, 20.0],
];

/// A Lambertian spectrum: ρ(λ) at 450, 550 and 650 nm.
const RHO: [f64; 3] = [0.2, 0.5, 0.8];

fn put(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p
}

fn lambert3(dir: &Path) -> PathBuf {
    put(
        dir,
        "lambert3.toml",
        "kind = \"lambert\"\nchannels = [\"450nm\", \"550nm\", \"650nm\"]\nrho = [0.2, 0.5, 0.8]\n",
    )
}

/// The rows of a CSV file below its header, as numbers.
fn rows(p: &Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(p)
        .expect("read")
        .lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .map(|x| x.parse::<f64>().expect("number"))
                .collect()
        })
        .collect()
}

fn header(p: &Path) -> String {
    std::fs::read_to_string(p)
        .expect("read")
        .lines()
        .next()
        .expect("header")
        .to_string()
}

#[test]
fn the_long_form_holds_a_row_per_wavelength_and_reads_back_to_the_same_table() {
    let d = scratch("long");
    let model = put(&d, "laf3.toml", LAFORTUNE3);
    let long = d.join("long.csv");
    let v = ok_json(&[
        "export",
        &s(&model),
        "--format",
        "csv-long",
        "--out",
        &s(&long),
        "--json",
    ]);
    assert_eq!(v["format"], "csv-long", "{v}");
    assert_eq!(
        header(&long),
        "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,wavelength_nm,f_r_per_sr"
    );
    let r = rows(&long);
    // The model on the default 10° grid: 36 φi × 9 θi × 36 φo × 9 θo pairs, 3 rows each.
    assert_eq!(r.len(), 36 * 9 * 36 * 9 * 3);
    assert_eq!(
        r[..3].iter().map(|x| x[4]).collect::<Vec<_>>(),
        vec![450.0, 550.0, 650.0]
    );
    assert!(Path::new(&format!("{}.json", long.display())).exists());
    // Recognised from its content and opened as the same table: written wide from
    // the long form, the bytes are those written wide from the model.
    let head = std::fs::read(&long).expect("read");
    assert_eq!(gonio_dataset::detect(&head), Some(Kind::Csv));
    let wide_direct = d.join("direct.csv");
    let wide_back = d.join("back.csv");
    ok(&[
        "export",
        &s(&model),
        "--format",
        "csv",
        "--out",
        &s(&wide_direct),
    ]);
    ok(&[
        "export",
        &s(&long),
        "--format",
        "csv",
        "--out",
        &s(&wide_back),
    ]);
    assert_eq!(
        std::fs::read(&wide_back).expect("back"),
        std::fs::read(&wide_direct).expect("direct")
    );
    // And from the wide form back to the long one: the same bytes again.
    let long_back = d.join("long-back.csv");
    ok(&[
        "export",
        &s(&wide_direct),
        "--format",
        "csv-long",
        "--out",
        &s(&long_back),
    ]);
    assert_eq!(
        std::fs::read(&long_back).expect("back"),
        std::fs::read(&long).expect("long")
    );
}

#[test]
fn the_long_form_refuses_channels_that_are_not_wavelengths() {
    let d = scratch("long-rgb");
    let out = d.join("rgb.csv");
    let o = gonio(&[
        "export",
        &root()
            .join("config/models/cook-torrance-gold.toml")
            .display()
            .to_string(),
        "--format",
        "csv-long",
        "--out",
        &s(&out),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("no wavelengths (channels R,G,B)"), "{err}");
    assert!(err.contains("--format csv"), "{err}");
    assert!(!out.exists());
}

#[test]
fn a_spectral_run_reduces_checks_and_fits_per_wavelength() {
    let d = scratch("spectral-run");
    let sample = lambert3(&d);
    let sim = std::fs::read_to_string(root().join("config/sim-example.toml"))
        .expect("sim config")
        .replace(
            "# model = \"models/blue-paint-550nm.toml\"",
            &format!("model = {:?}", s(&sample)),
        );
    assert!(sim.contains("lambert3.toml"));
    let sim = put(&d, "sim.toml", &sim);
    let plan = put(
        &d,
        "plan.toml",
        &common::ISO_PLAN.replace(
            "name = \"isotropic grid\"",
            "name = \"spectral grid\"\nchannels = [\"450nm\", \"550nm\", \"650nm\"]",
        ),
    );
    let run = d.join("run.gonio");
    ok(&[
        "acquire",
        "--instrument",
        &s(&root().join("config/instrument-sim.toml")),
        "--plan",
        &s(&plan),
        "--sim",
        &s(&sim),
        "--out",
        &s(&run),
        "--json",
    ]);
    // Reduced to the long form: a row per pair per wavelength, each with its σ.
    let long = d.join("red.csv");
    let v = ok_json(&["reduce", &s(&run), "--out", &s(&long), "--long", "--json"]);
    assert_eq!(
        v["channels"],
        serde_json::json!(["450nm", "550nm", "650nm"])
    );
    assert_eq!(
        v["wavelengths_nm"],
        serde_json::json!([450.0, 550.0, 650.0])
    );
    assert_eq!(v["wrote"], "108 rows (long form, 3 wavelengths)", "{v}");
    let per_channel = v["reduction"]["channels"].as_array().expect("channels");
    assert_eq!(per_channel.len(), 3);
    assert_eq!(
        header(&long),
        "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,wavelength_nm,f_r_per_sr,sigma_per_sr"
    );
    // Every reduced f_r(λ) within 5σ of ρ(λ)/π, and χ²/n near 1 over the run.
    let r = rows(&long);
    assert_eq!(r.len(), 36 * 3);
    let mut chi2 = 0.0;
    for row in &r {
        let c = [450.0, 550.0, 650.0]
            .iter()
            .position(|w| *w == row[4])
            .expect("a wavelength of the run");
        let truth = RHO[c] / std::f64::consts::PI;
        let z = (row[5] - truth) / row[6];
        assert!(row[6] > 0.0 && z.abs() < 5.0, "{row:?}: z = {z}");
        chi2 += z * z;
    }
    let chi2n = chi2 / r.len() as f64;
    assert!((0.3..3.0).contains(&chi2n), "χ²/n = {chi2n}");
    // The long form read back whole, through the dataset opener: written long again,
    // the same bytes (the sidecar keeps it isotropic).
    let again = d.join("again.csv");
    ok(&[
        "export",
        &s(&long),
        "--format",
        "csv-long",
        "--out",
        &s(&again),
    ]);
    assert_eq!(
        std::fs::read(&again).expect("again"),
        std::fs::read(&long).expect("long")
    );
    // `check` reads the long form and measures per wavelength: albedos ρ(λ).
    let v = ok_json(&["check", &s(&long), "--json"]);
    assert_eq!(
        v["wavelengths_nm"],
        serde_json::json!([450.0, 550.0, 650.0])
    );
    assert_eq!(
        v["channels"],
        serde_json::json!(["450nm", "550nm", "650nm"])
    );
    assert_eq!(v["symmetry"], "isotropic", "{v}");
    // A Lambertian fit (no lobes) per wavelength: ρd(λ) to 1e-4 relative. (Not to a
    // few of the fit's standard errors: those count only the samples' independent
    // noise, while the calibration and dark terms are common to every sample.)
    let model = d.join("fit.toml");
    let v = ok_json(&[
        "fit",
        &s(&long),
        "--lobes",
        "0",
        "--out",
        &s(&model),
        "--json",
    ]);
    assert_eq!(
        v["wavelengths_nm"],
        serde_json::json!([450.0, 550.0, 650.0])
    );
    for (c, ch) in v["fit"]["channels"]
        .as_array()
        .expect("channels")
        .iter()
        .enumerate()
    {
        let rho = ch["params"]["rho_d"].as_f64().expect("rho");
        assert!(
            ch["std_err"]["rho_d"].as_f64().expect("std err") > 0.0,
            "{ch}"
        );
        assert!((rho / RHO[c] - 1.0).abs() < 1e-4, "{ch}");
    }
}

#[test]
fn lobe_fits_recover_each_wavelengths_parameters_and_the_model_loads_back() {
    let d = scratch("spectral-fit");
    let truth = put(&d, "laf3.toml", LAFORTUNE3);
    let long = d.join("data.csv");
    ok(&[
        "export",
        &s(&truth),
        "--format",
        "csv-long",
        "--out",
        &s(&long),
    ]);
    let model = d.join("fit.toml");
    let v = ok_json(&[
        "fit",
        &s(&long),
        "--lobes",
        "1",
        "--out",
        &s(&model),
        "--json",
    ]);
    assert_eq!(
        v["wavelengths_nm"],
        serde_json::json!([450.0, 550.0, 650.0])
    );
    let chans = v["fit"]["channels"].as_array().expect("channels");
    assert_eq!(chans.len(), 3);
    // Noise-free data of the model itself: every parameter of every wavelength to
    // 1e-6 (relative for n).
    for (c, ch) in chans.iter().enumerate() {
        assert_eq!(ch["channel"], format!("{}nm", [450, 550, 650][c]));
        let p = &ch["params"];
        let lobe = p["lobes"][0].as_array().expect("lobe");
        let got = [
            p["rho_d"].as_f64().expect("rho"),
            lobe[0].as_f64().expect("cx"),
            lobe[1].as_f64().expect("cy"),
            lobe[2].as_f64().expect("cz"),
            lobe[3].as_f64().expect("n"),
        ];
        for (k, (g, t)) in got.iter().zip(TRUTH[c]).enumerate() {
            let tol = if k == 4 { 1e-6 * t } else { 1e-6 };
            assert!(
                (g - t).abs() < tol,
                "{}: parameter {k}: {g} vs {t}",
                ch["channel"]
            );
        }
    }
    // The model file: the wavelengths as its channels, a list per parameter with a
    // value per wavelength.
    let text = std::fs::read_to_string(&model).expect("model");
    assert!(
        text.contains("channels = [\"450nm\", \"550nm\", \"650nm\"]"),
        "{text}"
    );
    for key in ["rho", "cx", "cy", "cz", "n"] {
        let line = text
            .lines()
            .find(|l| l.starts_with(&format!("{key} = [")))
            .unwrap_or_else(|| panic!("no {key} in {text}"));
        assert_eq!(line.matches(',').count(), 2, "{line}");
    }
    // Loaded back, it gives the data: exported long, every value within 1e-8 of the
    // truth's.
    let back = d.join("back.csv");
    ok(&[
        "export",
        &s(&model),
        "--format",
        "csv-long",
        "--out",
        &s(&back),
    ]);
    let (a, b) = (rows(&long), rows(&back));
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x[..5], y[..5]);
        assert!(
            (x[5] - y[5]).abs() <= 1e-8 * x[5].abs().max(1e-3),
            "{x:?} vs {y:?}"
        );
    }
}

/// Three scattered samples (no grid), the third small enough for exponent form.
fn samples_csv(channels: &[&str], values: [[f64; 2]; 3]) -> String {
    let cols: Vec<String> = channels
        .iter()
        .map(|c| {
            if *c == "value" {
                "f_r_per_sr".to_string()
            } else {
                format!("f_r_{c}_per_sr")
            }
        })
        .collect();
    let mut out = format!(
        "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,{}\n",
        cols.join(",")
    );
    for (pair, v) in ["30,0,30,180", "30,0,45,170", "20,0,60,90"]
        .iter()
        .zip(values)
    {
        out.push_str(pair);
        for x in &v[..channels.len()] {
            out.push_str(&format!(",{x}"));
        }
        out.push('\n');
    }
    out
}

#[test]
fn astm_text_has_a_column_per_wavelength_and_single_band_files_are_unchanged() {
    let d = scratch("astm");
    let values = [[0.25, 0.5], [0.125, 0.0625], [2.5e-6, 0.75]];
    // One band: the form Gonio has always written, byte for byte.
    let single = put(&d, "single.csv", &samples_csv(&["value"], values));
    let astm = d.join("single.astm");
    ok(&[
        "export",
        &s(&single),
        "--format",
        "astm",
        "--out",
        &s(&astm),
    ]);
    assert_eq!(
        std::fs::read_to_string(&astm).expect("astm"),
        "# ASTM E1392-style BRDF written by Gonio\n\
         # angles in degrees (theta from the normal, phi from +x towards +y), BRDF in 1/sr\n\
         NUM_POINTS 3\n\
         VARS theta_i,phi_i,theta_s,phi_s,value\n\
         30,0,30,180,0.25\n\
         30,0,45,170,0.125\n\
         20,0,60,90,2.5e-6\n"
    );
    // Two wavelengths: a VARS column each, named as the channels are.
    let spectral = put(
        &d,
        "spectral.csv",
        &samples_csv(&["450nm", "550nm"], values),
    );
    let astm = d.join("spectral.astm");
    ok(&[
        "export",
        &s(&spectral),
        "--format",
        "astm",
        "--out",
        &s(&astm),
    ]);
    let text = std::fs::read_to_string(&astm).expect("astm");
    assert_eq!(
        text,
        "# ASTM E1392-style BRDF written by Gonio\n\
         # angles in degrees (theta from the normal, phi from +x towards +y), BRDF in 1/sr\n\
         NUM_POINTS 3\n\
         VARS theta_i,phi_i,theta_s,phi_s,450nm,550nm\n\
         30,0,30,180,0.25,0.5\n\
         30,0,45,170,0.125,0.0625\n\
         20,0,60,90,2.5e-6,0.75\n"
    );
    // Read back as spectral data: to the long form (a row per wavelength) and back
    // to ASTM, the same bytes.
    let long = d.join("spectral-long.csv");
    ok(&[
        "export",
        &s(&astm),
        "--format",
        "csv-long",
        "--out",
        &s(&long),
    ]);
    let r = rows(&long);
    assert_eq!(r.len(), 6);
    assert_eq!(r[4], vec![20.0, 0.0, 60.0, 90.0, 450.0, 2.5e-6]);
    assert_eq!(r[5], vec![20.0, 0.0, 60.0, 90.0, 550.0, 0.75]);
    let again = d.join("again.astm");
    ok(&["export", &s(&long), "--format", "astm", "--out", &s(&again)]);
    assert_eq!(std::fs::read_to_string(&again).expect("again"), text);
}

#[test]
fn albedo_is_plotted_against_wavelength_for_a_spectrum() {
    let d = scratch("spectral-plot");
    let model = lambert3(&d);
    // The plot's numbers, from a tabulated Lambertian spectrum read back from the
    // long form: ρ(λ) at every wavelength and θi, to the quadrature's 0.5%.
    let long = d.join("t.csv");
    ok(&[
        "export",
        &s(&model),
        "--format",
        "csv-long",
        "--out",
        &s(&long),
    ]);
    let opened = gonio_dataset::open(&long, &OpenOptions::default()).expect("opens");
    let b = opened.data.brdf().expect("a table");
    let v = plot::spectral_albedo_values(
        &Source::Brdf(b),
        None,
        &[0.0, 35.0, 65.0],
        &AlbedoOptions::default(),
    )
    .expect("values");
    assert_eq!(v.wavelengths_nm, vec![450.0, 550.0, 650.0]);
    for row in &v.data {
        for (a, r) in row.iter().zip(RHO) {
            assert!((a / r - 1.0).abs() < 5e-3, "{a} vs {r}");
        }
    }
    // `gonio plot --kind albedo` on several wavelengths draws that figure.
    let svg = d.join("albedo.svg");
    ok(&[
        "plot",
        &s(&model),
        "--kind",
        "albedo",
        "--theta-i",
        "0,35",
        "--out",
        &s(&svg),
    ]);
    let text = std::fs::read_to_string(&svg).expect("svg");
    for want in ["wavelength λ (nm)", "θi = 0°", "θi = 35°", "ρ(λ)"] {
        assert!(text.contains(want), "missing {want:?}");
    }
    // One channel chosen: the θi figure as before.
    let one = d.join("one.svg");
    ok(&[
        "plot",
        &s(&model),
        "--kind",
        "albedo",
        "--channel",
        "550nm",
        "--out",
        &s(&one),
    ]);
    let text = std::fs::read_to_string(&one).expect("svg");
    assert!(text.contains("θi (degrees)") && !text.contains("wavelength λ"));
}
