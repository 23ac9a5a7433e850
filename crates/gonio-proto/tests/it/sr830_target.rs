//! Reading to a precision target, on virtual time: the transient fit against the
//! filter cascade's analytic response, the sequential rule against synthetic noise of
//! known law, and the expected times.

use gonio_core::rng::SplitMix64;
use gonio_proto::sr830::ranging::{fixed_changes, targeted_changes};
use gonio_proto::sr830::target::{
    NoiseDensity, ReadTarget, Sequential, TRANSIENT_FRACTION, choose_time_constant, estimate,
    fit_transient, step_residual,
};
use gonio_proto::sr830::{FilterSlope, Sensitivity, TimeConstant};

/// The output of an N-stage RC cascade (time constant 1) with constant input `u`,
/// from stage deviations `z0` (stage 1 first) at τ = 0: stage k's deviation is
/// e^(−τ) Σ_{j<k} z_{k−j}(0) τ^j/j! — each stage's free decay passed through the
/// stages after it. Written out here, independently of the code under test.
fn cascade(u: f64, z0: &[f64], tau: f64) -> f64 {
    let n = z0.len();
    let mut sum = 0.0;
    let mut term = 1.0;
    for j in 0..n {
        sum += z0[n - 1 - j] * term;
        term *= tau / (j + 1) as f64;
    }
    u + (-tau).exp() * sum
}

#[test]
fn the_fit_recovers_the_settled_value_and_extrapolates_the_transient_exactly() {
    // Arbitrary stage states (not a settled step): what a move sweeping the beam leaves.
    for z0 in [
        vec![0.8],
        vec![-0.3, 0.5],
        vec![0.2, -0.7, 1.1],
        vec![1.5, -0.4, 0.9, 2.0],
    ] {
        let u = 0.42;
        let taus: Vec<f64> = (0..14).map(|k| 1.7 + 1.35 * k as f64).collect();
        let ys: Vec<f64> = taus.iter().map(|t| cascade(u, &z0, *t)).collect();
        let fit = fit_transient(&taus, &ys, z0.len()).expect("fits");
        assert!((fit.value - u).abs() < 1e-9, "{z0:?}: {}", fit.value);
        for tau in [2.0, 5.0, 12.0, 25.0, 40.0] {
            let truth = cascade(u, &z0, tau) - u;
            assert!(
                (fit.transient(tau) - truth).abs() < 1e-9,
                "{z0:?} at τ {tau}: {} vs {truth}",
                fit.transient(tau)
            );
        }
    }
}

#[test]
fn a_constant_time_offset_is_absorbed() {
    // Snapshots stamped 0.3 T late (a reply's latency): the same polynomial family.
    let z0 = [0.0, 0.0, 0.0, -1.0];
    let u = 1.0;
    let taus: Vec<f64> = (0..12).map(|k| 2.0 + 1.4 * k as f64).collect();
    let ys: Vec<f64> = taus.iter().map(|t| cascade(u, &z0, t - 0.3)).collect();
    let fit = fit_transient(&taus, &ys, 4).expect("fits");
    assert!((fit.value - u).abs() < 1e-9, "{}", fit.value);
}

#[test]
fn step_residual_matches_the_manual_and_the_settling_factors() {
    // Manual, "SR830 Basics": 99 % after 5, 7, 9, 10 T at 6, 12, 18, 24 dB/oct (the
    // table rounds: 0.67 %, 0.73 %, 0.62 %, 1.03 %).
    for (order, tau, left) in [
        (1, 5.0, 0.0067),
        (2, 7.0, 0.0073),
        (3, 9.0, 0.0062),
        (4, 10.0, 0.0103),
    ] {
        assert!((step_residual(order, tau) - left).abs() < 5e-5, "{order}");
    }
    let f = FilterSlope::Db24.settle_factor_for(1e-4);
    assert!((step_residual(4, f) - 1e-4).abs() < 1e-9);
}

