//! DC runs: a simulated Keithley 6485 on a photodiode (config/instrument-mixed.toml
//! with config/sim-mixed.toml) reduced with the picoammeter's own budget — the
//! scalar dark, s/√n noise, the seven-digit replies and the range accuracy.

use crate::truth;

use std::path::PathBuf;

use gonio_brdf::{Brdf, Model};
use gonio_driver::InstrumentConfig;
use gonio_plan::StepKind;
use gonio_reduce::{DC_TERMS, Detector, Options, Reduction, reduce};
use gonio_run::{ReadingRecord, RunStore};
use gonio_sim::SimConfig;
use truth::root;

/// In-plane scans with drift references, a dark and the incident beam through ND3,
/// repeated at the end: the incident beam is read on 2 µA, the samples on the
/// nA ranges.
const PLAN: &str = r#"
name = "dc reduction"
[points]
kind = "in-plane"
phi_i = 0
theta_i = [10, 40]
theta_o = { from = -70, to = 70, step = 10 }
[drift]
every = 5
at = [0, 0, 30, 180]
[calibration]
dark = true
incident = { transmittance = 1e-3 }
repeat_at_end = true
"#;

/// One dark, one incident reading (at `transmittance`), no drift references: the
/// calibration is a single reading, for hand computations.
fn single(transmittance: f64) -> String {
    format!(
        r#"
name = "dc hand computation"
[points]
kind = "in-plane"
phi_i = 0
theta_i = [30]
theta_o = {{ from = -70, to = 70, step = 5 }}
[calibration]
dark = true
dark_readings = 1           # one dark: the hand computation's
incident = {{ transmittance = {transmittance} }}
"#
    )
}

/// Measures `plan_text` on the simulated mixed-family instrument (its picoammeter
/// the detector) into a fresh `run.gonio`; returns its path and the sample model.
fn measure(name: &str, plan_text: &str, seed: u64) -> (PathBuf, Model) {
    measure_with(name, plan_text, seed, |_| {})
}

/// [`measure`], after `tweak` has changed the simulator's config.
fn measure_with(
    name: &str,
    plan_text: &str,
    seed: u64,
    tweak: impl FnOnce(&mut SimConfig),
) -> (PathBuf, Model) {
    let (inst, inst_text) =
        InstrumentConfig::load_with_text(&root().join("config/instrument-mixed.toml"))
            .expect("inst");
    let sim_path = root().join("config/sim-mixed.toml");
    let mut sim = SimConfig::load(&sim_path).expect("sim");
    tweak(&mut sim);
    let (path, store, model) = truth::Run {
        name: &format!("dc-{name}"),
        instrument: (&inst, inst_text),
        sim: &sim,
        sim_text: std::fs::read_to_string(&sim_path).expect("sim text"),
        plan_text,
        seed,
    }
    .acquire();
    drop(store);
    (path, model)
}

/// χ²/n of (f − f_true) with the independent terms (noise, resolution) on the
/// diagonal and the dark and the calibration as rank-one shared terms (Woodbury,
/// as `truth::chi2_correlated`). The range accuracy is left out: the simulated
/// meter is exact on every range, so the residuals carry none of it (it would only
/// shrink χ²).
fn chi2_without_range(red: &Reduction, model: &Model) -> f64 {
    const SHARED: [usize; 2] = [2, 3];
    let mut out = vec![0.0; model.channels().len()];
    let (mut q, mut b, mut g) = (0.0, [0.0; 2], [[0.0; 2]; 2]);
    for (s, terms) in red.samples.samples.iter().zip(&red.budget) {
        let d = s.pair.to_dirs();
        model.eval(d.wi, d.wo, &mut out);
        let r = s.value[0] - out[0];
        let t = &terms[0];
        let dvar = t[0] * t[0] + t[1] * t[1] + t[4] * t[4];
        q += r * r / dvar;
        for (a, &ka) in SHARED.iter().enumerate() {
            b[a] += t[ka] * r / dvar;
            for (c, &kc) in SHARED.iter().enumerate() {
                g[a][c] += t[ka] * t[kc] / dvar;
            }
        }
    }
    g[0][0] += 1.0;
    g[1][1] += 1.0;
    let det = g[0][0] * g[1][1] - g[0][1] * g[1][0];
    let x = [
        (g[1][1] * b[0] - g[0][1] * b[1]) / det,
        (g[0][0] * b[1] - g[1][0] * b[0]) / det,
    ];
    (q - b[0] * x[0] - b[1] * x[1]) / red.samples.samples.len() as f64
}

