//! `--serve` and `gonio view` as processes: bad addresses refused before anything
//! is created, and a view that follows a run measured by another process without
//! ever taking its lock (docs/live.md).

use crate::common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use common::{config, gonio, s, scratch, stderr};
use serde_json::Value;

const PLAN: &str = r#"
name = "served"
[points]
kind = "in-plane"
theta_i = [30]
theta_o = { from = -60, to = 60, step = 10 }
[calibration]
dark = true
dark_readings = 1
incident = { transmittance = 1e-3 }
"#;

/// The simulator's example config with its clock at `scale` of real time.
fn sim_at(dir: &std::path::Path, scale: f64) -> String {
    let text = std::fs::read_to_string(config("sim-example.toml")).expect("sim");
    let line = text
        .lines()
        .find(|l| l.starts_with("time_scale"))
        .expect("a time_scale line");
    let p = dir.join("sim.toml");
    std::fs::write(&p, text.replace(line, &format!("time_scale = {scale}"))).expect("write");
    s(&p)
}

fn acquire_args(dir: &std::path::Path, sim: &str) -> Vec<String> {
    let plan = dir.join("plan.toml");
    std::fs::write(&plan, PLAN).expect("plan");
    [
        "acquire",
        "--instrument",
        &config("instrument-sim.toml"),
        "--plan",
        &s(&plan),
        "--sim",
        sim,
        "--out",
        &s(&dir.join("run.gonio")),
    ]
    .map(String::from)
    .to_vec()
}

#[test]
fn a_bad_or_busy_address_is_refused_before_the_run_exists() {
    let dir = scratch("serve-bad");
    let sim = sim_at(&dir, 0.0);
    let busy = std::net::TcpListener::bind("127.0.0.1:0").expect("binds");
    let busy = busy.local_addr().expect("addr").to_string();
    for (addr, says) in [
        ("lab-pc:8080", "not IP:PORT"),
        ("70000", "not IP:PORT"),
        (busy.as_str(), "cannot listen there"),
    ] {
        let mut args = acquire_args(&dir, &sim);
        args.extend(["--serve".into(), addr.into()]);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = gonio(&args);
        assert_eq!(o.status.code(), Some(2), "{addr}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains(&format!("--serve {addr}")) && e.contains(says),
            "{e}"
        );
        assert!(
            !dir.join("run.gonio").exists(),
            "{addr}: a run file was created"
        );
    }
    // --control means nothing without a page.
    let mut args = acquire_args(&dir, &sim);
    args.push("--control".into());
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = gonio(&args);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--serve"), "{}", stderr(&o));
    assert!(!dir.join("run.gonio").exists());
    // `view` refuses what is not a run file, before listening.
    let plan = dir.join("plan.toml");
    for bad in [plan.clone(), dir.join("absent.gonio")] {
        let o = gonio(&["view", &s(&bad), "--serve", "127.0.0.1:0"]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(&s(&bad)), "{}", stderr(&o));
    }
}

/// A child `gonio` whose stderr lines arrive on a channel.
struct Proc {
    child: Child,
    lines: mpsc::Receiver<String>,
}

