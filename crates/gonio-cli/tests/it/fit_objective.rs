//! `gonio fit --objective` and `--conserve-energy` through the binary: the objective
//! is said in the text report, the JSON and the model file; the energy-constrained fit
//! reports its active set.

use crate::common;

use common::{gonio, ok, ok_json, s, scratch};
use gonio_brdf::Model;
use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use gonio_process::Samples;

/// A diffuse 0.6 and a lobe about the mirror direction: albedo 1.28 at normal
/// incidence.
const BRIGHT: &str = "kind = \"lafortune\"\nchannels = [\"value\"]\n[diffuse]\nrho = [0.6]\n\
                      [[lobes]]\ncx = [-1.0266]\ncy = [-1.0266]\ncz = [1.0266]\nn = [10.0]\n";

/// The model's samples on θi 0…70° by 10°, θo 5…85° by 10°, φo by 30°, with σ = 1%
/// of the value when `sigma`.
fn csv(dir: &std::path::Path, sigma: bool) -> std::path::PathBuf {
    let model = Model::from_toml(BRIGHT, None).expect("model");
    let mut pairs = Vec::new();
    for ti in (0..=70).step_by(10) {
        for to in (5..=85).step_by(10) {
            for k in 0..12 {
                pairs.push(PairDeg {
                    incident: SphericalDeg::new(f64::from(ti), 0.0),
                    outgoing: SphericalDeg::new(f64::from(to), 30.0 * f64::from(k)),
                });
            }
        }
    }
    let mut samples = Samples::from_brdf(&model, &pairs);
    if sigma {
        for x in &mut samples.samples {
            x.sigma = Some(x.value.iter().map(|v| 0.01 * v).collect());
        }
    }
    let path = dir.join(if sigma { "sigma.csv" } else { "plain.csv" });
    std::fs::write(&path, gonio_process::file::write_samples(&samples)).expect("write");
    path
}

fn fitted(path: &std::path::Path) -> (String, Model) {
    let text = std::fs::read_to_string(path).expect("model file");
    let m = Model::from_toml(&text, Some(path)).expect("the model file loads");
    (text, m)
}

#[test]
fn the_objective_is_said_in_the_report_the_json_and_the_model_file() {
    let d = scratch("fit-objective");
    let with = csv(&d, true);
    let out = d.join("fit.toml");
    let o = ok(&["fit", &s(&with), "--lobes", "1", "--out", &s(&out)]);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        text.contains("objective chi2 (default: every sample has σ > 0): minimises the sum of ((f_model - f_data) / σ)²"),
        "{text}"
    );
    let (file, model) = fitted(&out);
    assert!(file.contains("[fit]\nobjective = \"chi2\""), "{file}");
    let Model::Lafortune(l) = model else {
        panic!("lafortune")
    };
    assert_eq!(l.fit_note().expect("note").objective, "chi2");

    for (args, want) in [
        (vec![], "cosine"),
        (vec!["--objective", "relative"], "relative"),
        (vec!["--unweighted"], "cosine"),
    ] {
        let input = if want == "cosine" && args.is_empty() {
            csv(&d, false)
        } else {
            with.clone()
        };
        let mut a = vec!["fit", "--lobes", "1", "--force", "--json", "--out"];
        let (i, o) = (s(&input), s(&out));
        a.push(&o);
        a.push(&i);
        a.extend(args.iter().copied());
        let r = ok_json(&a);
        assert_eq!(r["fit"]["objective"]["name"], want, "{args:?}: {r}");
        assert!(r["fit"]["objective"]["formula"].is_string());
        let (file, _) = fitted(&out);
        assert!(
            file.contains(&format!("objective = \"{want}\"")),
            "{args:?}: {file}"
        );
    }
}

#[test]
fn a_bad_objective_is_refused_with_exit_2() {
    let d = scratch("fit-objective-bad");
    let with = csv(&d, true);
    let plain = csv(&d, false);
    let out = s(&d.join("x.toml"));
    for args in [
        vec!["fit", &s(&with), "--objective", "l2", "--out", &out],
        vec![
            "fit",
            &s(&with),
            "--objective",
            "chi2",
            "--unweighted",
            "--out",
            &out,
        ],
        // χ² needs σ on every sample.
        vec!["fit", &s(&plain), "--objective", "chi2", "--out", &out],
    ] {
        let o = gonio(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", common::stderr(&o));
    }
}

#[test]
fn conserve_energy_reports_the_active_set_and_holds_every_incidence() {
    let d = scratch("fit-energy");
    let with = csv(&d, true);
    let out = d.join("fit.toml");
    let r = ok_json(&[
        "fit",
        &s(&with),
        "--lobes",
        "1",
        "--conserve-energy",
        "--out",
        &s(&out),
        "--json",
    ]);
    let e = &r["fit"]["energy"];
    assert_eq!(e["constrained"], true, "{r}");
    assert_eq!(e["directions"], 8);
    let ch = &e["channels"][0];
    assert!(ch["unconstrained_max_albedo"].as_f64().expect("albedo") > 1.2);
    assert!(ch["max_albedo"].as_f64().expect("albedo") <= 1.0 + 1e-6);
    assert!(ch["cost"].as_f64() >= ch["unconstrained_cost"].as_f64());
    let active = ch["active"].as_array().expect("active set");
    assert!(!active.is_empty());
    assert!(active.iter().all(|a| a["multiplier"].as_f64() > Some(0.0)));
    // The model file's own albedo at each incidence of the data.
    let (_, model) = fitted(&out);
    let mut a = [0.0];
    for t in (0..=70).step_by(10) {
        gonio_brdf::Brdf::albedo(
            &model,
            gonio_core::Dir::from_angles(f64::from(t).to_radians(), 0.0),
            &mut a,
        );
        assert!(a[0] <= 1.0 + 1e-6, "θi {t}: {}", a[0]);
    }
    let o = ok(&[
        "fit",
        &s(&with),
        "--lobes",
        "1",
        "--conserve-energy",
        "--out",
        &s(&out),
        "--force",
    ]);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        text.contains("the constrained optimum") && text.contains("multiplier"),
        "{text}"
    );
}
