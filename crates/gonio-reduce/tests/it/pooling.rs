//! The lock-in's noise pooled across time constants and snapshot counts (reading
//! time, issue 24): synthetic run files whose readings are taken at 10, 30 and
//! 100 ms with 2 … 40 snapshots each, their snapshot scatter following a known
//! white-noise density d(R)² = a' + b'·R behind a 12 dB/oct filter, reduced and
//! compared with the analytic σ of each reading's mean, (d²·ENBW·A(n, ρ)/n)^½.
//!
//! A run at one time constant reduces bit for bit as before: the golden outputs of
//! `gonio-cli/tests/dc_reduce.rs` (`data/sr830-in-plane.{csv,txt,json}`) and the
//! closure, drift and spectral tests of this crate pin that.

use crate::truth;

use gonio_core::rng::SplitMix64;
use gonio_driver::InstrumentConfig;
use gonio_plan::{Plan, StepKind};
use gonio_proto::sr830::{FilterSlope, TimeConstant};
use gonio_reduce::{Options, Reduction, SNAPSHOT_GAP_S, reduce, variance_factors};
use gonio_run::{Inputs, ReadingRecord, RunStore, flags};
use truth::root;

/// One incidence, an in-plane sweep: about sixty sample readings, a dark and the
/// incident beam.
const PLAN: &str = r#"
name = "pooling"
[points]
kind = "in-plane"
phi_i = 0
theta_i = [20, 50]
theta_o = { from = -70, to = 70, step = 5 }
[calibration]
dark = true
incident = { transmittance = 1e-3 }
[order]
optimise = false
"#;

/// The noise density's floor a', V²/Hz (10 nV/√Hz), and its slope b', V/Hz (shot
/// noise): equal at R = 1 mV.
const A_DENSITY: f64 = 1e-16;
const B_DENSITY: f64 = 1e-13;
/// The filter: 12 dB/oct, ENBW = 1/(8T).
const SLOPE_DB: u8 = 12;
/// The time constants the readings cycle through, s.
const TIME_CONSTANTS: [f64; 3] = [0.01, 0.03, 0.1];
/// The snapshot counts they cycle through.
const COUNTS: [u32; 7] = [2, 3, 5, 8, 13, 24, 40];

/// The snapshot variance of X at R and T: d²(R)·ENBW(T), V².
fn snapshot_variance(r: f64, t: f64) -> f64 {
    let tc = time_constant(t);
    let enbw = FilterSlope::from_db(SLOPE_DB).expect("slope").enbw_hz(tc);
    (A_DENSITY + B_DENSITY * r) * enbw
}

fn time_constant(t: f64) -> TimeConstant {
    TimeConstant::all()
        .find(|c| c.seconds() == t)
        .expect("an SR830 time constant")
}

/// The snapshots' correlation the reduction assumes (one time constant plus the
/// default gap apart).
fn rho(t: f64) -> f64 {
    (-(t + SNAPSHOT_GAP_S) / t).exp()
}

/// The analytic σ of a reading's mean X: (d²·ENBW·A(n, ρ)/n)^½.
fn sigma_of_mean(r: f64, t: f64, n: u32) -> f64 {
    let (a, _) = variance_factors(n, rho(t));
    (snapshot_variance(r, t) * a / f64::from(n)).sqrt()
}

/// How a reading's snapshot statistics are made.
#[derive(Clone, Copy)]
enum Snapshots {
    /// Their expectations: s² = B·σ² exactly (a dark: half its mean R² is σ²).
    Expected,
    /// Drawn: X and Y each R (or 0) plus first-order autoregressive noise of
    /// variance σ² and lag-one correlation ρ, seeded.
    Drawn(u64),
}

/// (r_mean, r_std, x_mean, y_mean) of `n` snapshots of a signal `r` along X.
fn statistics(
    r: f64,
    t: f64,
    n: u32,
    how: Snapshots,
    rng: &mut SplitMix64,
) -> (f64, f64, f64, f64) {
    let var = snapshot_variance(r, t);
    match how {
        Snapshots::Expected if r == 0.0 => ((2.0 * var).sqrt(), 0.0, 0.0, 0.0),
        Snapshots::Expected => {
            let (_, b) = variance_factors(n, rho(t));
            (r, (b * var).sqrt(), r, 0.0)
        }
        Snapshots::Drawn(_) => {
            let p = rho(t);
            let sd = var.sqrt();
            let innovation = (1.0 - p * p).sqrt();
            let (mut ex, mut ey) = (sd * rng.next_normal(), sd * rng.next_normal());
            let mut rs = Vec::new();
            let (mut sx, mut sy) = (0.0, 0.0);
            for k in 0..n {
                if k > 0 {
                    ex = p * ex + innovation * sd * rng.next_normal();
                    ey = p * ey + innovation * sd * rng.next_normal();
                }
                sx += r + ex;
                sy += ey;
                rs.push((r + ex).hypot(ey));
            }
            let nf = f64::from(n);
            let mean = rs.iter().sum::<f64>() / nf;
            let s2 = rs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (nf - 1.0).max(1.0);
            (mean, s2.sqrt(), sx / nf, sy / nf)
        }
    }
}