/// One simulated reading: a step from `y0` to `u` at τ = 0 through a 24 dB/oct
/// cascade, first-order noise of standard deviation `sigma` (correlation e^(−Δτ)),
/// snapshots from τ = 2 every `spacing`, until the rule says done. Returns the
/// window's mean, its snapshot times, and the snapshots taken.
fn one_reading(
    seq: &mut Sequential,
    target: &ReadTarget,
    law: Option<&dyn Fn(f64) -> f64>,
    (u, y0, sigma, spacing): (f64, f64, f64, f64),
    rng: &mut SplitMix64,
) -> (f64, Vec<f64>, usize) {
    let mut noise = sigma * rng.next_normal();
    let mut tau = 2.0;
    let mut taus = Vec::new();
    for k in 0..100_000 {
        if k > 0 {
            let rho = (-spacing).exp();
            noise = rho * noise + sigma * (1.0 - rho * rho).sqrt() * rng.next_normal();
            tau += spacing;
        }
        let clean = u + (y0 - u) * step_residual(4, tau);
        seq.push(tau, clean + noise, 0.0);
        taus.push(tau);
        if seq.assess(target, law).done {
            let start = seq.window_start().expect("a window");
            let w = seq.result().expect("a mean");
            return (w.r_mean, taus[start..].to_vec(), taus.len());
        }
    }
    panic!("never done");
}

/// Σ_{i,j} e^(−|τᵢ − τⱼ|): the exact variance of a sum of first-order noise, in σ².
fn correlation_sum(taus: &[f64]) -> f64 {
    taus.iter()
        .map(|a| taus.iter().map(|b| (-(a - b).abs()).exp()).sum::<f64>())
        .sum()
}

#[test]
fn the_rule_never_stops_before_the_target_on_noise_of_known_law() {
    let (u, sigma) = (1e-3, 1e-5);
    let target = ReadTarget {
        sigma_relative: 1e-3,
        sigma_absolute: 0.0,
        max_s: 1e9,
        min_samples: 2,
    };
    let law = |_: f64| sigma * sigma;
    let mut rng = SplitMix64::new(24);
    let (mut zs, mut total) = (Vec::new(), 0usize);
    for trial in 0..300 {
        // Steps up and down, of up to 3 values.
        let y0 = u * [0.0, 4.0, 0.5, 2.0][trial % 4];
        let mut seq = Sequential::new(4, 2.0);
        let (mean, window, taken) =
            one_reading(&mut seq, &target, Some(&law), (u, y0, sigma, 1.4), &mut rng);
        let n = window.len() as f64;
        // The true σ of the window's mean, from the law and the snapshots' times.
        let true_sigma = sigma * correlation_sum(&window).sqrt() / n;
        let goal = target.sigma(mean);
        assert!(
            true_sigma <= goal * (1.0 + 1e-12),
            "trial {trial}: stopped at σ {true_sigma:e} > target {goal:e} ({} snapshots)",
            window.len()
        );
        zs.push((mean - u) / goal);
        total += taken;
    }
    // The realised errors: unbiased within the transient's allowance, and spread as
    // stated (300 trials: the RMS is good to about 4 %).
    let m = zs.len() as f64;
    let mean_z = zs.iter().sum::<f64>() / m;
    let rms = (zs.iter().map(|z| z * z).sum::<f64>() / m).sqrt();
    assert!(mean_z.abs() < TRANSIENT_FRACTION + 0.15, "mean z {mean_z}");
    assert!((0.85..=1.12).contains(&rms), "rms z {rms}");
    // The noise needs 100 (1 + ρ)/(1 − ρ) = 166 snapshots (ρ = e^−1.4); settling adds
    // the 10 to 14 snapshots before the transient is under 0.2 of the target.
    let per = total as f64 / 300.0;
    assert!(
        (166.0..=166.0 + 16.0).contains(&per),
        "{per} snapshots a reading"
    );
}

#[test]
fn without_a_law_the_window_scatter_decides_from_five_snapshots() {
    let (u, sigma) = (2e-3, 4e-6);
    let target = ReadTarget {
        sigma_relative: 1e-3,
        sigma_absolute: 0.0,
        max_s: 1e9,
        min_samples: 2,
    };
    let mut rng = SplitMix64::new(7);
    let mut zs = Vec::new();
    for _ in 0..200 {
        let mut seq = Sequential::new(4, 2.0);
        let (mean, window, _) =
            one_reading(&mut seq, &target, None, (u, 0.0, sigma, 1.4), &mut rng);
        assert!(window.len() >= 5, "{}", window.len());
        zs.push((mean - u) / target.sigma(mean));
    }
    let rms = (zs.iter().map(|z| z * z).sum::<f64>() / zs.len() as f64).sqrt();
    // Its own scatter from a handful of snapshots can be low by chance; the error
    // stays near the target.
    assert!(rms < 1.35, "rms z {rms}");
}

