//! Logs: `--log FILE` holds the session's spans and events as JSON lines, one per
//! committed step at debug, and is never written over.

mod common;

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
}
