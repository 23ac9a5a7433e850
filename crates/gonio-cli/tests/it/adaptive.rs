//! Adaptive acquisition as processes: `plan check` states the budget and the coarse
//! pass; a run spends its budget and never more, records every decision, and ends
//! identical after kills and resumes; its file reduces, checks, fits, exports and
//! reports like a grid run's; and `plan compare` shows the adaptive plan beating
//! uniform plans of the same size on a sharp sample and matching them on a broad one.

use crate::common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use common::{
    config, gonio, kill_and_resume_until_complete, ok, ok_json, s, scratch, status, stderr,
};
use rusqlite::Connection;
use serde_json::Value;

/// A small adaptive plan: two incidences, 120 points, batches of 24.
const PLAN: &str = r#"
name = "adaptive test"
[points]
kind = "adaptive"
theta_i = [30, 60]
budget = { points = 120 }
batch = 0.2
candidates = 2048
[drift]
every = 20
[calibration]
dark = true
dark_readings = 1
incident = { transmittance = 1e-3 }
"#;

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    s(&p)
}

fn acquire(plan: &str, out: &Path, extra: &[&str]) {
    let inst = config("instrument-sim.toml");
    let mut args = vec!["acquire", "--instrument", &inst, "--plan", plan, "--out"];
    let out = s(out);
    args.push(&out);
    args.extend_from_slice(extra);
    ok(&args);
}

/// `(step id, kind, plan index, θi, φi, θo, φo)` of every step.
type StepRow = (
    i64,
    String,
    Option<i64>,
    Option<f64>,
    Option<f64>,
    Option<f64>,
    Option<f64>,
);

fn steps(path: &Path) -> Vec<StepRow> {
    rows(
        path,
        "SELECT id, kind, plan_index, theta_i, phi_i, theta_o, phi_o FROM steps ORDER BY id",
        |r| {
            Ok((
                r.get(0)?,
                r.get(1)?,
                r.get(2)?,
                r.get(3)?,
                r.get(4)?,
                r.get(5)?,
                r.get(6)?,
            ))
        },
    )
}

/// Every row of `sql` on the run file at `path`, read by `f`.
fn rows<T>(
    path: &Path,
    sql: &str,
    f: impl FnMut(&rusqlite::Row<'_>) -> rusqlite::Result<T>,
) -> Vec<T> {
    let c = Connection::open(path).expect("opens");
    let mut q = c.prepare(sql).expect("query");
    q.query_map([], f)
        .expect("rows")
        .collect::<Result<_, _>>()
        .expect("values")
}

/// `(id, first_step, steps, points, method, readings, detail)` of every decision.
type DecisionRow = (i64, i64, i64, i64, String, i64, String);

fn decisions(path: &Path) -> Vec<DecisionRow> {
    rows(
        path,
        "SELECT id, first_step, steps, points, method, readings, detail FROM decisions \
         ORDER BY id",
        |r| {
            Ok((
                r.get(0)?,
                r.get(1)?,
                r.get(2)?,
                r.get(3)?,
                r.get(4)?,
                r.get(5)?,
                r.get(6)?,
            ))
        },
    )
}

/// Every reading's values (not its times or session) by step.
fn readings(path: &Path) -> Vec<(i64, f64, f64, i64, i64)> {
    rows(
        path,
        "SELECT step_id, r_mean, r_std, sensitivity, flags FROM readings ORDER BY step_id",
        |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?)),
    )
}

#[test]
fn plan_check_states_the_budget_the_coarse_pass_and_the_batches() {
    let plan = config("plan-adaptive.toml");
    let inst = config("instrument-sim.toml");
    let v = ok_json(&["plan", "check", &plan, "--instrument", &inst, "--json"]);
    let a = &v["adaptive"];
    assert_eq!(a["budget"]["points"], 600);
    assert_eq!(a["points"], 600);
    assert_eq!(a["batch"], 60);
    assert_eq!(a["method"], "residual");
    // The coarse pass is the schedule: 90 lattice directions and the mirror at each
    // of two incidences, less what the arms cannot reach.
    assert_eq!(v["pairs"], 182);
    assert_eq!(a["coarse"], v["accepted"]);
    assert_eq!(
        a["pool"].as_u64().expect("pool") + a["refused"].as_u64().expect("refused"),
        2 * 32768
    );
    // The whole run: the coarse pass (the schedule, with the session's start-up),
    // then every later point at a trial batch's time per point.
    let point_s = a["point_s"].as_f64().expect("point_s");
    let total = v["estimate"]["total_s"].as_f64().expect("total");
    let coarse = a["coarse"].as_f64().expect("coarse");
    let whole = a["estimate_s"].as_f64().expect("estimate_s");
    assert!((whole - (total + (600.0 - coarse) * point_s)).abs() < 1e-6);
    assert!(point_s > 0.0 && point_s < total / coarse * 2.0, "{point_s}");
    let text = String::from_utf8(ok(&["plan", "check", &plan, "--instrument", &inst]).stdout)
        .expect("utf-8");
    let line = text
        .lines()
        .find(|l| l.starts_with("adaptive: "))
        .expect("the adaptive line");
    assert!(
        line.starts_with(&format!(
            "adaptive: budget 600 points; the schedule above is the coarse pass ({coarse} \
             points, {:.0}% of the budget); then batches of 60 points chosen by residual among {} \
             measurable candidates",
            100.0 * coarse / 600.0,
            a["pool"]
        )),
        "{line}"
    );
}