impl Proc {
    fn start(args: &[String]) -> Proc {
        let mut child = Command::new(env!("CARGO_BIN_EXE_gonio"))
            .args(args)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("gonio starts");
        let err = child.stderr.take().expect("stderr");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for l in BufReader::new(err).lines().map_while(Result::ok) {
                if tx.send(l).is_err() {
                    return;
                }
            }
        });
        Proc { child, lines }
    }

    /// The first stderr line containing `what`, within `within`.
    fn line(&self, what: &str, within: Duration) -> String {
        let t0 = Instant::now();
        while let Some(left) = within.checked_sub(t0.elapsed()) {
            match self.lines.recv_timeout(left) {
                Ok(l) if l.contains(what) => return l,
                Ok(_) => {}
                Err(_) => break,
            }
        }
        panic!("no line with {what:?} within {within:?}");
    }

    /// Sends SIGTERM and waits for the exit status.
    fn term(mut self) -> Option<i32> {
        let pid = self.child.id().to_string();
        let ok = Command::new("kill")
            .args(["-TERM", &pid])
            .status()
            .expect("kill");
        assert!(ok.success());
        let t0 = Instant::now();
        loop {
            if let Some(st) = self.child.try_wait().expect("wait") {
                return st.code();
            }
            assert!(
                t0.elapsed() < Duration::from_secs(30),
                "no exit after SIGTERM"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `GET /state` of the page at `base` (`http://127.0.0.1:PORT/`).
fn state(base: &str) -> Value {
    let host = base
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .split('/')
        .next()
        .expect("host");
    let mut c = TcpStream::connect(host).expect("connects");
    c.set_read_timeout(Some(Duration::from_secs(20)))
        .expect("timeout");
    c.write_all(b"GET /state HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n")
        .expect("sends");
    let mut text = String::new();
    c.read_to_string(&mut text).expect("reads");
    let (head, body) = text.split_once("\r\n\r\n").expect("an HTTP answer");
    assert!(head.starts_with("HTTP/1.0 200"), "{head}");
    serde_json::from_str(body).expect("JSON")
}

/// Polls `/state` until `ok`, for at most `within`; returns the last state.
fn until(base: &str, within: Duration, ok: impl Fn(&Value) -> bool) -> Value {
    let t0 = Instant::now();
    loop {
        let v = state(base);
        if ok(&v) || t0.elapsed() > within {
            return v;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

fn done(v: &Value) -> u64 {
    v["status"]["done"].as_u64().unwrap_or(0)
}

#[test]
fn view_follows_a_run_measured_elsewhere_and_never_holds_its_lock() {
    let dir = scratch("serve-view");
    // About 100 s of instrument time at a twentieth: long enough to watch.
    let sim = sim_at(&dir, 0.05);
    let run = dir.join("run.gonio");
    let acq = Proc::start(&acquire_args(&dir, &sim));
    acq.line("steps (", Duration::from_secs(30));
    let view = Proc::start(&[
        "view".into(),
        s(&run),
        "--serve".into(),
        "127.0.0.1:0".into(),
    ]);
    let l = view.line("live view at ", Duration::from_secs(30));
    let base = l.rsplit(' ').next().expect("a URL").to_string();
    assert!(
        base.starts_with("http://127.0.0.1:") && base.ends_with('/'),
        "{l}"
    );

    let first = until(&base, Duration::from_secs(30), |v| {
        v["status"]["state"] == "running" && done(v) >= 1
    });
    assert_eq!(first["status"]["state"], "running", "{}", first["status"]);
    assert_eq!(first["run"]["live"], false);
    assert_eq!(first["run"]["control"], false);
    let later = until(&base, Duration::from_secs(30), |v| done(v) > done(&first));
    assert!(done(&later) > done(&first), "{}", later["status"]);
    assert!(
        later["trace"].as_array().map_or(0, Vec::len) as u64 >= done(&later),
        "every reading so far is in the trace"
    );

    // Stopped by its signal: the view says so, and links the report when the readings
    // so far reduce (on a loaded machine the run may stop before its first sample's
    // calibrations: then the reduction says why and no report is offered). The link
    // comes with the final reduction, which can be an update after the state's.
    assert_eq!(acq.term(), Some(130));
    let reduced = |v: &Value| {
        v["brdf"]["note"].is_null()
            && v["brdf"]["samples"]
                .as_array()
                .is_some_and(|a| !a.is_empty())
    };
    let stopped = until(&base, Duration::from_secs(10), |v| {
        v["status"]["state"] == "interrupted" && (v["report"] == "/report.html" || !reduced(v))
    });
    assert_eq!(
        stopped["status"]["state"], "interrupted",
        "{}",
        stopped["status"]
    );
    if reduced(&stopped) {
        assert_eq!(stopped["report"], "/report.html");
    } else {
        assert!(stopped["report"].is_null(), "{}", stopped["brdf"]);
    }
    let total = stopped["status"]["total"].as_u64().expect("total");
    assert!(done(&stopped) < total);

    // The view holds no lock: the run resumes while it is open, and the view
    // follows the new session to the end.
    let o = gonio(&["resume", &s(&run), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let end = until(&base, Duration::from_secs(10), |v| {
        v["status"]["state"] == "complete" && v["report"] == "/report.html"
    });
    assert_eq!(end["status"]["state"], "complete", "{}", end["status"]);
    assert_eq!(end["report"], "/report.html");
    assert_eq!(done(&end), total);
    assert_eq!(end["status"]["sessions"], 2);
    assert!(end["brdf"]["samples"].as_array().map_or(0, Vec::len) > 5);
    assert_eq!(view.term(), Some(0));
}

#[test]
fn a_killed_measurement_shows_as_stale() {
    let dir = scratch("serve-stale");
    let sim = sim_at(&dir, 0.05);
    let run = dir.join("run.gonio");
    let mut acq = Proc::start(&acquire_args(&dir, &sim));
    acq.line("steps (", Duration::from_secs(30));
    let view = Proc::start(&["view".into(), s(&run)]);
    let l = view.line("live view at ", Duration::from_secs(30));
    let base = l.rsplit(' ').next().expect("a URL").to_string();
    let running = until(&base, Duration::from_secs(30), |v| done(v) >= 1);
    assert_eq!(running["status"]["state"], "running");
    // `show` and `runs` agree with the page while the measuring process holds the lock.
    assert_eq!(
        common::ok_json(&["show", &s(&run), "--json"])["status"],
        "running"
    );
    let pid = acq.child.id();
    assert!(
        running["status"]["message"]
            .as_str()
            .is_some_and(|m| m.contains(&pid.to_string())),
        "{}",
        running["status"]
    );
    // Killed outright: the file still says running, but nobody holds its lock.
    acq.child.kill().expect("kill");
    acq.child.wait().expect("wait");
    let v = until(&base, Duration::from_secs(10), |v| {
        v["status"]["state"] == "stale"
    });
    assert_eq!(v["status"]["state"], "stale", "{}", v["status"]);
    assert!(
        v["status"]["message"]
            .as_str()
            .is_some_and(|m| m.contains("gonio resume"))
    );
    assert_eq!(v["status"]["eta_s"], Value::Null);
    assert_eq!(view.term(), Some(0));
    // So do `show` and `runs`, in text and JSON: the status stored is still
    // `running`, but nobody measures the run.
    let shown = common::ok_json(&["show", &s(&run), "--json"]);
    assert_eq!(shown["status"], "stale", "{shown}");
    assert!(
        shown["status_note"]
            .as_str()
            .is_some_and(|m| m.contains("gonio resume"))
    );
    let text = String::from_utf8_lossy(&common::ok(&["show", &s(&run)]).stdout).into_owned();
    assert!(
        text.lines().next().is_some_and(|l| l.ends_with(": stale")),
        "{text}"
    );
    assert!(text.contains("`gonio resume` continues it"), "{text}");
    let listed = common::ok_json(&["runs", &s(&dir), "--json"]);
    assert_eq!(listed["runs"][0]["status"], "stale", "{listed}");
    let text = String::from_utf8_lossy(&common::ok(&["runs", &s(&dir)]).stdout).into_owned();
    assert!(text.contains(" stale "), "{text}");
    assert!(!text.contains("running"), "{text}");
}

#[test]
fn one_stop_signal_ends_a_served_session_and_the_process() {
    let dir = scratch("serve-signal");
    let sim = sim_at(&dir, 0.05);
    let mut args = acquire_args(&dir, &sim);
    args.push("--serve".into());
    let acq = Proc::start(&args);
    let l = acq.line("live view at ", Duration::from_secs(30));
    let base = l.rsplit(' ').next().expect("a URL").to_string();
    until(&base, Duration::from_secs(30), |v| done(v) >= 1);
    // Whoever sends the signal wants the process to end: the page does not stay.
    assert_eq!(acq.term(), Some(130));
    let o = gonio(&["show", &s(&dir.join("run.gonio"))]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("interrupted"));
}
