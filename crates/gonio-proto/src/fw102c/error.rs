//! Why an operation on the wheel failed.

use std::time::Duration;

use super::{ConfigError, ErrorCode, ReplyError};
use crate::TransportError;

/// A failed wheel operation.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Fw102cError {
    /// The configuration is not usable.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// A position outside 1..=positions: refused before any byte was sent.
    #[error("filter wheel position {position} is not in 1..={positions}")]
    PositionOutOfRange {
        /// The position asked for.
        position: u8,
        /// The wheel's positions.
        positions: u8,
    },
    /// No band-pass filter is centred within the tolerance of the wavelength.
    #[error("no band-pass filter in the wheel is centred within {tolerance_nm} nm of {nm} nm")]
    NoFilterForBand {
        /// The channel's wavelength, nm.
        nm: f64,
        /// The tolerance, nm.
        tolerance_nm: f64,
    },
    /// No long-pass filter has its cut-on between half the wavelength and the
    /// wavelength.
    #[error("no long-pass filter in the wheel cuts on between {} and {nm} nm", nm / 2.0)]
    NoOrderSortingFilter {
        /// The channel's wavelength, nm.
        nm: f64,
    },
    /// No position holds an opaque blank.
    #[error("no dark (opaque) position is configured in the filter wheel")]
    NoDarkPosition,
    /// `*idn?` named another instrument.
    #[error("{port}: not a Thorlabs FW102C/FW212C filter wheel: {identity:?}")]
    NotAFilterWheel {
        /// The port.
        port: String,
        /// What it answered.
        identity: String,
    },
    /// `pcount?` does not match the configured wheel.
    #[error("the wheel's firmware counts {device} positions (pcount?), the config says {config}")]
    PositionCountMismatch {
        /// The config's `positions`.
        config: u8,
        /// What `pcount?` answered.
        device: u8,
    },
    /// A setting read back differs from what was set.
    #[error("{command} was not applied: the wheel reads back {read}")]
    NotApplied {
        /// The set command.
        command: String,
        /// What the query answered.
        read: String,
    },
    /// The wheel answered `Command error ...`.
    #[error("the wheel refused {command}: Command error {code}")]
    Refused {
        /// The command refused.
        command: String,
        /// Its code.
        code: ErrorCode,
    },
    /// A line that is neither the echo, nor a value, nor an error.
    #[error(
        "unexpected reply to {command}: {:?} ({source})",
        String::from_utf8_lossy(reply)
    )]
    Protocol {
        /// The command.
        command: String,
        /// The line.
        reply: Vec<u8>,
        /// What is wrong with it.
        source: ReplyError,
    },
    /// The link failed during a command.
    #[error("{command}: {source}")]
    Transport {
        /// The command.
        command: String,
        /// The fault.
        source: TransportError,
    },
    /// The port vanished and could not be reopened.
    #[error("port {port} lost and not reopened after {attempts} attempts: {source}")]
    Disconnected {
        /// The port.
        port: String,
        /// Reopenings tried.
        attempts: u32,
        /// The last fault.
        source: TransportError,
    },
    /// The wheel did not read the position asked for within the move timeout.
    #[error("the wheel did not reach position {position} within {waited:?} (last read {last:?})")]
    MoveTimeout {
        /// The position asked for.
        position: u8,
        /// The last position `pos?` answered, if any.
        last: Option<u8>,
        /// How long the session waited.
        waited: Duration,
    },
}
