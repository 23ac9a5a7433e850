//! `gonio acquire` / `resume` / `show` / `runs` / `plan check` as processes: killed at
//! random instants and resumed until done, the readings equal an uninterrupted run's;
//! Ctrl-C stops the stages and leaves the run resumable.

use crate::common;

use common::{
    config, gonio, kill_and_resume_until_complete, readings, scratch, sim_file_at, status, stderr,
};
use std::io::{BufRead, BufReader, Read, Write};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use rusqlite::Connection;

fn spawn(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_gonio"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the gonio binary starts")
}

/// The default simulator config at another time scale, written into `dir`.
fn sim_at(dir: &Path, scale: f64) -> String {
    sim_file_at(dir, "sim-example.toml", scale)
}

/// A small plan: 2 incidence angles × 9 outgoing angles, a dark and an incident
/// reading, a drift reference every 5 pairs.
const PLAN: &str = r#"
name = "kill test"
[points]
kind = "in-plane"
theta_i = [20, 50]
theta_o = { from = -70, to = 70, step = 10 }
[drift]
every = 5
[calibration]
dark = true
dark_readings = 1
incident = { transmittance = 1e-3 }
"#;

/// A tiny deterministic generator for the kill instants.
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        self.0 >> 33
    }
}

/// Sends `sig` (`-TERM`, …) to `pid`.
fn send(sig: &str, pid: u32) {
    let ok = Command::new("kill")
        .args([sig, &pid.to_string()])
        .status()
        .expect("kill runs")
        .success();
    assert!(ok, "kill {sig} {pid}");
}

