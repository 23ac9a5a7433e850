//! Acquisition: the run engine that takes a run file's pending steps through a
//! goniometer, commits each reading as it is taken, and recovers from faults.
//!
//! - [`engine`]: the async engine, its fault policy, its events.
//! - [`stored()`]: a run file's instrument config and simulator, parsed back.
//!
//! Plans come from `gonio-plan`, the run file from `gonio-run`, the instrument from
//! `gonio-driver`; nothing here knows whether the instrument is real or simulated.

pub mod engine;
mod stored;

pub use engine::{
    Engine, EngineConfig, EngineError, Event, Outcome, Pauser, Planner, SessionReport, Stopper,
};
pub use stored::{Stored, stored};
