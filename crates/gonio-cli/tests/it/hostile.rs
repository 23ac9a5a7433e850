//! Nothing a user types can crash Gonio (issue 16): each class of hostile input
//! exits 2 at once, in bounded memory, with a message naming the field or flag and the
//! limit, and leaves nothing behind.
//!
//! - Non-finite or absurd numbers in configs and model files (`start_position = nan`
//!   aborted `acquire` with status 134; `poll_interval_ms = 2^64 − 1` was accepted).
//! - Sizes that would allocate or loop without bound (`--grid 0.001,0.001` panicked
//!   with status 101; `--rays 2^64 − 1` and `--lobes 100000` never ended).
//! - Inputs that are not regular files: a FIFO (which blocked `open` for ever),
//!   `/dev/zero` (read for ever), a directory.
//!
//! Each run is bounded by [`run`]: a command that hangs fails its test instead of
//! hanging the suite.

use crate::common;

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::{config, s, scratch, stderr};

/// Runs `gonio` with `args`, killing it (and failing) if it has not finished within
/// a minute: every refusal here takes milliseconds, so only a hang reaches the limit.
fn run(args: &[&str]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_gonio"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the gonio binary runs");
    let started = Instant::now();
    while child.try_wait().expect("waits").is_none() {
        if started.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("gonio {args:?} did not finish within a minute");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    child.wait_with_output().expect("output")
}

/// Runs `gonio`, asserting exit status 2 and that stderr contains `want`.
fn refused(args: &[&str], want: &str) -> String {
    let o = run(args);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
    assert!(e.contains(want), "{args:?}: {e:?} lacks {want:?}");
    e
}

/// `text` with `from` replaced by `to` (which must occur).
fn edit(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "{from:?} not found");
    text.replacen(from, to, 1)
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(config(rel)).expect("a config file")
}

/// A FIFO at `path`, or `false` where `mkfifo` is missing.
fn mkfifo(path: &Path) -> bool {
    Command::new("mkfifo")
        .arg(path)
        .status()
        .is_ok_and(|s| s.success())
}

const ONE_PAIR_PLAN: &str = "name = \"one pair\"\n[points]\nkind = \"in-plane\"\n\
                             theta_i = [30]\ntheta_o = [30]\n";

#[test]
fn non_finite_and_absurd_numbers_in_configs_exit_2_naming_field_and_limit() {
    let d = scratch("hostile-numbers");
    let plan = d.join("plan.toml");
    std::fs::write(&plan, ONE_PAIR_PLAN).expect("write");
    let inst = config("instrument-sim.toml");

    // The simulator's axis: NaN used to reach the controller model and abort the
    // process in the middle of `acquire` (status 134).
    let sim = d.join("sim-nan.toml");
    let text = edit(
        &read("sim-example.toml"),
        "start_position = 12.5",
        "start_position = nan",
    );
    std::fs::write(&sim, &text).expect("write");
    let out = d.join("nan.gonio");
    refused(
        &[
            "acquire",
            "--instrument",
            &inst,
            "--plan",
            &s(&plan),
            "--sim",
            &s(&sim),
            "--out",
            &s(&out),
        ],
        &format!(
            "{}:18:18: field `controllers[0].start_position`: must be finite, got NaN",
            s(&sim)
        ),
    );
    assert!(!out.exists(), "a refused acquisition leaves no run file");

    // time_scale = 1e308 panicked a step's task ("cannot convert float seconds").
    let sim = d.join("sim-scale.toml");
    let text = edit(
        &read("sim-example.toml"),
        "time_scale = 0.0",
        "time_scale = 1e308",
    );
    std::fs::write(&sim, &text).expect("write");
    refused(
        &[
            "acquire",
            "--instrument",
            &inst,
            "--plan",
            &s(&plan),
            "--sim",
            &s(&sim),
            "--out",
            &s(&out),
        ],
        "field `time_scale`: must be at most 1000, got 1e308",
    );

    // An integer that fits no timeout was accepted.
    let rig = d.join("rig.toml");
    let text = edit(
        &read("instrument-sim.toml"),
        "poll_interval_ms = 50",
        "poll_interval_ms = 18446744073709551615",
    );
    std::fs::write(&rig, &text).expect("write");
    refused(
        &["instrument", "check", &s(&rig)],
        &format!(
            "{}:7:20: field `motion.poll_interval_ms`: must be at most 60000 ms, got \
             18446744073709551615",
            s(&rig)
        ),
    );

    // A plan's ordering budget of 1e20 s panicked in Duration::from_secs_f64.
    let p = d.join("budget.toml");
    std::fs::write(&p, format!("{ONE_PAIR_PLAN}[order]\nbudget_s = 1e20\n")).expect("write");
    refused(
        &["plan", "check", "--instrument", &inst, &s(&p)],
        &format!(
            "{}:7:12: field `order.budget_s`: must be at most 3600 s, got 1e20",
            s(&p)
        ),
    );

    // Model files: Blinn's n = 1e308 hung `model albedo`, Cook–Torrance's alpha =
    // 1e300 panicked it.
    let m = d.join("blinn.toml");
    let text = edit(
        &read("models/blinn-phong-plastic.toml"),
        "n = [200, 200, 200]",
        "n = [1e308, 200, 200]",
    );
    std::fs::write(&m, &text).expect("write");
    refused(
        &["model", "albedo", &s(&m)],
        &format!(
            "{}:6:5: field `n`: 1e308 for channel R must be in [0, 1e6]",
            s(&m)
        ),
    );
    let m = d.join("gold.toml");
    let text = edit(
        &read("models/cook-torrance-gold.toml"),
        "alpha = [0.25, 0.25, 0.25]",
        "alpha = [0.25, 1e300, 0.25]",
    );
    std::fs::write(&m, &text).expect("write");
    refused(
        &["model", "eval", &s(&m), &config("dirs-example.csv")],
        &format!(
            "{}:7:9: field `alpha`: 1e300 for channel G must be in [1e-4, 10]",
            s(&m)
        ),
    );

    // A surface whose roughness no tracer follows: rms_height = 1e8 traced for ever.
    let surf = d.join("rough.toml");
    let text = edit(
        &read("micro-gaussian-gold.toml"),
        "rms_height = 0.75",
        "rms_height = 1e8",
    );
    std::fs::write(&surf, &text).expect("write");
    refused(
        &["micro", &s(&surf), "--out", &s(&d.join("t.csv"))],
        "field `surface.rms_height`: must be at most 250, got 1e8 (at most 50 × \
         correlation_length: an RMS slope 2σ/l of at most 100)",
    );

    // A flag's number.
    refused(
        &[
            "model",
            "albedo",
            &config("models/white-reference.toml"),
            "--phi-i",
            "nan",
        ],
        "--phi-i: must be finite, got NaN",
    );
}

