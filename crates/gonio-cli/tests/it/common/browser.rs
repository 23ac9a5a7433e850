//! A real browser for the live view's tests: Debian's headless Chromium driven through
//! WebDriver (chromedriver, started on a free port and killed with its browser when
//! dropped). Every wait is bounded and fails with what the page last showed, after
//! saving a screenshot under `target/artifacts/`.

#![allow(dead_code)]

use std::fmt;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use fantoccini::{Client, ClientBuilder, Locator};
use hyper_util::client::legacy::connect::HttpConnector;
use serde_json::{Value, json};

use super::live::{DEADLINE, try_request};

/// Where the tests leave their screenshots and chromedriver's log:
/// `target/artifacts/` of the workspace.
pub fn artifacts() -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .parent()
        .expect("CARGO_TARGET_TMPDIR is target/tmp")
        .join("artifacts");
    std::fs::create_dir_all(&dir).expect("create target/artifacts");
    dir
}

/// A file from an environment variable, else a default path; the test fails (never
/// passes silently) when it is missing.
fn program(var: &str, default: &str) -> PathBuf {
    let path = std::env::var_os(var).map_or_else(|| PathBuf::from(default), PathBuf::from);
    assert!(
        path.is_file(),
        "no {} at {} (from {}): run scripts/browsers, which installs Debian's chromium and \
         chromium-driver, or point {var} at one",
        path.file_name()
            .map_or(default.into(), |n| n.to_string_lossy()),
        path.display(),
        if std::env::var_os(var).is_some() {
            var
        } else {
            "the default"
        },
    );
    path
}

/// A chromedriver process on a free port of 127.0.0.1, in a process group of its own
/// so that dropping it ends the browsers it started too.
struct Driver {
    child: Child,
    port: u16,
}

