//! The run file: one SQLite database per run (`.gonio`), the unit that is archived,
//! resumed and reprocessed. Schema and guarantees in `docs/run-file.md`.
//!
//! - [`RunStore`]: opening (with every integrity check), creating atomically,
//!   committing a step whole, events, sessions, an adaptive plan's batches
//!   ([`RunStore::append_batch`], [`Batch`], [`DecisionRecord`]).
//! - [`RunMeta`]: the metadata, typed; [`create()`] builds it from a prepared plan.
//! - [`schema`]: tables, migrations, reading flags; [`records`]: rows as values.
//! - [`summary()`]: what `gonio show` prints.
//!
//! This is the only crate that depends on SQLite.

pub mod create;
mod error;
mod integrity;
mod lock;
pub mod meta;
pub mod records;
pub mod schema;
mod store;
mod summary;
mod time;

pub use create::{CreateError, Inputs, create};
pub use error::StoreError;
pub use integrity::Integrity;
pub use meta::{Estimate, RunMeta, RunStatus, keys};
pub use records::{
    Batch, Decision, DecisionRecord, EventRecord, ReadingRecord, SessionRow, StoredStep,
};
pub use schema::{APPLICATION_ID, SCHEMA_VERSION, flags};
pub use store::{ColumnValues, RunStore, is_run_file};
pub use summary::{BatchesSummary, STALE_NOTE, SessionSummary, Summary, status_now, summary};
pub use time::{utc, wall_now};
