//! The link between a session and its instrument, as a session sees it, and the
//! interface every running operation offers its pump ([`Operation`]).

use std::time::Duration;

use crate::FrameError;

/// Why an operation on the serial link failed, as a transport reports it and the
/// sessions' typed errors carry it.
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
    /// Bytes that make no frame of a binary protocol (line noise, a lost byte).
    #[error("garbled bytes on the line: {0}")]
    Garbled(&'static str),
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

impl TransportError {
    /// A lost, late, garbled or truncated line: sending the command again may cure it.
    pub fn is_transient(&self) -> bool {
        matches!(
            self,
            TransportError::Timeout(_)
                | TransportError::LineTooLong
                | TransportError::Garbled(_)
                | TransportError::Nul
        )
    }
}

impl From<FrameError> for TransportError {
    fn from(e: FrameError) -> Self {
        match e {
            FrameError::Nul => TransportError::Nul,
            FrameError::TooLong(_) => TransportError::LineTooLong,
            FrameError::Desync(why) => TransportError::Garbled(why),
        }
    }
}

/// I/O an operation asks of the link, from [`Operation::poll_io`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Io<'a> {
    /// Write these bytes (one command line, terminator included), then report the
    /// outcome with [`Operation::handle_sent`].
    Transmit(&'a [u8]),
    /// Discard everything received and not yet read, so that a late or partial reply
    /// is not taken for the next one. Needs no answer (a failure here changes nothing).
    ClearInput,
    /// Reopen the port after it vanished, then report the outcome with
    /// [`Operation::handle_reconnected`].
    Reconnect,
}

/// What an operation waits for, and until when, from [`Operation::poll_timeout`].
/// Every time is a `now` value: the time since the caller's arbitrary origin.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Deadline {
    /// A reply line is due by this time. Hand it in with
    /// [`handle_line`](Operation::handle_line), a link fault (including the link's own
    /// timeout) with [`handle_link_error`](Operation::handle_link_error), or, once the
    /// time has passed without a line, call [`handle_timeout`](Operation::handle_timeout).
    Reply(Duration),
    /// A pause between status polls, ending at this time, and an abort point: if the
    /// operator asked to abort, call [`handle_abort`](Operation::handle_abort) instead of
    /// waiting; otherwise wait until then and call
    /// [`handle_timeout`](Operation::handle_timeout).
    Poll(Duration),
    /// Nothing to do until this time (a settling wait, a reconnection delay, a
    /// controller booting): wait, then call [`handle_timeout`](Operation::handle_timeout).
    Sleep(Duration),
}

impl Deadline {
    /// The time it falls due.
    pub fn at(self) -> Duration {
        match self {
            Deadline::Reply(t) | Deadline::Poll(t) | Deadline::Sleep(t) => t,
        }
    }
}

/// One operation of a session (a move, a home search, a reading), running: a
/// deterministic state machine that does no I/O and reads no clock. Bytes, lines,
/// link faults and times are handed in; what to do next is polled out.
///
/// A caller (a *pump*) drives it in this order, until it has an output:
///
/// 1. [`poll_io`](Self::poll_io) until `None`, doing each [`Io`] and answering
///    [`Io::Transmit`] with [`handle_sent`](Self::handle_sent) and [`Io::Reconnect`] with
///    [`handle_reconnected`](Self::handle_reconnected) before polling again;
/// 2. [`poll_output`](Self::poll_output): `Some` ends the operation;
/// 3. [`poll_timeout`](Self::poll_timeout), which is then always `Some`: wait as its
///    [`Deadline`] says and hand in what happened with a `handle_*` call.
///
/// Each `handle_*` takes `now`, the time when the event happened (read after the I/O
/// it reports). A `handle_*` call that does not answer what the operation waits for is
/// ignored.
pub trait Operation {
    /// The operation's typed result.
    type Output;

    /// The next I/O to do, if any. A transmission or reconnection stays the answer
    /// until it is reported with `handle_sent` or `handle_reconnected`.
    fn poll_io(&mut self) -> Option<Io<'_>>;

    /// What the operation waits for, when it needs no I/O and has no output.
    fn poll_timeout(&self) -> Option<Deadline>;

    /// The result, once (and only once) the operation has finished.
    fn poll_output(&mut self) -> Option<Self::Output>;

    /// The outcome of an [`Io::Transmit`].
    fn handle_sent(&mut self, now: Duration, result: Result<(), TransportError>);

    /// The outcome of an [`Io::Reconnect`].
    fn handle_reconnected(&mut self, now: Duration, result: Result<(), TransportError>);

    /// A line received while a [`Deadline::Reply`] is pending, terminator removed.
    fn handle_line(&mut self, now: Duration, line: &[u8]);

    /// The link failed while a [`Deadline::Reply`] was pending: its own timeout, a NUL
    /// byte, an overlong line, a vanished port.
    fn handle_link_error(&mut self, now: Duration, error: TransportError);

    /// The pending deadline has passed: a reply that never came
    /// ([`TransportError::Timeout`] of the time waited), or the end of a pause.
    fn handle_timeout(&mut self, now: Duration);

    /// The operator asked to abort, at a [`Deadline::Poll`]: the session stops what it
    /// moves and the operation ends with its `Aborted` error.
    fn handle_abort(&mut self, now: Duration);
}

/// A message a line must carry at least every `every` for as long as it is open,
/// whatever else is going on: a session declares it (the APT controllers' "server
/// alive", [`AptSession::keepalive`](crate::apt::AptSession::keepalive)) and the pump
/// sends it from its clock, between and during the session's operations.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct KeepAlive {
    /// The message, as sent.
    pub bytes: Vec<u8>,
    /// How often it is sent: shorter than the longest gap the device allows (the
    /// session knows that; the APT manual's is a second, the session's period half).
    pub every: Duration,
    /// Its name, for the log.
    pub name: &'static str,
}
