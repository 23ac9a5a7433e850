//! Reliability, class by class (issue 16): no output replaces a file unasked, a run
//! file is never written onto, and outputs appear whole or not at all.

mod common;

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