/// A sample reading's settings: the k-th sample cycles through the time constants
/// and (at another period) the snapshot counts; its signal spans 20 µV … 2 mV.
fn settings(k: usize, samples: usize) -> (f64, f64, u32) {
    let t = TIME_CONSTANTS[k % TIME_CONSTANTS.len()];
    let n = COUNTS[(k / 2) % COUNTS.len()];
    let r = 2e-5 * 100f64.powf(k as f64 / (samples - 1) as f64);
    (r, t, n)
}

/// A synthetic run: the plan's schedule, each step committed with a reading made
/// by `how`. Returns the open store and, per sample step id, (R, T, n).
fn synthetic_run(
    name: &str,
    how: Snapshots,
    mut tweak: impl FnMut(usize, &mut ReadingRecord),
) -> (RunStore, std::collections::BTreeMap<i64, (f64, f64, u32)>) {
    let (inst, inst_text) =
        InstrumentConfig::load_with_text(&root().join("config/instrument-sim.toml")).expect("inst");
    let plan_path = root().join("config/plan.toml");
    let plan = Plan::from_toml(PLAN, Some(&plan_path)).expect("plan");
    let mech = inst.mechanics().expect("mechanics");
    let prepared = gonio_plan::prepare(&mech, inst.reading_seconds(), &plan).expect("prepares");
    let inputs = Inputs {
        instrument_text: inst_text,
        plan_text: PLAN.into(),
        plan_path: Some(plan_path),
        software: "test".into(),
        ..Inputs::default()
    };
    let dir = tempfile::Builder::new()
        .prefix(&format!("gonio-pooling-{name}-"))
        .tempdir()
        .expect("temp dir")
        .keep();
    let mut store =
        gonio_run::create(&dir.join("run.gonio"), &plan, &prepared, &inputs).expect("creates");
    store.begin_session("test").expect("session");
    let steps = store.steps().expect("steps");
    let samples = steps
        .iter()
        .filter(|s| s.step.kind == StepKind::Sample)
        .count();
    let mut rng = SplitMix64::new(match how {
        Snapshots::Expected => 0,
        Snapshots::Drawn(seed) => seed,
    });
    let mut truth = std::collections::BTreeMap::new();
    let mut k = 0;
    for (i, s) in steps.iter().enumerate() {
        let (r, t, n) = match s.step.kind {
            StepKind::Dark => (0.0, 0.1, 20),
            StepKind::Incident => (0.02, 0.1, 20),
            StepKind::Sample => {
                let v = settings(k, samples);
                truth.insert(s.id, v);
                k += 1;
                v
            }
            other => panic!("unexpected step {other:?}"),
        };
        let (r_mean, r_std, x_mean, y_mean) = statistics(r, t, n, how, &mut rng);
        let pair = s.step.pair.unwrap_or(gonio_core::dirfile::PairDeg {
            incident: gonio_core::SphericalDeg::new(0.0, 0.0),
            outgoing: gonio_core::SphericalDeg::new(0.0, 0.0),
        });
        let mut reading = ReadingRecord {
            step_id: s.id,
            commanded: s.step.stages,
            position: s.step.stages.unwrap_or([0.0; 4]),
            read_pair: pair,
            sensitivity: 20,
            sensitivity_v: 0.05,
            time_constant: time_constant(t).index(),
            time_constant_s: t,
            slope_db: SLOPE_DB,
            r_mean,
            r_std,
            x_mean,
            y_mean,
            n,
            autorange_steps: 0,
            lias: 0,
            flags: 0,
            retries: 0,
            physical_s: 10.0 * i as f64,
            wall_s: 1.7e9 + 10.0 * i as f64,
        };
        tweak(i, &mut reading);
        store.commit(&reading, &[]).expect("commits");
    }
    (store, truth)
}

