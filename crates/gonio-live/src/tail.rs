//! Following a run file: what is new since the last look, as an [`Update`], and the
//! whole state as a [`Snapshot`].
//!
//! The run file is the page's one source, whether this process measures the run or
//! another does: the engine commits every reading and logs every event there before
//! it tells anyone, so the page shows nothing the run file does not hold, and a page
//! opened on a finished run shows what one open during the run ended with.

use std::collections::{BTreeMap, VecDeque};
use std::path::Path;
use std::time::{Duration, Instant};

use gonio_reduce::{Detector, Options};
use gonio_run::{RunStore, flags};

use crate::LiveError;
use crate::state::{
    Brdf, DRIFT_ROWS, DriftRow, LOG_ROWS, LogRow, Now, RunInfo, SCHEMA, Snapshot, Status,
    TRACE_ROWS, TraceRow, Update,
};

/// The shortest time between two reductions while the run goes on.
const REDUCE_EVERY: Duration = Duration::from_secs(1);
/// A reduction may take at most this share of the time between two.
const REDUCE_SHARE: u32 = 20;

/// The route of the report, offered once the run has ended.
pub const REPORT: &str = "/report.html";

/// A run file being followed.
pub struct Tail {
    store: RunStore,
    /// Each step's kind and channel (read again when an adaptive run's planner has
    /// appended steps).
    steps: BTreeMap<i64, (String, Option<String>)>,
    /// An adaptive run's budget, for the time its batches to come will take.
    adaptive: Option<AdaptiveLeft>,
    snapshot: Snapshot,
    /// The latest reading's commit time seen.
    last_wall: f64,
    /// The latest event's row id seen.
    last_event: i64,
    /// Whether the latest pause has not ended.
    paused: bool,
    /// Each session's first reading's instrument time: a session's first step
    /// carries its start-up (homing), which says nothing of the pace after.
    first_physical: BTreeMap<i64, f64>,
    /// The instrument time between a session's first and last readings, and the
    /// steps in between, summed over the sessions.
    pace: (f64, usize),
    /// Readings seen, and at the last reduction.
    readings: usize,
    reduced_readings: Option<usize>,
    reduced_at: Option<Instant>,
    reduce_cost: Duration,
}

impl Tail {
    /// Opens `path` read-only (with every integrity check of
    /// [`RunStore::open_read_only`]) and reads the run as it stands.
    pub fn open(path: &Path, control: bool, live: bool) -> Result<Tail, LiveError> {
        let store = RunStore::open_read_only(path)?;
        let meta = store.run_meta()?;
        let steps = kinds(&store)?;
        let adaptive = AdaptiveLeft::of(&store, &meta)?;
        let detector = Detector::of_instrument(&meta.instrument);
        let axes = axes_of(&meta.instrument);
        let info = RunInfo {
            file: path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            name: meta.name.clone().unwrap_or_default(),
            axes,
            detector: match detector {
                Detector::LockIn => "lock-in",
                Detector::Dc => "dc",
            },
            unit: match detector {
                Detector::LockIn => "V",
                Detector::Dc => "A",
            },
            estimate_s: meta.estimate.map(|e| e.total_s()),
            control,
            live,
        };
        let mut tail = Tail {
            store,
            steps,
            adaptive,
            snapshot: Snapshot {
                schema: SCHEMA,
                run: info,
                status: Status {
                    state: "created",
                    message: String::new(),
                    done: 0,
                    failed: 0,
                    total: 0,
                    physical_s: 0.0,
                    eta_s: None,
                    sessions: 0,
                },
                now: None,
                trace: VecDeque::new(),
                drift: VecDeque::new(),
                log: VecDeque::new(),
                brdf: Brdf::default(),
                report: None,
            },
            last_wall: f64::NEG_INFINITY,
            last_event: 0,
            paused: false,
            first_physical: BTreeMap::new(),
            pace: (0.0, 0),
            readings: 0,
            reduced_readings: None,
            reduced_at: None,
            reduce_cost: Duration::ZERO,
        };
        tail.refresh(Instant::now(), true)?;
        Ok(tail)
    }

    /// The state as it stands.
    pub fn snapshot(&self) -> &Snapshot {
        &self.snapshot
    }

