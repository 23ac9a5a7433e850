//! The crate's integration tests, one binary (a module per file): linking one test
//! binary per file cost most of the suite's build time (TESTING.md).

mod albedo_quadrature;
mod columns_reader;
mod floors;
mod hemisphere;
mod interpolation;
mod limits;
mod loaders_never_panic;
mod properties;
mod samples;
mod separability;
mod sh;