#[test]
fn a_run_spends_its_budget_never_more_and_records_every_decision() {
    let dir = scratch("adaptive-run");
    let plan = write(&dir, "plan.toml", PLAN);
    let run = dir.join("run.gonio");
    acquire(&plan, &run, &["--seed", "3"]);
    assert_eq!(status(&run), "complete");
    ok(&["verify", &s(&run)]);
    let st = steps(&run);
    let points: BTreeSet<i64> = st
        .iter()
        .filter(|r| r.1 == "sample")
        .filter_map(|r| r.2)
        .collect();
    // The budget exactly: the last batch takes what is left.
    assert_eq!(points.len(), 120);
    let ds = decisions(&run);
    let meta_steps: i64 = Connection::open(&run)
        .expect("opens")
        .query_row("SELECT value FROM meta WHERE key = 'step_count'", [], |r| {
            r.get::<_, String>(0)
        })
        .expect("step_count")
        .parse()
        .expect("count");
    let coarse: BTreeSet<i64> = st
        .iter()
        .filter(|r| r.0 < meta_steps && r.1 == "sample")
        .filter_map(|r| r.2)
        .collect();
    let mut first = meta_steps;
    let mut before = coarse.len() as i64;
    for (k, d) in ds.iter().enumerate() {
        let (id, first_step, n_steps, n_points, method, n_readings, detail) = d;
        assert_eq!(*id, k as i64 + 1);
        assert_eq!(*first_step, first, "batches follow each other");
        assert_eq!(method, "residual");
        // Decided when every step before it was measured (none failed here).
        assert_eq!(*n_readings, *first_step);
        let detail: Value = serde_json::from_str(detail).expect("JSON detail");
        assert_eq!(detail["batch"], k + 1);
        assert_eq!(detail["budget_points"], 120);
        assert_eq!(detail["points_before"], before);
        // Which points and why: the picks are the batch's sample steps, in pairs.
        let picks = detail["picks"].as_array().expect("picks");
        assert_eq!(picks.len() as i64, *n_points);
        let batch: Vec<&StepRow> = st
            .iter()
            .filter(|r| r.0 >= *first_step && r.0 < first_step + n_steps)
            .collect();
        assert_eq!(batch.len() as i64, *n_steps);
        let key = |v: [f64; 4]| v.map(|x| (x * 1e6).round() as i64);
        let picked: BTreeSet<[i64; 4]> = picks
            .iter()
            .map(|p| {
                let a = p.as_array().expect("row");
                key([0, 1, 2, 3].map(|i| a[i].as_f64().expect("angle")))
            })
            .collect();
        let measured: BTreeSet<[i64; 4]> = batch
            .iter()
            .filter(|r| r.1 == "sample")
            .map(|r| key([r.3, r.4, r.5, r.6].map(|x| x.expect("angle"))))
            .collect();
        assert_eq!(picked, measured, "batch {id}");
        // Each pick's score is positive, falls through the batch, and none is
        // nearer a measured point than the planner's minimum spacing.
        let scores: Vec<f64> = picks
            .iter()
            .map(|p| p[4].as_f64().expect("score"))
            .collect();
        assert!(scores.iter().all(|x| *x > 0.0));
        assert!(scores.windows(2).all(|w| w[0] >= w[1]), "{scores:?}");
        assert!(
            picks
                .iter()
                .all(|p| p[7].as_f64().expect("gap") >= gonio_plan::adaptive::MIN_SPACING_DEG)
        );
        // A drift reference opens and closes each batch.
        assert_eq!(batch.first().expect("first").1, "reference");
        assert_eq!(batch.last().expect("last").1, "reference");
        first += n_steps;
        before += n_points;
    }
    assert_eq!(
        first as usize,
        st.len(),
        "every step is the schedule's or a batch's"
    );
    assert_eq!(before, 120);
    // The coarse pass: 18 lattice directions and the mirror at each incidence, less
    // what the arms cannot reach; then full batches of 24, and the rest.
    assert!(coarse.len() <= 38 && coarse.len() >= 34, "{}", coarse.len());
    let rest = 120 - coarse.len() as i64 - 72;
    assert!((1..24).contains(&rest));
    assert_eq!(
        ds.iter().map(|d| d.3).collect::<Vec<_>>(),
        vec![24, 24, 24, rest]
    );
    // The run file reads like any: show, reduce, check, fit, export, report.
    let v = ok_json(&["show", &s(&run), "--json"]);
    assert_eq!(v["status"], "complete");
    assert_eq!(v["batches"]["decided"], ds.len());
    assert_eq!(v["batches"]["points"], 120 - coarse.len());
    assert_eq!(v["batches"]["steps"], st.len() as i64 - meta_steps);
    let samples = dir.join("samples.csv");
    ok(&["reduce", &s(&run), "--out", &s(&samples)]);
    let csv = std::fs::read_to_string(&samples).expect("samples");
    let rows = csv
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("theta_i"))
        .count();
    // Every point once, and the drift reference pair among them.
    assert_eq!(rows, 120);
    // Scattered samples need a grid to be checked, as a list run's do; a grid of the
    // outgoing hemisphere at the two incidences measured is the finest the run
    // supports, and a grid run of the same incidences resamples the same way.
    let o = gonio(&["check", &s(&run)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("pass --grid DTHETA,DPHI"),
        "{}",
        stderr(&o)
    );
    let v = ok_json(&["check", &s(&run), "--grid", "15,30", "--json"]);
    assert_eq!(v["nodes"], 2 * 12 * 6, "{v}");
    let model = dir.join("fit.toml");
    ok(&["fit", &s(&run), "--out", &s(&model)]);
    let exported = dir.join("out.csv");
    ok(&[
        "export",
        &s(&run),
        "--format",
        "csv",
        "--out",
        &s(&exported),
    ]);
    let report = dir.join("report.html");
    ok(&["report", &s(&run), "--out", &s(&report)]);
    let grid_plan = write(
        &dir,
        "grid.toml",
        "[points]\nkind = \"grid\"\ntheta_i = [30, 60]\nphi_i = 0\n\
         theta_o = { from = 10, to = 80, step = 10 }\nphi_o = { from = 0, to = 330, step = 30 }\n\
         [calibration]\ndark = true\ndark_readings = 1\nincident = { transmittance = 1e-3 }\n",
    );
    let grid_run = dir.join("grid.gonio");
    acquire(&grid_plan, &grid_run, &["--seed", "3"]);
    for (k, r) in [&run, &grid_run].into_iter().enumerate() {
        let table = dir.join(format!("table-{k}.csv"));
        ok(&["reduce", &s(r), "--grid", "15,30", "--out", &s(&table)]);
        let text = std::fs::read_to_string(&table).expect("table");
        let rows: Vec<&str> = text
            .lines()
            .filter(|l| l.starts_with("30,0,") || l.starts_with("60,0,"))
            .collect();
        assert_eq!(rows.len(), 2 * 12 * 6, "{}", r.display());
    }
}

