//! Logs: `--log FILE` holds the session's spans and events as JSON lines, one per
//! committed step at debug, and is never written over.

use crate::common;

use common::{config, gonio, scratch, stderr};

#[test]
fn acquire_writes_its_log_as_json_lines_beside_the_run() {
    let dir = scratch("log");
    let run = dir.join("run.gonio");
    let log = dir.join("run.log.jsonl");
    let o = gonio(&[
        "acquire",
        "--instrument",
        &config("instrument-sim.toml"),
        "--plan",
        &config("plan-list.toml"),
        "--out",
        &run.display().to_string(),
        "--log",
        &log.display().to_string(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    // Without -v or RUST_LOG the terminal shows warnings only: no serial lines.
    assert!(!stderr(&o).contains("dir="), "{}", stderr(&o));
    let text = std::fs::read_to_string(&log).expect("the log file");
    let lines: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).expect("each line one JSON object"))
        .collect();
    let message = |v: &serde_json::Value| v["fields"]["message"].as_str().unwrap_or("").to_string();
    // One "step committed" a measured step, each inside its run and step spans.
    let committed: Vec<&serde_json::Value> = lines
        .iter()
        .filter(|v| message(v) == "step committed")
        .collect();
    assert_eq!(
        committed.len() as u64,
        report["measured"].as_u64().expect("measured")
    );
    for v in &committed {
        assert_eq!(v["level"], "DEBUG");
        let spans: Vec<&str> = v["spans"]
            .as_array()
            .expect("span list")
            .iter()
            .filter_map(|s| s["name"].as_str())
            .collect();
        assert_eq!(spans, ["run", "step"], "{v}");
        assert!(v["fields"]["r_mean"].as_f64().is_some_and(|r| r > 0.0));
    }
    assert!(lines.iter().any(|v| message(v) == "session started"));
    // The file is at debug: state changes, not the wire (that is -vv).
    assert!(lines.iter().any(|v| message(v) == "operation started"));
    assert!(lines.iter().all(|v| v["fields"]["dir"].is_null()));
    assert!(
        lines.iter().any(
            |v| message(v).starts_with("session ended") && v["fields"]["outcome"] == "complete"
        )
    );
    // The log is never written over: a second session refuses the same file.
    let again = gonio(&[
        "acquire",
        "--instrument",
        &config("instrument-sim.toml"),
        "--plan",
        &config("plan-list.toml"),
        "--out",
        &dir.join("other.gonio").display().to_string(),
        "--log",
        &log.display().to_string(),
    ]);
    assert_eq!(again.status.code(), Some(2), "{}", stderr(&again));
    assert!(stderr(&again).contains("cannot create the log file"));
    assert_eq!(std::fs::read_to_string(&log).expect("log"), text);
    assert!(!dir.join("other.gonio").exists());
    // Input refused before anything is created leaves no log file behind either.
    let bad = dir.join("bad-plan.toml");
    std::fs::write(
        &bad,
        "[points]\nkind = \"in-plane\"\ntheta_i = [0]\ntheta_o = [95]\n",
    )
    .expect("write");
    let fresh = dir.join("bad.log.jsonl");
    let refused = gonio(&[
        "acquire",
        "--instrument",
        &config("instrument-sim.toml"),
        "--plan",
        &bad.display().to_string(),
        "--out",
        &dir.join("bad.gonio").display().to_string(),
        "--log",
        &fresh.display().to_string(),
    ]);
    assert_eq!(refused.status.code(), Some(2), "{}", stderr(&refused));
    assert!(stderr(&refused).contains("field `points.theta_o`"));
    assert!(!fresh.exists() && !dir.join("bad.gonio").exists());
}

#[test]
fn trace_shows_every_serial_exchange_of_the_demo() {
    let dir = scratch("trace");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_gonio"))
        .args(["demo", "--out"])
        .arg(dir.join("demo.gonio"))
        .env("RUST_LOG", "trace")
        .output()
        .expect("the gonio binary runs");
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    let wire: Vec<&str> = err.lines().filter(|l| l.contains(" dir=")).collect();
    let sent = |what: &str| {
        wire.iter()
            .any(|l| l.contains("dir=\"tx\"") && l.contains(&format!("line={what}")))
    };
    let received = |what: &str| {
        wire.iter()
            .any(|l| l.contains("dir=\"rx\"") && l.contains(&format!("line={what}")))
    };
    // An absolute move of the source arm and the lock-in's snapshot go out, with the
    // lines that answer them coming back.
    assert!(sent("1PA"), "no move sent");
    assert!(sent("1TS\\r\\n") && received("1TS"), "no status exchange");
    assert!(sent("SNAP? 1,2\\n"), "no snapshot sent");
    assert!(
        wire.iter().any(|l| l.contains("port=\"sim:detector\"")
            && l.contains("dir=\"rx\"")
            && l.contains(',')),
        "no snapshot reply"
    );
    // Every exchange is there: as many lines sent to the lock-in as answered, plus the
    // set commands that have no answer.
    let tx = wire.iter().filter(|l| l.contains("dir=\"tx\"")).count();
    let rx = wire.iter().filter(|l| l.contains("dir=\"rx\"")).count();
    assert!(tx >= rx && rx > 1000, "{tx} sent, {rx} received");
}
