//! What the live view's tests share on the server's side: a simulated acquisition slow
//! enough to watch, `gonio` serving its page as a child process (its address read
//! from the line it prints), and plain HTTP/1.1 over a `TcpStream`.

#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::common::{config, root};

/// How long any wait on the server may take before the test fails.
pub const DEADLINE: Duration = Duration::from_secs(60);

/// An in-plane plan of 3 incidences × 15 outgoing angles (3 pairs shadowed), with a
/// dark, an incident and drift references: [`PLAN_STEPS`] steps, about 390 s of
/// instrument time (12 s of wall time at a time scale of 0.03).
pub const PLAN: &str = r#"
name = "live view test"
[points]
kind = "in-plane"
theta_i = [20, 40, 60]
theta_o = { from = -70, to = 70, step = 10 }
[drift]
every = 5
[calibration]
dark = true
dark_readings = 1
incident = { transmittance = 1e-3 }
"#;

/// The steps of [`PLAN`] on the simulated instrument, as `gonio plan check` counts
/// them: 42 pairs, a dark, an incident and 10 drift references.
pub const PLAN_STEPS: u64 = 54;

/// The simulator's config at `scale` (wall seconds per instrument second) and
/// [`PLAN`], written into `dir`; returns (sim, plan) as arguments.
pub fn sim_and_plan(dir: &Path, scale: f64) -> (String, String) {
    let text = std::fs::read_to_string(config("sim-example.toml")).expect("sim config");
    let slowed = text.replace("time_scale = 0.0 ", &format!("time_scale = {scale} "));
    assert_ne!(
        slowed, text,
        "config/sim-example.toml has no `time_scale = 0.0`"
    );
    let sim = dir.join("sim.toml");
    std::fs::write(&sim, slowed).expect("write sim config");
    let plan = dir.join("plan.toml");
    std::fs::write(&plan, PLAN).expect("write plan");
    (sim.display().to_string(), plan.display().to_string())
}

/// The arguments of `gonio acquire` on the simulator, writing `out`.
pub fn acquire_args(sim: &str, plan: &str, out: &Path) -> Vec<String> {
    [
        "acquire",
        "--instrument",
        &config("instrument-sim.toml"),
        "--plan",
        plan,
        "--out",
        &out.display().to_string(),
        "--sim",
        sim,
        "--seed",
        "7",
    ]
    .map(String::from)
    .to_vec()
}

/// A `gonio` process serving a live view: its address, and the token when it printed
/// one. Killed when dropped (a failed test leaves no server behind).
pub struct Served {
    child: Child,
    lines: Receiver<String>,
    /// Everything the process wrote on stderr so far.
    pub stderr: Arc<Mutex<String>>,
    /// `http://IP:PORT/`, as printed.
    pub url: String,
    /// The control token, when the server printed a URL with `?token=`.
    pub token: Option<String>,
}

impl Served {
    /// Starts `gonio ARGS` in the repository's root (so that a server which served
    /// files from its directory would serve `Cargo.toml`), and waits for its
    /// `gonio: live view at …` line(s): the second, with the token, when `control`.
    pub fn start(args: &[String], control: bool) -> Served {
        let mut child = Command::new(env!("CARGO_BIN_EXE_gonio"))
            .args(args)
            .current_dir(root())
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("the gonio binary starts");
        let (tx, lines) = channel();
        let stderr = Arc::new(Mutex::new(String::new()));
        let all = Arc::clone(&stderr);
        let pipe = child.stderr.take().expect("stderr");
        std::thread::spawn(move || {
            for line in BufReader::new(pipe).lines() {
                let Ok(line) = line else { break };
                all.lock().expect("lock").push_str(&format!("{line}\n"));
                // The receiver may be gone: the test no longer listens.
                let _ = tx.send(line);
            }
        });
        let mut served = Served {
            child,
            lines,
            stderr,
            url: String::new(),
            token: None,
        };
        let t = Instant::now();
        while served.url.is_empty() || (control && served.token.is_none()) {
            let left = DEADLINE.saturating_sub(t.elapsed());
            match served.lines.recv_timeout(left) {
                Ok(line) => {
                    let Some(rest) = line.strip_prefix("gonio: live view at ") else {
                        continue;
                    };
                    let url = rest.split_whitespace().next().unwrap_or_default();
                    match url.split_once("?token=") {
                        Some((base, token)) => {
                            served.token = Some(token.to_string());
                            if served.url.is_empty() {
                                served.url = base.to_string();
                            }
                        }
                        None => served.url = url.to_string(),
                    }
                }
                Err(RecvTimeoutError::Timeout) => panic!(
                    "no live-view address after {DEADLINE:?}; stderr:\n{}",
                    served.stderr()
                ),
                Err(RecvTimeoutError::Disconnected) => {
                    let status = served.child.wait().expect("wait");
                    panic!(
                        "gonio ended ({status}) without a live-view address{}; stderr:\n{}",
                        if control { " and token" } else { "" },
                        served.stderr()
                    )
                }
            }
        }
        assert!(
            served.url.starts_with("http://127.0.0.1:") && served.url.ends_with('/'),
            "address {:?}",
            served.url
        );
        served
    }

    /// The URL with the token, as the terminal printed it.
    pub fn token_url(&self) -> String {
        format!(
            "{}?token={}",
            self.url,
            self.token.as_deref().expect("a token")
        )
    }

