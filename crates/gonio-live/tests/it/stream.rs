//! The live view over HTTP on a simulated run measured in this process: a page
//! that follows the event stream from the start ends with exactly the state of a
//! page opened at the end, and of the run file read afresh; the reduction it shows
//! is `gonio reduce`'s; pause and stop work through the control routes, with the
//! token only.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use gonio_acquire::engine::{Engine, EngineConfig, Outcome};
use gonio_driver::InstrumentConfig;
use gonio_run::{Inputs, RunStore};
use gonio_sim::{SimBench, SimClock, SimConfig};
use serde_json::Value;

const PLAN: &str = r#"
name = "live test"
[points]
kind = "in-plane"
theta_i = [30]
theta_o = { from = -60, to = 60, step = 20 }
[drift]
every = 3
[calibration]
dark = true
dark_readings = 1
incident = { transmittance = 1e-3 }
"#;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A run file of [`PLAN`] and an engine on the simulator, whose clock runs at
/// `time_scale` of real time.
fn setup(dir: &Path, time_scale: f64) -> (PathBuf, Engine<SimClock, SimBench>) {
    setup_plan(dir, time_scale, PLAN)
}

/// [`setup`] with another plan.
fn setup_plan(
    dir: &Path,
    time_scale: f64,
    plan_text: &str,
) -> (PathBuf, Engine<SimClock, SimBench>) {
    let (inst, inst_text) =
        InstrumentConfig::load_with_text(&root().join("config/instrument-sim.toml"))
            .expect("instrument");
    let plan = gonio_plan::Plan::from_toml(plan_text, Some(&root().join("config/test-plan.toml")))
        .expect("plan");
    let mech = inst.mechanics().expect("mechanics");
    let prepared = gonio_plan::prepare(&mech, inst.reading_seconds(), &plan).expect("prepares");
    let mut sim = SimConfig::default_config().expect("sim");
    sim.seed = 5;
    sim.time_scale = time_scale;
    let inputs = Inputs {
        instrument_text: inst_text,
        plan_text: plan_text.into(),
        sim: Some((
            gonio_sim::config::DEFAULT_SIM.to_string(),
            sim.sample_model_text().expect("sample"),
        )),
        seed: Some(5),
        software: "test".into(),
        ..Inputs::default()
    };
    let out = dir.join("run.gonio");
    let store = gonio_run::create(&out, &plan, &prepared, &inputs).expect("creates");
    let (g, shared) = gonio_sim::connect(&inst, &sim).expect("sim");
    let cfg = EngineConfig {
        incident_transmittance: 1e-3,
        ..EngineConfig::default()
    };
    let engine = Engine::new(g, SimBench::new(shared, None), store, mech, cfg);
    (out, engine)
}

/// A runtime as the command's (two workers), and the page of `run` served on it
/// while `engine` measures, with the control routes when `control`.
fn serve(
    run: &Path,
    engine: &Engine<SimClock, SimBench>,
    control: bool,
) -> (tokio::runtime::Runtime, gonio_live::Server) {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    let listener = gonio_live::bind(gonio_live::parse_addr("").expect("addr")).expect("binds");
    let controls = control.then(|| gonio_live::Controls {
        stopper: engine.stopper(),
        pauser: engine.pauser(),
    });
    let srv = {
        let _in = rt.enter();
        gonio_live::Server::start(
            listener,
            run,
            gonio_live::Options {
                control: controls,
                events: Some(engine.subscribe()),
                ..Default::default()
            },
        )
        .expect("serves")
    };
    (rt, srv)
}

/// One HTTP/1.0 exchange (the answer ends with the connection): status and body.
fn request(addr: SocketAddr, head: &str) -> (u16, String) {
    let mut s = TcpStream::connect(addr).expect("connects");
    s.set_read_timeout(Some(Duration::from_secs(20)))
        .expect("timeout");
    s.write_all(head.as_bytes()).expect("sends");
    let mut text = String::new();
    s.read_to_string(&mut text).expect("reads");
    let code = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .expect("status line");
    let body = text
        .split_once("\r\n\r\n")
        .map_or("", |(_, b)| b)
        .to_string();
    (code, body)
}

fn post(addr: SocketAddr, path: &str, token: Option<&str>) -> (u16, String) {
    let auth = token.map_or(String::new(), |t| format!("X-Gonio-Token: {t}\r\n"));
    request(
        addr,
        &format!("POST {path} HTTP/1.0\r\nHost: 127.0.0.1\r\n{auth}Content-Length: 0\r\n\r\n"),
    )
}