/// Per sample, (the reduction's σ of its mean X, V; its R, T, n), read from the
/// noise term of its budget (1/sr: f times the σ relative to the signal,
/// |(X, Y) − dark|).
fn noise_terms(
    store: &RunStore,
    red: &Reduction,
    truth: &std::collections::BTreeMap<i64, (f64, f64, u32)>,
) -> Vec<(f64, (f64, f64, u32))> {
    let steps = store.steps().expect("steps");
    let readings = store.readings().expect("readings");
    let dark = red.report.channels[0].dark_v;
    red.samples
        .samples
        .iter()
        .zip(&red.budget)
        .map(|(s, b)| {
            let step = steps
                .iter()
                .find(|st| st.step.kind == StepKind::Sample && st.step.pair == Some(s.pair))
                .expect("the sample's step");
            let r = readings
                .iter()
                .find(|r| r.step_id == step.id)
                .expect("its reading");
            let v = (r.x_mean - dark[0]).hypot(r.y_mean - dark[1]);
            (b[0][0] / s.value[0] * v, truth[&step.id])
        })
        .collect()
}

/// With every reading's scatter at its expectation the pooled line is the law
/// itself: each reading's noise term is the analytic σ of its mean, whatever its
/// time constant and snapshot count, to rounding.
#[test]
fn expected_scatter_at_three_time_constants_gives_the_analytic_sigma_of_each_mean() {
    let (store, truth) = synthetic_run("expected", Snapshots::Expected, |_, _| {});
    let red = reduce(&store, &Options::default()).expect("reduces");
    let terms = noise_terms(&store, &red, &truth);
    assert!(terms.len() >= 50, "{} samples", terms.len());
    let mut seen_t = std::collections::BTreeSet::new();
    let mut seen_n = std::collections::BTreeSet::new();
    for (got, (r, t, n)) in &terms {
        let want = sigma_of_mean(*r, *t, *n);
        assert!(
            ((got - want) / want).abs() < 1e-9,
            "R {r:e} V, T {t} s, n {n}: σ {got:e} V, want {want:e} V"
        );
        seen_t.insert(t.to_bits());
        seen_n.insert(*n);
    }
    assert_eq!(seen_t.len(), 3);
    assert_eq!(seen_n.len(), COUNTS.len());
    let source = &red.report.channels[0].budget[0].source;
    assert!(
        source.contains("their time constants") && source.contains("T = 0.1 s"),
        "{source}"
    );
    assert!(!source.contains("capped"), "{source}");
    assert_eq!(red.report.capped, 0);
}

/// Snapshots drawn at random: the pooled σ of every reading, n = 2 ones included,
/// lies within three standard deviations of a variance estimated from the pool's
/// ν = Σ(n − 1) degrees of freedom (relative sd √(2/ν), the σ's half of it; the
/// factor two left covers the two-parameter line away from its centre), where a
/// two-snapshot reading's own scatter misses by far more.
#[test]
fn drawn_scatter_pools_to_the_analytic_sigma_within_the_pools_precision() {
    for seed in [1u64, 2, 3] {
        let (store, truth) =
            synthetic_run(&format!("drawn-{seed}"), Snapshots::Drawn(seed), |_, _| {});
        let red = reduce(&store, &Options::default()).expect("reduces");
        let terms = noise_terms(&store, &red, &truth);
        let nu: f64 = store
            .readings()
            .expect("readings")
            .iter()
            .map(|r| f64::from(r.n - 1))
            .sum();
        let tol = 3.0 * (2.0 / nu).sqrt();
        assert!(tol < 0.2, "ν = {nu}");
        let mut worst = 0.0f64;
        for (got, (r, t, n)) in &terms {
            let want = sigma_of_mean(*r, *t, *n);
            worst = worst.max(((got - want) / want).abs());
        }
        assert!(
            worst < tol,
            "seed {seed}: worst relative error {worst:.3}, tolerance {tol:.3}"
        );
        // What the pool saves: the two-snapshot readings' own scatter.
        let readings = store.readings().expect("readings");
        let own_worst = readings
            .iter()
            .filter(|r| r.n == 2 && truth.contains_key(&r.step_id))
            .map(|r| {
                let (_, b) = variance_factors(2, rho(r.time_constant_s));
                let (a, _) = variance_factors(2, rho(r.time_constant_s));
                let own = (r.r_std * r.r_std / b * a / 2.0).sqrt();
                let (rr, t, n) = truth[&r.step_id];
                ((own - sigma_of_mean(rr, t, n)) / sigma_of_mean(rr, t, n)).abs()
            })
            .fold(0.0f64, f64::max);
        assert!(
            own_worst > 3.0 * tol,
            "seed {seed}: own scatter {own_worst:.3}"
        );
    }
}

