//! The crate's integration tests, one binary (a module per file): linking one test
//! binary per file cost most of the suite's build time (TESTING.md).

mod acquire;
mod adaptive;
mod adaptive_report;
mod budget;
mod check_tables;
mod cli;
mod colour;
mod common;
mod dc_reduce;
mod estimates;
mod fit;
mod fit_objective;
mod half_turn;
mod hostile;
mod instruments;
mod io;
mod live_browser;
mod live_http;
mod loaders;
mod logs;
mod micro;
mod plan_spectral;
mod process;
mod reading_time;
mod reliability;
mod serve;
mod spectral;
mod spectral_outputs;