/// The reading of every sample of a reduction (its nominal pair's step), with the
/// dark and the incident readings.
struct Readings {
    samples: Vec<ReadingRecord>,
    darks: Vec<ReadingRecord>,
    incident: Vec<ReadingRecord>,
}

fn readings(store: &RunStore, red: &Reduction) -> Readings {
    let steps = store.steps().expect("steps");
    let all = store.readings().expect("readings");
    let of = |id: i64| all.iter().rev().find(|r| r.step_id == id).cloned();
    let kind = |k: StepKind| -> Vec<ReadingRecord> {
        steps
            .iter()
            .filter(|s| s.step.kind == k)
            .filter_map(|s| of(s.id))
            .collect()
    };
    let samples = red
        .samples
        .samples
        .iter()
        .map(|s| {
            let step = steps
                .iter()
                .find(|t| t.step.kind == StepKind::Sample && t.step.pair == Some(s.pair))
                .expect("the sample's step");
            of(step.id).expect("its reading")
        })
        .collect();
    Readings {
        samples,
        darks: kind(StepKind::Dark),
        incident: kind(StepKind::Incident),
    }
}

#[test]
fn the_instrument_config_names_the_detector() {
    let mixed = std::fs::read_to_string(root().join("config/instrument-mixed.toml")).expect("m");
    let sim = std::fs::read_to_string(root().join("config/instrument-sim.toml")).expect("s");
    assert_eq!(Detector::of_instrument(&mixed), Detector::Dc);
    assert_eq!(Detector::of_instrument(&sim), Detector::LockIn);
    assert_eq!(Detector::of_instrument(""), Detector::LockIn);
    assert_eq!(Detector::of_instrument("not toml ["), Detector::LockIn);
}

/// Over four seeds, the reduced BRDF against the simulated paint. The simulated
/// picoammeter has noise but no range gain or offset error, so the residuals are held
/// against the independent terms with the dark and calibration as rank-one
/// correlations: χ²/n near 1 (seeds 11–14: 1.26, 0.88, 0.97, 1.23), and a mean relative
/// error of a few 1e-5, far inside the range-accuracy σ (1.7e-3), which with the full σ
/// makes χ²/n near 0. (Before the simulated APT stages homed to the instrument's zero,
/// the sample stood 4° off and the residuals showed it as a 0.3 % bias: this test is
/// what found it.)
#[test]
fn a_dc_run_reduces_to_the_truth_within_its_stated_uncertainty() {
    let mut chis = Vec::new();
    for seed in [11, 12, 13, 14] {
        let (path, model) = measure("truth", PLAN, seed);
        let store = RunStore::open(&path).expect("opens");
        let red = reduce(&store, &Options::default()).expect("reduces");
        truth::assert_covariance_adds_up(&red);
        assert_eq!(red.detector, Detector::Dc);
        let n = red.samples.samples.len();
        assert!(n >= 26, "{n} samples");
        let chi = chi2_without_range(&red, &model);
        let plain = truth::chi2(&truth::residuals(&red, &model));
        let ch = &red.report.channels[0];
        println!(
            "seed {seed}: {n} samples, χ²/n {chi:.3} (noise, resolution, drift; dark and \
             calibration correlated), {plain:.4} with the full σ; incident {:.4e} A, dark {:.3e} A, \
             mean rel. error {:+.2e}",
            ch.incident_v,
            ch.dark_v[0],
            truth::mean_rel(&truth::residuals(&red, &model))
        );
        if seed == 11 {
            for t in &ch.budget {
                println!(
                    "    {:<14} {:.2e} median, {:.2e} max ({}): {}",
                    t.term, t.rel_median, t.rel_max, t.correlation, t.source
                );
            }
        }
        // Every term of the DC budget is reported, the range accuracy last of them, in
        // amps; then the position term.
        let terms: Vec<&str> = ch.budget.iter().map(|t| t.term).collect();
        assert_eq!(terms[..DC_TERMS.len()], DC_TERMS);
        assert_eq!(terms[DC_TERMS.len()..], [gonio_reduce::POSITION_TERM]);
        assert_eq!(ch.budget[6].correlation, "range");
        assert!(ch.budget[6].rel_median > 0.0);
        for t in &ch.budget {
            assert!(!t.source.contains(" V"), "{}", t.source);
        }
        assert!(
            ch.budget[2].source.contains(" A"),
            "{}",
            ch.budget[2].source
        );
        // The budget is the σ.
        for (s, b) in red.samples.samples.iter().zip(&red.budget) {
            let sum = b[0].iter().map(|x| x * x).sum::<f64>().sqrt();
            let sigma = s.sigma.as_ref().expect("σ")[0];
            assert!((sum - sigma).abs() <= 1e-12 * sigma, "{sum} vs {sigma}");
        }
        let bias = truth::mean_rel(&truth::residuals(&red, &model));
        let range_sigma = ch.budget[6].rel_median;
        assert!(
            bias.abs() < 1e-4 && bias.abs() < 0.1 * range_sigma,
            "{bias} vs {range_sigma}"
        );
        assert!(plain < 0.05, "χ²/n {plain} with the full σ");
        chis.push((plain, chi));
    }
    let mean = chis.iter().map(|c| c.1).sum::<f64>() / chis.len() as f64;
    println!("mean χ²/n over the seeds without the range accuracy: {mean:.3}; {chis:?}");
    assert!((0.6..1.6).contains(&mean), "{chis:?}");
}