#[test]
fn a_noiseless_step_opens_the_window_where_the_analytic_transient_allows() {
    // Without a noise law the fitted value is not read (its variance needs the law),
    // so the window alone decides, from its own scatter, from five snapshots on.
    let (u, y0) = (1.0, 3.0);
    let target = ReadTarget {
        sigma_relative: 1e-4,
        sigma_absolute: 0.0,
        max_s: 1e9,
        min_samples: 1,
    };
    let mut seq = Sequential::new(4, 2.0);
    let allowed = TRANSIENT_FRACTION * target.sigma(u);
    let mut tau = 2.0;
    let mut taus = Vec::new();
    while seq.window_start().is_none() {
        seq.push(tau, u + (y0 - u) * step_residual(4, tau), 0.0);
        taus.push(tau);
        seq.assess(&target, None);
        tau += 0.5;
        assert!(tau < 100.0);
    }
    assert!(!seq.fitted());
    // The window's mean holds no more of the analytic transient than allowed, and
    // it opened as soon as a window of five could: one snapshot earlier, the five
    // latest held too much.
    let start = seq.window_start().expect("window");
    let share = |w: &[f64]| {
        w.iter()
            .map(|t| (y0 - u) * step_residual(4, *t))
            .sum::<f64>()
            / w.len() as f64
    };
    assert!(
        share(&taus[start..]) <= allowed * (1.0 + 1e-6),
        "{} > {allowed}",
        share(&taus[start..])
    );
    let k = taus.len();
    assert!(k - start >= 5);
    assert!(
        share(&taus[k - 6..k - 1]) > allowed,
        "window at τ {}",
        taus[start]
    );
    // A step of 2 within 2e-5 on average: the window opens past 18 T at 24 dB/oct.
    let last = taus[k - 1];
    assert!((18.0..21.5).contains(&last), "{last}");
}

#[test]
fn a_noiseless_step_is_read_through_its_transient() {
    // With a noise law the fit's settled value is read once it has one degree of
    // freedom (four coefficients, the value, one more snapshot): six snapshots, from
    // any stage states, however far from settled.
    let target = ReadTarget {
        sigma_relative: 1e-4,
        sigma_absolute: 0.0,
        max_s: 1e9,
        min_samples: 1,
    };
    // Stage states stay positive, as a positive light leaves them, so R = X.
    for (u, z0) in [(1.0, [2.0, 0.0, 0.0, 0.0]), (0.3, [0.2, 0.5, 1.0, 0.05])] {
        let mut seq = Sequential::new(4, 0.5);
        let mut tau = 0.5;
        let mut taken = 0;
        loop {
            seq.push(tau, cascade(u, &z0, tau), 0.0);
            taken += 1;
            if seq.assess(&target, Some(&|_| 1e-30)).done {
                break;
            }
            tau += 0.7;
            assert!(taken < 100);
        }
        assert_eq!(taken, 6);
        assert!(seq.fitted());
        let w = seq.result().expect("a reading");
        assert!(w.fitted && w.n == 6);
        assert!((w.r_mean - u).abs() < 1e-9 * u, "{} vs {u}", w.r_mean);
        // The residuals of an exact model are rounding.
        assert!(w.r_std < 1e-9 * u, "{}", w.r_std);
        assert!((w.interval_tc.expect("interval") - 0.7).abs() < 1e-12);
    }
}

#[test]
fn a_change_long_past_is_not_fitted() {
    let target = ReadTarget {
        sigma_relative: 1e-3,
        sigma_absolute: 0.0,
        max_s: 1e9,
        min_samples: 1,
    };
    let mut seq = Sequential::new(4, 80.0);
    seq.push(80.0, 0.5, 0.0);
    let a = seq.assess(&target, Some(&|_| 1e-12));
    assert_eq!(a.window_start, Some(0));
    assert!(a.done);
}

fn noise() -> NoiseDensity {
    NoiseDensity {
        floor: 20e-9,
        shot: 2e-6,
    }
}

fn target() -> ReadTarget {
    ReadTarget {
        sigma_relative: 1e-4,
        sigma_absolute: 0.0,
        max_s: 30.0,
        min_samples: 2,
    }
}

