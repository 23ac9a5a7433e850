//! One module a command (or a group of subcommands): each defines its arguments as
//! one `clap::Args` struct and a `run` that takes it.

pub mod acquire;
pub mod check;
pub mod correct;
pub mod demo;
pub mod export;
pub mod fit;
pub mod harmonics;
pub mod instrument;
pub mod micro;
pub mod model;
pub mod plan;
pub mod plot;
pub mod reduce;
pub mod report;
pub mod runs;
pub mod verify;
