//! The live view: a run's web page, served by Gonio itself while the run is
//! measured (`gonio acquire --serve`, `gonio resume --serve`) or afterwards, for
//! any run file (`gonio view`). See docs/live.md for the routes and the event
//! schema.
//!
//! - [`tail`]: the run file followed read-only: what is new, as an update, and the
//!   whole state, as a snapshot.
//! - [`hub`]: the fan-out of numbered updates to every page, bounded per page.
//! - `http`: the routes (axum), the host check and the control token.
//! - [`Server`]: the three together, with the thread that follows the run file.
//!
//! The run file is the page's only source. When this process measures the run, the
//! engine's events only say *when* to look: the engine commits each reading and
//! logs each event before it tells its listeners, so the page, the progress bar and
//! the run file's event log tell the same story.

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, mpsc};
use std::time::{Duration, Instant};

use gonio_acquire::{Event, Pauser, Stopper};
use tokio::sync::{broadcast, watch};

mod http;
pub mod hub;
pub mod state;
pub mod tail;

pub use http::TOKEN_HEADER;
pub use tail::Tail;

/// The least time between two looks at the run file: at most five updates a
/// second, however fast the engine goes.
pub const MIN_GAP: Duration = Duration::from_millis(200);
/// How often the run file is looked at with nothing to say when (`gonio view`, or
/// a run whose engine is quiet).
pub const POLL: Duration = Duration::from_millis(500);

/// Why the view cannot start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// `--serve ADDR` does not parse.
    #[error("--serve {text}: {why}")]
    Address {
        /// What was given.
        text: String,
        /// Why it is not an address.
        why: String,
    },
    /// The address cannot be listened on.
    #[error("--serve {addr}: cannot listen there: {source}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// Why.
        source: std::io::Error,
    },
    /// The run file.
    #[error(transparent)]
    Store(#[from] gonio_run::StoreError),
    /// The operating system gave no random token, or the server could not start.
    #[error("live view: {0}")]
    Io(String),
}

impl LiveError {
    /// True when the user's input is at fault (exit status 2).
    pub fn is_input(&self) -> bool {
        match self {
            LiveError::Address { .. } | LiveError::Bind { .. } => true,
            LiveError::Store(e) => e.is_bad_input(),
            LiveError::Io(_) => false,
        }
    }
}

/// The address `--serve` listens on: `IP:PORT`, a bare port (on 127.0.0.1) or a
/// bare IP (a free port on it); empty for 127.0.0.1 at a free port.
pub fn parse_addr(text: &str) -> Result<SocketAddr, LiveError> {
    let t = text.trim();
    if t.is_empty() {
        return Ok(SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), 0));
    }
    if let Ok(a) = t.parse::<SocketAddr>() {
        return Ok(a);
    }
    if let Ok(port) = t.parse::<u16>() {
        return Ok(SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), port));
    }
    if let Ok(ip) = t
        .trim_start_matches('[')
        .trim_end_matches(']')
        .parse::<IpAddr>()
    {
        return Ok(SocketAddr::new(ip, 0));
    }
    Err(LiveError::Address {
        text: text.to_string(),
        why: "not IP:PORT, a port or an IP address (host names are not looked up)".into(),
    })
}

/// Listens on `addr`: done before anything is created, so that an address in use
/// refuses the command whole.
pub fn bind(addr: SocketAddr) -> Result<std::net::TcpListener, LiveError> {
    let l = std::net::TcpListener::bind(addr).map_err(|source| LiveError::Bind { addr, source })?;
    l.set_nonblocking(true)
        .map_err(|source| LiveError::Bind { addr, source })?;
    Ok(l)
}

/// The engine's handles the control routes use.
#[derive(Clone, Debug)]
pub struct Controls {
    /// The safe stop.
    pub stopper: Stopper,
    /// The pause between steps.
    pub pauser: Pauser,
}

/// Makes the run's HTML report from its file (the command's `gonio report`).
pub type ReportFn = Arc<dyn Fn(&Path) -> Result<String, String> + Send + Sync>;

/// What the server is given besides the run file.
#[derive(Default)]
pub struct Options {
    /// The engine's handles: the control routes are enabled (with a fresh token)
    /// only when given.
    pub control: Option<Controls>,
    /// The report maker, for `/report.html`.
    pub report: Option<ReportFn>,
    /// The events of the engine measuring the run in this process, if any.
    pub events: Option<broadcast::Receiver<Event>>,
}

/// Tells the thread that follows the run file when to look, and when the
/// session ended.
#[derive(Debug)]
pub(crate) struct Waker {
    tx: SyncSender<()>,
    ended: AtomicBool,
    quit: AtomicBool,
    /// The follower has published the state after the session's end.
    settled: AtomicBool,
}

