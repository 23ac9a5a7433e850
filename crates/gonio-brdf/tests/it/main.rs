//! The crate's integration tests, one binary (a module per file): linking one test
//! binary per file cost most of the suite's build time (TESTING.md).

mod albedo;
mod closed_forms;
mod common;
mod loaders_never_panic;
mod model_files;
mod reciprocity;
mod sampling;