/// Adding a known offset to every stored current (the darks too) moves the dark by
/// exactly that offset and leaves every BRDF value as it was: the dark is a scalar
/// subtracted with its sign (a vector or Rayleigh dark would not cancel).
#[test]
fn a_dark_offset_is_removed_exactly() {
    let (path, _) = measure("offset", &single(1e-3), 21);
    let shifted = path.with_file_name("shifted.gonio");
    std::fs::copy(&path, &shifted).expect("copy");
    const OFFSET: f64 = 7.5e-10;
    {
        let db = rusqlite::Connection::open(&shifted).expect("sqlite");
        let n = db
            .execute(
                "UPDATE readings SET x_mean = x_mean + ?1, r_mean = r_mean + ?1",
                [OFFSET],
            )
            .expect("update");
        assert!(n > 10, "{n}");
    }
    let before = reduce(&RunStore::open(&path).expect("opens"), &Options::default()).expect("r");
    // The readings' checksums no longer match: open without the integrity check.
    let store = RunStore::open_unverified(&shifted).expect("opens");
    let after = reduce(&store, &Options::default()).expect("reduces");
    let (d0, d1) = (
        before.report.channels[0].dark_v,
        after.report.channels[0].dark_v,
    );
    println!("dark {:.6e} A → {:.6e} A", d0[0], d1[0]);
    assert!((d1[0] - d0[0] - OFFSET).abs() < 1e-22, "{d0:?} → {d1:?}");
    assert_eq!((d0[1], d1[1]), (0.0, 0.0), "a scalar dark");
    assert_eq!(before.samples.samples.len(), after.samples.samples.len());
    let mut worst = 0.0f64;
    for (a, b) in before.samples.samples.iter().zip(&after.samples.samples) {
        assert_eq!(a.pair, b.pair);
        worst = worst.max((a.value[0] - b.value[0]).abs() / a.value[0].abs());
    }
    println!("largest relative change of f: {worst:.2e}");
    assert!(worst < 1e-12, "{worst}");
}

/// The noise term of a reading is s/√n (its samples independent), propagated as
/// σ_f = f · (s/√n)/(I − I_dark); and pooled per range as a + b·I by default, which
/// stays within the scatter of the readings' own s.
#[test]
fn the_noise_of_a_dc_reading_is_its_sample_scatter_over_root_n() {
    let (path, _) = measure("noise", &single(1e-3), 22);
    let store = RunStore::open(&path).expect("opens");
    let own = reduce(
        &store,
        &Options {
            dc_pool_noise: false,
            ..Options::default()
        },
    )
    .expect("reduces");
    let rd = readings(&store, &own);
    let dark = rd.darks.iter().map(|r| r.x_mean).sum::<f64>() / rd.darks.len() as f64;
    assert_eq!(own.report.channels[0].dark_v[0], dark);
    for (k, (s, r)) in own.samples.samples.iter().zip(&rd.samples).enumerate() {
        let f = s.value[0];
        let v = r.x_mean - dark;
        let expected = f * (r.r_std / f64::from(r.n).sqrt()) / v;
        let got = own.budget[k][0][0];
        if k == 3 {
            println!(
                "sample {k}: I = {:.6e} A, s = {:.4e} A, n = {}, dark {dark:.4e} A, f = {f:.6e}/sr: \
                 σ_noise = f (s/√n)/(I − dark) = {expected:.6e}/sr, reduced {got:.6e}/sr",
                r.x_mean, r.r_std, r.n
            );
        }
        assert!(
            (got - expected).abs() <= 1e-12 * expected,
            "{k}: {got} vs {expected}"
        );
    }
    // Pooled, the σ of each reading is the line's, of the same size on average.
    let pooled = reduce(&store, &Options::default()).expect("reduces");
    let ratio: Vec<f64> = pooled
        .budget
        .iter()
        .zip(&own.budget)
        .map(|(p, o)| p[0][0] / o[0][0])
        .collect();
    let mean_sq = ratio.iter().map(|r| r.powi(-2)).sum::<f64>() / ratio.len() as f64;
    println!("mean (own s / pooled σ)² over the samples: {mean_sq:.3}");
    assert!((0.5..2.0).contains(&mean_sq), "{mean_sq}");
}

