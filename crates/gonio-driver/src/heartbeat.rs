//! Keep-alives: messages a line must carry at least every so often for as long as it
//! is open, whatever else the instrument is doing. The Thorlabs APT controllers are
//! the case in point (protocol manual, Issue 28, p. 130): on USB the host must send
//! `MOT_ACK_DCSTATUSUPDATE` at least once a second, or after about 50 status messages
//! the controller sends no more, move completions and status replies included.
//!
//! The session declares the duty ([`KeepAlive`]); a [`Heartbeat`] holds every line's
//! duty and sends each when it falls due. The instrument's lines share one, and every
//! wait of every line goes through it: the pump splits each wait (a reply, a pause
//! between polls, a settling time) at the next keep-alive and sends it, so an APT line
//! is kept alive while the lock-in settles, while another line's stage moves, while
//! the run is paused ([`Heartbeat::sleep_until`]) and during its own operations. It
//! runs on the pump's clock, so on virtual time it is as deterministic as the rest.

use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

pub use gonio_proto::link::KeepAlive;
use tracing::{debug, trace};

use crate::clock::Clock;
use crate::transport::{Escaped, Transport, TransportError};

/// A transport shared by a line's own operations and its keep-alives: every call
/// locks it for that call only. Everything runs on one thread, so the lock is never
/// contended; it only lets the heartbeat write between the operation's calls.
pub(crate) struct SharedLink<T>(Arc<Mutex<T>>);

impl<T> SharedLink<T> {
    pub(crate) fn new(t: T) -> Self {
        SharedLink(Arc::new(Mutex::new(t)))
    }

    fn lock(&self) -> MutexGuard<'_, T> {
        // A panic while holding it can only come from a transport's own bug; the
        // transport is still the best there is.
        self.0.lock().unwrap_or_else(|p| p.into_inner())
    }
}

impl<T> Clone for SharedLink<T> {
    fn clone(&self) -> Self {
        SharedLink(self.0.clone())
    }
}

impl<T: Transport> Transport for SharedLink<T> {
    fn send(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        self.lock().send(bytes)
    }
    fn receive_line(&mut self, timeout: Duration) -> Result<Vec<u8>, TransportError> {
        self.lock().receive_line(timeout)
    }
    fn clear_input(&mut self) -> Result<(), TransportError> {
        self.lock().clear_input()
    }
    fn reconnect(&mut self) -> Result<(), TransportError> {
        self.lock().reconnect()
    }
    fn name(&self) -> String {
        self.lock().name()
    }
}

/// One line's duty.
struct Beat {
    port: String,
    link: Box<dyn Transport>,
    duty: KeepAlive,
    /// When it was last tried: the next is due a period later.
    tried: Option<Duration>,
    /// When the first went out.
    first_sent: Option<Duration>,
    /// When one last went out.
    sent_at: Option<Duration>,
    sent: u64,
    /// The longest time between two that went out.
    longest_gap: Duration,
}

impl Beat {
    fn due(&self) -> Duration {
        self.tried
            .map_or(Duration::ZERO, |t| t.saturating_add(self.duty.every))
    }
}

/// The shortest period a keep-alive is sent at, whatever a session declares: a zero
/// period would make every wait a busy loop.
const MIN_PERIOD: Duration = Duration::from_millis(1);

/// Every line's keep-alive, sent when due at each wait of any line. Clones share the
/// duties: the instrument's lines hold one heartbeat between them, and their clocks
/// one time frame (every `now` handed in is the instrument's clock's).
#[derive(Clone, Default)]
pub struct Heartbeat(Arc<Mutex<Vec<Beat>>>);

impl std::fmt::Debug for Heartbeat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let beats = self.lock();
        f.debug_list()
            .entries(beats.iter().map(|b| (&b.port, b.duty.name, b.sent)))
            .finish()
    }
}

impl Heartbeat {
    /// A heartbeat with no duties.
    pub fn new() -> Self {
        Self::default()
    }

    fn lock(&self) -> MutexGuard<'_, Vec<Beat>> {
        self.0.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Adds `port`'s duty, sent over `link`; the first is due at once.
    pub(crate) fn add(&self, port: &str, link: Box<dyn Transport>, mut duty: KeepAlive) {
        duty.every = duty.every.max(MIN_PERIOD);
        self.lock().push(Beat {
            port: port.to_string(),
            link,
            duty,
            tried: None,
            first_sent: None,
            sent_at: None,
            sent: 0,
            longest_gap: Duration::ZERO,
        });
    }

    /// Moves `other`'s duties into this heartbeat (a line joining an instrument).
    pub(crate) fn absorb(&self, other: &Heartbeat) {
        if Arc::ptr_eq(&self.0, &other.0) {
            return;
        }
        let moved: Vec<Beat> = other.lock().drain(..).collect();
        self.lock().extend(moved);
    }

    /// True when no line has a duty.
    pub fn is_empty(&self) -> bool {
        self.lock().is_empty()
    }

    /// When the next keep-alive falls due, if any line has one.
    pub fn due(&self) -> Option<Duration> {
        self.lock().iter().map(Beat::due).min()
    }

    /// Sends every keep-alive due by `now`. A send that fails is logged and tried
    /// again a period later: the line's own next operation finds the fault and
    /// reopens the port.
    pub fn beat(&self, now: Duration) {
        for b in self.lock().iter_mut().filter(|b| b.due() <= now) {
            trace!(
                target: "gonio_driver::wire",
                port = %b.port,
                dir = "tx",
                line = %Escaped(&b.duty.bytes),
            );
            if let Err(e) = b.link.send(&b.duty.bytes) {
                debug!(port = %b.port, error = %e, "keep-alive not sent");
            } else {
                b.sent += 1;
                if let Some(t) = b.sent_at {
                    b.longest_gap = b.longest_gap.max(now.saturating_sub(t));
                }
                b.sent_at = Some(now);
                b.first_sent.get_or_insert(now);
                trace!(port = %b.port, message = b.duty.name, "keep-alive sent");
            }
            b.tried = Some(now);
        }
    }

    /// Waits on `clock` until `at`, sending each keep-alive as it falls due: what
    /// every pause of the instrument goes through.
    pub fn sleep_until(&self, clock: &impl Clock, at: Duration) {
        loop {
            let now = clock.now();
            self.beat(now);
            if now >= at {
                return;
            }
            let until = self.due().map_or(at, |d| d.clamp(now, at));
            clock.sleep(until.saturating_sub(now));
        }
    }

    /// Per line with a duty: the port, how many keep-alives went out, and the longest
    /// time without one from `since` to `now` (before the first, between two, after
    /// the last; all of it when none went out).
    pub fn report(&self, since: Duration, now: Duration) -> Vec<(String, u64, Duration)> {
        self.lock()
            .iter()
            .map(|b| {
                let before = b.first_sent.unwrap_or(now).saturating_sub(since);
                let after = now.saturating_sub(b.sent_at.unwrap_or(since));
                (b.port.clone(), b.sent, b.longest_gap.max(before).max(after))
            })
            .collect()
    }
}
