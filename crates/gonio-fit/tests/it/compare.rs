//! The comparison models: each recovers data of its own kind, and on lobe data the
//! lobes win.

use gonio_brdf::Model;
use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use gonio_fit::compare::{Kind, fit_model};
use gonio_fit::data::{DataOptions, FitData};
use gonio_process::Samples;

fn pairs() -> Vec<PairDeg> {
    let mut v = Vec::new();
    for ti in (0..=75).step_by(15) {
        for to in (0..=85).step_by(5) {
            for po in (0..360).step_by(20) {
                v.push(PairDeg {
                    incident: SphericalDeg::new(f64::from(ti), 0.0),
                    outgoing: SphericalDeg::new(f64::from(to), f64::from(po)),
                });
            }
        }
    }
    v
}

fn data(text: &str) -> FitData {
    let m = Model::from_toml(text, None).expect("model");
    FitData::from_samples(&Samples::from_brdf(&m, &pairs()), &DataOptions::default()).expect("data")
}

#[test]
fn each_model_recovers_its_own_data() {
    let ward = data(
        "kind = \"ward\"\nchannels = [\"value\"]\nrho_s = [0.3]\nalpha = [0.15]\n[diffuse]\nrho = [0.5]\n",
    );
    let w = &fit_model(Kind::Ward, &ward).expect("fit")[0];
    assert!(
        (w.shape - 0.15).abs() < 1e-6
            && (w.rho_s - 0.3).abs() < 1e-6
            && (w.rho_d - 0.5).abs() < 1e-6,
        "{w:?}"
    );
    assert!(w.relative_rms < 1e-8, "{w:?}");

    let ggx = data(
        "kind = \"cook-torrance\"\nchannels = [\"value\"]\ndistribution = \"ggx\"\nf0 = [0.2]\nalpha = [0.25]\nrho_s = [0.8]\n[diffuse]\nrho = [0.1]\n",
    );
    let fits: Vec<_> = Kind::ALL
        .iter()
        .map(|k| fit_model(*k, &ggx).expect("fit")[0].clone())
        .collect();
    let g = &fits[3];
    assert!(
        (g.shape - 0.25).abs() < 1e-6 && (g.f0.expect("f0") - 0.2).abs() < 1e-6,
        "{g:?}"
    );
    assert!(
        (g.rho_s - 0.8).abs() < 1e-5 && (g.rho_d - 0.1).abs() < 1e-6,
        "{g:?}"
    );
    // GGX data is best fitted by GGX.
    for f in &fits[..3] {
        assert!(
            f.relative_rms > 10.0 * g.relative_rms.max(1e-12),
            "{f:?} vs {g:?}"
        );
    }

    let bp = data(
        "kind = \"blinn-phong\"\nchannels = [\"value\"]\nrho_s = [0.4]\nn = [40]\n[diffuse]\nrho = [0.3]\n",
    );
    let b = &fit_model(Kind::BlinnPhong, &bp).expect("fit")[0];
    assert!(
        (b.shape - 40.0).abs() < 1e-4 && (b.rho_s - 0.4).abs() < 1e-6,
        "{b:?}"
    );
}
