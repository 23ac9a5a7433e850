//! The crate's integration tests, one binary (a module per file): linking one test
//! binary per file cost most of the suite's build time (TESTING.md).

mod apt;
mod config;
mod config_mode;
mod controller;
mod e2e;
mod faults;
mod filterwheel;
mod filterwheel_twin;
mod loaders_never_panic;
mod lockin;
mod lockin_buffer;
mod mixed;
mod monochromator;
mod optics;
mod picoammeter;
mod process;
mod samples;
mod session_rig;
mod sessions_detector;
mod sessions_motion;
mod spectral;
mod step_times;