/// The range-accuracy term, by hand: each reading's error is accuracy_a/√3 on its
/// range, one error per range. A sample on another range than the calibration and
/// the dark has the three in quadrature; a sample on the calibration's range has
/// their difference (the gain cancels, the offset's difference remains).
#[test]
fn the_range_accuracy_is_the_manual_s_bound_over_root_three_per_range() {
    use gonio_proto::k6485::{Range, accuracy_a};
    let u = |r: &ReadingRecord| {
        accuracy_a(Range::new(r.sensitivity).expect("range"), r.x_mean) / 3f64.sqrt()
    };
    let mut seen = (false, false);
    // ND3 puts the incident beam on 2 µA, away from the samples; ND5 on 20 nA,
    // with the brighter samples.
    for t in [1e-3, 1e-5] {
        let (path, _) = measure("range", &single(t), 23);
        let store = RunStore::open(&path).expect("opens");
        let red = reduce(&store, &Options::default()).expect("reduces");
        truth::assert_covariance_adds_up(&red);
        let rd = readings(&store, &red);
        assert_eq!(rd.darks.len(), 1);
        assert_eq!(rd.incident.len(), 1);
        let (dk, inc) = (&rd.darks[0], &rd.incident[0]);
        let dark = dk.x_mean;
        let vc = inc.x_mean - dark;
        for (k, (s, r)) in red.samples.samples.iter().zip(&rd.samples).enumerate() {
            let v = r.x_mean - dark;
            assert_ne!(r.sensitivity, dk.sensitivity, "the dark on its own range");
            // Relative error of f = (I − D)/(I_c − D) per range's error z.
            let dark_coeff = u(dk) * (1.0 / vc - 1.0 / v);
            let rel = if r.sensitivity == inc.sensitivity {
                (u(r) / v - u(inc) / vc).hypot(dark_coeff)
            } else {
                (u(r) / v).hypot(u(inc) / vc).hypot(dark_coeff)
            };
            let expected = rel * s.value[0];
            let got = red.budget[k][0][6];
            assert!(
                (got - expected).abs() <= 1e-12 * expected,
                "{k}: {got} vs {expected}"
            );
            let same = r.sensitivity == inc.sensitivity;
            if !seen.0 && !same || !seen.1 && same {
                println!(
                    "T = {t}: sample {k} on {} ({:.6e} A), incident on {} ({:.6e} A), dark on {} \
                     ({:.4e} A): σ_range/f = {:.4e} (reading {:.4e}, calibration {:.4e}, dark \
                     {:.4e})",
                    Range::new(r.sensitivity).expect("r"),
                    r.x_mean,
                    Range::new(inc.sensitivity).expect("r"),
                    inc.x_mean,
                    Range::new(dk.sensitivity).expect("r"),
                    dark,
                    rel,
                    u(r) / v,
                    u(inc) / vc,
                    dark_coeff
                );
            }
            if same {
                seen.1 = true;
                // On one range the gain error cancels: the term is well below the
                // sample's own gain share.
                let range = Range::new(r.sensitivity).expect("range");
                let gain = (accuracy_a(range, 1.0) - accuracy_a(range, 0.0)) / 3f64.sqrt();
                assert!(rel < 0.5 * gain, "{rel} vs {gain}");
            } else {
                seen.0 = true;
            }
        }
    }
    assert!(seen.0 && seen.1, "both cases: {seen:?}");
}
