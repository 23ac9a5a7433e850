//! What the process-level tests of processing, fitting and output share: running the
//! binary, scratch directories, the repository's configs, and a simulated run of an
//! isotropic grid the arms reach everywhere.

#![allow(dead_code)]

pub mod browser;
pub mod live;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

/// Runs `gonio` with `args`.
pub fn gonio(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gonio"))
        .args(args)
        .output()
        .expect("the gonio binary runs")
}

/// Runs `gonio`, asserting success.
pub fn ok(args: &[&str]) -> Output {
    let o = gonio(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// Runs `gonio … --json`, asserting success, and parses its one JSON object.
pub fn ok_json(args: &[&str]) -> Value {
    serde_json::from_slice(&ok(args).stdout).expect("one JSON object")
}

/// A fresh directory for one test's files, removed when dropped; derefs to its
/// path.
pub struct Scratch(tempfile::TempDir);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        self.0.path()
    }
}

/// A fresh directory named after the test (`gonio-NAME-…`).
pub fn scratch(name: &str) -> Scratch {
    Scratch(
        tempfile::Builder::new()
            .prefix(&format!("gonio-{name}-"))
            .tempdir()
            .expect("temp dir"),
    )
}

/// What a run of `gonio` wrote on stderr.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A file of the repository's `config/`, as an argument.
pub fn config(rel: &str) -> String {
    root().join("config").join(rel).display().to_string()
}

/// The repository's root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A path as an argument.
pub fn s(p: &Path) -> String {
    p.display().to_string()
}

/// An isotropic grid the simulated arms reach everywhere (no retro pair), so its
/// samples form a table.
pub const ISO_PLAN: &str = r#"
name = "isotropic grid"
[points]
kind = "isotropic"
theta_i = [20, 45, 70]
theta_o = [20, 45, 70]
delta_phi = { from = 45, to = 315, step = 90 }
[calibration]
dark = true
dark_readings = 1
incident = { transmittance = 1e-3 }
"#;

/// Measures `plan` on the simulated instrument into `dir/run.gonio`.
pub fn acquire(dir: &Path, plan: &str) -> PathBuf {
    let p = dir.join("plan.toml");
    std::fs::write(&p, plan).expect("plan");
    let run = dir.join("run.gonio");
    let inst = root().join("config/instrument-sim.toml");
    ok(&[
        "acquire",
        "--instrument",
        &s(&inst),
        "--plan",
        &s(&p),
        "--out",
        &s(&run),
        "--json",
    ]);
    run
}

/// The run's status, read directly (not through gonio, which refuses a damaged file).
pub fn status(path: &Path) -> String {
    rusqlite::Connection::open(path)
        .expect("opens")
        .query_row("SELECT value FROM meta WHERE key = 'status'", [], |r| {
            r.get(0)
        })
        .expect("status")
}

/// Starts `gonio acquire` with `acquire` (whose `--out` is `out`), kills it with SIGKILL
/// or SIGTERM after a pseudo-random delay of `base_ms` plus up to `spread_ms` (longer
/// each session, so that a slow machine still gets past start-up and homing), then
/// `gonio resume`s and kills it the same way, until a session completes the run. The
/// delays and signals come from a generator seeded with `seed`. Returns the number of
/// kills; every session that was not killed must have succeeded.
pub fn kill_and_resume_until_complete(
    out: &Path,
    acquire: &[&str],
    seed: u64,
    (base_ms, spread_ms): (u64, u64),
) -> usize {
    use std::process::Stdio;
    use std::time::{Duration, Instant};
    let spawn = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_gonio"))
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("the gonio binary starts")
    };
    let mut state = seed;
    let mut next = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        state >> 33
    };
    let out_s = s(out);
    let mut first = vec!["acquire"];
    first.extend_from_slice(acquire);
    let mut kills = 0;
    for session in 0.. {
        assert!(session < 100, "no progress after {session} sessions");
        let mut child = if out.exists() {
            spawn(&["resume", &out_s])
        } else {
            spawn(&first)
        };
        let delay = Duration::from_millis(base_ms + next() % spread_ms + 100 * session);
        let sig = ["-KILL", "-TERM"][(next() % 2) as usize];
        let start = Instant::now();
        while start.elapsed() < delay {
            if let Some(st) = child.try_wait().expect("wait") {
                assert!(st.success(), "session {session}: {st:?}");
                return kills;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        let killed = Command::new("kill")
            .args([sig, &child.id().to_string()])
            .status()
            .expect("kill runs")
            .success();
        assert!(killed, "kill {sig} {}", child.id());
        let _ = child.wait_with_output().expect("reaped");
        kills += 1;
        if out.exists() && status(out) == "complete" {
            return kills;
        }
    }
    kills
}

/// A shipped simulator config at another time scale, written into `dir`.
pub fn sim_file_at(dir: &Path, name: &str, scale: f64) -> String {
    let text = std::fs::read_to_string(config(name)).expect("sim config");
    let text = text.replace("time_scale = 0.0 ", &format!("time_scale = {scale} "));
    assert!(text.contains(&format!("time_scale = {scale}")));
    let p = dir.join(format!("{name}-{scale}.toml"));
    std::fs::write(&p, text).expect("write");
    p.display().to_string()
}

/// Every reading's values (not its times) by step, from a run file.
pub fn readings(path: &Path) -> Vec<Vec<String>> {
    let c = rusqlite::Connection::open(path).expect("opens");
    let mut stmt = c
        .prepare(
            "SELECT step_id, pos_0, pos_1, pos_2, pos_3, theta_i, phi_i, theta_o, phi_o, \
             sensitivity, time_constant, r_mean, r_std, x_mean, y_mean, n, autorange_steps, \
             lias, flags FROM readings ORDER BY step_id",
        )
        .expect("query");
    let rows = stmt
        .query_map([], |r| {
            (0..19)
                .map(|i| {
                    r.get::<_, rusqlite::types::Value>(i)
                        .map(|v| format!("{v:?}"))
                })
                .collect::<Result<Vec<_>, _>>()
        })
        .expect("rows");
    rows.collect::<Result<_, _>>().expect("values")
}