#[test]
fn a_budget_in_hours_is_never_exceeded_by_the_planned_time() {
    let dir = scratch("adaptive-hours");
    let plan = write(
        &dir,
        "plan.toml",
        &PLAN.replace("budget = { points = 120 }", "budget = { hours = 0.25 }"),
    );
    let run = dir.join("run.gonio");
    acquire(&plan, &run, &["--seed", "3"]);
    assert_eq!(status(&run), "complete");
    let ds = decisions(&run);
    assert!(!ds.is_empty());
    let last: Value = serde_json::from_str(&ds.last().expect("a batch").6).expect("JSON");
    let planned = last["planned_s"].as_f64().expect("planned_s");
    assert!(planned <= 0.25 * 3600.0, "{planned} s planned for 900 s");
    // And the budget is used: less than one more batch's time is left.
    let per_batch = last["estimate_s"].as_f64().expect("estimate_s");
    assert!(
        planned + per_batch > 0.25 * 3600.0 * 0.9,
        "{planned} + {per_batch}"
    );
}

/// Killed (SIGKILL, SIGTERM) at pseudo-random instants and resumed until done, an
/// adaptive run makes the same decisions and holds the same steps and readings as
/// the run taken at once.
#[test]
fn killed_and_resumed_it_ends_identical_to_an_uninterrupted_run() {
    let dir = scratch("adaptive-kill");
    let plan = write(&dir, "plan.toml", PLAN);
    let whole = dir.join("whole.gonio");
    acquire(&plan, &whole, &["--seed", "5"]);
    let text = std::fs::read_to_string(config("sim-example.toml")).expect("sim");
    let slow = text.replace("time_scale = 0.0 ", "time_scale = 0.01 ");
    assert_ne!(slow, text);
    let sim = write(&dir, "sim-slow.toml", &slow);
    let out = dir.join("killed.gonio");
    let inst = config("instrument-sim.toml");
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
            &sim,
            "--seed",
            "5",
        ],
        11,
        (300, 700),
    );
    assert!(kills >= 3, "{kills} interruptions: too quick to interrupt");
    assert_eq!(decisions(&out), decisions(&whole));
    assert_eq!(steps(&out), steps(&whole));
    assert_eq!(readings(&out), readings(&whole));
    ok(&["verify", &s(&out)]);
}