impl Waker {
    /// Something happened: look soon.
    pub(crate) fn poke(&self) {
        // Full means a look is already due.
        if let Err(TrySendError::Disconnected(_)) = self.tx.try_send(()) {
            tracing::debug!("live view: the follower has gone");
        }
    }

    /// The session ended: take the last look, with a final reduction.
    pub(crate) fn end(&self) {
        self.ended.store(true, Ordering::SeqCst);
        self.poke();
    }

    pub(crate) fn has_ended(&self) -> bool {
        self.ended.load(Ordering::SeqCst)
    }

    fn quit(&self) {
        self.quit.store(true, Ordering::SeqCst);
        self.poke();
    }
}

/// The live view of one run, serving until [`Server::stop`].
pub struct Server {
    url: String,
    token: Option<String>,
    addr: SocketAddr,
    waker: Arc<Waker>,
    hub: Arc<hub::Hub>,
    shutdown: watch::Sender<bool>,
    task: tokio::task::JoinHandle<()>,
    follower: Option<std::thread::JoinHandle<()>>,
}

impl Server {
    /// Serves the run at `run` on `listener` (from [`bind`]). Must be called
    /// within a tokio runtime, which runs the server; a thread of its own follows
    /// the run file.
    pub fn start(
        listener: std::net::TcpListener,
        run: &Path,
        opts: Options,
    ) -> Result<Server, LiveError> {
        let addr = listener
            .local_addr()
            .map_err(|e| LiveError::Io(e.to_string()))?;
        let live = opts.events.is_some();
        let token = opts.control.as_ref().map(|_| new_token()).transpose()?;
        let tail = Tail::open(run, opts.control.is_some(), live)?;
        let hub = Arc::new(hub::Hub::new(tail.snapshot().clone()));
        let (tx, rx) = mpsc::sync_channel(1);
        let waker = Arc::new(Waker {
            tx,
            ended: AtomicBool::new(false),
            quit: AtomicBool::new(false),
            settled: AtomicBool::new(false),
        });
        let follower = {
            let (hub, waker) = (hub.clone(), waker.clone());
            std::thread::Builder::new()
                .name("gonio-live".into())
                .spawn(move || follow(tail, &hub, &waker, &rx, live))
                .map_err(|e| LiveError::Io(e.to_string()))?
        };
        if let Some(mut events) = opts.events {
            let waker = waker.clone();
            tokio::spawn(async move {
                use broadcast::error::{RecvError, TryRecvError};
                loop {
                    match events.recv().await {
                        Ok(Event::Finished { .. }) | Err(RecvError::Closed) => {
                            waker.end();
                            return;
                        }
                        Ok(_) | Err(RecvError::Lagged(_)) => waker.poke(),
                    }
                    // The follower looks at most once per MIN_GAP, so the events until
                    // then are taken together: waiting on each woke this task, and a
                    // runtime thread, at every step, which at time scale 0 (a step
                    // every 0.4–0.6 ms) cost the engine 11–14% (BENCHMARKS.md, "Live
                    // view"). The engine's channel holds 1 024 events; a lag loses
                    // only older ones, never the last (`Finished`).
                    tokio::time::sleep(MIN_GAP).await;
                    let mut more = false;
                    loop {
                        match events.try_recv() {
                            Ok(Event::Finished { .. }) | Err(TryRecvError::Closed) => {
                                waker.end();
                                return;
                            }
                            Ok(_) | Err(TryRecvError::Lagged(_)) => more = true,
                            Err(TryRecvError::Empty) => break,
                        }
                    }
                    if more {
                        waker.poke();
                    }
                }
            });
        }
        let (shutdown, shutdown_rx) = watch::channel(false);
        let app = Arc::new(http::App {
            hub: hub.clone(),
            waker: waker.clone(),
            control: opts.control,
            token: token.clone(),
            report: opts.report,
            run: PathBuf::from(run),
            loopback: addr.ip().is_loopback(),
            shutdown: shutdown_rx.clone(),
            report_cache: tokio::sync::Mutex::new(None),
        });
        let listener = tokio::net::TcpListener::from_std(listener)
            .map_err(|e| LiveError::Io(e.to_string()))?;
        let router = http::router(app);
        let mut done = shutdown_rx;
        let task = tokio::spawn(async move {
            let serve = axum::serve(listener, router).with_graceful_shutdown(async move {
                let _ = done.wait_for(|d| *d).await;
            });
            if let Err(e) = serve.await {
                tracing::warn!("live view: the server stopped: {e}");
            }
        });
        let host = match addr.ip() {
            IpAddr::V6(ip) => format!("[{ip}]"),
            IpAddr::V4(ip) => ip.to_string(),
        };
        let url = format!("http://{host}:{}/", addr.port());
        tracing::info!(%url, control = token.is_some(), "live view serving");
        Ok(Server {
            url,
            token,
            addr,
            waker,
            hub,
            shutdown,
            task,
            follower: Some(follower),
        })
    }

