//! Rows as Rust values, and the row checksum that catches a damaged value.

use rusqlite::types::Value;

use gonio_core::dirfile::PairDeg;
use gonio_plan::schedule::Step;

#[allow(unused_imports)] // the doc links
use crate::schema::flags;

/// One reading as stored.
#[derive(Clone, Debug, PartialEq)]
pub struct ReadingRecord {
    /// The step it measures.
    pub step_id: i64,
    /// Stage targets commanded, role order (none when the step does not move).
    pub commanded: Option<[f64; 4]>,
    /// Stage positions read back, role order.
    pub position: [f64; 4],
    /// The directions the read-back positions mean, degrees.
    pub read_pair: PairDeg,
    /// `SENS` index.
    pub sensitivity: u8,
    /// Full scale, V.
    pub sensitivity_v: f64,
    /// `OFLT` index.
    pub time_constant: u8,
    /// Time constant, s.
    pub time_constant_s: f64,
    /// Filter slope, dB/oct.
    pub slope_db: u8,
    /// Mean R, V.
    pub r_mean: f64,
    /// Standard deviation of R, V.
    pub r_std: f64,
    /// Mean X, V.
    pub x_mean: f64,
    /// Mean Y, V.
    pub y_mean: f64,
    /// Samples.
    pub n: u32,
    /// Range changes before the reading.
    pub autorange_steps: u32,
    /// The raw `LIAS?` byte.
    pub lias: u8,
    /// [`flags`] bits.
    pub flags: u32,
    /// Exchanges retried while taking this step.
    pub retries: u64,
    /// Instrument clock at the reading, s since the session started.
    pub physical_s: f64,
    /// Wall clock, Unix seconds.
    pub wall_s: f64,
}

/// A stored step with its state.
#[derive(Clone, Debug, PartialEq)]
pub struct StoredStep {
    /// Its id (position in the schedule).
    pub id: i64,
    /// The step.
    pub step: Step,
    /// `pending`, `done` or `failed`.
    pub state: String,
    /// Times it was attempted.
    pub attempts: u32,
}

/// A session (one process working on the run) as stored.
#[derive(Clone, Debug, PartialEq)]
pub struct SessionRow {
    /// Its id.
    pub id: i64,
    /// Start, Unix seconds.
    pub started_s: f64,
    /// End, Unix seconds (none: killed, or still running).
    pub ended_s: Option<f64>,
    /// `complete`, `interrupted` or `faulted`.
    pub outcome: Option<String>,
}

/// An event as stored.
#[derive(Clone, Debug, PartialEq)]
pub struct EventRecord {
    /// Wall clock, Unix seconds.
    pub wall_s: f64,
    /// `start`, `resume`, `rehome`, `retry`, `fault`, `interrupt`, `stop`, ...
    pub kind: String,
    /// The step concerned.
    pub step_id: Option<i64>,
    /// What happened.
    pub message: String,
}

/// What an adaptive plan's planner decided: the points it chose and why. The run
/// file keeps it with the steps it added, without interpreting `detail`.
#[derive(Clone, Debug, PartialEq)]
pub struct Decision {
    /// How the points were chosen (the planner's name for its criterion).
    pub method: String,
    /// Sample geometry points chosen (a point may take several steps: bands,
    /// repeats, references).
    pub points: u32,
    /// The planner's account of each point, JSON text.
    pub detail: String,
}

/// A batch of steps an adaptive plan's planner appends to the run, with the decision
/// that chose them.
#[derive(Clone, Debug, PartialEq)]
pub struct Batch {
    /// Why.
    pub decision: Decision,
    /// The steps, in the order they are to be taken.
    pub steps: Vec<Step>,
}

/// One row of the `decisions` table: a batch as stored.
#[derive(Clone, Debug, PartialEq)]
pub struct DecisionRecord {
    /// The batch's number: 1, 2, … in the order they were appended.
    pub id: i64,
    /// The session that appended it.
    pub session: Option<i64>,
    /// When, Unix seconds.
    pub wall_s: f64,
    /// Id of its first step; its steps are `first_step .. first_step + steps`.
    pub first_step: i64,
    /// Steps appended.
    pub steps: u32,
    /// Sample geometry points chosen ([`Decision::points`]).
    pub points: u32,
    /// [`Decision::method`].
    pub method: String,
    /// Readings committed when the decision was made: the data it was made from.
    pub readings: u64,
    /// The integrity record of those readings, `COUNT:DIGEST` (as the `meta` row
    /// `integrity_readings` stood): which data, not only how many.
    pub digest: String,
    /// [`Decision::detail`], JSON text.
    pub detail: String,
}