/// A page's state from the stream: snapshots replace it, updates append rows
/// (kept within the same bounds as the server's) and replace values.
#[derive(Default)]
struct Page {
    state: Value,
    snapshots: usize,
    updates: usize,
}

impl Page {
    fn event(&mut self, kind: &str, data: &str) {
        let v: Value = serde_json::from_str(data).expect("event data is JSON");
        match kind {
            "snapshot" => {
                self.snapshots += 1;
                self.state = v;
            }
            "update" => {
                self.updates += 1;
                for (k, cap) in [("trace", 200), ("drift", 10_000), ("log", 500)] {
                    if let Some(rows) = v.get(k).and_then(Value::as_array) {
                        let list = self.state[k].as_array_mut().expect("a list");
                        list.extend(rows.iter().cloned());
                        let extra = list.len().saturating_sub(cap);
                        list.drain(..extra);
                    }
                }
                for k in ["status", "now", "brdf", "report"] {
                    if let Some(x) = v.get(k) {
                        self.state[k] = x.clone();
                    }
                }
            }
            other => panic!("unexpected event {other}"),
        }
    }
}

/// Follows `/events` until `done` says the page has seen enough, or the deadline.
fn follow(addr: SocketAddr, deadline: Duration, done: impl Fn(&Page) -> bool) -> Page {
    let mut s = TcpStream::connect(addr).expect("connects");
    s.set_read_timeout(Some(Duration::from_millis(200)))
        .expect("timeout");
    s.write_all(b"GET /events HTTP/1.0\r\nHost: localhost\r\n\r\n")
        .expect("sends");
    let t0 = Instant::now();
    let (mut buf, mut page) = (String::new(), Page::default());
    let mut headers_done = false;
    let mut chunk = [0u8; 65536];
    while t0.elapsed() < deadline {
        match s.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => buf.push_str(std::str::from_utf8(&chunk[..n]).expect("utf-8")),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(e) => panic!("reading the stream: {e}"),
        }
        if !headers_done {
            let Some((head, rest)) = buf.split_once("\r\n\r\n") else {
                continue;
            };
            assert!(
                head.starts_with("HTTP/1.0 200") || head.starts_with("HTTP/1.1 200"),
                "{head}"
            );
            assert!(
                head.to_ascii_lowercase()
                    .contains("content-type: text/event-stream"),
                "{head}"
            );
            buf = rest.to_string();
            headers_done = true;
        }
        // Whole events only: each ends with a blank line.
        while let Some((ev, rest)) = buf.split_once("\n\n") {
            let (mut kind, mut data) = ("", String::new());
            for line in ev.lines() {
                if let Some(k) = line.strip_prefix("event: ") {
                    kind = k;
                } else if let Some(d) = line.strip_prefix("data: ") {
                    data.push_str(d);
                }
            }
            if !kind.is_empty() {
                page.event(kind, &data);
            }
            buf = rest.to_string();
        }
        if headers_done && page.snapshots > 0 && done(&page) {
            break;
        }
    }
    page
}

fn state_of(page: &Page) -> &str {
    page.state["status"]["state"].as_str().unwrap_or_default()
}

