//! Acquisition: measurement plans checked against the instrument, ordered for least
//! motion, taken step by step by an async engine into a crash-safe run file.
//!
//! - [`plan`]: plan files, their expansion into direction pairs, and the check of
//!   every pair against the stages' limits and the optical geometry.
//! - [`order`]: the visiting order that minimises motion time.
//! - [`schedule`]: the steps of a run (channels, repeats, drift references,
//!   calibrations), fixed when the run is created.
//! - [`store`]: the run file (SQLite).
//! - [`engine`]: the run engine; [`bench`]: what changes the light path between kinds
//!   of readings.
//! - [`run`]: creating and resuming runs, the glue the CLI calls.

pub mod bench;
pub mod engine;
pub mod order;
pub mod plan;
pub mod run;
pub mod schedule;
pub mod store;