/// The chaos test: SIGTERM, SIGHUP, SIGINT and SIGKILL at pseudo-random instants,
/// each followed by a resume, until the run completes. The readings equal the
/// uninterrupted run's; a signal Gonio can handle never leaves the run `running`;
/// a second `resume` while one is working is always refused.
#[test]
fn interrupted_by_any_signal_and_resumed_runs_end_with_the_uninterrupted_readings() {
    let dir = scratch("kill");
    let plan = dir.join("plan.toml");
    std::fs::write(&plan, PLAN).expect("plan");
    let plan = plan.display().to_string();
    let inst = config("instrument-sim.toml");

    // The uninterrupted run, as fast as possible.
    let whole = dir.join("whole.gonio");
    let o = gonio(&[
        "acquire",
        "--instrument",
        &inst,
        "--plan",
        &plan,
        "--out",
        &whole.display().to_string(),
        "--seed",
        "11",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let want = readings(&whole);
    assert!(want.len() > 20, "{}", want.len());

    // The same run slowed down (20 ms of wall time per physical second) and
    // interrupted at pseudo-random instants, then resumed, until it completes.
    let slow = sim_at(&dir, 0.02);
    let out = dir.join("killed.gonio");
    let out_s = out.display().to_string();
    let lock = dir.join("killed.gonio.lock");
    let mut rng = Lcg(2026);
    let mut kills = 0;
    let mut by_signal = std::collections::BTreeMap::new();
    let mut refused = 0;
    let mut sessions = 0;
    loop {
        assert!(sessions < 200, "no progress after {sessions} sessions");
        sessions += 1;
        // What the run said before this session: a signal that comes before the
        // session's handler exists leaves it so (`running` after a SIGKILL).
        let before = out.exists().then(|| status(&out));
        let mut child = if out.exists() {
            spawn(&["resume", &out_s])
        } else {
            spawn(&[
                "acquire",
                "--instrument",
                &inst,
                "--plan",
                &plan,
                "--out",
                &out_s,
                "--sim",
                &slow,
                "--seed",
                "11",
            ])
        };
        let delay = Duration::from_millis(40 + rng.next() % 400);
        let sig = ["-TERM", "-HUP", "-INT", "-KILL"][(rng.next() % 4) as usize];
        let start = Instant::now();
        let mut finished = None;
        let mut tried_second = false;
        while start.elapsed() < delay {
            if let Some(s) = child.try_wait().expect("wait") {
                finished = Some(s);
                break;
            }
            // Once this session holds the run, a second resume is refused.
            let holder = std::fs::read_to_string(&lock).unwrap_or_default();
            if !tried_second && holder.trim() == child.id().to_string() {
                tried_second = true;
                let o = gonio(&["resume", &out_s]);
                if child.try_wait().expect("wait").is_none() {
                    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
                    assert!(
                        stderr(&o).contains(&format!("process {}", child.id())),
                        "{}",
                        stderr(&o)
                    );
                    assert!(
                        stderr(&o).contains("holds the run's lock"),
                        "{}",
                        stderr(&o)
                    );
                    // A reader checks the live run as it stood at one commit.
                    let o = gonio(&["verify", &out_s]);
                    assert!(o.status.success(), "live: {}", stderr(&o));
                    refused += 1;
                }
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        match finished {
            Some(status) => {
                let mut err = String::new();
                let _ = child
                    .stderr
                    .take()
                    .expect("stderr")
                    .read_to_string(&mut err);
                assert!(status.success(), "session {sessions}: {status:?} {err}");
                break;
            }
            None => {
                send(sig, child.id());
                let t = Instant::now();
                let o = child.wait_with_output().expect("reaped");
                kills += 1;
                *by_signal.entry(sig).or_insert(0) += 1;
                if sig != "-KILL" {
                    // Handled: the stages stop and the process exits within a
                    // moment, 130, or 0 when the last step had just been committed.
                    // (A signal before the handler exists ends a process that has not
                    // begun a session yet.)
                    assert!(
                        t.elapsed() < Duration::from_secs(5),
                        "{sig}: {:?}",
                        t.elapsed()
                    );
                    use std::os::unix::process::ExitStatusExt;
                    assert!(
                        matches!(o.status.code(), Some(0 | 130)) || o.status.signal().is_some(),
                        "{sig}: {:?} {}",
                        o.status,
                        stderr(&o)
                    );
                    if out.exists() && o.status.signal().is_none() {
                        assert_ne!(status(&out), "running", "{sig}: {}", stderr(&o));
                    } else if out.exists() && before.is_some() {
                        // Ended by the signal itself: no session had begun.
                        assert_eq!(Some(status(&out)), before, "{sig}: {}", stderr(&o));
                    }
                }
                // Whatever instant the signal hit, the file (if created) opens intact.
                if out.exists() {
                    let o = gonio(&["verify", &out_s]);
                    assert!(o.status.success(), "after {sig} ({kills}): {}", stderr(&o));
                    // The signal came just after the last step.
                    if status(&out) == "complete" {
                        break;
                    }
                }
            }
        }
    }
    assert!(
        kills >= 20 && by_signal.len() == 4,
        "{kills} interruptions ({by_signal:?}): the run was too quick to interrupt"
    );
    assert!(refused >= 5, "only {refused} concurrent resumes tried");
    eprintln!("{kills} interruptions {by_signal:?}, {refused} concurrent resumes refused");
    let got = readings(&out);
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(&want) {
        assert_eq!(g, w, "step {}", w[0]);
    }
    // Every session but the last ended without a clean stop, and the file says so.
    let o = gonio(&["show", &out_s, "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    assert_eq!(v["status"], "complete");
    let s = v["sessions"].as_array().expect("sessions");
    assert!(s.len() >= 2 && s.len() <= kills + 1);
    assert_eq!(s.last().expect("last")["outcome"], "complete");
    assert_eq!(v["states"]["done"].as_u64(), Some(want.len() as u64));
}

/// The mixed-family instrument (SMC100 arms, a KDC101 + PRM1-Z8 and a K10CR1 on APT
/// lines of their own, a K6485 picoammeter): its run, killed (SIGKILL, SIGTERM) at
/// pseudo-random instants and resumed until done, holds the same readings, byte for
/// byte, as the run taken at once.
#[test]
fn mixed_instrument_run_is_identical_after_kill_and_resume() {
    let dir = scratch("mixed-kill");
    let plan = dir.join("plan.toml");
    std::fs::write(&plan, PLAN).expect("plan");
    let plan = plan.display().to_string();
    let inst = config("instrument-mixed.toml");
    let fast = config("sim-mixed.toml");
    let whole = dir.join("whole.gonio");
    let o = gonio(&[
        "acquire",
        "--instrument",
        &inst,
        "--plan",
        &plan,
        "--out",
        &whole.display().to_string(),
        "--sim",
        &fast,
        "--seed",
        "11",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let want = readings(&whole);
    assert_eq!(want.len(), 37);
    // The picoammeter's dark reading is the photodiode's dark current, 10 pA, and
    // every reading is a clean DC one (no lock-in status bits).
    let dark: f64 = want[0][11]
        .trim_start_matches("Real(")
        .trim_end_matches(')')
        .parse()
        .expect("r_mean");
    assert!((dark - 1e-11).abs() < 2e-13, "dark {dark}");
    assert!(want.iter().all(|r| r[17] == "Integer(0)"), "{want:?}");

    let slow = sim_file_at(&dir, "sim-mixed.toml", 0.02);
    let out = dir.join("killed.gonio");
    let out_s = out.display().to_string();
    let kills = kill_and_resume_until_complete(
        &out,
        &[
            "--instrument",
            &inst,
            "--plan",
            &plan,
            "--out",
            &out_s,
            "--sim",
            &slow,
            "--seed",
            "11",
        ],
        7,
        (150, 500),
    );
    assert!(
        kills >= 3,
        "{kills} interruptions: the run was too quick to interrupt"
    );
    assert_eq!(readings(&out), want);
}

/// SIGTERM (a service manager's stop; Ctrl-C and SIGHUP take the same path) during a
/// run on real serial lines (the simulator on pseudo-terminals, so nothing is
/// simulated on the driver's side): the acquisition exits 130 with the run
/// `interrupted`, and the controllers, asked over their own line afterwards, are not
/// moving. The run then resumes to completion.
#[test]
fn sigterm_stops_the_stages_and_the_run_resumes() {
    let dir = scratch("ctrlc");
    // The simulator at a quarter of real time, on two pseudo-terminals.
    let mut sim = Command::new(env!("CARGO_BIN_EXE_gonio"))
        .args(["sim", "--seed", "5", "--time-scale", "0.25"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .expect("gonio sim starts");
    let mut line = String::new();
    BufReader::new(sim.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("pty paths");
    let ptys: serde_json::Value = serde_json::from_str(&line).expect("JSON");
    let (motion, detector) = (
        ptys["motion"].as_str().expect("path").to_string(),
        ptys["detector"].as_str().expect("path").to_string(),
    );
    let inst_text = std::fs::read_to_string(config("instrument-sim.toml"))
        .expect("instrument")
        .replacen("port = \"sim\"", &format!("port = \"{motion}\""), 1)
        .replacen("port = \"sim\"", &format!("port = \"{detector}\""), 1)
        // Quick readings: this test is about motion.
        .replace("samples = 10", "samples = 2")
        .replace("settle_residual = 1e-4", "settle_residual = 0.01");
    let inst = dir.join("instrument.toml");
    std::fs::write(&inst, inst_text).expect("write");
    // Long moves: pairs far apart, no calibrations (an operator would be asked).
    let plan = dir.join("plan.toml");
    std::fs::write(
        &plan,
        "[points]\nkind = \"in-plane\"\ntheta_i = [10]\ntheta_o = [-70, 70]\n\
         [order]\noptimise = false\n",
    )
    .expect("plan");
    let out = dir.join("run.gonio");
    let out_s = out.display().to_string();
    let mut child = spawn(&[
        "acquire",
        "--instrument",
        &inst.display().to_string(),
        "--plan",
        &plan.display().to_string(),
        "--out",
        &out_s,
    ]);
    // The operator confirms the sample is mounted.
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(b"\n")
        .expect("answer");
    // Homing and the first move take seconds of physical time: interrupt during them.
    std::thread::sleep(Duration::from_millis(1200));
    assert!(child.try_wait().expect("wait").is_none(), "still running");
    send("-TERM", child.id());
    let t = Instant::now();
    let o = child.wait_with_output().expect("exits");
    assert!(
        t.elapsed() < Duration::from_secs(5),
        "took {:?} to stop",
        t.elapsed()
    );
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    assert!(stderr(&o).contains("interrupted"), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_slice(&gonio(&["show", &out_s, "--json"]).stdout).expect("JSON");
    assert_eq!(v["status"], "interrupted");

    // Ask the controllers over their own line. A stopped stage decelerates (0.25 s of
    // physical time at 80°/s², 1 s of wall time here), then reports READY; and it
    // stopped short of the first step's targets, which it was on its way to.
    let mut port = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&motion)
        .expect("motion pty");
    let mut ask = |q: String| -> String {
        port.write_all(q.as_bytes()).expect("ask");
        let mut reply = Vec::new();
        let mut b = [0u8; 1];
        let t = Instant::now();
        while !reply.ends_with(b"\r\n") && t.elapsed() < Duration::from_secs(2) {
            if port.read(&mut b).expect("read") == 1 {
                reply.push(b[0]);
            }
        }
        String::from_utf8_lossy(&reply).trim().to_string()
    };
    let t = Instant::now();
    loop {
        let states: Vec<String> = (1..=4).map(|a| ask(format!("{a}TS\r\n"))).collect();
        for (a, s) in (1..=4).zip(&states) {
            assert!(s.starts_with(&format!("{a}TS")), "{s:?}");
        }
        if states.iter().all(|s| !s.ends_with("28")) {
            break;
        }
        assert!(
            t.elapsed() < Duration::from_secs(3),
            "still moving: {states:?}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let c = Connection::open(&out).expect("run file");
    let targets: [f64; 4] = c
        .query_row(
            "SELECT target_0, target_1, target_2, target_3 FROM steps WHERE id = 0",
            [],
            |r| Ok([r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?]),
        )
        .expect("step 0");
    let short: Vec<f64> = (1..=4)
        .map(|a| {
            let r = ask(format!("{a}TP\r\n"));
            let p: f64 = r[3..].parse().expect("a position");
            (p - targets[a - 1]).abs()
        })
        .collect();
    assert!(
        short.iter().any(|d| *d > 1.0),
        "reached {targets:?}: {short:?}"
    );
    drop(port);

    // Resume finishes the run; every step measured exactly once.
    let mut child = spawn(&["resume", &out_s]);
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(b"\n")
        .expect("answer");
    let o = child.wait_with_output().expect("exits");
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_slice(&gonio(&["show", &out_s, "--json"]).stdout).expect("JSON");
    assert_eq!(v["status"], "complete");
    assert_eq!(v["states"]["done"], 2);
    assert_eq!(v["sessions"][0]["outcome"], "interrupted");
    let _ = sim.kill();
    let _ = sim.wait();
}

#[test]
fn plan_check_reports_reasons_and_estimates() {
    let o = gonio(&[
        "plan",
        "check",
        &config("plan-in-plane.toml"),
        "--instrument",
        &config("instrument-sim.toml"),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    assert_eq!(v["pairs"], 99);
    assert_eq!(v["accepted"], 90);
    assert_eq!(v["rejected_by_reason"]["shadowed"], 9);
    let e = &v["estimate"];
    assert!(e["motion_s"].as_f64() <= e["raster_motion_s"].as_f64());
    // A bad plan: exit 2, naming the file, line and field.
    let dir = scratch("badplan");
    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        "[points]\nkind = \"in-plane\"\ntheta_i = [0]\ntheta_o = [95]\n",
    )
    .expect("write");
    let o = gonio(&[
        "plan",
        "check",
        &bad.display().to_string(),
        "--instrument",
        &config("instrument-sim.toml"),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains(&format!("{}:4:11: field `points.theta_o`", bad.display())),
        "{}",
        stderr(&o)
    );
}

#[test]
fn show_and_runs_refuse_damaged_files_with_status_2() {
    let dir = scratch("damaged");
    let good = dir.join("a.gonio");
    let o = gonio(&[
        "acquire",
        "--instrument",
        &config("instrument-sim.toml"),
        "--plan",
        &config("plan-list.toml"),
        "--out",
        &good.display().to_string(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    assert_eq!(v["status"], "complete");
    // Acquiring onto an existing run file is refused.
    let o = gonio(&[
        "acquire",
        "--instrument",
        &config("instrument-sim.toml"),
        "--plan",
        &config("plan-list.toml"),
        "--out",
        &good.display().to_string(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("exists already"), "{}", stderr(&o));
    let bad = dir.join("b.gonio");
    std::fs::write(&bad, "not a database at all, but long enough").expect("write");
    let o = gonio(&["show", &bad.display().to_string()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("not a Gonio run file"),
        "{}",
        stderr(&o)
    );
    let o = gonio(&["resume", &good.display().to_string()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("complete; nothing to resume"),
        "{}",
        stderr(&o)
    );
    let o = gonio(&["runs", &dir.display().to_string(), "--json"]);
    assert!(o.status.success());
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    let runs = v["runs"].as_array().expect("runs");
    assert_eq!(runs.len(), 2);
    assert_eq!(runs[0]["status"], "complete");
    // The list's pairs × 3 repeats and the plan's default four dark readings (at
    // least its repeats; there were 3).
    assert_eq!(runs[0]["done"], 22);
    assert_eq!(runs[1]["status"], "unreadable");
}
