//! Spectral runs: the simulated goniometer behind a simulated Cornerstone 130
//! monochromator (config/instrument-spectral.toml with config/sim-spectral.toml)
//! measures a paint whose BRDF changes with wavelength; the reduction recovers
//! f_r(λ) at every wavelength within its stated uncertainty, and the order-sorting
//! filter is what keeps second-order light out of the long wavelengths.

use crate::truth;

use std::path::PathBuf;

use gonio_brdf::{Brdf, Model};
use gonio_driver::InstrumentConfig;
use gonio_reduce::{Options, Reduction, reduce};
use gonio_run::RunStore;
use gonio_sim::SimConfig;
use truth::root;

/// In-plane at two incidences, ten wavelengths from 400 to 760 nm, a dark and the
/// incident beam at every wavelength.
const PLAN: &str = r#"
name = "spectral truth"
wavelengths = { from = 400, to = 760, step = 40 }
[points]
kind = "in-plane"
phi_i = 0
theta_i = [15, 45]
theta_o = { from = -60, to = 60, step = 20 }
[calibration]
dark = true
incident = { transmittance = 1e-3 }
"#;

/// Measures `PLAN` on the simulated spectral instrument, with `tweak` applied to
/// the instrument config; returns the run and the sample.
fn measure(name: &str, seed: u64, tweak: impl FnOnce(&mut InstrumentConfig)) -> (PathBuf, Model) {
    let (mut inst, inst_text) =
        InstrumentConfig::load_with_text(&root().join("config/instrument-spectral.toml"))
            .expect("inst");
    tweak(&mut inst);
    let sim_path = root().join("config/sim-spectral.toml");
    let (path, store, model) = truth::Run {
        name: &format!("spectral-{name}"),
        instrument: (&inst, inst_text),
        sim: &SimConfig::load(&sim_path).expect("sim"),
        sim_text: std::fs::read_to_string(&sim_path).expect("sim text"),
        plan_text: PLAN,
        seed,
    }
    .acquire();
    drop(store);
    (path, model)
}

/// The sample's f_r at every sample of `red` and every channel of the reduction
/// (wavelengths), interpolated linearly between the model's wavelength channels.
fn truth(red: &Reduction, model: &Model) -> Vec<Vec<f64>> {
    let gonio_core::Channels::Wavelengths(mw) = model.channels().clone() else {
        panic!("the sample is spectral");
    };
    let gonio_core::Channels::Wavelengths(rw) = red.samples.channels.clone() else {
        panic!("the reduction is spectral: {}", red.samples.channels);
    };
    let mut out = vec![0.0; mw.len()];
    red.samples
        .samples
        .iter()
        .map(|s| {
            let d = s.pair.to_dirs();
            model.eval(d.wi, d.wo, &mut out);
            rw.iter()
                .map(|nm| gonio_sim::spectral::interpolate(&mw, &out, *nm))
                .collect()
        })
        .collect()
}

/// Per channel, χ²/n of (f − f_true) against the full covariance: the independent
/// terms (noise, resolution, drift) on the diagonal, and the channel's own dark,
/// calibration and wavelength terms each a rank-one shared term (the wavelength
/// scale's one error moves every sample of a wavelength, each by its own slope;
/// Woodbury, as `truth::chi2_correlated`); then the plain χ²/n and the mean
/// relative error.
fn chi2_per_channel(red: &Reduction, model: &Model) -> Vec<(f64, f64, f64)> {
    const SHARED: [usize; 3] = [2, 3, 7];
    let truth = truth(red, model);
    let nc = red.samples.channels.len();
    (0..nc)
        .map(|c| {
            let (mut q, mut b, mut g) = (0.0, [0.0; 3], [[0.0; 3]; 3]);
            let (mut rel, mut plain) = (0.0, 0.0);
            for ((s, terms), t) in red.samples.samples.iter().zip(&red.budget).zip(&truth) {
                let r = s.value[c] - t[c];
                rel += r / t[c];
                plain += (r / s.sigma.as_ref().expect("σ")[c]).powi(2);
                let u = &terms[c];
                let dvar = u[0] * u[0] + u[1] * u[1] + u[4] * u[4];
                q += r * r / dvar;
                for (a, &ka) in SHARED.iter().enumerate() {
                    b[a] += u[ka] * r / dvar;
                    for (k, &kc) in SHARED.iter().enumerate() {
                        g[a][k] += u[ka] * u[kc] / dvar;
                    }
                }
            }
            for (a, row) in g.iter_mut().enumerate() {
                row[a] += 1.0;
            }
            let x = truth::solve3(g, b);
            let n = red.samples.samples.len() as f64;
            let chi2 = q - b.iter().zip(x).map(|(b, x)| b * x).sum::<f64>();
            (chi2 / n, plain / n, rel / n)
        })
        .collect()
}