#[test]
fn sizes_that_would_allocate_or_loop_without_bound_exit_2_naming_the_cap() {
    let d = scratch("hostile-sizes");
    let model = config("models/blue-paint-550nm.toml");
    // Grids: 0.001° panicked on the node count (status 101).
    let cap = "more than the 33554432 a grid may have (the finest is about 2.5,2.5)";
    refused(&["check", &model, "--grid", "0.001,0.001"], cap);
    refused(
        &[
            "reduce",
            &s(&d.join("run.gonio")),
            "--out",
            &s(&d.join("t.csv")),
            "--grid",
            "0.0001,0.0001",
        ],
        "0.0001,0.0001 makes a grid of 1.05e25 nodes",
    );
    // Rays and lobes: 2^64 − 1 rays and 100 000 lobes never ended.
    let surface = config("micro-sawtooth-deyoung.toml");
    let table = s(&d.join("t.csv"));
    refused(
        &[
            "micro",
            &surface,
            "--out",
            &table,
            "--rays",
            "18446744073709551615",
        ],
        "--rays: must be at most 1000000000 rays, got 18446744073709551615",
    );
    refused(
        &[
            "micro",
            &surface,
            "--out",
            &table,
            "--max-bounces",
            "4294967295",
        ],
        "--max-bounces: must be at most 10000 bounces, got 4294967295",
    );
    refused(
        &[
            "micro",
            &surface,
            "--out",
            &table,
            "--sh",
            "1000",
            "--sh-out",
            &s(&d.join("sh.toml")),
        ],
        "--sh: must be at most 128, got 1000",
    );
    assert!(!d.join("t.csv").exists());
    refused(
        &[
            "fit",
            &model,
            "--lobes",
            "100000",
            "--out",
            &s(&d.join("fit.toml")),
        ],
        "--lobes: must be at most 8, got 100000",
    );
    refused(
        &[
            "harmonics",
            &model,
            "--order",
            "100000",
            "--out",
            &s(&d.join("sh.toml")),
        ],
        "--order: must be at most 128, got 100000",
    );
    // A plan of 8.1 × 10^11 pairs, and one of 8 × 10^9 readings.
    let inst = config("instrument-sim.toml");
    let p = d.join("huge.toml");
    std::fs::write(
        &p,
        "[points]\nkind = \"isotropic\"\ntheta_i = { from = 0, to = 90, step = 1e-4 }\n\
         theta_o = { from = 0, to = 90, step = 1e-4 }\ndelta_phi = [0]\n",
    )
    .expect("write");
    refused(
        &["plan", "check", "--instrument", &inst, &s(&p)],
        "field `points`: expands to 810001800001 pairs, more than 1000000",
    );
    std::fs::write(
        &p,
        "repeats = 10000\n[points]\nkind = \"isotropic\"\ntheta_i = { from = 0, to = 90, step = 0.1 }\n\
         theta_o = { from = 0, to = 90, step = 0.1 }\ndelta_phi = [0]\n",
    )
    .expect("write");
    refused(
        &["plan", "check", "--instrument", &inst, &s(&p)],
        "field `repeats`: 811801 pairs and 0 standard pairs × 10000 repeats × 1 channels is \
         about 8118030000 readings, more than the 2000000 a plan may take",
    );
}

