//! `gonio plan check`'s estimate against the instrument time of the simulated run, for
//! every shipped plan on its simulated instrument and at several seeds: within 5 %,
//! start-up, range changes and serial exchanges all counted. `acquire` announces and
//! records the same estimate. (`scripts/estimates` prints the same comparison.)

use crate::common;

use common::{config, ok, ok_json, s, scratch, stderr};

/// The seeds each plan is run at: the simulator's noise decides, among other things,
/// where a dark reading's autoranging stops.
const SEEDS: [&str; 3] = ["3", "11", "29"];

/// The whole run's estimate `plan check` gives: an adaptive plan's (its coarse pass
/// and the batches its budget leaves), else the run's total.
fn estimate_s(check: &serde_json::Value) -> f64 {
    match check["adaptive"].as_object() {
        Some(a) => a["estimate_s"].as_f64().expect("adaptive estimate"),
        None => check["estimate"]["total_s"].as_f64().expect("total"),
    }
}

/// Runs `plan` on `instrument` with the simulator `sim` at every seed and holds the
/// instrument time each took to `plan check`'s estimate within 5 %; returns the
/// estimate and the instrument times.
fn runs_within_five_percent(plan: &str, instrument: &str, sim: &str) -> (f64, Vec<f64>) {
    let dir = scratch(&format!("estimates-{plan}"));
    let (plan, inst, sim) = (config(plan), config(instrument), config(sim));
    let check = ok_json(&[
        "plan",
        "check",
        &plan,
        "--instrument",
        &inst,
        "--sim",
        &sim,
        "--json",
    ]);
    let estimate = estimate_s(&check);
    let mut times = Vec::new();
    for seed in SEEDS {
        let out = s(&dir.join(format!("run-{seed}.gonio")));
        let run = ok_json(&[
            "acquire",
            "--instrument",
            &inst,
            "--plan",
            &plan,
            "--sim",
            &sim,
            "--seed",
            seed,
            "--out",
            &out,
            "--json",
        ]);
        assert_eq!(run["status"], "complete", "{run}");
        let physical = run["physical_s"].as_f64().expect("physical_s");
        let off = estimate / physical - 1.0;
        assert!(
            off.abs() <= 0.05,
            "{plan} at seed {seed}: estimate {estimate:.1} s, run {physical:.1} s ({:+.1} %)",
            100.0 * off
        );
        // The run file records the estimate `plan check` gave (an adaptive run's, its
        // coarse pass's).
        let stored = &ok_json(&["show", &out, "--json"])["estimate"];
        let e = &check["estimate"];
        for k in ["startup_s", "motion_s", "detector_s", "band_s"] {
            let (a, b) = (stored[k].as_f64(), e[k].as_f64());
            assert!(
                (a.expect(k) - b.expect(k)).abs() < 1e-6,
                "{k}: {stored} vs {e}"
            );
        }
        times.push(physical);
    }
    (estimate, times)
}

#[test]
fn in_plane_and_list_plans_are_estimated_within_five_percent() {
    let (e, t) = runs_within_five_percent(
        "plan-in-plane.toml",
        "instrument-sim.toml",
        "sim-example.toml",
    );
    // The range changes are most of what the schedule alone left out: 383 s then.
    assert!(e > 540.0 && t.iter().all(|t| *t > 540.0), "{e} {t:?}");
    runs_within_five_percent("plan-list.toml", "instrument-sim.toml", "sim-example.toml");
}

#[test]
fn hemisphere_plans_are_estimated_within_five_percent() {
    runs_within_five_percent(
        "plan-hemisphere.toml",
        "instrument-sim.toml",
        "sim-example.toml",
    );
    runs_within_five_percent(
        "plan-hemisphere-targeted.toml",
        "instrument-sim.toml",
        "sim-example.toml",
    );
}

#[test]
fn the_spectral_plan_is_estimated_within_five_percent() {
    runs_within_five_percent(
        "plan-spectral.toml",
        "instrument-spectral.toml",
        "sim-spectral.toml",
    );
}

#[test]
fn the_adaptive_plan_is_estimated_within_five_percent() {
    runs_within_five_percent(
        "plan-adaptive.toml",
        "instrument-sim.toml",
        "sim-example.toml",
    );
}

#[test]
fn acquire_announces_the_estimate_plan_check_gives() {
    let dir = scratch("estimates-announce");
    let (plan, inst) = (
        config("plan-hemisphere-targeted.toml"),
        config("instrument-sim.toml"),
    );
    let check = ok_json(&["plan", "check", &plan, "--instrument", &inst, "--json"]);
    // A targeted plan: the targeted readings' estimate, not the fixed reading's.
    let e = &check["estimate"];
    assert_eq!(e["detector_s"], check["reading"]["detector_s"]);
    assert!(e["detector_s"].as_f64() < e["fixed_detector_s"].as_f64());
    let out = s(&dir.join("run.gonio"));
    let o = ok(&[
        "acquire",
        "--instrument",
        &inst,
        "--plan",
        &plan,
        "--seed",
        "3",
        "--out",
        &out,
    ]);
    let hms = |x: &serde_json::Value| {
        let t = x.as_f64().expect("seconds").round() as u64;
        format!("{}m{:02}s", t / 60, t % 60)
    };
    let line = stderr(&o);
    let want = format!(
        "estimated {} (start-up {}s, motion {}, detector {})",
        hms(&e["total_s"]),
        e["startup_s"].as_f64().expect("startup").round(),
        hms(&e["motion_s"]),
        hms(&e["detector_s"]),
    );
    assert!(line.contains(&want), "{want} in {line}");
}