impl Driver {
    /// Starts chromedriver ($GONIO_CHROMEDRIVER, else /usr/bin/chromedriver) and waits
    /// until it reports itself ready.
    fn start() -> Driver {
        use std::os::unix::process::CommandExt;
        let exe = program("GONIO_CHROMEDRIVER", "/usr/bin/chromedriver");
        // A port the kernel just handed out and released: free unless another process
        // takes it in the instant before chromedriver binds it.
        let port = TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("a free port")
            .port();
        let log = artifacts().join(format!("chromedriver-{port}.log"));
        let child = Command::new(&exe)
            .arg(format!("--port={port}"))
            .arg(format!("--log-path={}", log.display()))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .process_group(0)
            .spawn()
            .unwrap_or_else(|e| panic!("{} does not start: {e}", exe.display()));
        let mut driver = Driver { child, port };
        let addr = format!("127.0.0.1:{port}");
        let t = Instant::now();
        let mut last;
        loop {
            if let Some(status) = driver.child.try_wait().expect("try_wait") {
                panic!(
                    "chromedriver exited ({status}) at start; its log: {}",
                    log.display()
                );
            }
            // A driver still starting may refuse or reset a connection: not ready yet.
            match try_request(&addr, "GET", "/status", "127.0.0.1", &[], None) {
                Ok(r) => {
                    let ready = serde_json::from_str::<Value>(&r.body)
                        .ok()
                        .and_then(|v| v["value"]["ready"].as_bool());
                    if r.status == 200 && ready == Some(true) {
                        return driver;
                    }
                    last = format!("{} {}", r.status, r.body);
                }
                Err(e) => last = e,
            }
            assert!(
                t.elapsed() < Duration::from_secs(30),
                "chromedriver not ready after 30 s: {last}; its log: {}",
                log.display()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Driver {
    fn drop(&mut self) {
        // The whole group: chromedriver and the Chromium processes it started.
        let _ = Command::new("kill")
            .args(["-KILL", "--", &format!("-{}", self.child.id())])
            .stderr(Stdio::null())
            .status();
        let _ = self.child.wait();
    }
}

/// What the page's elements (docs/live.md, "The page") show at one instant.
#[derive(Debug, Clone, Default, serde::Deserialize)]
pub struct Page {
    /// `#status`'s text.
    pub status: Option<String>,
    /// `#done`'s text.
    pub done: Option<String>,
    /// `#total`'s text.
    pub total: Option<String>,
    /// `#brdf-count`'s text.
    pub brdf_count: Option<String>,
    /// The number of `#brdf circle.pt` elements.
    pub circles: u64,
    /// Whether `#report-link` is rendered and visible.
    pub report_visible: bool,
    /// `#report-link`'s resolved `href`.
    pub report_href: Option<String>,
    /// `#control-msg`'s text.
    pub control_msg: Option<String>,
    /// `#connection`'s text.
    pub connection: Option<String>,
    /// Whether `#stop` is visible.
    pub stop_visible: bool,
    /// The page's address.
    pub url: String,
}

/// An element's text as an integer.
fn int(text: &Option<String>) -> Option<u64> {
    text.as_deref()?.trim().parse().ok()
}

impl Page {
    /// `#done` as an integer.
    pub fn done(&self) -> Option<u64> {
        int(&self.done)
    }
    /// `#total` as an integer.
    pub fn total(&self) -> Option<u64> {
        int(&self.total)
    }
    /// `#brdf-count` as an integer.
    pub fn brdf_count(&self) -> Option<u64> {
        int(&self.brdf_count)
    }
    /// Whether `#status` says `state`.
    pub fn is(&self, state: &str) -> bool {
        self.status.as_deref().map(str::trim) == Some(state)
    }
}

/// Reads every element of [`Page`] in one script, so that they are from one instant.
const READ_PAGE: &str = r#"
const q = s => document.querySelector(s);
const text = s => { const e = q(s); return e ? e.textContent.trim() : null; };
const shown = e => !!e && !e.hidden && e.getClientRects().length > 0
    && getComputedStyle(e).visibility !== 'hidden';
const link = q('#report-link');
return {
    status: text('#status'), done: text('#done'), total: text('#total'),
    brdf_count: text('#brdf-count'),
    circles: document.querySelectorAll('#brdf circle.pt').length,
    report_visible: shown(link), report_href: link ? link.href : null,
    control_msg: text('#control-msg'), connection: text('#connection'),
    stop_visible: shown(q('#stop')), url: location.href,
};
"#;

/// A headless Chromium session on a fresh profile, with its chromedriver.
pub struct Browser {
    /// The WebDriver session.
    pub client: Client,
    _profile: tempfile::TempDir,
    _driver: Driver,
}

/// An error of the page, in a test's terms.
pub struct Failure(String);

impl fmt::Debug for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl Browser {
    /// Starts chromedriver and opens a headless Chromium ($GONIO_CHROMIUM, else
    /// /usr/bin/chromium) on a fresh temporary profile.
    pub async fn open() -> Browser {
        let chromium = program("GONIO_CHROMIUM", "/usr/bin/chromium");
        let driver = Driver::start();
        let profile = tempfile::Builder::new()
            .prefix("gonio-chromium-")
            .tempdir()
            .expect("profile dir");
        let args = [
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--window-size=1280,900",
        ]
        .map(String::from)
        .into_iter()
        .chain([format!("--user-data-dir={}", profile.path().display())])
        .collect::<Vec<_>>();
        let caps = json!({
            "browserName": "chrome",
            "goog:chromeOptions": { "binary": chromium.display().to_string(), "args": args },
        });
        let Value::Object(caps) = caps else {
            unreachable!("a JSON object literal")
        };
        let url = format!("http://127.0.0.1:{}", driver.port);
        let client = tokio::time::timeout(
            DEADLINE,
            ClientBuilder::new(HttpConnector::new())
                .capabilities(caps)
                .connect(&url),
        )
        .await
        .unwrap_or_else(|_| panic!("no WebDriver session in {DEADLINE:?}"))
        .unwrap_or_else(|e| panic!("no WebDriver session: {e}"));
        Browser {
            client,
            _profile: profile,
            _driver: driver,
        }
    }

    /// Opens `url` and waits for its document.
    pub async fn goto(&self, url: &str) {
        tokio::time::timeout(DEADLINE, self.client.goto(url))
            .await
            .unwrap_or_else(|_| panic!("{url} did not load in {DEADLINE:?}"))
            .unwrap_or_else(|e| panic!("{url}: {e}"));
    }

    /// What the page shows now.
    pub async fn page(&self) -> Result<Page, Failure> {
        let v = self
            .client
            .execute(READ_PAGE, vec![])
            .await
            .map_err(|e| Failure(format!("reading the page: {e}")))?;
        serde_json::from_value(v.clone()).map_err(|e| Failure(format!("{v}: {e}")))
    }

    /// Polls the page until `ok` holds, for at most [`DEADLINE`]; on time-out saves
    /// `target/artifacts/failed-WHAT.png` and fails with what the page last showed.
    pub async fn wait_for(&self, what: &str, ok: impl Fn(&Page) -> bool) -> Page {
        let t = Instant::now();
        loop {
            let last = self.page().await;
            if let Ok(p) = &last
                && ok(p)
            {
                return p.clone();
            }
            if t.elapsed() > DEADLINE {
                let name = format!(
                    "failed-{}.png",
                    what.replace(|c: char| !c.is_alphanumeric(), "-")
                );
                let shot = self.screenshot(&name).await;
                panic!(
                    "waited {DEADLINE:?} for {what}; the page last showed {last:?} \
                     (screenshot {})",
                    shot.display()
                );
            }
            tokio::time::sleep(Duration::from_millis(150)).await;
        }
    }

    /// Clicks the element `css` as a user would.
    pub async fn click(&self, css: &str) {
        let e = self
            .client
            .find(Locator::Css(css))
            .await
            .unwrap_or_else(|e| panic!("no {css} on the page: {e}"));
        e.click()
            .await
            .unwrap_or_else(|e| panic!("clicking {css}: {e}"));
    }

    /// Sends `method path` from the page (its origin, no token) with `fetch`;
    /// returns the status and the body.
    pub async fn fetch(&self, method: &str, path: &str) -> (u64, String) {
        let script = r#"
const [method, path, done] = arguments;
fetch(path, { method })
    .then(r => r.text().then(body => done([r.status, body])))
    .catch(e => done([0, String(e)]));
"#;
        let v = self
            .client
            .execute_async(script, vec![json!(method), json!(path)])
            .await
            .unwrap_or_else(|e| panic!("fetch {method} {path}: {e}"));
        (
            v[0].as_u64().expect("a status"),
            v[1].as_str().unwrap_or_default().to_string(),
        )
    }

    /// The document's title.
    pub async fn title(&self) -> String {
        self.client.title().await.expect("the title")
    }

    /// Saves a screenshot of the window as `target/artifacts/NAME`; returns its path.
    pub async fn screenshot(&self, name: &str) -> PathBuf {
        let path = artifacts().join(name);
        let png = self.client.screenshot().await.expect("a screenshot");
        assert!(png.starts_with(b"\x89PNG"), "the screenshot is not a PNG");
        std::fs::write(&path, png).expect("write the screenshot");
        path
    }

    /// Ends the session (Chromium quits), then chromedriver.
    pub async fn close(self) {
        let Browser {
            client,
            _profile,
            _driver,
        } = self;
        let _ = tokio::time::timeout(Duration::from_secs(10), client.close()).await;
    }
}

/// Runs an async test body on a runtime of its own (two workers: the WebDriver
/// session's task keeps going while the test waits on a process).
pub fn run<F: std::future::Future<Output = ()>>(body: F) {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("a tokio runtime")
        .block_on(body);
}
