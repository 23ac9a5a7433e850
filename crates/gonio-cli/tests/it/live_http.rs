//! The live view's server (docs/live.md) over plain HTTP, no browser: the event
//! stream opens with a snapshot, a foreign `Host` is refused (DNS rebinding), nothing
//! from disk is served, and control needs `--control` and the token.

use crate::common;
use crate::common::live;

use common::scratch;
use live::{PLAN_STEPS, Served, acquire_args, get, request, sim_and_plan};
use serde_json::Value;

/// The JSON body of a response.
fn json(r: &live::Response) -> Value {
    serde_json::from_str(&r.body).unwrap_or_else(|e| panic!("{e}: {r:?}"))
}

/// Polls `GET /state` until `ok` holds, for at most [`live::DEADLINE`]; fails with the
/// last state.
fn wait_state(addr: &str, what: &str, ok: impl Fn(&Value) -> bool) -> Value {
    let t = std::time::Instant::now();
    loop {
        let state = json(&get(addr, "/state"));
        if ok(&state) {
            return state;
        }
        assert!(
            t.elapsed() < live::DEADLINE,
            "waited {:?} for {what}; last state: {state}",
            live::DEADLINE
        );
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
}

/// A live, controllable acquisition: the routes answer as the contract says, and the
/// right token (only) stops the run.
#[test]
fn routes_refuse_what_they_must() {
    let dir = scratch("live-http");
    // About 30 s of wall time, if nothing stopped it.
    let (sim, plan) = sim_and_plan(&dir, 0.08);
    let out = dir.join("run.gonio");
    let mut args = acquire_args(&sim, &plan, &out);
    args.extend(["--serve".into(), "127.0.0.1:0".into(), "--control".into()]);
    let served = Served::start(&args, true);
    let addr = served.addr();
    let token = served.token.clone().expect("a token");

    // The page, and the snapshot the stream starts with.
    let page = get(&addr, "/");
    assert_eq!(page.status, 200, "{page:?}");
    assert!(
        page.header("content-type")
            .is_some_and(|t| t.starts_with("text/html")),
        "{:?}",
        page.headers
    );
    let events = request(&addr, "GET", "/events", "127.0.0.1", &[], Some("\n\n"));
    assert_eq!(events.status, 200, "{events:?}");
    assert!(
        events
            .header("content-type")
            .is_some_and(|t| t.starts_with("text/event-stream")),
        "{:?}",
        events.headers
    );
    // A chunked stream's first line is its first chunk's size.
    let chunked = events
        .header("transfer-encoding")
        .is_some_and(|t| t.contains("chunked"));
    let body = match events.body.split_once("\r\n") {
        Some((_, rest)) if chunked => rest,
        _ => events.body.as_str(),
    };
    assert!(body.starts_with("event: snapshot\n"), "{:?}", events.body);
    let data = body
        .lines()
        .nth(1)
        .and_then(|l| l.strip_prefix("data: "))
        .unwrap_or_else(|| panic!("no data line: {:?}", events.body));
    let snapshot: Value = serde_json::from_str(data).expect("the snapshot's JSON");
    assert_eq!(snapshot["schema"], 1);
    assert_eq!(snapshot["run"]["file"], "run.gonio");
    assert_eq!(snapshot["run"]["control"], true);
    assert_eq!(snapshot["run"]["live"], true);
    assert_eq!(snapshot["status"]["total"], PLAN_STEPS);
    let state = json(&get(&addr, "/state"));
    assert_eq!(state["schema"], 1);
    assert_eq!(state["run"]["name"], "live view test");

    // DNS rebinding: a page of evil.example resolving to 127.0.0.1 is refused, for
    // reading as for control; the names of loopback are accepted.
    for path in ["/", "/state", "/events"] {
        let r = request(&addr, "GET", path, "evil.example", &[], None);
        assert_eq!(r.status, 421, "{path}: {r:?}");
    }
    let host = format!("evil.example:{}", addr.rsplit(':').next().expect("port"));
    let r = request(
        &addr,
        "POST",
        "/control/stop",
        &host,
        &[&format!("X-Gonio-Token: {token}")],
        None,
    );
    assert_eq!(r.status, 421, "{r:?}");
    for host in [
        "localhost",
        &format!("localhost:{}", addr.rsplit(':').next().expect("port")),
    ] {
        let r = request(&addr, "GET", "/state", host, &[], None);
        assert_eq!(r.status, 200, "Host {host}: {r:?}");
    }

    // Nothing from disk: the server runs in the repository's root.
    for path in [
        "/../../etc/passwd",
        "/%2e%2e/%2e%2e/etc/passwd",
        "/Cargo.toml",
        "/README.md",
        "/assets/app.js",
        "/run.gonio",
    ] {
        let r = get(&addr, path);
        assert_eq!(r.status, 404, "{path}: {r:?}");
        assert!(!r.body.contains("root:"), "{path}: {r:?}");
        assert!(!r.body.contains("[workspace]"), "{path}: {r:?}");
    }

    // Control: 403 without the token or with a wrong one, and the run goes on.
    for extra in [
        vec![],
        vec!["X-Gonio-Token: 00000000000000000000000000000000".to_string()],
    ] {
        let extra: Vec<&str> = extra.iter().map(String::as_str).collect();
        for path in ["/control/stop", "/control/pause"] {
            let r = request(&addr, "POST", path, "127.0.0.1", &extra, None);
            assert_eq!(r.status, 403, "{path} {extra:?}: {r:?}");
            assert!(json(&r)["error"].is_string(), "{r:?}");
        }
    }
    // The token as a query parameter is not the header: refused too.
    let r = request(
        &addr,
        "POST",
        &format!("/control/stop?token={token}"),
        "127.0.0.1",
        &[],
        None,
    );
    assert_eq!(r.status, 403, "{r:?}");
    // Refused, they changed nothing: the run goes on, past its calibrations (so
    // that the report has samples to show).
    let state = wait_state(&addr, "4 steps done", |s| {
        s["status"]["state"] == "running" && s["status"]["done"].as_u64() >= Some(4)
    });
    assert_eq!(state["run"]["control"], true, "{state}");

    // With the token: stopped, then 409 (no longer running).
    let header = format!("X-Gonio-Token: {token}");
    let r = request(
        &addr,
        "POST",
        "/control/stop",
        "127.0.0.1",
        &[&header],
        None,
    );
    assert_eq!(r.status, 200, "{r:?}");
    assert_eq!(json(&r)["ok"], true, "{r:?}");
    let state = wait_state(&addr, "interrupted", |s| {
        s["status"]["state"] == "interrupted"
    });
    assert_eq!(state["report"], "/report.html", "{state}");
    assert!(
        state["status"]["done"].as_u64() < Some(PLAN_STEPS),
        "{state}"
    );
    let r = request(
        &addr,
        "POST",
        "/control/stop",
        "127.0.0.1",
        &[&header],
        None,
    );
    assert_eq!(r.status, 409, "{r:?}");
    let report = get(&addr, "/report.html");
    assert_eq!(report.status, 200, "{report:?}");
    assert!(
        report.body.contains("Gonio run report"),
        "{}",
        &report.body[..report.body.len().min(500)]
    );

    let (status, err) = served.terminate();
    assert_eq!(status.code(), Some(130), "{err}");
    let v = common::ok_json(&["show", &out.display().to_string(), "--json"]);
    assert_eq!(v["status"], "interrupted");

    // `gonio view`: control is off, whatever the header says.
    let served = Served::start(
        &[
            "view".into(),
            out.display().to_string(),
            "--serve".into(),
            "127.0.0.1:0".into(),
        ],
        false,
    );
    let addr = served.addr();
    let state = json(&get(&addr, "/state"));
    assert_eq!(state["run"]["live"], false, "{state}");
    assert_eq!(state["run"]["control"], false, "{state}");
    let r = request(
        &addr,
        "POST",
        "/control/stop",
        "127.0.0.1",
        &[&header],
        None,
    );
    assert_eq!(r.status, 403, "{r:?}");
    let (status, err) = served.terminate();
    assert_eq!(status.code(), Some(0), "{err}");
    // `view` changed nothing.
    let after = common::ok_json(&["show", &out.display().to_string(), "--json"]);
    assert_eq!(after["status"], "interrupted");
    assert_eq!(after["states"], v["states"]);
}