fn wavelengths(red: &Reduction) -> Vec<f64> {
    match &red.samples.channels {
        gonio_core::Channels::Wavelengths(w) => w.to_vec(),
        other => panic!("not spectral: {other}"),
    }
}

/// Every wavelength's f_r within its σ of the truth over four seeds (each its own
/// draw of the monochromator's calibration error, as `config/sim-spectral.toml`
/// asks): χ²/n against the full covariance near 1 on average over the seeds, and at
/// no wavelength of any seed far from it. Before the twin drew its error (a fixed
/// 0.05 nm against the config's stated 0.1 nm) the mean was 0.48: a σ twice what
/// the instrument did.
#[test]
fn a_spectral_run_reduces_to_the_truth_at_every_wavelength() {
    let (mut full, mut plain) = (Vec::new(), Vec::new());
    for seed in [21, 22, 23, 24] {
        let (path, model) = measure("truth", seed, |_| {});
        let store = RunStore::open(&path).expect("opens");
        let red = reduce(&store, &Options::default()).expect("reduces");
        truth::assert_covariance_adds_up(&red);
        let w = wavelengths(&red);
        assert_eq!(
            w,
            [
                400.0, 440.0, 480.0, 520.0, 560.0, 600.0, 640.0, 680.0, 720.0, 760.0
            ]
        );
        // 2 × 7 pairs, less the two where the arms shadow the beam.
        assert_eq!(red.samples.samples.len(), 12);
        let per = chi2_per_channel(&red, &model);
        for (nm, (chi, p, rel)) in w.iter().zip(&per) {
            println!("seed {seed} {nm} nm: χ²/n {chi:.2} (plain {p:.2}), mean rel {rel:+.2e}");
            assert!(*chi < 4.0, "seed {seed} {nm} nm: χ²/n {chi}");
        }
        let n = per.len() as f64;
        full.push(per.iter().map(|p| p.0).sum::<f64>() / n);
        plain.push(per.iter().map(|p| p.1).sum::<f64>() / n);
        println!(
            "seed {seed}: mean χ²/n {:.2} (plain {:.2})",
            full[full.len() - 1],
            plain[plain.len() - 1]
        );
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    println!(
        "over the seeds: χ²/n {:.3} (plain {:.3})",
        mean(&full),
        mean(&plain)
    );
    assert!(
        (0.8..=1.25).contains(&mean(&full)),
        "mean χ²/n {}",
        mean(&full)
    );
}

/// With the order-sorting filter left out (the session's automatic choice turned
/// off), second-order light at λ/2 reaches the detector above twice the lamp's
/// shortest light: the paint reflects its blue (at λ/2) four times better than its
/// red, so the long wavelengths read high, by many σ, while the short ones — where
/// no filter is needed — are unchanged.
#[test]
fn without_the_order_filter_second_order_light_shows_at_long_wavelengths() {
    let (path, model) = measure("second-order", 21, |inst| {
        let m = inst.monochromator.as_mut().expect("monochromator");
        m.cs130.auto_order_filter = false;
    });
    let store = RunStore::open(&path).expect("opens");
    let red = reduce(&store, &Options::default()).expect("reduces");
    let w = wavelengths(&red);
    let per = chi2_per_channel(&red, &model);
    for (nm, (chi, _, rel)) in w.iter().zip(&per) {
        println!("no filter {nm} nm: χ²/n {chi:.1}, mean rel {rel:+.2e}");
    }
    for (nm, (chi, _, rel)) in w.iter().zip(&per) {
        if *nm >= 680.0 {
            // λ/2 ≥ 340 nm: the lamp's blue through the grating's second order.
            assert!(*chi > 25.0 && *rel > 0.01, "{nm} nm: χ²/n {chi}, rel {rel}");
        }
        if *nm <= 480.0 {
            // λ/2 ≤ 240 nm: below the shortest light in the beam, nothing to sort.
            assert!(*chi < 4.0, "{nm} nm: χ²/n {chi}");
        }
    }
}