    /// Reads what is new and returns it (empty when nothing changed), already
    /// applied to the snapshot. The run is reduced again when new readings arrived
    /// and the last reduction is old enough (at least a second, and twenty times
    /// what it cost), or when `force` (the run's end).
    pub fn refresh(&mut self, now: Instant, force: bool) -> Result<Update, LiveError> {
        if self.store.is_outdated() {
            // A finished run resumed by another process while it was being viewed.
            tracing::info!("live view: the run is being measured again; reopening it");
            self.store = RunStore::open_read_only(self.store.path())?;
        }
        let mut u = Update::default();
        let per_session = self.store.session_readings()?;
        // A session's instrument clock starts at 0: sessions follow each other.
        let mut offsets = BTreeMap::new();
        let mut physical = 0.0;
        let mut readings = 0;
        for (id, (n, t)) in &per_session {
            offsets.insert(*id, physical);
            if t.is_finite() {
                physical += t;
            }
            readings += n;
        }
        for (session, r) in self.store.readings_since(self.last_wall)? {
            if !self.steps.contains_key(&r.step_id) {
                // A batch appended since the schedule was read.
                self.steps = kinds(&self.store)?;
            }
            self.last_wall = r.wall_s;
            self.first_physical.entry(session).or_insert(r.physical_s);
            let (kind, channel) = self
                .steps
                .get(&r.step_id)
                .cloned()
                .unwrap_or_else(|| ("sample".into(), None));
            let physical_s = offsets.get(&session).copied().unwrap_or(0.0) + r.physical_s;
            if kind == "reference" {
                u.drift.push(DriftRow {
                    step_id: r.step_id,
                    channel: channel.clone(),
                    r_mean: r.r_mean,
                    r_std: r.r_std,
                    physical_s,
                });
            }
            u.trace.push(TraceRow {
                step_id: r.step_id,
                kind: kind.clone(),
                channel: channel.clone(),
                r_mean: r.r_mean,
                r_std: r.r_std,
                flags: r.flags & !flags::HOW_READ,
                physical_s,
                wall_s: r.wall_s,
            });
            let p = &r.read_pair;
            u.now = Some(Now {
                step_id: r.step_id,
                kind,
                channel,
                position: r.position,
                pair: [
                    p.incident.theta_deg,
                    p.incident.phi_deg,
                    p.outgoing.theta_deg,
                    p.outgoing.phi_deg,
                ],
                r_mean: r.r_mean,
                r_std: r.r_std,
                // The page marks what questions a reading, not how it was read.
                flags: r.flags & !flags::HOW_READ,
                flag_text: flags::text(r.flags & !flags::HOW_READ),
            });
        }
        self.pace = per_session
            .iter()
            .filter_map(|(id, (n, t))| {
                Some((t - self.first_physical.get(id)?, n.saturating_sub(1)))
            })
            .filter(|(span, _)| span.is_finite())
            .fold((0.0, 0), |(s, k), (ds, dk)| (s + ds, k + dk));
        keep_last(&mut u.trace, TRACE_ROWS);
        keep_last(&mut u.drift, DRIFT_ROWS);
        let mut last_stop = None;
        for (id, e) in self.store.events_after(self.last_event)? {
            self.last_event = id;
            match e.kind.as_str() {
                "pause" => self.paused = true,
                "continue" | "start" | "resume" | "stop" => self.paused = false,
                _ => {}
            }
            if e.kind == "stop" {
                last_stop = Some(e.message.clone());
            }
            u.log.push(LogRow {
                id,
                wall_s: e.wall_s,
                kind: e.kind,
                step_id: e.step_id,
                message: e.message,
            });
        }
        keep_last(&mut u.log, LOG_ROWS);
        let status = self.status(physical, last_stop)?;
        if status != self.snapshot.status {
            u.status = Some(status.clone());
        }
        let active = status.is_active();
        self.readings = readings;
        let fresh = self.reduced_readings != Some(readings);
        let gap = REDUCE_EVERY.max(self.reduce_cost * REDUCE_SHARE);
        let due = self.reduced_at.is_none_or(|t| now.duration_since(t) >= gap);
        // A run that has ended is reduced at once, so that the page's last picture
        // is the final one.
        if fresh && (force || due || !active) {
            let brdf = self.reduce(active || status.state == "created");
            if brdf != self.snapshot.brdf {
                u.brdf = Some(brdf);
            }
        }
        // The report is offered once the run has ended, if it reduces: the report
        // is made of the reduction.
        let reduced = u.brdf.as_ref().unwrap_or(&self.snapshot.brdf);
        if !active
            && self.snapshot.report.is_none()
            && status.state != "created"
            && reduced.note.is_none()
            && !reduced.samples.is_empty()
        {
            u.report = Some(REPORT);
        }
        self.snapshot.apply(&u);
        Ok(u)
    }

