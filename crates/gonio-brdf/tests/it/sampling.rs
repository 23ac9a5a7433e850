//! Every sampler against its pdf: chi-square goodness of fit, the pdf's total mass, the
//! pdf a sample reports against `Brdf::pdf`, and an unbiased Monte Carlo albedo.

use crate::common;

use common::{deg, rng, zoo};
use gonio_brdf::check::{ChiSquareConfig, chi_square};
use gonio_brdf::{Brdf, IncidentSampler};
use rand::Rng;

/// Incident directions per model; φ = 20° so anisotropic models are tilted off-axis.
const THETAS: [f64; 4] = [0.0, 35.0, 65.0, 85.0];

/// Significance 1% over the whole suite, Šidák-corrected for the number of tests.
fn threshold() -> f64 {
    let tests = (zoo().len() * THETAS.len()) as f64;
    1.0 - 0.99f64.powf(1.0 / tests)
}

fn model(name: &str) -> gonio_brdf::Model {
    zoo()
        .into_iter()
        .find(|(n, _)| *n == name)
        .unwrap_or_else(|| panic!("{name} not in the zoo"))
        .1
}

fn chi_square_for(name: &str) {
    let m = model(name);
    let cfg = ChiSquareConfig::default();
    for (k, t) in THETAS.iter().enumerate() {
        let wi = deg(*t, 20.0);
        let mut r = rng(1000 + k as u64);
        let res = chi_square(&m, wi, &cfg, &mut || r.random::<f64>());
        let p_delta = res.mirror_probability;
        assert_eq!(res.failed, 0, "{name} θi={t}: sampler failed");
        assert_eq!(
            res.pdf_mismatches, 0,
            "{name} θi={t}: sample pdf ≠ Brdf::pdf"
        );
        assert!(
            (res.pdf_mass - (1.0 - p_delta)).abs() < 2e-5,
            "{name} θi={t}: pdf integrates to {} over the hemisphere, want {}",
            res.pdf_mass,
            1.0 - p_delta
        );
        // The number of mirror samples is binomial(N, p_delta).
        let n = cfg.samples as f64;
        let sd = (n * p_delta * (1.0 - p_delta)).sqrt().max(1.0);
        assert!(
            (res.delta as f64 - n * p_delta).abs() < 5.0 * sd,
            "{name} θi={t}: {} mirror samples, expected {}",
            res.delta,
            n * p_delta
        );
        assert!(
            res.p_value > threshold(),
            "{name} θi={t}: chi² = {} with {} dof, p = {:e}",
            res.statistic,
            res.dof,
            res.p_value
        );
    }
}

/// The sampler's estimate `mean(f cos θo / pdf)` (mirror samples weighted by their
/// reflectance over their probability) must agree with `Brdf::albedo` to within
/// 5 standard errors: this ties `eval`, `sample`, `pdf` and `albedo` together.
fn monte_carlo_albedo_for(name: &str) {
    let m = model(name);
    let k = m.channels().len();
    let mut f = vec![0.0; k];
    let mut mirror = vec![0.0; k];
    let mut exact = vec![0.0; k];
    for (j, t) in THETAS.iter().enumerate() {
        let wi = deg(*t, 20.0);
        m.albedo(wi, &mut exact);
        let has_mirror = m.mirror(wi, &mut mirror);
        let mut r = rng(2000 + j as u64);
        let sampler = IncidentSampler::new(&m, wi);
        let n = 100_000;
        let (mut sum, mut sum2) = (vec![0.0; k], vec![0.0; k]);
        for _ in 0..n {
            let s = sampler
                .sample(r.random(), [r.random(), r.random()])
                .expect("samplers never fail above the horizon");
            for c in 0..k {
                let w = if s.delta {
                    assert!(has_mirror);
                    mirror[c] / s.pdf
                } else {
                    m.eval(wi, s.wo, &mut f);
                    f[c] * s.wo.z / s.pdf
                };
                sum[c] += w;
                sum2[c] += w * w;
            }
        }
        for c in 0..k {
            let mean = sum[c] / n as f64;
            let var = (sum2[c] / n as f64 - mean * mean).max(0.0);
            let se = (var / n as f64).sqrt();
            assert!(
                (mean - exact[c]).abs() < 5.0 * se + 1e-9,
                "{name} θi={t} channel {c}: MC albedo {mean} ± {se}, albedo() = {}",
                exact[c]
            );
        }
    }
}

macro_rules! per_model {
    ($($test:ident => $name:literal),* $(,)?) => {
        mod chi2 {
            $(#[test] fn $test() { super::chi_square_for($name); })*
        }
        mod mc_albedo {
            $(#[test] fn $test() { super::monte_carlo_albedo_for($name); })*
        }
    };
}

per_model! {
    lambert => "lambert",
    minnaert => "minnaert",
    phong => "phong",
    phong_mirror => "phong-mirror",
    phong_shading => "phong-shading",
    blinn_phong => "blinn-phong",
    ward_iso => "ward-iso",
    ward_aniso => "ward-aniso",
    ct_beckmann => "ct-beckmann",
    ct_ggx_aniso => "ct-ggx-aniso",
    ct_ggx_rough => "ct-ggx-rough",
    oren_nayar => "oren-nayar",
    oren_nayar_q => "oren-nayar-q",
    lafortune_table1 => "lafortune-table1",
    lafortune_aniso_matrix => "lafortune-aniso-matrix",
    lafortune_tilted => "lafortune-tilted",
}

/// Every model in the zoo has a sampling test above.
#[test]
fn every_model_is_covered() {
    assert_eq!(zoo().len(), 16);
}
