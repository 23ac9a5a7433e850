//! The link between a session and an instrument: the errors a serial line reports.

use std::time::Duration;

use crate::FrameError;

/// Why an operation on the serial link failed: what a transport reports to the pump
/// and the pump hands to a session (`handle_sent`, `handle_link_error`), and what the
/// sessions' typed errors carry.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TransportError {
    /// No complete line arrived in time.
    #[error("no reply within {0:?}")]
    Timeout(Duration),
    /// A NUL byte arrived (an SMC100 that lost power sends one).
    #[error("NUL byte received (instrument power loss?)")]
    Nul,
    /// A line longer than the protocol allows, without a terminator.
    #[error("reply line too long (garbage on the line?)")]
    LineTooLong,
    /// The port is gone (unplugged adapter, closed pseudo-terminal) or cannot be opened.
    #[error("port {port} unavailable: {reason}")]
    Disconnected {
        /// The port path.
        port: String,
        /// What the OS said.
        reason: String,
    },
    /// A scripted test transport saw something other than its script.
    #[error("script: {0}")]
    Script(String),
}

impl From<FrameError> for TransportError {
    fn from(e: FrameError) -> Self {
        match e {
            FrameError::Nul => TransportError::Nul,
            FrameError::TooLong(_) => TransportError::LineTooLong,
        }
    }
}