/// FNV-1a, 64 bits: the checksum of a row (corruption, not tampering, is the threat).
fn fnv1a(h: &mut u64, bytes: &[u8]) {
    for b in bytes {
        *h ^= u64::from(*b);
        *h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
}

/// Checksum of a row's values, type tags included (NULL differs from 0).
pub(crate) fn row_crc(values: &[Value]) -> i64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for v in values {
        match v {
            Value::Null => fnv1a(&mut h, &[0]),
            Value::Integer(i) => {
                fnv1a(&mut h, &[1]);
                fnv1a(&mut h, &i.to_le_bytes());
            }
            Value::Real(x) => {
                fnv1a(&mut h, &[2]);
                // SQLite keeps −0.0 as 0 (an integral REAL is stored as an integer).
                let x = if *x == 0.0 { 0.0 } else { *x };
                fnv1a(&mut h, &x.to_bits().to_le_bytes());
            }
            Value::Text(s) => {
                fnv1a(&mut h, &[3]);
                fnv1a(&mut h, &(s.len() as u64).to_le_bytes());
                fnv1a(&mut h, s.as_bytes());
            }
            Value::Blob(b) => {
                fnv1a(&mut h, &[4]);
                fnv1a(&mut h, &(b.len() as u64).to_le_bytes());
                fnv1a(&mut h, b);
            }
        }
    }
    h as i64
}

fn opt(x: Option<f64>) -> Value {
    x.map_or(Value::Null, real)
}

/// A REAL value; SQLite has no NaN or infinity (it would store NULL), so a
/// non-finite number is stored as NULL and read back as NaN.
fn real(x: f64) -> Value {
    if x.is_finite() {
        Value::Real(x)
    } else {
        Value::Null
    }
}

pub(crate) fn step_values(id: i64, s: &Step) -> Vec<Value> {
    let pair = s.pair.map(|p| {
        [
            p.incident.theta_deg,
            p.incident.phi_deg,
            p.outgoing.theta_deg,
            p.outgoing.phi_deg,
        ]
    });
    let mut v = vec![
        Value::Integer(id),
        Value::Text(s.kind.as_str().into()),
        s.channel.clone().map_or(Value::Null, Value::Text),
        Value::Integer(i64::from(s.repeat)),
        s.plan_index
            .map_or(Value::Null, |i| Value::Integer(i as i64)),
    ];
    for k in 0..4 {
        v.push(opt(pair.map(|p| p[k])));
    }
    for k in 0..4 {
        v.push(opt(s.stages.map(|p| p[k])));
    }
    v
}

pub(crate) fn reading_values(r: &ReadingRecord, session: i64) -> Vec<Value> {
    let mut v = vec![Value::Integer(r.step_id), Value::Integer(session)];
    for k in 0..4 {
        v.push(opt(r.commanded.map(|c| c[k])));
    }
    for k in 0..4 {
        v.push(real(r.position[k]));
    }
    let p = &r.read_pair;
    for x in [
        p.incident.theta_deg,
        p.incident.phi_deg,
        p.outgoing.theta_deg,
        p.outgoing.phi_deg,
    ] {
        v.push(real(x));
    }
    v.extend([
        Value::Integer(i64::from(r.sensitivity)),
        real(r.sensitivity_v),
        Value::Integer(i64::from(r.time_constant)),
        real(r.time_constant_s),
        Value::Integer(i64::from(r.slope_db)),
        real(r.r_mean),
        real(r.r_std),
        real(r.x_mean),
        real(r.y_mean),
        Value::Integer(i64::from(r.n)),
        Value::Integer(i64::from(r.autorange_steps)),
        Value::Integer(i64::from(r.lias)),
        Value::Integer(i64::from(r.flags)),
        Value::Integer(r.retries as i64),
        real(r.physical_s),
        real(r.wall_s),
    ]);
    v
}

pub(crate) fn decision_values(d: &DecisionRecord) -> Vec<Value> {
    vec![
        Value::Integer(d.id),
        d.session.map_or(Value::Null, Value::Integer),
        real(d.wall_s),
        Value::Integer(d.first_step),
        Value::Integer(i64::from(d.steps)),
        Value::Integer(i64::from(d.points)),
        Value::Text(d.method.clone()),
        Value::Integer(d.readings as i64),
        Value::Text(d.digest.clone()),
        Value::Text(d.detail.clone()),
    ]
}