    /// `IP:PORT` of the server.
    pub fn addr(&self) -> String {
        self.url
            .trim_start_matches("http://")
            .trim_end_matches('/')
            .to_string()
    }

    /// What the process wrote on stderr so far.
    pub fn stderr(&self) -> String {
        self.stderr.lock().expect("lock").clone()
    }

    /// Whether the process is still running.
    pub fn running(&mut self) -> bool {
        self.child.try_wait().expect("try_wait").is_none()
    }

    /// Sends SIGTERM and waits (bounded) for the process to end.
    pub fn terminate(mut self) -> (ExitStatus, String) {
        assert!(
            self.running(),
            "gonio ended before it was stopped; stderr:\n{}",
            self.stderr()
        );
        let ok = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .expect("kill runs")
            .success();
        assert!(ok, "kill -TERM {}", self.child.id());
        let t = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().expect("try_wait") {
                // The reader thread sees the pipe close right after the exit.
                let t = Instant::now();
                while self.lines.recv_timeout(Duration::from_millis(200)).is_ok()
                    && t.elapsed() < Duration::from_secs(2)
                {}
                return (status, self.stderr());
            }
            assert!(
                t.elapsed() < Duration::from_secs(10),
                "gonio still running 10 s after SIGTERM; stderr:\n{}",
                self.stderr()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// An HTTP response: its status code, its header lines and its body.
#[derive(Debug)]
pub struct Response {
    /// The status code.
    pub status: u16,
    /// The header lines, as sent.
    pub headers: Vec<String>,
    /// The body (as much of it as was read).
    pub body: String,
}

impl Response {
    /// The value of header `name` (case-insensitive), if sent.
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers.iter().find_map(|h| {
            let (k, v) = h.split_once(':')?;
            k.trim().eq_ignore_ascii_case(name).then(|| v.trim())
        })
    }
}

/// Sends `method path` to `addr` with `Host: host` and `extra` header lines, and
/// reads the response until the connection closes, `Content-Length` bytes arrived,
/// or (for a stream) `until` appears in the body. Bounded: 10 s.
pub fn request(
    addr: &str,
    method: &str,
    path: &str,
    host: &str,
    extra: &[&str],
    until: Option<&str>,
) -> Response {
    try_request(addr, method, path, host, extra, until).unwrap_or_else(|e| panic!("{e}"))
}

/// [`request`], with what went wrong as an error rather than a panic: for a server
/// still starting, whose connections may be refused or reset.
pub fn try_request(
    addr: &str,
    method: &str,
    path: &str,
    host: &str,
    extra: &[&str],
    until: Option<&str>,
) -> Result<Response, String> {
    let mut s = TcpStream::connect(addr).map_err(|e| format!("connect {addr}: {e}"))?;
    s.set_read_timeout(Some(Duration::from_secs(10)))
        .map_err(|e| format!("timeout: {e}"))?;
    let mut req = format!("{method} {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n");
    for h in extra {
        req.push_str(h);
        req.push_str("\r\n");
    }
    if method == "POST" {
        req.push_str("Content-Length: 0\r\n");
    }
    req.push_str("\r\n");
    s.write_all(req.as_bytes())
        .map_err(|e| format!("{method} {path}: send: {e}"))?;
    let t = Instant::now();
    let mut raw = Vec::new();
    let mut buf = [0u8; 4096];
    loop {
        let n = match s.read(&mut buf) {
            Ok(n) => n,
            Err(e) => {
                return Err(format!(
                    "{method} {path}: read failed after {:?} ({e}); so far: {:?}",
                    t.elapsed(),
                    String::from_utf8_lossy(&raw)
                ));
            }
        };
        raw.extend_from_slice(&buf[..n]);
        let text = String::from_utf8_lossy(&raw);
        if n == 0 {
            break;
        }
        if let Some((head, body)) = text.split_once("\r\n\r\n") {
            if until.is_some_and(|u| body.contains(u)) {
                break;
            }
            let length = head.lines().find_map(|l| {
                let (k, v) = l.split_once(':')?;
                k.trim()
                    .eq_ignore_ascii_case("content-length")
                    .then(|| v.trim().parse::<usize>().ok())?
            });
            let chunked = head.lines().any(|l| {
                l.to_ascii_lowercase().starts_with("transfer-encoding:") && l.contains("chunked")
            });
            if length.is_some_and(|n| body.len() >= n) || (chunked && body.ends_with("0\r\n\r\n")) {
                break;
            }
        }
        if t.elapsed() >= Duration::from_secs(10) {
            return Err(format!(
                "{method} {path}: no complete response in 10 s: {text:?}"
            ));
        }
    }
    let text = String::from_utf8_lossy(&raw).into_owned();
    let (head, body) = text
        .split_once("\r\n\r\n")
        .ok_or_else(|| format!("{method} {path}: no header end in {text:?}"))?;
    let mut lines = head.lines();
    let first = lines.next().unwrap_or_default();
    let status = first
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .ok_or_else(|| format!("{method} {path}: status line {first:?}"))?;
    Ok(Response {
        status,
        headers: lines.map(String::from).collect(),
        body: body.to_string(),
    })
}

/// `GET path` with `Host: 127.0.0.1`.
pub fn get(addr: &str, path: &str) -> Response {
    request(addr, "GET", path, "127.0.0.1", &[], None)
}
