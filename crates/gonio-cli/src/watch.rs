//! How far a long call is, as the program that made it sees it: [`Watch`] (the
//! caller's stop flag and the [`Progress`] so far), and [`follow`], which turns an
//! acquisition's engine events into it. Both the Python API ([`crate::api`]) and the
//! commands (`cmd::acquire`) use it, so it sits below both.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

/// A long call as the program that made it sees it while it works (the Python
/// package's progress bar and Ctrl-C): a stop flag the caller raises, and what the
/// call has done so far, which the caller reads from another thread.
#[derive(Debug, Default)]
pub struct Watch {
    stop: Arc<AtomicBool>,
    state: Mutex<State>,
}

/// What a [`Watch`] holds: the stage going on, and those that ended since the
/// caller last looked (so that a reader that looks now and then sees each stage's
/// end).
#[derive(Debug, Default)]
struct State {
    now: Progress,
    ended: Vec<Progress>,
}

/// What a long call has done so far.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Progress {
    /// What it is doing: `acquire`, `resume`, a compared plan (`adaptive`,
    /// `lattice`, `grid`), `trace`.
    pub stage: String,
    /// Units done in this stage.
    pub done: u64,
    /// Units in the stage, once known (an adaptive run's grows batch by batch).
    pub total: Option<u64>,
    /// What a unit is: `steps`, `incidences`.
    pub unit: String,
    /// The latest reading or event, one line.
    pub message: String,
    /// The live page's address, once it is served.
    pub url: Option<String>,
    /// Counts the changes: a reader that saw this count has seen everything.
    pub seq: u64,
}

impl Watch {
    /// A watch of a call not yet started.
    pub fn new() -> Arc<Watch> {
        Arc::new(Watch::default())
    }

    /// The stop flag, for work that polls a flag of its own (ray tracing).
    pub fn stop_flag(&self) -> Arc<AtomicBool> {
        self.stop.clone()
    }

    /// Asks the call to stop (safely: an acquisition stops its stages first).
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }

    /// Whether the caller asked the call to stop.
    pub fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }

    /// A panic elsewhere while the lock was held leaves a state still worth showing.
    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// What the call has done so far.
    pub fn progress(&self) -> Progress {
        self.lock().now.clone()
    }

    /// The stages that ended since the last call, as they ended, and the one going
    /// on.
    pub fn take(&self) -> (Vec<Progress>, Progress) {
        let mut s = self.lock();
        (std::mem::take(&mut s.ended), s.now.clone())
    }

    fn update(&self, f: impl FnOnce(&mut Progress)) {
        let p = &mut self.lock().now;
        f(p);
        p.seq += 1;
    }

    /// A new stage: nothing done, the total not yet known, the address kept. The
    /// stage before it, if any, is kept as it ended for [`Watch::take`].
    pub fn begin(&self, stage: &str, unit: &str) {
        {
            let mut s = self.lock();
            if !s.now.stage.is_empty() {
                let ended = s.now.clone();
                s.ended.push(ended);
            }
        }
        self.update(|p| {
            p.stage = stage.into();
            p.unit = unit.into();
            p.done = 0;
            p.total = None;
            p.message.clear();
        });
    }

    /// `done` of `total` units.
    pub fn set(&self, done: u64, total: Option<u64>) {
        self.update(|p| {
            p.done = done;
            p.total = total;
        });
    }

    /// One more unit done.
    pub fn advance(&self) {
        self.update(|p| p.done += 1);
    }

    /// The live page's address.
    pub fn set_url(&self, url: String) {
        self.update(|p| p.url = Some(url));
    }
}

/// Follows a session's engine events into `watch` as the progress bar shows them:
/// steps done of the total, and the last reading.
pub(crate) async fn follow(
    mut rx: tokio::sync::broadcast::Receiver<gonio_acquire::engine::Event>,
    watch: Arc<Watch>,
) {
    use gonio_acquire::engine::Event;
    use tokio::sync::broadcast::error::RecvError;
    loop {
        match rx.recv().await {
            Ok(Event::Started { done, total, .. }) => {
                watch.set(done as u64, Some(total as u64));
            }
            Ok(Event::Measured {
                done,
                total,
                kind,
                r_mean,
                r_std,
                flags,
                ..
            }) => watch.update(|p| {
                p.done = done as u64;
                p.total = Some(total as u64);
                p.message = format!(
                    "{}: R = {r_mean:.4e} ± {r_std:.1e} V{}",
                    kind.as_str(),
                    if gonio_run::flags::questioned(flags) {
                        " (flagged)"
                    } else {
                        ""
                    }
                );
            }),
            Ok(Event::Batch {
                batch,
                points,
                steps,
                total,
            }) => watch.update(|p| {
                p.total = Some(total as u64);
                p.message = format!("batch {batch}: {points} points, {steps} steps");
            }),
            Ok(Event::Paused) => watch.update(|p| p.message = "paused (stages idle)".into()),
            Ok(Event::Resumed) => watch.update(|p| p.message = "pause ended".into()),
            Ok(Event::Finished { .. }) | Err(RecvError::Closed) => return,
            Ok(_) | Err(RecvError::Lagged(_)) => {}
        }
    }
}