    /// The run reduced as `gonio reduce` reduces it by default; while it is
    /// `active`, a reduction that cannot be made yet says so as what it waits for.
    fn reduce(&mut self, active: bool) -> Brdf {
        let t = Instant::now();
        let r = gonio_reduce::reduce(&self.store, &Options::default());
        self.reduce_cost = t.elapsed();
        self.reduced_at = Some(Instant::now());
        self.reduced_readings = Some(self.readings);
        tracing::debug!(
            cost_ms = self.reduce_cost.as_secs_f64() * 1e3,
            "live view: reduced"
        );
        match r {
            Ok(red) => {
                let s = &red.samples;
                let n = s.channels.len();
                let mut incidences: Vec<[f64; 2]> = Vec::new();
                let samples = s
                    .samples
                    .iter()
                    .map(|x| {
                        let (i, o) = (x.pair.incident, x.pair.outgoing);
                        let inc = [i.theta_deg, i.phi_deg];
                        if !incidences.contains(&inc) {
                            incidences.push(inc);
                        }
                        let mut row = vec![i.theta_deg, i.phi_deg, o.theta_deg, o.phi_deg];
                        row.extend(&x.value);
                        match &x.sigma {
                            Some(sig) => row.extend(sig),
                            None => row.extend(std::iter::repeat_n(f64::NAN, n)),
                        }
                        row.push(f64::from(x.flags));
                        row
                    })
                    .collect();
                Brdf {
                    channels: s.channels.names(),
                    samples,
                    incidences,
                    note: None,
                }
            }
            Err(e) => {
                let why = match e {
                    gonio_reduce::ReduceError::Missing { why, .. } => why,
                    other => other.to_string(),
                };
                Brdf {
                    note: Some(if active {
                        format!("not reduced yet (the calibrations come first): {why}")
                    } else {
                        format!("the run cannot be reduced: {why}")
                    }),
                    ..Brdf::default()
                }
            }
        }
    }

    /// Where the run stands, from its metadata, step counts, the holder of its
    /// lock and the pause events.
    fn status(&self, physical_s: f64, last_stop: Option<String>) -> Result<Status, LiveError> {
        let counts = self.store.state_counts()?;
        let count = |k: &str| counts.get(k).copied().unwrap_or(0);
        let total: u64 = counts.values().sum();
        let (done, failed) = (count("done"), count("failed"));
        let sessions = self.store.sessions()?.len();
        let stored = self.store.meta_value("status")?.unwrap_or_default();
        let previous = || {
            last_stop
                .clone()
                .or_else(|| {
                    self.snapshot
                        .log
                        .iter()
                        .rev()
                        .find(|e| e.kind == "stop")
                        .map(|e| e.message.clone())
                })
                .unwrap_or_default()
        };
        let (state, message) = match stored.as_str() {
            "running" => match self.store.measured_by() {
                Some(_) if self.paused => ("paused", "paused on request; stages idle".into()),
                Some(pid) => ("running", format!("measuring (process {pid})")),
                None => ("stale", gonio_run::STALE_NOTE.into()),
            },
            "complete" => ("complete", "every step finished".into()),
            "interrupted" => ("interrupted", previous()),
            "faulted" => ("faulted", previous()),
            _ => ("created", "created; no session has started".into()),
        };
        let remaining = total.saturating_sub(done + failed) as f64;
        // This run's own pace once it has one, else the planner's.
        let per_step = match self.pace {
            (span, steps) if steps > 0 => Some(span / steps as f64),
            _ => self
                .snapshot
                .run
                .estimate_s
                .filter(|_| total > 0)
                .map(|e| e / total as f64),
        };
        // An adaptive run also has the batches its budget has left to come.
        let to_come = match &self.adaptive {
            Some(a) => a.to_come(&self.store, per_step)?,
            None => 0.0,
        };
        let eta_s = per_step
            .filter(|_| matches!(state, "running" | "paused"))
            .map(|p| p * remaining + to_come);
        Ok(Status {
            state,
            message,
            done,
            failed,
            total,
            physical_s,
            eta_s,
            sessions,
        })
    }
}

