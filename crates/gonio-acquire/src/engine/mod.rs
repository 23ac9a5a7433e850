//! The run engine: takes a run file's pending steps one by one through the
//! goniometer, commits each reading as it is taken, and tells listeners.
//!
//! The drivers block (serial I/O, waits on the instrument clock), so each step runs
//! on tokio's blocking pool and the async side stays free for listeners and for
//! Ctrl-C. The instrument, the bench and the store travel together into each step
//! and back; nothing else touches them meanwhile.
//!
//! What the engine does with faults:
//! - lost, late or garbled replies are retried by the drivers; the count is stored
//!   with the reading and logged as a `retry` event;
//! - after a controller was reset or lost power, every axis that lost its reference
//!   is re-homed (the NUL byte on the shared line does not say which controller sent
//!   it), and the step is measured again (up to [`EngineConfig::max_attempts`] times);
//! - a flagged reading (overload, unlock) is read again up to
//!   [`EngineConfig::flagged_rereads`] times, then stored with its flags: data is
//!   never thrown away, the reduction decides;
//! - a step the instrument refuses for good (a target outside the limits, a signal
//!   autoranging cannot hold) is marked failed with its reason, and the run goes on;
//! - anything else that persists (a stalled stage, a dead line) stops the stages and
//!   ends the session `faulted`, resumable once the cause is fixed;
//! - raising the [`Stopper`] (Ctrl-C) aborts the move in flight, stops every stage,
//!   and ends the session `interrupted`, resumable.
//!
//! An adaptive plan adds a [`Planner`] ([`Engine::with_planner`]): whenever no step
//! is pending, it is asked for the next batch of steps, which is appended to the run
//! file and measured like the schedule's, until it has nothing to add. A planner
//! that fails ends the session `faulted`, resumable.

use gonio_core::goniometer::Mechanics;
use gonio_driver::bench::{Bench, Setup};
use gonio_driver::smc100::AbortFlag;
pub use gonio_driver::sr830::ReadTarget;
use gonio_driver::{Clock, Goniometer};
use gonio_plan::StepKind;
use gonio_run::{Batch, RunStore, StoreError, StoredStep};
use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use tokio::sync::broadcast;

mod rig;

use rig::{Planned, Rig, StepOutcome};

/// An adaptive plan's planner: given the run file (every reading committed so far),
/// the next batch of steps to measure, or `None` when the run needs no more; an
/// error ends the session `faulted` (resumable), with the message.
///
/// Kill and resume make the same choices as an uninterrupted run, because the engine
/// asks the planner only when no step is pending, and appends its batch (steps,
/// decision, event) in one transaction ([`RunStore::append_batch`]): a kill before
/// that commit leaves the file as if the planner had never been asked, and a resume
/// asks it again on the same readings; a kill after it leaves the batch's steps
/// pending, and a resume measures them. So a planner must decide from the file alone
/// (the readings, its earlier decisions), never from state of its own that a kill
/// would lose.
pub type Planner = Box<dyn FnMut(&RunStore) -> Result<Option<Batch>, String> + Send>;

/// How hard the engine tries.
#[derive(Clone, Debug, PartialEq)]
pub struct EngineConfig {
    /// Attempts at one step (re-measured after a recovered fault) before the run stops.
    pub max_attempts: u32,
    /// Extra readings of a step whose reading came back flagged.
    pub flagged_rereads: u32,
    /// Transmittance of the incident-beam filter (from the plan).
    pub incident_transmittance: f64,
    /// Software version written with each session.
    pub software: String,
    /// The plan's `[reading]` target for a sample reading (`sigma_absolute` 0: the
    /// detector's own floor); `None` reads a fixed number of snapshots.
    pub reading: Option<ReadTarget>,
}

/// A plan's `[reading]` table as the detector's target (`sigma_absolute` 0 when the
/// plan leaves the floor to the detector).
pub fn read_target(r: &gonio_plan::ReadingConfig) -> ReadTarget {
    ReadTarget {
        sigma_relative: r.sigma_relative,
        sigma_absolute: r.sigma_absolute.unwrap_or(0.0),
        max_s: r.max_s,
        min_samples: r.min_samples as usize,
    }
}

