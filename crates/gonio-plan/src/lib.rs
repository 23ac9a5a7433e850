//! Measurement plans, checked and ordered before anything moves.
//!
//! - [`plan`]: plan files, their expansion into direction pairs, and the check of
//!   every pair through the instrument's inverse kinematics against the stages'
//!   limits and the optical geometry.
//! - [`order`]: the visiting order that minimises motion time.
//! - [`schedule`]: the steps of a run (channels, repeats, drift references,
//!   calibrations), fixed when the run is created; with several bands, which of
//!   wavelength and geometry is the inner loop, and why.
//! - [`prepare()`]: all three on one instrument, with the estimates.
//!
//! Pure: the instrument comes in as a [`gonio_core::goniometer::Mechanics`] value,
//! so this crate knows nothing of serial ports, controllers, run files or clocks.

pub mod adaptive;
pub mod order;
pub mod plan;
mod prepare;
pub mod schedule;

pub use plan::{Checked, Inner, Mechanics, Plan, ReadingConfig, Rejection, Wavelengths};
pub use prepare::{PrepareError, Prepared, prepare, rejection_counts};
pub use schedule::{Loop, LoopEstimate, Schedule, SpectralDecision, Step, StepKind};
