//! Reading to a precision target, as processes: `plan check` estimates a targeted
//! plan's time, a reading that reaches its cap is kept and flagged, and a targeted
//! run on a simulator that models the settling transient, killed and resumed, reads
//! exactly what an uninterrupted one reads.

use crate::common;

use std::path::Path;

use common::{
    config, gonio, kill_and_resume_until_complete, ok_json, readings, s, scratch, sim_file_at,
    stderr,
};
use gonio_run::flags;

/// A small in-plane plan read to `sigma` (relative) within `max_s` a reading.
fn plan(dir: &Path, sigma: f64, max_s: f64) -> String {
    let text = format!(
        r#"
name = "targeted in-plane"
[points]
kind = "in-plane"
theta_i = [20, 50]
theta_o = {{ from = -70, to = 70, step = 10 }}
[drift]
every = 5
[calibration]
dark = true
dark_readings = 1
incident = {{ transmittance = 1e-3 }}
[reading]
sigma_relative = {sigma:e}
max_s = {max_s}
"#
    );
    let p = dir.join(format!("plan-{sigma:e}-{max_s}.toml"));
    std::fs::write(&p, text).expect("plan");
    s(&p)
}

/// `gonio acquire` of `plan` into `out` at `seed`, on the simulator `sim` (a config
/// file) or the default one.
fn acquire(plan: &str, out: &Path, sim: Option<&str>, seed: &str) -> std::process::Output {
    let inst = config("instrument-sim.toml");
    let out = s(out);
    let mut args = vec![
        "acquire",
        "--instrument",
        &inst,
        "--plan",
        plan,
        "--out",
        &out,
    ];
    args.extend(["--seed", seed, "--json"]);
    if let Some(sim) = sim {
        args.extend(["--sim", sim]);
    }
    let o = gonio(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    o
}

/// Every reading's flags, by step.
fn flag_bits(path: &Path) -> Vec<u32> {
    readings(path)
        .iter()
        .map(|r| {
            r[18]
                .trim_start_matches("Integer(")
                .trim_end_matches(')')
                .parse()
                .expect("flags")
        })
        .collect()
}

#[test]
fn plan_check_estimates_a_targeted_run_within_five_percent() {
    let dir = scratch("reading-check");
    let plan = config("plan-hemisphere-targeted.toml");
    let inst = config("instrument-sim.toml");
    let check = ok_json(&["plan", "check", &plan, "--instrument", &inst, "--json"]);
    let r = &check["reading"];
    let detector = r["detector_s"].as_f64().expect("detector_s");
    let fixed = check["estimate"]["fixed_detector_s"]
        .as_f64()
        .expect("fixed");
    let total = check["estimate"]["total_s"].as_f64().expect("total");
    assert_eq!(check["estimate"]["detector_s"], r["detector_s"]);
    assert_eq!(r["targeted"], true);
    // The split adds up, and the target cuts the fixed reading's time by more than 2.
    let parts = ["settle_s", "averaging_s", "serial_s"]
        .iter()
        .map(|k| r[k].as_f64().expect("part"))
        .sum::<f64>();
    assert!((parts - detector).abs() < 1e-6 * detector, "{r}");
    assert!(detector < fixed / 2.0, "{detector} vs {fixed}");
    // With the plan's default four dark readings.
    assert_eq!(r["readings"], 639);
    // Against the run itself (seed 11): the estimate's total within 5 % (its readings
    // start from the step a move makes, which the simulator's default filters,
    // settled at each point, skip; read through the transient by its fit, a reading
    // takes about as long either way: the estimate is 1 % short).
    let out = dir.join("run.gonio");
    let run: serde_json::Value =
        serde_json::from_slice(&acquire(&plan, &out, None, "11").stdout).expect("JSON");
    let physical = run["physical_s"].as_f64().expect("physical_s");
    let ratio = total / physical;
    assert!(
        (0.95..1.05).contains(&ratio),
        "estimate {total} vs run {physical}"
    );
    // Every reading is a targeted one.
    assert!(flag_bits(&out).iter().all(|f| f & flags::TARGETED != 0));
    // And the estimate from that run's readings agrees with the simulator's to 5 %.
    let like = ok_json(&[
        "plan",
        "check",
        &plan,
        "--instrument",
        &inst,
        "--like",
        &s(&out),
        "--json",
    ]);
    let from_run = like["reading"]["detector_s"].as_f64().expect("detector_s");
    assert!(
        (from_run / detector - 1.0).abs() < 0.05,
        "{from_run} vs {detector}"
    );
}

#[test]
fn a_reading_that_reaches_its_cap_is_kept_and_flagged() {
    let dir = scratch("reading-capped");
    // 1e-7 of the value within 0.4 s: no reading gets there.
    let plan = plan(&dir, 1e-7, 0.4);
    let out = dir.join("run.gonio");
    acquire(&plan, &out, None, "3");
    let bits = flag_bits(&out);
    assert_eq!(bits.len(), 37, "every step has its reading");
    assert!(bits.iter().all(|f| f & flags::CAPPED != 0), "{bits:?}");
    // Each holds what the time allowed: snapshots, a value, no more than the cap.
    for r in readings(&out) {
        let n: u32 = r[15]
            .trim_start_matches("Integer(")
            .trim_end_matches(')')
            .parse()
            .expect("n");
        assert!(n >= 1, "{r:?}");
        assert!(r[11].starts_with("Real("), "{r:?}");
    }
    // The reduction keeps them, and says so.
    let samples = dir.join("samples.csv");
    let red = ok_json(&["reduce", &s(&out), "--out", &s(&samples), "--json"]);
    assert_eq!(red["reduction"]["capped"], 37, "{}", red["reduction"]);
}

#[test]
fn a_targeted_run_killed_and_resumed_reads_what_an_uninterrupted_one_did() {
    let dir = scratch("reading-kill");
    let inst = config("instrument-sim.toml");
    let plan = plan(&dir, 1e-4, 30.0);
    let fast = sim_file_at(&dir, "sim-transient.toml", 0.0);
    let whole = dir.join("whole.gonio");
    acquire(&plan, &whole, Some(&fast), "11");
    let want = readings(&whole);
    assert_eq!(want.len(), 37);
    let slow = sim_file_at(&dir, "sim-transient.toml", 0.02);
    let out = dir.join("killed.gonio");
    let kills = kill_and_resume_until_complete(
        &out,
        &[
            "--instrument",
            &inst,
            "--plan",
            &plan,
            "--out",
            &s(&out),
            "--sim",
            &slow,
            "--seed",
            "11",
        ],
        13,
        (150, 400),
    );
    assert!(kills >= 3, "{kills} interruptions: the run was too quick");
    assert_eq!(readings(&out), want);
}