/// The target of a step's reading, from the plan's (`base`) and the absolute floor
/// in force (the plan's, else the detector's): the plan's own for a sample or a dark,
/// a third of it for a calibration or drift reference, whose error every sample it
/// calibrates shares (so that it adds a ninth at most to a sample's variance).
pub fn target_for_kind(base: &ReadTarget, kind: gonio_plan::StepKind, floor: f64) -> ReadTarget {
    use gonio_plan::StepKind;
    let share = match kind {
        StepKind::Sample | StepKind::Dark => 1.0,
        StepKind::Reference | StepKind::Incident | StepKind::Standard => 1.0 / 3.0,
    };
    ReadTarget {
        sigma_relative: base.sigma_relative * share,
        sigma_absolute: if base.sigma_absolute > 0.0 {
            base.sigma_absolute
        } else {
            floor
        },
        ..*base
    }
}

impl Default for EngineConfig {
    fn default() -> Self {
        EngineConfig {
            max_attempts: 3,
            flagged_rereads: 2,
            incident_transmittance: 1.0,
            software: concat!("gonio ", env!("CARGO_PKG_VERSION")).into(),
            reading: None,
        }
    }
}

/// How a session ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// Every step is done or failed.
    Complete,
    /// Stopped on request (Ctrl-C); resumable.
    Interrupted,
    /// Stopped by a fault that persisted; resumable once it is fixed.
    Faulted(String),
}

impl Outcome {
    /// The run status it leaves: `complete`, `interrupted` or `faulted`.
    pub fn status(&self) -> &'static str {
        match self {
            Outcome::Complete => "complete",
            Outcome::Interrupted => "interrupted",
            Outcome::Faulted(_) => "faulted",
        }
    }
}

/// What listeners hear.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    /// A session started: `done` of `total` steps already finished.
    Started {
        /// Steps done or failed before this session.
        done: usize,
        /// Steps in the schedule.
        total: usize,
        /// True when an earlier session worked on the run.
        resumed: bool,
    },
    /// Axes were homed.
    Homed {
        /// Their names.
        axes: Vec<String>,
    },
    /// The bench was set up (light path or band).
    Bench {
        /// What was done.
        what: String,
    },
    /// A step was measured and committed.
    Measured {
        /// The step.
        step_id: i64,
        /// Its kind.
        kind: StepKind,
        /// Steps finished so far.
        done: usize,
        /// Steps in the schedule.
        total: usize,
        /// Mean R, V.
        r_mean: f64,
        /// Standard deviation of R, V.
        r_std: f64,
        /// [`gonio_run::flags`] bits.
        flags: u32,
        /// Instrument time since the session started, s.
        physical_s: f64,
    },
    /// A fault, and whether the engine recovers from it.
    Fault {
        /// The step, if any.
        step_id: Option<i64>,
        /// What happened.
        message: String,
        /// True when the engine carries on.
        recovering: bool,
    },
    /// An adaptive plan's planner appended a batch of steps to the run.
    Batch {
        /// The batch's number (1, 2, …; its row in the run's `decisions` table).
        batch: i64,
        /// Sample geometry points it chose.
        points: u32,
        /// Steps it added.
        steps: usize,
        /// Steps in the run now.
        total: usize,
    },
    /// The engine paused between steps on request ([`Pauser`]); the stages are idle.
    Paused,
    /// The pause ended; the next step follows.
    Resumed,
    /// A step was given up.
    Skipped {
        /// The step.
        step_id: i64,
        /// Why.
        reason: String,
    },
    /// The session ended.
    Finished {
        /// How.
        outcome: Outcome,
    },
}

/// Why the engine itself failed (the run file could not be written, a step panicked).
/// The stages are stopped first.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    /// The run file.
    #[error("run file: {0}")]
    Store(#[from] StoreError),
    /// A step's task panicked.
    #[error("a step's task failed: {0}")]
    Task(String),
}

/// Stops a running engine from elsewhere (a signal handler): the move in flight is
/// aborted, the stages stop, the session ends `interrupted`.
#[derive(Clone, Debug)]
pub struct Stopper(AbortFlag);

impl Stopper {
    /// Requests the stop.
    pub fn stop(&self) {
        self.0.raise();
    }

    /// True once requested.
    pub fn is_stopped(&self) -> bool {
        self.0.is_raised()
    }
}

/// Pauses a running engine between steps, from elsewhere (the live view's button):
/// the step in flight finishes and is committed, then the engine waits with the
/// stages idle until [`Pauser::resume`] or a stop. Each pause and its end go into the
/// run's event log (`pause`, `continue`).
#[derive(Clone, Debug, Default)]
pub struct Pauser(Arc<AtomicBool>);

