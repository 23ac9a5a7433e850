//! Issue 24's bar on the simulated instrument: the hemisphere plan read to
//! σ/f = 1e-4 leaves at least 95 % of the reduced samples at σ/f ≤ 1.1e-4, in at
//! most half the instrument time of today's fixed reading, and agrees with the
//! simulated truth within its stated σ (χ²/n ≤ 1.5) — with the simulator's points
//! starting settled, and starting from the previous reading's output (the transient
//! the settling rule has to see through, at about the settled start's time).

use crate::truth;

use gonio_reduce::{Options, reduce};
use gonio_run::flags;

/// σ/f of every reduced sample, sorted, χ²/n against the truth, the run's
/// instrument time, s, and the share of its readings fitted through the transient.
fn measure(plan: &str, transient: bool) -> (Vec<f64>, f64, f64, f64) {
    let text = std::fs::read_to_string(truth::root().join(plan)).expect("plan");
    let (store, model) = truth::measure("reading-time", &text, None, 11, |s| {
        if transient {
            s.lockin.point_start = gonio_sim::lockin::PointStart::Previous;
        }
    });
    let red = reduce(&store, &Options::default()).expect("reduces");
    let mut rel: Vec<f64> = red
        .samples
        .samples
        .iter()
        .map(|s| s.sigma.as_ref().expect("σ")[0] / s.value[0])
        .collect();
    rel.sort_by(f64::total_cmp);
    let chi2 = truth::chi2(&truth::residuals(&red, &model));
    let readings = store.readings().expect("readings");
    let physical = readings.iter().map(|r| r.physical_s).fold(0.0, f64::max);
    let targeted = readings
        .iter()
        .filter(|r| r.flags & flags::TARGETED != 0)
        .count();
    assert!(
        targeted == 0 || targeted == readings.len(),
        "{targeted} of {} readings targeted",
        readings.len()
    );
    let fitted = readings
        .iter()
        .filter(|r| r.flags & flags::FITTED != 0)
        .count() as f64
        / readings.len() as f64;
    (rel, chi2, physical, fitted)
}

#[test]
fn the_hemisphere_plan_read_to_1e_4_meets_the_bar_in_half_the_time() {
    let mut times = Vec::new();
    for transient in [false, true] {
        let (fixed_rel, fixed_chi2, fixed_s, none) =
            measure("config/plan-hemisphere.toml", transient);
        let (rel, chi2, physical, fitted) =
            measure("config/plan-hemisphere-targeted.toml", transient);
        assert_eq!(none, 0.0);
        let within = |v: &[f64]| v.iter().filter(|x| **x <= 1.1e-4).count() as f64 / v.len() as f64;
        println!(
            "transient {transient}: fixed {fixed_s:.0} s, {:.1} % within 1.1e-4, χ²/n {fixed_chi2:.2}; \
             targeted {physical:.0} s ({:.1} %), {:.1} % within, median σ/f {:.2e}, χ²/n {chi2:.2}",
            100.0 * within(&fixed_rel),
            100.0 * physical / fixed_s,
            100.0 * within(&rel),
            rel[rel.len() / 2],
        );
        assert_eq!(rel.len(), 618);
        assert!(
            within(&rel) >= 0.95,
            "transient {transient}: {}",
            within(&rel)
        );
        assert!(
            physical <= 0.5 * fixed_s,
            "transient {transient}: {physical} vs {fixed_s}"
        );
        assert!(chi2 <= 1.5, "transient {transient}: χ²/n {chi2}");
        // From the previous reading, nearly every reading is its fit's value: the
        // residuals agree with the noise law (snapshots timed when the query is sent;
        // timed at the reply, steps of half the value put them at up to 78 times the
        // law and the fit is refused).
        if transient {
            assert!(fitted >= 0.9, "{fitted}");
        }
        times.push(physical);
    }
    // Read through by the fit, the transient costs next to nothing: 1280 s against
    // 1279 s settled (waited out by the window alone it cost 34 s, 1316 s).
    assert!(times[1] <= 1.01 * times[0], "{times:?}");
}
