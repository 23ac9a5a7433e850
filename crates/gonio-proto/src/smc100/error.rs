//! What a motion operation returns: its typed errors (shared by every motion family,
//! see `crate::motion`) and what an SMC100's start-up learns.

use std::time::Duration;

use super::{ControllerState, ErrorCode, PositionerErrors};
use crate::TransportError;

/// Why an operation on one axis failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AxisError {
    /// The link failed (timeout, vanished port, bad framing).
    #[error("{0}")]
    Transport(#[from] TransportError),
    /// The controller refused a command: its `TE` letter.
    #[error("controller refused `{command}`: error {code}")]
    Controller {
        /// The command line sent, without terminator.
        command: String,
        /// The error letter.
        code: ErrorCode,
    },
    /// A reply that is not a reply to what was asked.
    #[error("bad reply to `{sent}`: {reply:?} ({reason})")]
    Protocol {
        /// The command line sent.
        sent: String,
        /// The reply received.
        reply: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A target outside the axis' limits; nothing was sent.
    #[error(
        "target {target} {units} is outside the limits [{min}, {max}] {units}; nothing was sent"
    )]
    OutOfLimits {
        /// The refused target.
        target: f64,
        /// Lower limit.
        min: f64,
        /// Upper limit.
        max: f64,
        /// Units.
        units: String,
    },
    /// The controller lost its reference (state NOT REFERENCED) where it should have had it.
    #[error("controller is NOT REFERENCED (state {state}); home it again")]
    NotReferenced {
        /// The state reported.
        state: ControllerState,
    },
    /// The controller restarted (state `0A` mid-run, or a NUL byte on the line: power loss).
    #[error("controller was reset or lost power; home it again")]
    ControllerReset,
    /// The controller disabled the motor (e.g. a following error).
    #[error("controller went to DISABLE (state {state}, errors {errors:04X})")]
    Disabled {
        /// The state reported.
        state: ControllerState,
        /// The positioner error bits seen.
        errors: u16,
    },
    /// The home search ended without reaching READY.
    #[error("home search failed (state {state}, errors {errors:04X})")]
    HomingFailed {
        /// The state reported.
        state: ControllerState,
        /// The positioner error bits seen.
        errors: u16,
    },
    /// The state does not allow the operation (CONFIGURATION, JOGGING).
    #[error("controller is in state {state}, which does not allow {operation}")]
    WrongState {
        /// The state reported.
        state: ControllerState,
        /// What was attempted.
        operation: &'static str,
    },
    /// A move or home search did not finish in time; the stage was stopped.
    #[error(
        "{operation} did not finish within {waited:?} (target {target}, at {position:?}); stopped"
    )]
    Timeout {
        /// `move` or `home`.
        operation: &'static str,
        /// The target.
        target: f64,
        /// The position read after stopping, if it could be read.
        position: Option<f64>,
        /// How long was waited.
        waited: Duration,
    },
    /// The move ended away from its target.
    #[error("stage stopped at {position}, {} from its target {target} (tolerance {tolerance})", (position - target).abs())]
    TargetNotReached {
        /// The target.
        target: f64,
        /// Where the stage is.
        position: f64,
        /// The tolerance.
        tolerance: f64,
    },
    /// A non-idempotent command's acknowledgement was lost: it may or may not have run,
    /// and it must not be re-sent. The stage was stopped.
    #[error("lost the acknowledgement of `{command}`, which must not be re-sent; stage stopped")]
    Ambiguous {
        /// The command line.
        command: String,
    },
    /// The stage has no reference (a family whose status says so with a bit, such as
    /// Thorlabs APT's "homed"): home it again.
    #[error("stage is not homed; home it again")]
    NotHomed,
    /// The controller reported a fault in its own terms (an APT error response, a
    /// limit switch hit, a motor error bit).
    #[error("controller fault after `{command}`: {reason}")]
    Device {
        /// What was sent, by name.
        command: String,
        /// What the controller reported.
        reason: String,
    },
    /// The operation was aborted; the stages were stopped.
    #[error("aborted; stages stopped")]
    Aborted,
    /// A configuration change the controller would refuse (not a configuration
    /// parameter, or a value outside the manual's range); nothing was sent.
    #[error(
        "`{code}{value}` is not a configuration the controller accepts ({reason}); nothing was sent"
    )]
    InvalidSetting {
        /// The parameter's command code.
        code: &'static str,
        /// The refused value.
        value: f64,
        /// Why.
        reason: &'static str,
    },
}

impl AxisError {
    /// `target` within `min..=max` (and finite), checked before any byte is sent;
    /// else [`AxisError::OutOfLimits`] in `units`.
    pub(crate) fn check_limits(target: f64, min: f64, max: f64, units: &str) -> Result<(), Self> {
        if target.is_finite() && target >= min && target <= max {
            Ok(())
        } else {
            Err(AxisError::OutOfLimits {
                target,
                min,
                max,
                units: units.into(),
            })
        }
    }
}

/// An error on a named axis.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MotionError {
    /// Something failed on this axis.
    #[error("axis {axis}: {source}")]
    AtAxis {
        /// The axis' name.
        axis: String,
        /// What failed.
        #[source]
        source: AxisError,
    },
    /// No axis has this name.
    #[error("no axis named {0:?}")]
    UnknownAxis(String),
    /// The chain configuration is not usable.
    #[error("chain configuration: {0}")]
    Config(String),
}

/// What the driver learnt about a controller at start-up.
#[derive(Clone, Debug, PartialEq)]
pub struct ControllerInfo {
    /// The `VE` text.
    pub version: String,
    /// The `ID?` stage name.
    pub stage: String,
    /// The state found.
    pub state: ControllerState,
}

/// A positioner error word's named bits, for messages.
pub fn describe_errors(e: PositionerErrors) -> Vec<&'static str> {
    crate::codec::bit_names(e.0, PositionerErrors::NAMES)
}

impl crate::engine::motion::AxisFault for AxisError {
    fn aborted() -> Self {
        AxisError::Aborted
    }

    fn overdue(
        operation: &'static str,
        target: f64,
        position: Option<f64>,
        waited: Duration,
    ) -> Self {
        AxisError::Timeout {
            operation,
            target,
            position,
            waited,
        }
    }
}

/// Why a motion of either family ended early (`engine::motion`).
pub(crate) type Halt = crate::engine::motion::Halt<AxisError, MotionError>;

/// An axis' failure during a motion, which stops every stage.
pub(crate) fn stop(axis: usize) -> impl FnOnce(AxisError) -> Halt {
    move |e| Halt::Stop(axis, e)
}
