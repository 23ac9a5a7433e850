//! Reliability, class by class (issue 16): no output replaces a file unasked, a run
//! file is never written onto, and outputs appear whole or not at all.

use crate::common;

use std::path::Path;

use common::{ISO_PLAN, acquire, config, gonio, ok, s, scratch, stderr};

/// Every file in `dir` (names), sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .expect("dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Each command with an output, as `(name, args before --out, output file name)`.
fn writers(d: &Path, run: &Path) -> Vec<(&'static str, Vec<String>, &'static str)> {
    let model = config("models/blue-paint-550nm.toml");
    let table = d.join("t.csv");
    let sv = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    vec![
        ("reduce", sv(&["reduce", &s(run)]), "r.csv"),
        (
            "export",
            sv(&["export", &s(&table), "--format", "astm"]),
            "e.astm",
        ),
        (
            "correct",
            sv(&["correct", &model, "--grid", "30,90", "--reciprocity", "1"]),
            "c.csv",
        ),
        (
            "harmonics",
            sv(&["harmonics", &s(&table), "--order", "2"]),
            "h.toml",
        ),
        ("fit", sv(&["fit", &s(run), "--lobes", "1"]), "f.toml"),
        ("plot", sv(&["plot", &model, "--kind", "polar"]), "p.svg"),
        (
            "model eval",
            sv(&["model", "eval", &model, &config("dirs-example.csv")]),
            "m.csv",
        ),
        (
            "micro",
            sv(&[
                "micro",
                &config("micro-sawtooth-deyoung.toml"),
                "--grid",
                "30,90",
                "--rays",
                "200",
            ]),
            "u.csv",
        ),
    ]
}

#[test]
fn no_output_replaces_a_file_unasked_and_none_writes_onto_a_run_file() {
    let d = scratch("outputs");
    let run = acquire(&d, ISO_PLAN);
    let run_bytes = std::fs::read(&run).expect("run");
    ok(&[
        "correct",
        &config("models/blue-paint-550nm.toml"),
        "--grid",
        "30,90",
        "--reciprocity",
        "1",
        "--out",
        &s(&d.join("t.csv")),
    ]);
    for (name, args, out) in writers(&d, &run) {
        let out = d.join(out);
        let with = |target: &Path, extra: &[&str]| {
            let mut a: Vec<&str> = args.iter().map(String::as_str).collect();
            let t = s(target);
            a.extend(["--out", &t]);
            a.extend(extra);
            gonio(&a)
        };
        // Onto the run file: refused, even with --force, and the run is untouched.
        for extra in [&[][..], &["--force"][..]] {
            let o = with(&run, extra);
            assert_eq!(o.status.code(), Some(2), "{name} {extra:?}: {}", stderr(&o));
            assert!(
                stderr(&o).contains("is a Gonio run file; an output never replaces a run file"),
                "{name}: {}",
                stderr(&o)
            );
            assert_eq!(std::fs::read(&run).expect("run"), run_bytes, "{name}");
        }
        // Onto an existing file: refused without --force, the file kept.
        std::fs::write(&out, b"precious").expect("write");
        let o = with(&out, &[]);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!(
                "{}: exists already; give --force to replace it",
                out.display()
            )),
            "{name}: {}",
            stderr(&o)
        );
        assert_eq!(std::fs::read(&out).expect("kept"), b"precious", "{name}");
        // With --force: replaced whole, nothing left beside it.
        let o = with(&out, &["--force"]);
        assert!(o.status.success(), "{name} --force: {}", stderr(&o));
        let written = std::fs::read(&out).expect("written");
        assert!(written.len() > 100 && written != b"precious", "{name}");
        assert!(
            !names(&d).iter().any(|n| n.contains(".gonio-tmp-")),
            "{name}: a temporary file was left: {:?}",
            names(&d)
        );
        // Into a directory, or one that does not exist: refused before any work.
        for bad in [d.to_path_buf(), d.join("no/such/dir/x.csv")] {
            let o = with(&bad, &[]);
            assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        }
    }
}