#[test]
fn a_page_following_the_stream_ends_where_a_fresh_one_and_the_run_file_do() {
    let dir = tempfile::tempdir().expect("dir");
    // About 2.5 s of wall time: several updates, each coalescing a few steps.
    let (run, engine) = setup(dir.path(), 0.05);
    let (rt, srv) = serve(&run, &engine, false);
    let addr = srv.local_addr();
    let page = std::thread::spawn(move || {
        follow(addr, Duration::from_secs(60), |p| {
            state_of(p) == "complete" && !p.state["report"].is_null()
        })
    });
    let (report, _store) = rt.block_on(engine.run()).expect("runs");
    assert_eq!(report.outcome, Outcome::Complete);
    srv.session_ended();
    rt.block_on(srv.settled(Duration::from_secs(20)));
    let page = page.join().expect("follower");
    assert!(
        page.updates >= 3,
        "{} updates: the run should take several",
        page.updates
    );

    // What the page built from the stream is what a page opened now gets whole…
    let (code, body) = request(addr, "GET /state HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n");
    assert_eq!(code, 200);
    let fresh: Value = serde_json::from_str(&body).expect("json");
    assert_eq!(page.state, fresh);
    // …and what a reader of the run file afresh gets (but for being a view of a
    // run measured elsewhere).
    // Through text, as the pages get it (serde_json's parser may land an ulp away
    // from the value it printed).
    let mut cold: Value = serde_json::from_str(
        &serde_json::to_string(
            gonio_live::Tail::open(&run, false, false)
                .expect("opens")
                .snapshot(),
        )
        .expect("json"),
    )
    .expect("json");
    cold["run"]["live"] = Value::Bool(true);
    assert_eq!(fresh, cold);

    let s = &fresh["status"];
    let store = RunStore::open_read_only(&run).expect("opens");
    let steps = store.steps().expect("steps").len() as u64;
    assert_eq!(
        (s["done"].as_u64(), s["total"].as_u64()),
        (Some(steps), Some(steps))
    );
    assert_eq!(s["eta_s"], Value::Null);
    assert_eq!(fresh["report"], "/report.html");
    // Every reading is in the trace (fewer than its 200), the drift references in
    // their list, every event of the file in the log.
    assert_eq!(
        fresh["trace"].as_array().map(Vec::len),
        Some(steps as usize)
    );
    let refs = store
        .steps()
        .expect("steps")
        .iter()
        .filter(|x| x.step.kind == gonio_plan::StepKind::Reference)
        .count();
    assert!(refs >= 2);
    assert_eq!(fresh["drift"].as_array().map(Vec::len), Some(refs));
    assert_eq!(
        fresh["log"].as_array().map(Vec::len),
        Some(store.events().expect("events").len())
    );
    // The BRDF is `gonio reduce`'s, value for value.
    let red = gonio_reduce::reduce(&store, &gonio_reduce::Options::default()).expect("reduces");
    let rows = fresh["brdf"]["samples"].as_array().expect("samples");
    assert_eq!(rows.len(), red.samples.samples.len());
    assert_eq!(rows.len(), 7);
    for (row, x) in rows.iter().zip(&red.samples.samples) {
        let row: Vec<f64> = row
            .as_array()
            .expect("row")
            .iter()
            .map(|v| v.as_f64().expect("number"))
            .collect();
        assert_eq!(row[2], x.pair.outgoing.theta_deg);
        // Within the ulp that serde_json's parser may be off by.
        let near = |a: f64, b: f64| (a - b).abs() <= 2.0 * f64::EPSILON * b.abs();
        assert!(near(row[4], x.value[0]), "{} {}", row[4], x.value[0]);
        assert!(near(row[5], x.sigma.as_ref().expect("σ")[0]));
    }
    assert_eq!(
        fresh["brdf"]["incidences"],
        serde_json::json!([[30.0, 0.0]])
    );
    rt.block_on(srv.stop());
}

#[test]
fn control_needs_the_token_and_a_pause_shows_on_the_page() {
    let dir = tempfile::tempdir().expect("dir");
    let (run, engine) = setup(dir.path(), 0.05);
    let (rt, srv) = serve(&run, &engine, true);
    let addr = srv.local_addr();
    let token = srv.token().expect("a token").to_string();
    assert!(srv.url().ends_with(&format!("/?token={token}")));
    let driver = std::thread::spawn(move || {
        // Refused without the token, or with a wrong one: nothing changes.
        for t in [None, Some("0123456789abcdef0123456789abcdef")] {
            let (code, body) = post(addr, "/control/pause", t);
            assert_eq!(code, 403, "{body}");
            assert!(body.contains("refused"), "{body}");
        }
        assert_eq!(post(addr, "/control/pause", Some(&token)).0, 200);
        let page = follow(addr, Duration::from_secs(30), |p| state_of(p) == "paused");
        assert_eq!(state_of(&page), "paused", "{}", page.state["status"]);
        let done = page.state["status"]["done"].as_u64().expect("done");
        // Paused: nothing is measured for as long as it lasts.
        std::thread::sleep(Duration::from_millis(600));
        let (_, body) = request(addr, "GET /state HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n");
        let v: Value = serde_json::from_str(&body).expect("json");
        assert_eq!(v["status"]["done"].as_u64(), Some(done));
        assert_eq!(v["status"]["state"], "paused");
        assert_eq!(post(addr, "/control/resume", Some(&token)).0, 200);
        let page = follow(addr, Duration::from_secs(30), |p| {
            p.state["status"]["done"].as_u64() > Some(done)
        });
        assert_eq!(state_of(&page), "running");
        assert_eq!(post(addr, "/control/stop", Some(&token)).0, 200);
        let page = follow(addr, Duration::from_secs(30), |p| {
            state_of(p) == "interrupted"
        });
        assert_eq!(state_of(&page), "interrupted");
        // Once the session has ended, control has nothing to act on.
        let (code, _) = post(addr, "/control/pause", Some(&token));
        assert_eq!(code, 409);
        let kinds: Vec<String> = page.state["log"]
            .as_array()
            .expect("log")
            .iter()
            .map(|e| e["kind"].as_str().unwrap_or_default().to_string())
            .collect();
        assert!(
            kinds.windows(2).any(|w| w == ["pause", "continue"]),
            "{kinds:?}"
        );
        kinds
    });
    let (report, _) = rt.block_on(engine.run()).expect("runs");
    srv.session_ended();
    let kinds = driver.join().expect("driver");
    assert_eq!(report.outcome, Outcome::Interrupted);
    assert!(report.finished < report.total);
    assert_eq!(kinds.last().map(String::as_str), Some("stop"));
    rt.block_on(srv.stop());
}

