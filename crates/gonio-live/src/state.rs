//! The page's data: what a `snapshot` holds whole and an `update` holds in part
//! (docs/live.md, "Objects"). Everything here is plain values, serialised as they
//! are.

use std::collections::VecDeque;

use serde::Serialize;

/// The version of the event schema, in every snapshot.
pub const SCHEMA: u32 = 1;
/// Readings kept for the detector trace.
pub const TRACE_ROWS: usize = 200;
/// Events kept for the log.
pub const LOG_ROWS: usize = 500;
/// Drift-reference readings kept.
pub const DRIFT_ROWS: usize = 10_000;

/// What does not change while the page is open.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunInfo {
    /// The run file's name, without its directory.
    pub file: String,
    /// The run's name from its metadata.
    pub name: String,
    /// The role axes' names, in stage order.
    pub axes: Vec<String>,
    /// `lock-in` or `dc`.
    pub detector: &'static str,
    /// The readings' unit: `V` or `A`.
    pub unit: &'static str,
    /// The planner's estimate of the whole run's instrument time, s.
    pub estimate_s: Option<f64>,
    /// Whether the control routes are enabled.
    pub control: bool,
    /// Whether this process measures the run.
    pub live: bool,
}

/// Where the run stands.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Status {
    /// `created`, `running`, `paused`, `complete`, `interrupted`, `faulted` or `stale`.
    pub state: &'static str,
    /// The same in words.
    pub message: String,
    /// Steps measured.
    pub done: u64,
    /// Steps given up.
    pub failed: u64,
    /// Steps in the schedule.
    pub total: u64,
    /// Instrument time of every session so far, s.
    pub physical_s: f64,
    /// Instrument time still needed at this run's own pace, s.
    pub eta_s: Option<f64>,
    /// Sessions so far.
    pub sessions: usize,
}

impl Status {
    /// Whether a session is (or may still be) working on the run.
    pub fn is_active(&self) -> bool {
        matches!(self.state, "running" | "paused")
    }
}

/// The latest reading.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Now {
    /// Its step.
    pub step_id: i64,
    /// The step's kind.
    pub kind: String,
    /// The step's channel, if any.
    pub channel: Option<String>,
    /// Stage positions, degrees.
    pub position: [f64; 4],
    /// `[θi, φi, θo, φo]` as read back, degrees.
    pub pair: [f64; 4],
    /// The reading.
    pub r_mean: f64,
    /// Its standard deviation.
    pub r_std: f64,
    /// Flag bits.
    pub flags: u32,
    /// Their names.
    pub flag_text: String,
}

/// A row of the detector trace.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TraceRow {
    /// The step.
    pub step_id: i64,
    /// Its kind.
    pub kind: String,
    /// Its channel.
    pub channel: Option<String>,
    /// The reading.
    pub r_mean: f64,
    /// Its standard deviation.
    pub r_std: f64,
    /// Flag bits.
    pub flags: u32,
    /// Instrument time across sessions, s.
    pub physical_s: f64,
    /// Wall clock, Unix seconds.
    pub wall_s: f64,
}

/// A drift-reference reading.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DriftRow {
    /// The step.
    pub step_id: i64,
    /// Its channel.
    pub channel: Option<String>,
    /// The reading.
    pub r_mean: f64,
    /// Its standard deviation.
    pub r_std: f64,
    /// Instrument time across sessions, s.
    pub physical_s: f64,
}

/// A row of the event log.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LogRow {
    /// The event's row id in the run file.
    pub id: i64,
    /// Wall clock, Unix seconds.
    pub wall_s: f64,
    /// Its kind.
    pub kind: String,
    /// Its step, if any.
    pub step_id: Option<i64>,
    /// What happened.
    pub message: String,
}

/// The run reduced.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Brdf {
    /// Channel names.
    pub channels: Vec<String>,
    /// `[θi, φi, θo, φo, f…, σ…, flags]`, one row a sample.
    pub samples: Vec<Vec<f64>>,
    /// The distinct `[θi, φi]`.
    pub incidences: Vec<[f64; 2]>,
    /// Why there is nothing yet, if so.
    pub note: Option<String>,
}

/// Everything the page shows.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Snapshot {
    /// [`SCHEMA`].
    pub schema: u32,
    /// The run.
    pub run: RunInfo,
    /// Where it stands.
    pub status: Status,
    /// The latest reading.
    pub now: Option<Now>,
    /// The last [`TRACE_ROWS`] readings.
    pub trace: VecDeque<TraceRow>,
    /// Drift-reference readings (at most [`DRIFT_ROWS`], the latest).
    pub drift: VecDeque<DriftRow>,
    /// The last [`LOG_ROWS`] events.
    pub log: VecDeque<LogRow>,
    /// The reduction.
    pub brdf: Brdf,
    /// The report's route once the run has ended.
    pub report: Option<&'static str>,
}

/// What changed since the previous event: rows to append, values to replace.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Update {
    /// The new status, if it changed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub status: Option<Status>,
    /// The new latest reading, if any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub now: Option<Now>,
    /// New trace rows.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub trace: Vec<TraceRow>,
    /// New drift rows.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub drift: Vec<DriftRow>,
    /// New log rows.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub log: Vec<LogRow>,
    /// The new reduction, if it was redone.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub brdf: Option<Brdf>,
    /// The report's route, when it became available.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub report: Option<&'static str>,
}

impl Update {
    /// Nothing changed.
    pub fn is_empty(&self) -> bool {
        *self == Update::default()
    }
}

impl Snapshot {
    /// Applies an update, keeping every list within its bound: what a page does
    /// with the stream, so that a snapshot taken later equals the page's state.
    pub fn apply(&mut self, u: &Update) {
        if let Some(s) = &u.status {
            self.status = s.clone();
        }
        if let Some(n) = &u.now {
            self.now = Some(n.clone());
        }
        push_bounded(&mut self.trace, &u.trace, TRACE_ROWS);
        push_bounded(&mut self.drift, &u.drift, DRIFT_ROWS);
        push_bounded(&mut self.log, &u.log, LOG_ROWS);
        if let Some(b) = &u.brdf {
            self.brdf = b.clone();
        }
        if u.report.is_some() {
            self.report = u.report;
        }
    }
}

/// Appends `rows`, dropping the oldest beyond `cap`.
fn push_bounded<T: Clone>(q: &mut VecDeque<T>, rows: &[T], cap: usize) {
    q.extend(rows.iter().cloned());
    while q.len() > cap {
        q.pop_front();
    }
}