#[test]
fn the_report_and_the_demo_keep_what_exists() {
    let d = scratch("report-exists");
    let run = acquire(&d, ISO_PLAN);
    let rep = d.join("rep");
    ok(&["report", &s(&run), "--out", &s(&rep)]);
    let o = gonio(&["report", &s(&run), "--out", &s(&rep)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("report.html: exists already; give --force"));
    ok(&["report", &s(&run), "--out", &s(&rep), "--force"]);
    assert!(std::fs::read(rep.join("report.html")).expect("page").len() > 1000);
    // The demo keeps its run beside a name that is free, never over a run.
    let o = gonio(&["demo", "--out", &s(&run)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("exists already; a run file is never replaced"));
}

/// Runs SQL on a run file behind Gonio's back.
fn edit(path: &Path, sql: &str) {
    rusqlite::Connection::open(path)
        .expect("opens")
        .execute_batch(sql)
        .expect("edits");
}

/// One reading's R, read directly.
fn r_mean(path: &Path, step: i64) -> Option<f64> {
    use rusqlite::OptionalExtension;
    rusqlite::Connection::open(path)
        .expect("opens")
        .query_row(
            "SELECT r_mean FROM readings WHERE step_id = ?1",
            [step],
            |r| r.get(0),
        )
        .optional()
        .expect("query")
}

#[test]
fn verify_finds_a_deleted_row_an_altered_value_and_an_edited_config_and_resume_remeasures() {
    let d = scratch("verify");
    let run = acquire(&d, ISO_PLAN);
    let run_s = s(&run);
    let o = ok(&["verify", &run_s]);
    assert!(
        String::from_utf8_lossy(&o.stdout).contains(": intact ("),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    let pristine = std::fs::read(&run).expect("bytes");

    // A deleted reading: verify exits 1 naming the step; show and reduce refuse.
    let step = 7;
    let before = r_mean(&run, step).expect("measured");
    edit(
        &run,
        &format!("DELETE FROM readings WHERE step_id = {step}"),
    );
    let o = gonio(&["verify", &run_s, "--json"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    assert_eq!(v["intact"], false);
    assert_eq!(v["missing"], serde_json::json!([step]));
    for cmd in [
        &["show", &run_s][..],
        &["reduce", &run_s, "--out", &s(&d.join("x.csv"))],
    ] {
        let o = gonio(cmd);
        assert_eq!(o.status.code(), Some(2), "{cmd:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!(
                "1 committed reading(s) missing (steps {step}); `gonio resume` measures them again"
            )),
            "{cmd:?}: {}",
            stderr(&o)
        );
    }
    // Resume measures it again (same seed, same value), and says so.
    let o = gonio(&["resume", &run_s]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("measuring those steps again"),
        "{}",
        stderr(&o)
    );
    assert_eq!(r_mean(&run, step), Some(before));
    ok(&["verify", &run_s]);
    let v: serde_json::Value =
        serde_json::from_slice(&ok(&["show", &run_s, "--json"]).stdout).expect("JSON");
    assert_eq!(v["status"], "complete");
    assert_eq!(v["events"]["remeasure"], 1, "{}", v["events"]);

    // An altered value, and an edited config, each on a fresh copy.
    for (sql, says) in [
        (
            format!("UPDATE readings SET r_mean = r_mean * 2 WHERE step_id = {step}"),
            format!("readings row {step} fails its checksum"),
        ),
        (
            "UPDATE meta SET value = value || '# edited' WHERE key = 'instrument'".to_string(),
            "the metadata (configs, seed, geometry) differ from those recorded".to_string(),
        ),
        (
            "UPDATE steps SET theta_o = 1 WHERE id = 3".to_string(),
            "steps row 3 fails its checksum".to_string(),
        ),
    ] {
        std::fs::write(&run, &pristine).expect("restore");
        edit(&run, &sql);
        let o = gonio(&["verify", &run_s]);
        assert_eq!(o.status.code(), Some(1), "{sql}: {}", stderr(&o));
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(out.contains(&says), "{sql}: {out}");
        assert!(
            stderr(&o).contains("damaged (1 fault(s))"),
            "{}",
            stderr(&o)
        );
        // Resume refuses damage it cannot repair.
        let o = gonio(&["resume", &run_s]);
        assert_eq!(o.status.code(), Some(2), "{sql}: {}", stderr(&o));
        assert!(stderr(&o).contains(&says), "{sql}: {}", stderr(&o));
    }

    // A meta row gone: named, exit 1.
    std::fs::write(&run, &pristine).expect("restore");
    edit(&run, "DELETE FROM meta WHERE key = 'plan'");
    let o = gonio(&["show", &run_s]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("the run's meta row `plan` is missing"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn every_input_is_checked_before_the_run_file_exists() {
    let d = scratch("validate-first");
    let inst = config("instrument-sim.toml");
    let run = d.join("run.gonio");
    let plan_with = |standard: &str| {
        let p = d.join("plan.toml");
        std::fs::write(
            &p,
            format!(
                "[points]\nkind = \"in-plane\"\ntheta_i = [20]\ntheta_o = [-40, 40]\n\
                 [calibration]\nstandard = {{ model = \"{standard}\", at = [[0, 0, 45, 180]] }}\n"
            ),
        )
        .expect("plan");
        s(&p)
    };
    // The standard's model file missing, then not a model: exit 2, naming it, and
    // nothing created (no run file, no temporary, no lock).
    std::fs::write(d.join("bad.toml"), "kind = \"lafortune\"\nrho_d = \"x\"\n").expect("bad");
    for (standard, says) in [
        ("absent.toml", "absent.toml"),
        ("bad.toml", "reference standard model"),
    ] {
        let o = gonio(&[
            "acquire",
            "--instrument",
            &inst,
            "--plan",
            &plan_with(standard),
            "--out",
            &s(&run),
        ]);
        assert_eq!(o.status.code(), Some(2), "{standard}: {}", stderr(&o));
        assert!(stderr(&o).contains(says), "{standard}: {}", stderr(&o));
        assert_eq!(names(&d), ["bad.toml", "plan.toml"], "{standard}");
    }
    // An output in a directory that does not exist.
    let o = gonio(&[
        "acquire",
        "--instrument",
        &inst,
        "--plan",
        &config("plan-in-plane.toml"),
        "--out",
        &s(&d.join("no/such/run.gonio")),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("does not exist"), "{}", stderr(&o));
}
