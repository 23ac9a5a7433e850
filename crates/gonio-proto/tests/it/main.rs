//! The crate's integration tests, one binary (a module per file): linking one test
//! binary per file cost most of the suite's build time (TESTING.md).

mod apt;
mod codecs;
mod cs130;
mod cs130_config;
mod cs130_session;
mod fw102c;
mod fw102c_config;
mod fw102c_session;
mod k6485;
mod smc100;
mod sr830;
mod sr830_buffer;
mod sr830_target;
mod unconfirmed;