#[test]
fn the_estimate_is_what_the_rule_takes_on_noise_of_the_law() {
    // The estimate runs the rule on two fixed seeds; the same rule on forty other
    // seeds takes, on average, the same time to within a tenth.
    let ex = 0.0375;
    for (r, tc) in [(1e-4, 7u8), (3e-4, 7), (3e-4, 8), (1e-3, 6)] {
        let tc = TimeConstant::new(tc).expect("OFLT");
        let t = tc.seconds();
        let e = estimate(r, 0.25 * r, &target(), &noise(), FilterSlope::Db24, tc, ex);
        let var = noise().snapshot_variance(r, FilterSlope::Db24, tc);
        let law = |_: f64| var;
        let spacing = ex / t;
        let mut total = 0.0;
        for seed in 0..40 {
            let mut rng = SplitMix64::new(1000 + seed);
            let mut seq = Sequential::new(4, 0.0);
            let sigma = var.sqrt();
            let mut n = sigma * rng.next_normal();
            let mut tau = spacing;
            loop {
                seq.push(tau, r + 0.25 * r * step_residual(4, tau) + n, 0.0);
                if seq.assess(&target(), Some(&law)).done {
                    break;
                }
                let rho = (-spacing).exp();
                n = rho * n + sigma * (1.0 - rho * rho).sqrt() * rng.next_normal();
                tau += spacing;
            }
            total += tau * t;
        }
        let mean = total / 40.0;
        assert!(
            (e.total_s() / mean - 1.0).abs() < 0.1,
            "{r} at {tc}: estimate {} s, the rule {mean} s",
            e.total_s()
        );
        // Averaging is the window; settling what came before it.
        assert!(e.settle_s >= 0.0 && e.averaging_s >= 0.0);
    }
    // Dimmer is longer; a bright signal is read through its transient: the fit's
    // six snapshots (its value, four coefficients and a degree of freedom), where
    // waiting the step of a quarter of 0.5 V out to within 0.2 of 5e-5 V would take
    // 15.4 T at 24 dB/oct.
    let tc = TimeConstant::new(7).expect("30 ms");
    let dim = estimate(1e-4, 2.5e-5, &target(), &noise(), FilterSlope::Db24, tc, ex);
    let mid = estimate(1e-3, 2.5e-4, &target(), &noise(), FilterSlope::Db24, tc, ex);
    let bright = estimate(0.5, 0.125, &target(), &noise(), FilterSlope::Db24, tc, ex);
    assert!(dim.total_s() > mid.total_s() && mid.total_s() >= bright.total_s());
    assert!(
        (bright.total_s() - 6.0 * ex).abs() < 1e-9,
        "{}",
        bright.total_s()
    );
    let settle = FilterSlope::Db24.settle_factor_for(0.2 * 5e-5 / 0.125) * 0.03;
    assert!(
        bright.total_s() < 0.5 * settle,
        "{} vs {settle}",
        bright.total_s()
    );
}

#[test]
fn the_time_constant_is_the_fastest_for_the_signal() {
    let choices: Vec<TimeConstant> = (6..=11).filter_map(TimeConstant::new).collect();
    for expected in [1e-5, 1e-4, 1e-3, 1e-1] {
        let best = choose_time_constant(
            expected,
            &target(),
            &noise(),
            FilterSlope::Db24,
            choices.clone(),
            0.0375,
        )
        .expect("a choice");
        for tc in &choices {
            let e = estimate(
                expected,
                expected,
                &target(),
                &noise(),
                FilterSlope::Db24,
                *tc,
                0.0375,
            );
            assert!(best.total_s() <= e.total_s(), "{expected}: {tc}");
        }
    }
    // A bright signal takes six snapshots: at 30 ms the fit's five parameters and
    // a degree of freedom read through its transient; at 10 ms (3.75 T apart) four
    // snapshots wait it out and a window of two reads it. Longer ones take longer.
    let bright = choose_time_constant(
        0.1,
        &target(),
        &noise(),
        FilterSlope::Db24,
        choices.clone(),
        0.0375,
    )
    .expect("choice");
    assert!(
        (bright.total_s() - 6.0 * 0.0375).abs() < 1e-9,
        "{}",
        bright.total_s()
    );
    assert!(bright.time_constant <= choices[1]);
}

