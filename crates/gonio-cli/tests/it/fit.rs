//! `gonio fit` through the whole stack: the simulated goniometer measures the blue
//! paint of Lafortune et al. (Table 1, the simulator's default sample), the run is
//! reduced and fitted, and the fitted model's error against the true one is at the
//! noise level of the readings.

use crate::common;

use common::{acquire, gonio, ok_json, root, s, scratch};
use gonio_brdf::{Brdf, Model};
use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;

const PLAN: &str = r#"
name = "blue paint, isotropic hemisphere"
[points]
kind = "isotropic"
theta_i = [10, 30, 50, 70]
theta_o = { from = 5, to = 85, step = 10 }
delta_phi = { from = 0, to = 180, step = 45 }
[calibration]
dark = true
dark_readings = 1
incident = { transmittance = 1e-3 }
"#;

#[test]
fn a_simulated_acquisition_reduced_and_fitted_recovers_the_paint_to_the_noise() {
    let d = scratch("fit");
    let run = acquire(&d, PLAN);
    let samples = d.join("samples.csv");
    ok_json(&["reduce", &s(&run), "--out", &s(&samples), "--json"]);
    let fit_file = d.join("fit.toml");
    let r = ok_json(&[
        "fit",
        &s(&run),
        "--lobes",
        "3",
        "--out",
        &s(&fit_file),
        "--json",
    ]);
    let ch = &r["fit"]["channels"][0];
    let chi2 = ch["reduced_chi2"].as_f64().expect("χ²");
    eprintln!("reduced χ² {chi2}, relative RMS {}", ch["relative_rms"]);
    // A χ² fit to honest uncertainties: the residuals are the noise.
    assert!(chi2 < 3.0, "reduced χ² {chi2}");

    // Against the truth, at the measured pairs: the fitted model is as close to the
    // paint as the readings' own noise, or closer.
    let truth = Model::from_toml(
        &std::fs::read_to_string(root().join("config/models/blue-paint-550nm.toml"))
            .expect("truth"),
        None,
    )
    .expect("model");
    let fitted =
        Model::from_toml(&std::fs::read_to_string(&fit_file).expect("fit"), None).expect("fit");
    let text = std::fs::read_to_string(&samples).expect("samples");
    let (mut err2, mut sig2, mut n) = (0.0, 0.0, 0);
    let (mut a, mut b) = ([0.0], [0.0]);
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
        truth.eval(dirs.wi, dirs.wo, &mut a);
        fitted.eval(dirs.wi, dirs.wo, &mut b);
        err2 += (a[0] - b[0]).powi(2);
        sig2 += f[5] * f[5];
        n += 1;
    }
    let (err, sig) = ((err2 / n as f64).sqrt(), (sig2 / n as f64).sqrt());
    eprintln!("{n} pairs: fitted − true RMS {err:.3e}, readings' σ RMS {sig:.3e}");
    assert!(n > 100);
    assert!(err < sig, "fit error {err} against noise {sig}");
}

#[test]
fn fit_refuses_bad_input_with_exit_2() {
    let d = scratch("fit-bad");
    let one = d.join("one.csv");
    std::fs::write(
        &one,
        "theta_i,phi_i,theta_o,phi_o,value\n30,0,20,0,0.1\n30,0,40,0,0.2\n",
    )
    .expect("write");
    let o = gonio(&["fit", &one.display().to_string(), "--out", "x.toml"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("one incident direction"));
    let o = gonio(&[
        "fit",
        &one.display().to_string(),
        "--model",
        "phong",
        "--out",
        "x.toml",
    ]);
    assert_eq!(o.status.code(), Some(2));
    let o = gonio(&[
        "fit",
        &one.display().to_string(),
        "--cutoff",
        "0",
        "--out",
        "x.toml",
    ]);
    assert_eq!(o.status.code(), Some(2));
}