/// A reading of one snapshot has no scatter of its own: it takes the pooled line
/// (here its own slope's), never σ = 0.
#[test]
fn a_single_snapshot_reading_takes_the_pooled_sigma() {
    let mut single = Vec::new();
    let (store, truth) = synthetic_run("single", Snapshots::Expected, |i, r| {
        if i % 7 == 3 && r.r_mean > 0.0 && r.time_constant_s < 0.1 {
            r.n = 1;
            r.r_std = 0.0;
            single.push(r.step_id);
        }
    });
    let red = reduce(&store, &Options::default()).expect("reduces");
    let readings = store.readings().expect("readings");
    let terms = noise_terms(&store, &red, &truth);
    let mut checked = 0;
    for (got, (r, t, _)) in &terms {
        let reading = readings
            .iter()
            .find(|x| x.time_constant_s == *t && x.x_mean == *r)
            .expect("reading");
        if reading.n == 1 {
            // One snapshot: the variance of the mean is the snapshot variance.
            let want = snapshot_variance(*r, *t).sqrt();
            assert!(
                ((got - want) / want).abs() < 1e-9,
                "σ {got:e}, want {want:e}"
            );
            checked += 1;
        }
    }
    assert!(
        checked >= 3,
        "{checked} single-snapshot samples of {:?}",
        single
    );
}

/// A capped reading is reduced like any other and counted in the report; the
/// count and the note are absent from a run without one (the JSON of every report
/// before reading time).
#[test]
fn capped_readings_are_counted_and_named_in_the_noise_source() {
    let (store, _) = synthetic_run("capped", Snapshots::Expected, |i, r| {
        if i % 10 == 5 {
            r.flags |= flags::CAPPED;
        }
    });
    let capped = store
        .readings()
        .expect("readings")
        .iter()
        .filter(|r| r.flags & flags::CAPPED != 0)
        .count();
    assert!(capped >= 3);
    let red = reduce(&store, &Options::default()).expect("reduces");
    assert_eq!(red.report.capped, capped);
    let json = serde_json::to_value(&red.report).expect("json");
    assert_eq!(json["capped"], serde_json::json!(capped));
    let source = &red.report.channels[0].budget[0].source;
    assert!(
        source.contains(&format!(
            "{capped} reading(s) reached the plan's reading.max_s"
        )),
        "{source}"
    );
    // Left out on request, they are counted as `capped`, not as an overload.
    let opts = Options {
        reject_flags: flags::CAPPED,
        ..Options::default()
    };
    let red = reduce(&store, &opts).expect("reduces");
    assert_eq!(red.report.capped, 0);
    assert!(
        red.report.rejected["capped"] >= 1,
        "{:?}",
        red.report.rejected
    );
    let json = serde_json::to_value(&red.report).expect("json");
    assert!(json.get("capped").is_none(), "{json}");
}

/// A single-snapshot reading whose slope has too few readings for a line of its
/// own borrows the nearest slope's, scaled by the two filters' ENBW: here every
/// other reading is at 24 dB/oct (ENBW 5/(64T)) and a few at 12 dB/oct (1/(8T)).
#[test]
fn a_single_snapshot_reading_of_a_lone_slope_borrows_the_nearest_slopes_line() {
    let k12 = FilterSlope::Db12.enbw_hz(time_constant(0.01)) * 0.01;
    let k24 = FilterSlope::Db24.enbw_hz(time_constant(0.01)) * 0.01;
    assert!((k12 - 1.0 / 8.0).abs() < 1e-15 && (k24 - 5.0 / 64.0).abs() < 1e-15);
    let to24 = (k24 / k12).sqrt();
    let mut lone = 0;
    let (store, truth) = synthetic_run("lone-slope", Snapshots::Expected, |i, r| {
        if i % 11 == 4 && r.x_mean > 0.0 && r.time_constant_s < 0.1 && lone < 4 {
            r.n = 1;
            r.r_std = 0.0;
            lone += 1;
        } else {
            // The same density behind the steeper filter.
            r.slope_db = 24;
            r.r_std *= to24;
            if r.x_mean == 0.0 {
                r.r_mean *= to24;
            }
        }
    });
    assert!(lone >= 3, "{lone}");
    let red = reduce(&store, &Options::default()).expect("reduces");
    let readings = store.readings().expect("readings");
    let mut checked = 0;
    for (got, (r, t, n)) in noise_terms(&store, &red, &truth) {
        let reading = readings
            .iter()
            .find(|x| x.time_constant_s == t && x.x_mean == r)
            .expect("reading");
        let want = if reading.slope_db == 12 {
            checked += 1;
            assert_eq!(reading.n, 1);
            snapshot_variance(r, t).sqrt()
        } else {
            sigma_of_mean(r, t, n) * to24
        };
        assert!(
            ((got - want) / want).abs() < 1e-9,
            "slope {} dB, R {r:e}, T {t}, n {}: σ {got:e}, want {want:e}",
            reading.slope_db,
            reading.n
        );
    }
    assert_eq!(checked, lone);
}