#[test]
fn the_floor_is_the_precision_the_cap_allows_on_the_dimmest_signal() {
    use gonio_proto::sr830::target::floor_sigma;
    let choices: Vec<TimeConstant> = (6..=11).filter_map(TimeConstant::new).collect();
    let t = target();
    let floor = floor_sigma(&t, &noise(), FilterSlope::Db24, &choices, 0.0375).expect("a floor");
    let s = floor / t.sigma_relative;
    let time = |s: f64| {
        choose_time_constant(s, &t, &noise(), FilterSlope::Db24, choices.clone(), 0.0375)
            .expect("choice")
            .total_s()
    };
    // The dimmest signal read within half the cap: a little dimmer is not.
    let half = t.max_s / 2.0;
    assert!(time(s) <= half && time(s * 0.99) > half, "{s}");
    // About 20 µV: σ_rel·S against the floor density over 15 s.
    assert!((1e-5..4e-5).contains(&s), "{s}");
}

// Autoranging's rules, on a steady signal (moved from `sr830/ranging.rs`).

#[test]
fn a_fixed_reading_walks_one_range_at_a_time() {
    let v = |i| Sensitivity::new(i).unwrap();
    // 22 nV of noise from 1 V: down to 200 nV (its tenth, 20 nV, holds it).
    assert_eq!(fixed_changes(Sensitivity::LEAST, 2.2e-8, 0.1), (20, v(6)));
    // A signal over range steps up until it fits: 3 mV from 1 mV is 2 steps.
    assert_eq!(fixed_changes(v(17), 3e-3, 0.1), (2, v(19)));
    // Within range: nothing.
    assert_eq!(fixed_changes(v(19), 3e-3, 0.1), (0, v(19)));
    // Nothing at all reads down to the most sensitive range.
    assert_eq!(
        fixed_changes(Sensitivity::LEAST, 0.0, 0.1).1,
        Sensitivity::MOST
    );
}

#[test]
fn a_targeted_reading_jumps_to_the_range_that_fits() {
    let v = |i| Sensitivity::new(i).unwrap();
    // 22 nV ± 10 nV from 1 V: one change, to 100 nV (0.9 × 100 nV ≥ 62 nV).
    assert_eq!(
        targeted_changes(Sensitivity::LEAST, 2.2e-8, 1e-8, 0.1),
        (1, v(5))
    );
    // 3 mV from 1 mV: three ranges up to 10 mV, which holds it.
    assert_eq!(targeted_changes(v(17), 3e-3, 0.0, 0.1), (1, v(20)));
}

proptest::proptest! {
    /// Whatever the snapshots (any finite values at increasing times, any spacing,
    /// with or without a noise law), the rule assesses without panicking and a
    /// reading it ends with is finite; a fitted one holds every snapshot and one
    /// residual degree of freedom at least.
    #[test]
    fn the_rule_takes_any_snapshots(
        start in 0.0f64..70.0,
        gaps in proptest::collection::vec(1e-3f64..5.0, 1..60),
        values in proptest::collection::vec(-1e3f64..1e3, 60),
        order in 1usize..=4,
        law in proptest::option::of(1e-20f64..1.0),
    ) {
        let target = ReadTarget {
            sigma_relative: 1e-3,
            sigma_absolute: 1e-9,
            max_s: 1e9,
            min_samples: 2,
        };
        let mut seq = Sequential::new(order, start);
        let mut tau = start;
        for (gap, v) in gaps.iter().zip(&values) {
            tau += gap;
            seq.push(tau, *v, 0.5 * v);
            let f = law.map(|l| move |_: f64| l);
            let a = seq.assess(&target, f.as_ref().map(|f| f as &dyn Fn(f64) -> f64));
            proptest::prop_assert!(!a.sigma_mean.is_nan());
            if a.fitted {
                proptest::prop_assert!(law.is_some() && seq.len() >= order + 2);
            }
        }
        let w = seq.result().expect("snapshots were taken");
        proptest::prop_assert!(w.r_mean.is_finite() && w.x_mean.is_finite() && w.y_mean.is_finite());
        proptest::prop_assert!(w.r_std.is_finite() && w.n >= 1 && w.n <= seq.len());
        if w.fitted {
            proptest::prop_assert_eq!(w.n, seq.len());
        }
    }
}
