//! The wheel's policy as a sans-IO state machine: [`Fw102cSession`].
//!
//! `ops` holds the exchange (a command, its echo and value) and the operations
//! (set-up, a move, a position read), each an `async fn` the engine runs.

mod ops;

use super::{Fw102cConfig, Fw102cError};
use crate::engine::Task;
use std::time::Duration;

/// The FW102C as a state machine: its configuration, the position it last read, and
/// every decision of its operations. It does no I/O and reads no clock.
///
/// ```
/// use std::time::Duration;
/// use gonio_proto::fw102c::{Fw102cConfig, Fw102cSession, Fw102cError};
/// use gonio_proto::link::{Io, Operation};
///
/// let mut session = Fw102cSession::new(Fw102cConfig::default(), "sim").unwrap();
/// // Position 7 on a 6-position wheel: refused before any byte.
/// let mut op = session.start_select(7, Duration::ZERO);
/// assert_eq!(op.poll_io(), None);
/// assert!(matches!(op.poll_output(), Some(Err(Fw102cError::PositionOutOfRange { .. }))));
/// drop(op);
/// let mut op = session.start_select(2, Duration::ZERO);
/// assert_eq!(op.poll_io(), Some(Io::Transmit(b"pos=2\r")));
/// ```
///
/// `gonio_driver::fw102c::Fw102c` is the pump that runs these operations over a port.
#[derive(Clone, Debug, PartialEq)]
pub struct Fw102cSession {
    config: Fw102cConfig,
    /// The port's name, for errors.
    port: String,
    /// The position last read, `None` while unknown (during a move, after a fault).
    position: Option<u8>,
    identity: Option<String>,
    reconnects: usize,
    retried: u64,
}

impl Fw102cSession {
    /// A session for the wheel on `port` (its name, for errors); nothing is sent until
    /// an operation starts. Fails if `config` does not validate.
    pub fn new(config: Fw102cConfig, port: impl Into<String>) -> Result<Self, Fw102cError> {
        config.validate()?;
        Ok(Fw102cSession {
            config,
            port: port.into(),
            position: None,
            identity: None,
            reconnects: 0,
            retried: 0,
        })
    }

    /// Takes the wheel over: `*idn?` (must name a FW102C or FW212C), `pcount?` (must
    /// equal `positions`), `speed=` and `speed?`, with `sensors_off_when_idle`
    /// `sensors=0` and `sensors?`, then `pos?`. Each set is read back, because a set
    /// command's success has no line of its own (see [`crate::fw102c`]). Returns the
    /// identification string.
    pub fn start_init(&mut self, now: Duration) -> Task<'_, String, Fw102cError> {
        Task::new(
            "fw102c.init",
            now,
            |link| async move { self.init(&link).await },
        )
    }

    /// Turns the wheel to `position`: refused before any byte outside
    /// 1..=`positions`; then `pos=n` and `pos?` every `poll_interval_ms` until it reads
    /// n, for at most `move_timeout_ms` ([`Fw102cError::MoveTimeout`]).
    pub fn start_select(&mut self, position: u8, now: Duration) -> Task<'_, (), Fw102cError> {
        Task::new("fw102c.select", now, move |link| async move {
            self.select(&link, position).await
        })
    }

    /// `pos?`.
    pub fn start_read_position(&mut self, now: Duration) -> Task<'_, u8, Fw102cError> {
        Task::new("fw102c.position", now, |link| async move {
            self.read_position(&link).await
        })
    }

    /// The configuration.
    pub fn config(&self) -> &Fw102cConfig {
        &self.config
    }

    /// The position last read, `None` while unknown.
    pub fn position(&self) -> Option<u8> {
        self.position
    }

    /// The identification string set-up read, once it has run.
    pub fn identity(&self) -> Option<&str> {
        self.identity.as_deref()
    }

    /// How many times the port was reopened.
    pub fn reconnects(&self) -> usize {
        self.reconnects
    }

    /// Commands sent again after a lost, late or garbled answer.
    pub fn retried(&self) -> u64 {
        self.retried
    }
}