#[test]
fn a_run_that_cannot_be_reduced_offers_no_report_and_says_why() {
    let dir = tempfile::tempdir().expect("dir");
    let (run, engine) = setup(dir.path(), 0.0);
    let created = gonio_live::Tail::open(&run, false, false).expect("opens");
    let s = created.snapshot();
    assert_eq!(s.status.state, "created");
    assert!(s.report.is_none());
    let note = s.brdf.note.as_deref().unwrap_or_default();
    assert!(note.starts_with("not reduced yet"), "{note}");
    // Stopped before its first step: nothing to reduce, so no report to offer.
    engine.stopper().stop();
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime");
    let (report, _) = rt.block_on(engine.run()).expect("runs");
    assert_eq!(report.outcome, Outcome::Interrupted);
    let tail = gonio_live::Tail::open(&run, false, false).expect("opens");
    let s = tail.snapshot();
    assert_eq!(s.status.state, "interrupted");
    assert!(s.report.is_none());
    assert!(s.brdf.samples.is_empty());
    let note = s.brdf.note.as_deref().unwrap_or_default();
    assert!(note.starts_with("the run cannot be reduced: "), "{note}");
}

/// A reading of step `id` at instrument time `t` (s since its session's start).
fn reading_at(id: i64, t: f64, wall: f64) -> gonio_run::ReadingRecord {
    use gonio_core::{SphericalDeg, dirfile::PairDeg};
    gonio_run::ReadingRecord {
        step_id: id,
        commanded: None,
        position: [0.0; 4],
        read_pair: PairDeg {
            incident: SphericalDeg::new(30.0, 0.0),
            outgoing: SphericalDeg::new(20.0, 180.0),
        },
        sensitivity: 17,
        sensitivity_v: 1e-3,
        time_constant: 8,
        time_constant_s: 0.1,
        slope_db: 24,
        r_mean: 1e-4,
        r_std: 1e-8,
        x_mean: 1e-4,
        y_mean: 0.0,
        n: 10,
        autorange_steps: 0,
        lias: 0,
        flags: 0,
        retries: 0,
        physical_s: t,
        wall_s: wall,
    }
}

#[test]
fn the_eta_is_the_runs_own_pace_without_each_sessions_start_up() {
    let dir = tempfile::tempdir().expect("dir");
    let (run, engine) = setup(dir.path(), 0.0);
    drop(engine);
    let mut w = RunStore::open(&run).expect("opens");
    w.lock().expect("locks");
    let ids: Vec<i64> = w.steps().expect("steps").iter().map(|s| s.id).collect();
    let total = ids.len() as f64;
    // Session 1: homing takes the first 100 s, then a step every 10 s.
    w.begin_session("test").expect("session");
    for (k, t) in [100.0, 110.0, 120.0].into_iter().enumerate() {
        w.commit(&reading_at(ids[k], t, 1000.0 + t), &[])
            .expect("commit");
    }
    let tail = gonio_live::Tail::open(&run, false, false).expect("opens");
    let s = &tail.snapshot().status;
    assert_eq!(s.state, "running");
    assert_eq!(s.physical_s, 120.0);
    let eta = s.eta_s.expect("an ETA");
    assert!((eta - 10.0 * (total - 3.0)).abs() < 1e-9, "{eta}");
    // Session 2 (after a stop): 50 s of start-up, then one step 5 s later. The pace
    // is (20 + 5) s over 3 steps; instrument time adds up across the sessions.
    w.end_session("interrupted").expect("end");
    w.begin_session("test").expect("session");
    w.commit(&reading_at(ids[3], 50.0, 2000.0), &[])
        .expect("commit");
    w.commit(&reading_at(ids[4], 55.0, 2005.0), &[])
        .expect("commit");
    let mut tail = tail;
    tail.refresh(std::time::Instant::now(), false)
        .expect("refresh");
    let snap = tail.snapshot();
    let s = &snap.status;
    assert_eq!((s.state, s.sessions, s.done), ("running", 2, 5));
    assert_eq!(s.physical_s, 175.0);
    let eta = s.eta_s.expect("an ETA");
    assert!((eta - 25.0 / 3.0 * (total - 5.0)).abs() < 1e-9, "{eta}");
    let last: Vec<f64> = snap.trace.iter().map(|r| r.physical_s).collect();
    assert_eq!(last, [100.0, 110.0, 120.0, 170.0, 175.0]);
    // Ended: no ETA.
    w.end_session("interrupted").expect("end");
    tail.refresh(std::time::Instant::now(), false)
        .expect("refresh");
    assert_eq!(tail.snapshot().status.state, "interrupted");
    assert_eq!(tail.snapshot().status.eta_s, None);
}

