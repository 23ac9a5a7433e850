//! The uncertainty budget closes: a simulated run of a known sample, reduced, agrees
//! with the sample's own BRDF within the uncertainties the reduction states, on
//! three plans and two samples with the simulator's noise on.

use crate::truth;

use gonio_reduce::{Options, TERMS, reduce};

/// An isotropic grid calibrated by the reference standard alone (no incident
/// beam), with drift references and the calibrations repeated at the end: the
/// calibration transfer from a standard.
const STANDARD_PLAN: &str = r#"
name = "closure: standard-calibrated grid"
[points]
kind = "isotropic"
phi_i = 0
theta_i = [10, 40, 70]
theta_o = { from = 5, to = 85, step = 10 }
delta_phi = { from = 0, to = 180, step = 30 }
[drift]
every = 20
[calibration]
dark = true
standard = { model = "models/white-reference.toml", at = [[0, 0, 45, 180], [45, 0, 0, 0]] }
repeat_at_end = true
"#;

fn plans() -> Vec<(&'static str, String)> {
    let read = |p: &str| std::fs::read_to_string(truth::root().join(p)).expect("plan");
    vec![
        ("hemisphere", read("config/plan-hemisphere.toml")),
        ("in-plane", read("config/plan-in-plane.toml")),
        ("standard", STANDARD_PLAN.to_string()),
    ]
}

/// Seeds of the runs; the first is the one of the findings.
const SEEDS: [u64; 8] = [11, 12, 13, 14, 15, 16, 17, 18];

/// For every plan × sample, over eight seeds: the mean χ²/n of (f − f_true)/σ, and
/// the mean χ²/n with the budget's shared terms as correlations (rᵀC⁻¹r/n), each
/// within [0.8, 1.25]. One run's plain χ²/n scatters more than its sample count
/// says: the dark's and the calibration's errors are single draws shared by every
/// sample, so χ²/n moves with them (0.68 … 2.01 over seeds 1–16 of the hemisphere
/// plan and the paint, mean 1.06; 1.84 at seed 11, whose dark is 1.8σ off).
/// Before the budget (seed 11): hemisphere 3.51 (paint) and 2.68 (Cook–Torrance).
#[test]
fn the_reduced_runs_agree_with_the_truth_within_their_stated_uncertainty() {
    let mut failed = Vec::new();
    for (plan_name, plan) in plans() {
        for (sample_name, sample) in [
            ("paint", None),
            ("cook-torrance", Some(truth::COOK_TORRANCE)),
        ] {
            let name = format!("{plan_name}-{sample_name}");
            let (mut plain, mut correlated) = (Vec::new(), Vec::new());
            for seed in SEEDS {
                let (store, model) = truth::measure(&name, &plan, sample, seed, |_| {});
                let red = reduce(&store, &Options::default()).expect("reduces");
                truth::assert_covariance_adds_up(&red);
                let r = truth::residuals(&red, &model);
                let chi2 = truth::chi2(&r);
                let corr = truth::chi2_correlated(&red, &model);
                let ch = &red.report.channels[0];
                println!(
                    "{name} seed {seed}: {} samples, {} calibration, χ²/n {chi2:.3}, with \
                     correlations {corr:.3}, mean relative error {:+.2e}",
                    r.len(),
                    ch.calibration,
                    truth::mean_rel(&r)
                );
                if seed == SEEDS[0] {
                    for t in &ch.budget {
                        println!(
                            "    {:<11} {:.2e} median, {:.2e} max ({})",
                            t.term, t.rel_median, t.rel_max, t.correlation
                        );
                    }
                }
                // The budget is the σ: its terms add in quadrature to every sample's.
                // The lock-in's terms and the position term.
                assert_eq!(ch.budget.len(), TERMS.len() + 1);
                for (s, b) in red.samples.samples.iter().zip(&red.budget) {
                    let sum = b[0].iter().map(|x| x * x).sum::<f64>().sqrt();
                    let sigma = s.sigma.as_ref().expect("σ")[0];
                    assert!((sum - sigma).abs() <= 1e-12 * sigma, "{sum} vs {sigma}");
                }
                plain.push(chi2);
                correlated.push(corr);
            }
            let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
            let (m_plain, m_corr) = (mean(&plain), mean(&correlated));
            println!(
                "{name}: mean χ²/n over the seeds {m_plain:.3}, with correlations {m_corr:.3}"
            );
            for (what, m) in [("χ²/n", m_plain), ("correlated χ²/n", m_corr)] {
                if !(0.8..=1.25).contains(&m) {
                    failed.push(format!("{name}: mean {what} {m:.3}"));
                }
            }
        }
    }
    assert!(failed.is_empty(), "{failed:?}");
}