/// The error table's headline rows (BENCHMARKS.md, "Adaptive acquisition"): at 600
/// points, a sharp Lafortune lobe (n = 500) is reconstructed with at least 3× less
/// error than by a uniform lattice or grid of the same points, and a broad one
/// (n = 5) with no more.
#[test]
fn compare_headline_rows() {
    let inst = config("instrument-sim.toml");
    let plan = config("plan-adaptive.toml");
    let mut got = BTreeMap::new();
    for sample in ["lafortune-n500", "ggx-0.05", "lafortune-n5", "ggx-0.5"] {
        let model = config(&format!("samples/{sample}.toml"));
        let v = ok_json(&[
            "plan",
            "compare",
            &plan,
            "--instrument",
            &inst,
            "--sample",
            &model,
            "--json",
        ]);
        let runs = v["runs"].as_array().expect("runs");
        let e: Vec<f64> = runs
            .iter()
            .map(|r| r["error"].as_f64().expect("error"))
            .collect();
        let n: Vec<u64> = runs
            .iter()
            .map(|r| r["points"].as_u64().expect("points"))
            .collect();
        // The same points, to within 1% (the uniform plans cannot hit any count).
        assert_eq!(n[0], 600);
        assert!(n[1] <= 600 && n[1] >= 594, "{n:?}");
        assert!(n[2] <= 600 && n[2] >= 594, "{n:?}");
        eprintln!(
            "{sample}: adaptive {:.4}, lattice {:.4}, grid {:.4}",
            e[0], e[1], e[2]
        );
        got.insert(sample, e);
    }
    for sharp in ["lafortune-n500", "ggx-0.05"] {
        let e = &got[sharp];
        assert!(e[1] >= 3.0 * e[0] && e[2] >= 3.0 * e[0], "{sharp}: {e:?}");
    }
    for broad in ["lafortune-n5", "ggx-0.5"] {
        let e = &got[broad];
        assert!(e[1] >= e[0] && e[2] >= e[0], "{broad}: {e:?}");
    }
}

/// `plan compare` refuses, with exit 2 and before measuring anything, a plan that is
/// not adaptive, a real instrument, a missing sample, and a `--keep` directory that
/// holds one of its files already (left as it was).
#[test]
fn compare_refuses_bad_input_before_measuring() {
    let dir = scratch("adaptive-compare-bad");
    let inst = config("instrument-sim.toml");
    let plan = config("plan-adaptive.toml");
    let refused = |args: &[&str], want: &str| {
        let o = gonio(args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
    };
    let grid = config("plan-hemisphere.toml");
    refused(
        &["plan", "compare", &grid, "--instrument", &inst],
        "field `points.kind`: `plan compare` compares an adaptive plan",
    );
    let real = config("instrument-example.toml");
    refused(
        &["plan", "compare", &plan, "--instrument", &real],
        "this instrument's ports are real",
    );
    let missing = s(&dir.join("missing.toml"));
    refused(
        &[
            "plan",
            "compare",
            &plan,
            "--instrument",
            &inst,
            "--sample",
            &missing,
        ],
        "missing.toml",
    );
    std::fs::write(dir.join("lattice.csv"), "mine\n").expect("write");
    let keep = s(&dir);
    refused(
        &[
            "plan",
            "compare",
            &plan,
            "--instrument",
            &inst,
            "--keep",
            &keep,
        ],
        "lattice.csv: exists already",
    );
    assert_eq!(
        std::fs::read_to_string(dir.join("lattice.csv")).expect("kept"),
        "mine\n"
    );
    assert!(!dir.join("adaptive.gonio").exists());
}