impl Pauser {
    /// Requests a pause before the next step.
    pub fn pause(&self) {
        self.0.store(true, Ordering::SeqCst);
    }

    /// Ends the pause.
    pub fn resume(&self) {
        self.0.store(false, Ordering::SeqCst);
    }

    /// True while a pause is requested.
    pub fn is_paused(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }
}

/// What a session did.
#[derive(Clone, Debug, PartialEq)]
pub struct SessionReport {
    /// How it ended.
    pub outcome: Outcome,
    /// Steps measured in this session.
    pub measured: usize,
    /// Steps given up in this session.
    pub skipped: usize,
    /// Steps done or failed in the whole run.
    pub finished: usize,
    /// Steps in the schedule.
    pub total: usize,
    /// Instrument time of the session, s.
    pub physical_s: f64,
}

/// A run in progress: the goniometer, the bench and the run file.
pub struct Engine<C: Clock + Clone, B: Bench> {
    rig: Rig<C, B>,
    stopper: Stopper,
    pauser: Pauser,
    planner: Option<Planner>,
}

impl<C, B> Engine<C, B>
where
    C: Clock + Clone + Send + 'static,
    B: Bench + 'static,
{
    /// An engine that will take `store`'s pending steps on `gonio`, whose stages play
    /// the roles of `mech`.
    pub fn new(
        gonio: Goniometer<C>,
        bench: B,
        store: RunStore,
        mech: Mechanics,
        cfg: EngineConfig,
    ) -> Self {
        // Cleared here, not when the session starts: a stop requested between now
        // and then (a live page's button) is the session's to honour.
        gonio.motion.abort_flag().clear();
        let stopper = Stopper(gonio.motion.abort_flag());
        let (events, _) = broadcast::channel(1024);
        let t0 = gonio.motion.clock().now();
        Engine {
            rig: Rig {
                gonio,
                bench,
                store,
                mech,
                cfg,
                setup: None,
                channel: None,
                shutter_open: None,
                t0,
                events,
                span: tracing::Span::none(),
                floor: None,
            },
            stopper,
            pauser: Pauser::default(),
            planner: None,
        }
    }

    /// The engine of an adaptive plan: once the pending steps run out, `planner` is
    /// asked for more (see [`Planner`]).
    pub fn with_planner(mut self, planner: Planner) -> Self {
        self.planner = Some(planner);
        self
    }

    /// The handle that stops the run.
    pub fn stopper(&self) -> Stopper {
        self.stopper.clone()
    }

    /// The handle that pauses the run between steps.
    pub fn pauser(&self) -> Pauser {
        self.pauser.clone()
    }

    /// A receiver of the engine's events (subscribe before [`run`](Self::run)).
    pub fn subscribe(&self) -> broadcast::Receiver<Event> {
        self.rig.events.subscribe()
    }

    /// Runs a session: start-up (identify, home what needs it, restore the detector),
    /// then every pending step, and with a planner, its batches as they come (pauses
    /// and stops are honoured between batches as between steps); returns the report
    /// and the run file.
    pub async fn run(self) -> Result<(SessionReport, RunStore), EngineError> {
        let Engine {
            mut rig,
            stopper,
            pauser,
            mut planner,
        } = self;
        rig.span = tracing::info_span!("run", file = %rig.store.path().display());
        let (mut rig, started) = blocking(rig, Rig::start).await?;
        let start = match started? {
            Ok(s) => s,
            Err(outcome) => {
                let (rig, r) = blocking(rig, move |rig| rig.finish(outcome, 0, 0)).await?;
                return Ok((r?, rig.store));
            }
        };
        let mut total = start.total;
        let mut finished = start.finished;
        let (mut measured, mut skipped) = (0, 0);
        let mut outcome = Outcome::Complete;
        let mut queue: VecDeque<StoredStep> = start.pending.into();
        let mut attempts = 0u32;
        loop {
            if queue.is_empty() && planner.is_none() {
                break;
            }
            if pauser.is_paused() {
                rig = pause(rig, &pauser, &stopper).await?;
            }
            if stopper.is_stopped() {
                outcome = Outcome::Interrupted;
                break;
            }
            let Some(step) = queue.front().cloned() else {
                // Nothing pending: the planner, if any, says whether more follows.
                let Some(p) = planner.take() else {
                    break;
                };
                let (r, (p, res)) = blocking(rig, move |rig| {
                    let mut p = p;
                    let res = rig.plan(&mut p, total);
                    (p, res)
                })
                .await?;
                rig = r;
                planner = Some(p);
                match res? {
                    Planned::Batch { steps, total: now } => {
                        queue.extend(steps);
                        total = now;
                        continue;
                    }
                    Planned::Done => break,
                    Planned::Stop(o) => {
                        outcome = o;
                        break;
                    }
                }
            };
            attempts += 1;
            let s = step.clone();
            let (r, res) = blocking(rig, move |rig| rig.step(&s)).await?;
            rig = r;
            match res? {
                StepOutcome::Measured(rec) => {
                    measured += 1;
                    finished += 1;
                    let _ = rig.events.send(Event::Measured {
                        step_id: step.id,
                        kind: step.step.kind,
                        done: finished,
                        total,
                        r_mean: rec.r_mean,
                        r_std: rec.r_std,
                        flags: rec.flags,
                        physical_s: rec.physical_s,
                    });
                    queue.pop_front();
                    attempts = 0;
                }
                StepOutcome::Again(why) => {
                    if stopper.is_stopped() {
                        outcome = Outcome::Interrupted;
                        break;
                    }
                    if attempts >= rig.cfg.max_attempts {
                        outcome = Outcome::Faulted(format!(
                            "step {} failed {attempts} times; last: {why}",
                            step.id
                        ));
                        break;
                    }
                }
                StepOutcome::Skip(reason) => {
                    tracing::warn!(parent: &rig.span, step = step.id, "step skipped: {reason}");
                    rig.store.fail_step(step.id, &reason)?;
                    let _ = rig.events.send(Event::Skipped {
                        step_id: step.id,
                        reason,
                    });
                    skipped += 1;
                    finished += 1;
                    queue.pop_front();
                    attempts = 0;
                }
                StepOutcome::Stop(o) => {
                    outcome = o;
                    break;
                }
            }
        }
        let (rig, r) = blocking(rig, move |rig| rig.finish(outcome, measured, skipped)).await?;
        Ok((r?, rig.store))
    }
}

