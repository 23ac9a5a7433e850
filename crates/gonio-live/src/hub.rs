//! The fan-out to the pages: one sequence of updates, each numbered, and the
//! snapshot they add up to.
//!
//! Publishing never waits for a reader: updates go into a bounded broadcast ring,
//! and a page that falls behind it (a slow link, a suspended tab, a client that
//! stopped reading) loses its place and is sent a fresh snapshot instead. Numbering
//! lets a page that subscribed between two publications skip the updates its
//! snapshot already holds.

use std::sync::{Arc, Mutex, PoisonError};

use tokio::sync::{Semaphore, broadcast};

use crate::state::{Snapshot, Update};

/// Updates a page may fall behind by before it is resent the snapshot.
pub const BUFFER: usize = 32;
/// Event streams open at once.
pub const MAX_CLIENTS: usize = 64;

/// A numbered update, serialised once for every page.
pub type Numbered = (u64, Arc<str>);

struct Latest {
    seq: u64,
    snapshot: Arc<Snapshot>,
    /// Its JSON, made when a page first asks for it.
    json: Option<Arc<str>>,
}

/// The published state and its subscribers.
pub struct Hub {
    latest: Mutex<Latest>,
    tx: broadcast::Sender<Numbered>,
    /// One permit an open event stream.
    pub clients: Arc<Semaphore>,
}

impl Hub {
    /// A hub whose state starts as `snapshot`.
    pub fn new(snapshot: Snapshot) -> Hub {
        Hub {
            latest: Mutex::new(Latest {
                seq: 0,
                snapshot: Arc::new(snapshot),
                json: None,
            }),
            tx: broadcast::channel(BUFFER).0,
            clients: Arc::new(Semaphore::new(MAX_CLIENTS)),
        }
    }

    fn latest(&self) -> std::sync::MutexGuard<'_, Latest> {
        // A panic while the lock was held leaves whole values behind (each field
        // is replaced by one assignment), so the state is still consistent.
        self.latest.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Publishes `update`, after which the state is `snapshot`.
    pub fn publish(&self, snapshot: &Snapshot, update: &Update) {
        let json: Arc<str> = match serde_json::to_string(update) {
            Ok(j) => j.into(),
            Err(e) => {
                tracing::warn!("live view: an update did not serialise: {e}");
                return;
            }
        };
        let mut l = self.latest();
        l.seq += 1;
        l.snapshot = Arc::new(snapshot.clone());
        l.json = None;
        // Under the lock, so that numbers and snapshots agree for every subscriber;
        // an error only says that no page is open.
        let _ = self.tx.send((l.seq, json));
    }

    /// The state now: its number and JSON.
    pub fn snapshot(&self) -> (u64, Arc<str>) {
        let mut l = self.latest();
        let json = match &l.json {
            Some(j) => j.clone(),
            None => {
                // Plain values serialise; should one not, the page is told in JSON.
                let j: Arc<str> = serde_json::to_string(&*l.snapshot)
                    .unwrap_or_else(|e| serde_json::json!({ "error": e.to_string() }).to_string())
                    .into();
                l.json = Some(j.clone());
                j
            }
        };
        (l.seq, json)
    }

    /// The state as a value.
    pub fn state(&self) -> Arc<Snapshot> {
        self.latest().snapshot.clone()
    }

    /// A subscription: the state now, and every update after it.
    pub fn subscribe(&self) -> (u64, Arc<str>, broadcast::Receiver<Numbered>) {
        // Subscribed before the snapshot is read, both under the lock: no update
        // falls between them.
        let l = self.latest();
        let rx = self.tx.subscribe();
        drop(l);
        let (seq, json) = self.snapshot();
        (seq, json, rx)
    }
}