/// An adaptive run's ETA adds the batches its budget has left, at the steps per
/// point of the coarse pass until a batch exists and of the batches after; a batch
/// appended while the page follows the run has its steps' kinds known (its drift
/// reference is a drift row, not a sample).
#[test]
fn an_adaptive_runs_eta_counts_the_batches_its_budget_has_left() {
    const ADAPTIVE: &str = "[points]\nkind = \"adaptive\"\ntheta_i = [30]\n\
                            budget = { points = 40 }\ncandidates = 1024\n[drift]\nevery = 50\n\
                            [calibration]\ndark = true\ndark_readings = 1\nincident = { transmittance = 1e-3 }\n";
    let dir = tempfile::tempdir().expect("dir");
    let (run, engine) = setup_plan(dir.path(), 0.0, ADAPTIVE);
    drop(engine);
    let mut w = RunStore::open(&run).expect("opens");
    w.lock().expect("locks");
    let steps = w.steps().expect("steps");
    let coarse_steps = steps.len() as f64;
    let samples: Vec<&gonio_run::StoredStep> = steps
        .iter()
        .filter(|s| s.step.kind == gonio_plan::StepKind::Sample)
        .collect();
    let coarse_points = samples.len() as f64;
    w.begin_session("test").expect("session");
    for (k, t) in [100.0, 110.0, 120.0].into_iter().enumerate() {
        w.commit(&reading_at(steps[k].id, t, 1000.0 + t), &[])
            .expect("commit");
    }
    let mut tail = gonio_live::Tail::open(&run, false, false).expect("opens");
    let eta = tail.snapshot().status.eta_s.expect("an ETA");
    // 10 s a step: the steps scheduled, and the 40 − coarse points to come at the
    // coarse pass's steps per point.
    let want =
        10.0 * (coarse_steps - 3.0) + 10.0 * (40.0 - coarse_points) * coarse_steps / coarse_points;
    assert!((eta - want).abs() < 1e-6, "{eta} against {want}");
    // A batch of 5 points in 7 steps: a drift reference, the points, the reference.
    let reference = steps
        .iter()
        .find(|s| s.step.kind == gonio_plan::StepKind::Reference)
        .expect("a reference")
        .step
        .clone();
    let mut batch = vec![reference.clone()];
    for (k, s) in samples.iter().take(5).enumerate() {
        let mut x = s.step.clone();
        x.plan_index = Some(1000 + k);
        batch.push(x);
    }
    batch.push(reference);
    let (d, appended) = w
        .append_batch(&gonio_run::Batch {
            decision: gonio_run::Decision {
                method: "residual".into(),
                points: 5,
                detail: "{}".into(),
            },
            steps: batch,
        })
        .expect("appended");
    assert_eq!(d.steps, 7);
    // Every coarse step measured, and the batch's first (its reference).
    let mut t = 120.0;
    for s in steps.iter().skip(3).chain(appended.iter().take(1)) {
        t += 10.0;
        w.commit(&reading_at(s.id, t, 1000.0 + t), &[])
            .expect("commit");
    }
    tail.refresh(Instant::now(), false).expect("refresh");
    let snap = tail.snapshot();
    assert_eq!(snap.status.total as f64, coarse_steps + 7.0);
    assert_eq!(
        snap.drift.back().expect("a drift row").step_id,
        appended[0].id
    );
    let eta = snap.status.eta_s.expect("an ETA");
    let want = 10.0 * 6.0 + 10.0 * (40.0 - coarse_points - 5.0) * 7.0 / 5.0;
    assert!((eta - want).abs() < 1e-6, "{eta} against {want}");
}
