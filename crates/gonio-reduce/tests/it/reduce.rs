//! Reduction of simulated runs: the BRDF the simulator's sample has, recovered from
//! raw lock-in readings within the propagated uncertainties, with and without a
//! drifting source.

use crate::truth;

use gonio_brdf::Model;
use gonio_reduce::{self as reduce, Drift, Options};

const PLAN: &str = r#"
name = "reduction test"
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

/// Measures PLAN on the simulator (seed 7) with a source drifting by `drift_per_hour`.
fn measure(name: &str, drift_per_hour: f64) -> (gonio_run::RunStore, Model) {
    truth::measure(name, PLAN, None, 7, |sim| {
        sim.optics.drift_per_hour = drift_per_hour;
    })
}

/// Normalised residuals (f − model)/σ and relative errors of a reduction.
fn residuals(red: &reduce::Reduction, model: &Model) -> (Vec<f64>, Vec<f64>) {
    truth::residuals(red, model).into_iter().unzip()
}

#[test]
fn a_steady_source_reduces_to_the_sample_brdf_within_its_uncertainty() {
    let (store, model) = measure("steady", 0.0);
    let red = reduce::reduce(&store, &Options::default()).expect("reduces");
    // 2 incidences × 15 θo, less the pairs the arms cannot reach (the source's own
    // direction and its 8° exclusion).
    assert!(
        red.samples.samples.len() >= 26,
        "{}",
        red.samples.samples.len()
    );
    assert_eq!(red.report.unmeasured, 0);
    let (z, rel) = residuals(&red, &model);
    let rms_z = (z.iter().map(|x| x * x).sum::<f64>() / z.len() as f64).sqrt();
    let worst = rel.iter().map(|x| x.abs()).fold(0.0, f64::max);
    // The uncertainties are honest: residuals scatter like unit normals.
    assert!(
        rms_z > 0.3 && rms_z < 2.0,
        "RMS normalised residual {rms_z}"
    );
    assert!(z.iter().all(|x| x.abs() < 5.0), "{z:?}");
    assert!(worst < 0.01, "worst relative error {worst}");
    let ch = &red.report.channels[0];
    assert_eq!(ch.calibration, "incident");
    assert_eq!(ch.calibration_readings, 2);
    assert!(ch.drift_max < 0.01, "{}", ch.drift_max);
}

#[test]
fn a_drifting_source_is_corrected_by_the_reference_readings() {
    // 120 %/h over a run of a few minutes: several per cent of drift.
    let (store, model) = measure("drift", 1.2);
    let with = |drift| {
        reduce::reduce(
            &store,
            &Options {
                drift,
                ..Options::default()
            },
        )
        .expect("reduces")
    };
    let (refs, cals, none) = (
        with(Drift::Auto),
        with(Drift::Calibrations),
        with(Drift::None),
    );
    let ch = &refs.report.channels[0];
    assert!(ch.drift_max > 0.01, "drift seen: {}", ch.drift_max);
    assert_eq!(ch.drift_readings, 7);
    let worst = |r: &reduce::Reduction| {
        let (z, rel) = residuals(r, &model);
        (
            rel.iter().map(|x| x.abs()).fold(0.0, f64::max),
            z.iter().map(|x| x.abs()).fold(0.0, f64::max),
        )
    };
    let (w_none, _) = worst(&none);
    let (w_refs, z_refs) = worst(&refs);
    let (w_cals, _) = worst(&cals);
    // Uncorrected, the drift shows at its full size; the references remove it to the
    // noise level; so does interpolating the start and end calibrations, the drift
    // being linear here.
    eprintln!("worst relative error: none {w_none}, references {w_refs}, calibrations {w_cals}");
    assert!(w_none > 0.03, "uncorrected: {w_none}");
    assert!(
        w_refs < 0.002 && z_refs < 5.0,
        "references: {w_refs}, |z| ≤ {z_refs}"
    );
    assert!(w_cals < 0.01, "calibrations: {w_cals}");
}