/// Each step's kind and channel.
fn kinds(store: &RunStore) -> Result<BTreeMap<i64, (String, Option<String>)>, LiveError> {
    Ok(store
        .steps()?
        .into_iter()
        .map(|s| (s.id, (s.step.kind.as_str().to_string(), s.step.channel)))
        .collect())
}

/// What an adaptive run's budget leaves to its batches to come.
#[derive(Clone, Debug)]
struct AdaptiveLeft {
    budget: gonio_plan::adaptive::Budget,
    /// Sample points and steps of the coarse pass (the schedule the run was created
    /// with).
    coarse_points: usize,
    coarse_steps: usize,
    /// The coarse pass's estimated time, s.
    coarse_s: f64,
}

impl AdaptiveLeft {
    /// The budget of the run in `store`, when its plan is adaptive.
    fn of(store: &RunStore, meta: &gonio_run::RunMeta) -> Result<Option<AdaptiveLeft>, LiveError> {
        let Ok(plan) = gonio_plan::Plan::from_toml(&meta.plan, None) else {
            return Ok(None);
        };
        let gonio_plan::plan::Points::Adaptive(a) = plan.points else {
            return Ok(None);
        };
        let first = meta.step_count.unwrap_or(0) as i64;
        let coarse: Vec<_> = store
            .steps()?
            .into_iter()
            .filter(|s| s.id < first)
            .collect();
        let coarse_points = coarse
            .iter()
            .filter(|s| s.step.kind == gonio_plan::StepKind::Sample)
            .filter_map(|s| s.step.plan_index)
            .collect::<std::collections::BTreeSet<_>>()
            .len();
        Ok(Some(AdaptiveLeft {
            budget: a.budget,
            coarse_points,
            coarse_steps: coarse.len(),
            coarse_s: meta
                .estimate
                .map_or(0.0, |e| e.motion_s + e.detector_s + e.band_s),
        }))
    }

    /// The instrument time the batches to come will take, s: with a budget in points,
    /// the points left at the steps per point of the batches so far (before the first,
    /// the coarse pass's) and the run's pace per step; with a budget in hours, the time
    /// the planner has not planned yet.
    fn to_come(&self, store: &RunStore, per_step: Option<f64>) -> Result<f64, LiveError> {
        let decisions = store.decisions()?;
        let chosen: u64 = decisions.iter().map(|d| u64::from(d.points)).sum();
        Ok(match self.budget {
            gonio_plan::adaptive::Budget::Points(p) => {
                let left = (p as u64).saturating_sub(self.coarse_points as u64 + chosen);
                let (steps, points) = if chosen > 0 {
                    (
                        decisions.iter().map(|d| u64::from(d.steps)).sum::<u64>(),
                        chosen,
                    )
                } else {
                    (self.coarse_steps as u64, self.coarse_points.max(1) as u64)
                };
                per_step.unwrap_or(0.0) * left as f64 * steps as f64 / points as f64
            }
            gonio_plan::adaptive::Budget::Hours(h) => {
                let planned: f64 = self.coarse_s
                    + decisions
                        .iter()
                        .filter_map(|d| {
                            serde_json::from_str::<serde_json::Value>(&d.detail)
                                .ok()?
                                .get("estimate_s")?
                                .as_f64()
                        })
                        .sum::<f64>();
                (h * 3600.0 - planned).max(0.0)
            }
        })
    }
}

/// Keeps the last `n` rows.
fn keep_last<T>(v: &mut Vec<T>, n: usize) {
    if v.len() > n {
        v.drain(..v.len() - n);
    }
}

/// The four role axes' names, in stage order, from the run's stored instrument
/// config; numbered when the text no longer parses (an older build's config).
fn axes_of(instrument: &str) -> Vec<String> {
    gonio_driver::InstrumentConfig::from_toml(instrument, None)
        .ok()
        .and_then(|c| c.mechanics().ok())
        .map(|m| m.axes.to_vec())
        .unwrap_or_else(|| (1..=4).map(|i| format!("axis {i}")).collect())
}
