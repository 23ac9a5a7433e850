//! `gonio reduce` of DC (picoammeter) runs, and of lock-in runs as before the DC
//! path: an SR830 run file kept in `crates/gonio-reduce/tests/data/` reduces to the
//! very bytes it reduced to before the picoammeter had a budget of its own.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{config, ok, ok_json, root, s, scratch};

/// The SR830 fixture and its outputs, written by `gonio reduce` before the DC path.
fn data(name: &str) -> PathBuf {
    root().join("crates/gonio-reduce/tests/data").join(name)
}

/// `gonio ARGS` run in `dir` (so that the outputs name the files as the fixtures do).
fn gonio_in(dir: &Path, args: &[&str]) -> Vec<u8> {
    let o = Command::new(env!("CARGO_BIN_EXE_gonio"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("the gonio binary runs");
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o.stdout
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Its output without the first line (which names the output file).
fn tail(out: &[u8]) -> &[u8] {
    let at = out.iter().position(|b| *b == b'\n').map_or(0, |i| i + 1);
    &out[at..]
}

#[test]
fn an_sr830_run_reduces_to_the_same_bytes_as_before_the_dc_path() {
    let d = scratch("dc-sr830-bytes");
    std::fs::copy(data("sr830-in-plane.gonio"), d.join("sr830.gonio")).expect("copy");
    // Table, text and JSON account, with the drift references (the default).
    let text = gonio_in(&d, &["reduce", "sr830.gonio", "--out", "sr830.csv"]);
    assert_eq!(
        read(&d.join("sr830.csv")),
        read(&data("sr830-in-plane.csv"))
    );
    assert_eq!(tail(&text), read(&data("sr830-in-plane.txt")).as_slice());
    let json = gonio_in(
        &d,
        &["reduce", "sr830.gonio", "--out", "sr830b.csv", "--json"],
    );
    assert_eq!(json, read(&data("sr830-in-plane.json")));
    // The other drift paths: interpolated calibrations, and none.
    for drift in ["calibrations", "none"] {
        let out = format!("sr830-{drift}.csv");
        let text = gonio_in(
            &d,
            &["reduce", "sr830.gonio", "--out", &out, "--drift", drift],
        );
        let want = format!("sr830-in-plane-drift-{drift}");
        assert_eq!(read(&d.join(&out)), read(&data(&format!("{want}.csv"))));
        assert_eq!(tail(&text), read(&data(&format!("{want}.txt"))).as_slice());
    }
}

/// A run of the mixed-family instrument (Keithley 6485 detector), acquired and
/// reduced by the CLI: the budget has the range-accuracy line, classified by
/// range, and every budget line names amps.
#[test]
fn a_picoammeter_run_reduces_with_the_dc_budget() {
    let d = scratch("dc-reduce");
    let run = d.join("run.gonio");
    ok(&[
        "acquire",
        "--instrument",
        &config("instrument-mixed.toml"),
        "--sim",
        &config("sim-mixed.toml"),
        "--plan",
        &config("plan-in-plane.toml"),
        "--out",
        &s(&run),
        "--seed",
        "11",
        "--json",
    ]);
    let v = ok_json(&["reduce", &s(&run), "--out", &s(&d.join("t.csv")), "--json"]);
    let ch = &v["reduction"]["channels"][0];
    let budget = ch["budget"].as_array().expect("budget");
    let terms: Vec<&str> = budget
        .iter()
        .map(|t| t["term"].as_str().expect("term"))
        .collect();
    // The DC terms, then the position term.
    assert_eq!(
        terms[..gonio_reduce::DC_TERMS.len()],
        gonio_reduce::DC_TERMS
    );
    assert_eq!(
        terms[gonio_reduce::DC_TERMS.len()..],
        [gonio_reduce::POSITION_TERM]
    );
    assert_eq!(budget[6]["correlation"], "range");
    let acc = budget[6]["rel_median"].as_f64().expect("median");
    let noise = budget[0]["rel_median"].as_f64().expect("median");
    println!("range accuracy median {acc:.3e}, noise median {noise:.3e}");
    assert!(acc > 0.0 && noise > 0.0);
    for t in budget {
        let source = t["source"].as_str().expect("source");
        assert!(!source.contains(" V"), "{source}");
    }
    // The calibration's current and the dark current are amps, and say so.
    assert_eq!(ch["unit"], "A");
    let incident = ch["incident_a"].as_f64().expect("incident_a");
    assert!(incident > 0.0 && incident < 1e-3, "{incident}");
    assert!(ch["dark_a"].is_array());
    assert!(
        ch.get("incident_v").is_none() && ch.get("dark_v").is_none(),
        "{ch}"
    );
    // The text account: the budget's lines in amps, the range accuracy among them.
    let out = ok(&["reduce", &s(&run), "--out", &s(&d.join("u.csv"))]);
    let text = String::from_utf8_lossy(&out.stdout);
    let lines: Vec<&str> = text.lines().filter(|l| l.starts_with("  σ ")).collect();
    // The DC terms and the position term.
    assert_eq!(lines.len(), 8, "{text}");
    assert!(
        lines.iter().any(|l| l.starts_with("  σ range accuracy")),
        "{text}"
    );
    assert!(lines.iter().all(|l| !l.contains(" V")), "{text}");
    let channel = text
        .lines()
        .find(|l| l.starts_with("channel "))
        .expect("channel line");
    assert!(
        channel.contains(" A ± ") && channel.contains(") A, drift") && !channel.contains(" V"),
        "{channel}"
    );
    assert!(lines[2].contains(" A"), "{text}");
    // The table: every sample reduced, with a positive value and σ (the
    // comparison with the paint's BRDF is gonio-reduce's tests/dc.rs).
    let table = std::fs::read_to_string(d.join("u.csv")).expect("table");
    let rows: Vec<Vec<f64>> = table
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("theta") && !l.is_empty())
        .map(|l| l.split(',').filter_map(|x| x.trim().parse().ok()).collect())
        .collect();
    assert!(rows.len() >= 80, "{}", rows.len());
    assert!(
        rows.iter()
            .all(|r| r.len() == 6 && r[4] > 0.0 && r[5] > 0.0)
    );
}