/// Waits out a pause between steps: logged at its start and end, ended by
/// [`Pauser::resume`] or by a stop (which the caller then sees).
async fn pause<C, B>(
    rig: Rig<C, B>,
    pauser: &Pauser,
    stopper: &Stopper,
) -> Result<Rig<C, B>, EngineError>
where
    C: Clock + Clone + Send + 'static,
    B: Bench + 'static,
{
    let (rig, r) = blocking(rig, |rig| {
        rig.note(Event::Paused, "pause", "paused on request; stages idle")
    })
    .await?;
    r?;
    // A pause is a person's decision: polled at a person's pace, never on the
    // instrument clock (which a simulation may run faster than real time). Each turn
    // sends the keep-alives due on the instrument's clock (the APT controllers want one
    // at least once a second, whatever the run does).
    let mut rig = rig;
    while pauser.is_paused() && !stopper.is_stopped() {
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
        let (r, ()) = blocking(rig, |rig| rig.gonio.keep_alive()).await?;
        rig = r;
    }
    let why = if stopper.is_stopped() {
        "pause ended by a stop"
    } else {
        "pause ended; continuing"
    };
    let (rig, r) = blocking(rig, move |rig| rig.note(Event::Resumed, "continue", why)).await?;
    r?;
    Ok(rig)
}

/// Runs `f` on the blocking pool with the rig, and hands the rig back.
async fn blocking<C, B, T, F>(rig: Rig<C, B>, f: F) -> Result<(Rig<C, B>, T), EngineError>
where
    C: Clock + Clone + Send + 'static,
    B: Bench + 'static,
    T: Send + 'static,
    F: FnOnce(&mut Rig<C, B>) -> T + Send + 'static,
{
    let mut rig = rig;
    tokio::task::spawn_blocking(move || {
        let t = f(&mut rig);
        (rig, t)
    })
    .await
    .map_err(|e| EngineError::Task(e.to_string()))
}

/// The set-up a kind of step needs.
pub fn setup_for(kind: StepKind, transmittance: f64) -> Setup {
    match kind {
        StepKind::Sample | StepKind::Reference => Setup::Sample,
        StepKind::Dark => Setup::Dark,
        StepKind::Incident => Setup::Incident { transmittance },
        StepKind::Standard => Setup::Standard,
    }
}