#[cfg(unix)]
#[test]
fn fifos_devices_and_directories_are_refused_without_blocking() {
    let d = scratch("hostile-files");
    let fifo = d.join("pipe");
    if !mkfifo(&fifo) {
        return; // no mkfifo on this system
    }
    let f = s(&fifo);
    let not_regular = |p: &str, what: &str| {
        format!("{p}: {what}, not a regular file (Gonio reads its inputs from regular files only)")
    };
    let fifo_msg = not_regular(&f, "a FIFO (named pipe)");
    let inst = config("instrument-sim.toml");
    let model = config("models/blue-paint-550nm.toml");
    let out = s(&d.join("out"));
    let plan = d.join("plan.toml");
    std::fs::write(&plan, ONE_PAIR_PLAN).expect("write");
    for args in [
        vec!["check", &f],
        vec!["export", &f, "--format", "csv", "--out", &out],
        vec!["model", "albedo", &f],
        vec!["model", "eval", &model, &f],
        vec![
            "plot", &model, "--fit", &f, "--kind", "albedo", "--out", "x.png",
        ],
        vec!["micro", &f, "--out", &out],
        vec!["instrument", "check", &f],
        vec!["plan", "check", "--instrument", &inst, &f],
        vec!["plan", "check", "--instrument", &f, &s(&plan)],
        vec!["reduce", &f, "--out", &out],
        vec!["show", &f],
        vec!["report", &f, "--out", &out],
    ] {
        refused(&args, &fifo_msg);
    }
    let run = s(&d.join("r.gonio"));
    refused(
        &[
            "acquire",
            "--instrument",
            &inst,
            "--plan",
            &s(&plan),
            "--sim",
            &f,
            "--out",
            &run,
        ],
        &fifo_msg,
    );
    assert!(!d.join("r.gonio").exists());
    // /dev/zero never ends; a directory is not a file.
    refused(
        &["check", "/dev/zero"],
        &not_regular("/dev/zero", "a character device"),
    );
    refused(
        &["model", "albedo", &s(&d)],
        &not_regular(&s(&d), "a directory"),
    );
    // A config larger than the cap is refused from its size, unread (a sparse file).
    let big = d.join("big.toml");
    std::fs::File::create(&big)
        .and_then(|f| f.set_len((16 << 20) + 1))
        .expect("sparse file");
    refused(
        &["instrument", "check", &s(&big)],
        &format!(
            "{}: larger than 16777216 bytes, the most this kind of file may have",
            s(&big)
        ),
    );
}

#[cfg(unix)]
#[test]
fn runs_skips_what_is_not_a_regular_file_without_opening_it() {
    let d = scratch("hostile-runs");
    if !mkfifo(&d.join("pipe.gonio")) {
        return;
    }
    std::fs::create_dir(d.join("dir.gonio")).expect("dir");
    std::fs::write(d.join("empty.gonio"), b"").expect("write");
    let o = run(&["runs", &s(&d), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    let runs = v["runs"].as_array().expect("runs");
    // The empty file is listed as unreadable; the FIFO and the directory are skipped.
    assert_eq!(runs.len(), 1, "{v}");
    assert_eq!(runs[0]["status"], "unreadable");
    assert!(
        runs[0]["path"]
            .as_str()
            .expect("path")
            .ends_with("empty.gonio"),
        "{v}"
    );
    let e = stderr(&o);
    assert!(
        e.contains("skipped: ") && e.contains("pipe.gonio: a FIFO (named pipe)"),
        "{e}"
    );
    assert!(e.contains("dir.gonio: a directory"), "{e}");
}

/// The albedo curve of a harmonics file is computed in closed form (it took 42 s by
/// cubature at degree 22); its exactness is tested in gonio-process (`tests/sh.rs`),
/// the command here.
#[test]
fn a_harmonics_albedo_plot_is_drawn() {
    let d = scratch("hostile-sh");
    let sh = d.join("sh.toml");
    let o = run(&[
        "harmonics",
        &config("models/white-reference.toml"),
        "--grid",
        "10,30",
        "--order",
        "12",
        "--out",
        &s(&sh),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let png = d.join("albedo.png");
    let o = run(&["plot", &s(&sh), "--kind", "albedo", "--out", &s(&png)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::metadata(&png).expect("a PNG").len() > 1000);
}