    /// The page's address, with the control token when there is one.
    pub fn url(&self) -> String {
        match &self.token {
            Some(t) => format!("{}?token={t}", self.url),
            None => self.url.clone(),
        }
    }

    /// The address listened on.
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// The control token, if control is enabled.
    pub fn token(&self) -> Option<&str> {
        self.token.as_deref()
    }

    /// The state the pages were last sent.
    pub fn state(&self) -> Arc<state::Snapshot> {
        self.hub.state()
    }

    /// Tells the view that the session in this process has ended (also learnt from
    /// the engine's `Finished` event): the run file is read a last time, the run
    /// reduced, the report offered; control is refused from now on.
    pub fn session_ended(&self) {
        self.waker.end();
    }

    /// Waits until the pages have been sent the state after the session's end (at
    /// most `timeout`).
    pub async fn settled(&self, timeout: Duration) {
        let t0 = Instant::now();
        while t0.elapsed() < timeout {
            if self.waker.settled.load(Ordering::SeqCst) {
                return;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }

    /// Stops serving: every page's stream ends, the follower thread stops.
    pub async fn stop(mut self) {
        self.waker.quit();
        let _ = self.shutdown.send(true);
        // Open streams end at the signal; a connection that will not close in a
        // second is dropped.
        let abort = self.task.abort_handle();
        if tokio::time::timeout(Duration::from_secs(1), &mut self.task)
            .await
            .is_err()
        {
            abort.abort();
        }
        if let Some(f) = self.follower.take() {
            let _ = tokio::task::spawn_blocking(move || f.join()).await;
        }
    }
}

/// 128 random bits from the operating system, in hex.
fn new_token() -> Result<String, LiveError> {
    let mut b = [0u8; 16];
    getrandom::fill(&mut b).map_err(|e| LiveError::Io(format!("no random token: {e}")))?;
    Ok(b.iter().map(|x| format!("{x:02x}")).collect())
}

/// The follower: looks at the run file when woken (or every [`POLL`]), at most
/// once per [`MIN_GAP`], and publishes what changed.
fn follow(mut tail: Tail, hub: &hub::Hub, waker: &Waker, rx: &Receiver<()>, live: bool) {
    let _span = tracing::info_span!("live").entered();
    let mut last = Instant::now();
    let mut finished = false;
    loop {
        match rx.recv_timeout(POLL) {
            Ok(()) | Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => return,
        }
        if waker.quit.load(Ordering::SeqCst) {
            return;
        }
        // While the engine runs, its events wake us; a quiet poll is for a run
        // measured elsewhere, or a pause.
        let since = last.elapsed();
        if since < MIN_GAP {
            std::thread::sleep(MIN_GAP - since);
        }
        let ended = waker.has_ended();
        if live && finished {
            // Nothing changes in the file once this process's session has ended.
            continue;
        }
        last = Instant::now();
        match tail.refresh(last, ended) {
            Ok(u) => {
                if !u.is_empty() {
                    hub.publish(tail.snapshot(), &u);
                }
                // Settled once the file shows the session's end.
                finished = ended && !tail.snapshot().status.is_active();
                if finished {
                    waker.settled.store(true, Ordering::SeqCst);
                }
            }
            Err(e) => tracing::warn!("live view: reading the run file: {e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_parse_in_every_accepted_form() {
        let ok = |t: &str| parse_addr(t).expect(t).to_string();
        assert_eq!(ok(""), "127.0.0.1:0");
        assert_eq!(ok("8080"), "127.0.0.1:8080");
        assert_eq!(ok("0.0.0.0:9000"), "0.0.0.0:9000");
        assert_eq!(ok("::1"), "[::1]:0");
        assert_eq!(ok("[::1]:81"), "[::1]:81");
        assert_eq!(ok("192.168.1.5"), "192.168.1.5:0");
        for bad in ["localhost:80", "70000", "1.2.3:4", "http://x"] {
            let e = parse_addr(bad).expect_err(bad);
            assert!(e.is_input());
            assert!(e.to_string().starts_with(&format!("--serve {bad}:")), "{e}");
        }
    }

    #[test]
    fn tokens_are_128_bits_of_hex_and_differ() {
        let a = new_token().expect("token");
        let b = new_token().expect("token");
        assert_eq!(a.len(), 32);
        assert!(a.bytes().all(|c| c.is_ascii_hexdigit()));
        assert_ne!(a, b);
    }

    #[test]
    fn an_address_in_use_is_refused_as_input() {
        let first = bind(parse_addr("").expect("addr")).expect("binds");
        let taken = first.local_addr().expect("addr");
        let e = bind(taken).expect_err("in use");
        assert!(e.is_input());
        assert!(e.to_string().contains("cannot listen there"), "{e}");
    }
}
