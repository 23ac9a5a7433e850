//! The crate's integration tests, one binary (a module per file): linking one test
//! binary per file cost most of the suite's build time (TESTING.md).

mod cs130;
mod fw102c;
mod goniometer;
mod hardware;
mod k6485;
mod loaders_never_panic;
mod pty;
mod smc100;
mod sr830;
mod wire_log;
