//! The errors every motion family's session returns: [`AxisError`] on one axis and
//! [`MotionError`] naming it. They began as the SMC100's, whose controller-specific
//! variants they keep; the motion the families share is written once in the engine
//! (`engine::motion`).

pub use crate::smc100::{AxisError, MotionError};
