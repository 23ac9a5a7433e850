//! The Newport Cornerstone 130 monochromator: wavelength, grating, order-sorting
//! filter and shutter, with recovery from a lost port.
//!
//! [`Cs130`] owns the transport, the clock and the monochromator's session
//! ([`gonio_proto::cs130::Cs130Session`]); each method starts an operation on the
//! session and pumps it. The policy is the session's: [`Cs130::go_to`] refuses a
//! wavelength outside every grating's range, or one no order-sorting filter serves,
//! before any byte is sent; otherwise it changes grating and filter when they differ,
//! sends `GOWAVE`, waits for the move with `*WAI` and `WAVE?`, checks the status byte
//! and returns the wavelength read back.
//!
//! The serial port: CR LF lines (frame on LF), 9600 baud 8N1 without flow control
//! per the Cornerstone 260B manual's Table 1 (**UNCONFIRMED** for the CS130; see
//! [`gonio_proto::cs130`]). Every wait goes through the [`Clock`], so tests run on
//! virtual time.

pub use gonio_proto::cs130::{
    Command, ConfigError, Cs130Config, Cs130Error, ErrorCode, GratingSpec, MonoState,
    OrderFilterSpec, SelectError,
};
use gonio_proto::cs130::{Cs130Session, Reply};
use tracing::debug_span;

use crate::clock::Clock;
use crate::heartbeat::Heartbeat;
use crate::pump::{pump, pumped};
use crate::transport::Transport;

/// The Cornerstone 130 on a transport, waiting on a clock.
#[derive(Debug)]
pub struct Cs130<T: Transport, C: Clock> {
    transport: T,
    clock: C,
    /// The instrument's heartbeat, kept beating through every wait.
    beats: Heartbeat,
    session: Cs130Session,
    /// The port's name, for the wire log.
    port: String,
}

/// Runs one operation of the session: starts it with `$start` (a method of the
/// session, given the clock's now) and pumps it over the transport.
macro_rules! run {
    ($d:ident, $start:ident($($arg:expr),*)) => {{
        let now = $d.clock.now();
        let op = $d.session.$start($($arg,)* now);
        pump(pumped!($d), None, op)
    }};
}

impl<T: Transport, C: Clock> Cs130<T, C> {
    /// A driver for the monochromator on `transport`; nothing is sent until an
    /// operation. Fails if `config` does not [`validate`](Cs130Config::validate).
    pub fn new(transport: T, clock: C, config: Cs130Config) -> Result<Self, Cs130Error> {
        let port = transport.name();
        let session = Cs130Session::new(config, port.clone())?;
        Ok(Cs130 {
            transport,
            clock,
            beats: Heartbeat::new(),
            session,
            port,
        })
    }

    /// Joins `beats`, the instrument's heartbeat: every wait of this device keeps the
    /// instrument's keep-alives going.
    pub fn set_heartbeat(&mut self, beats: Heartbeat) {
        beats.absorb(&self.beats);
        self.beats = beats;
    }

    /// Identifies the instrument (`INFO?`), selects nanometres and reads every
    /// setting; see [`Cs130Session::start_init`].
    pub fn init(&mut self) -> Result<MonoState, Cs130Error> {
        let _span = debug_span!("cs130.init", port = %self.port).entered();
        run!(self, start_init())
    }

    /// Goes to `nm` and returns the state with the wavelength read back; see the
    /// module docs and [`Cs130Session::start_go`].
    pub fn go_to(&mut self, nm: f64) -> Result<MonoState, Cs130Error> {
        let _span = debug_span!("cs130.go_to", port = %self.port, nm).entered();
        run!(self, start_go(nm))
    }

    /// Opens or closes the shutter.
    pub fn shutter(&mut self, open: bool) -> Result<MonoState, Cs130Error> {
        let _span = debug_span!("cs130.shutter", port = %self.port, open).entered();
        run!(self, start_shutter(open))
    }

    /// Reads every setting back from the instrument.
    pub fn state(&mut self) -> Result<MonoState, Cs130Error> {
        let _span = debug_span!("cs130.state", port = %self.port).entered();
        run!(self, start_read_state())
    }

    /// Sends any statement and, for a query, reads its answer, with the session's
    /// link policy.
    pub fn execute(&mut self, command: &Command) -> Result<Option<Reply>, Cs130Error> {
        let _span = debug_span!("cs130.execute", port = %self.port, command = ?command).entered();
        run!(self, start_execute(command))
    }

    /// The state as last set or read, when every setting is known (no I/O).
    pub fn known_state(&self) -> Option<MonoState> {
        self.session.state()
    }

    /// What `INFO?` answered at init.
    pub fn info(&self) -> Option<&str> {
        self.session.info()
    }

    /// The configuration.
    pub fn config(&self) -> &Cs130Config {
        self.session.config()
    }

    /// How many times the port was reopened.
    pub fn reconnects(&self) -> usize {
        self.session.reconnects()
    }

    /// Statements sent again after a lost, late or garbled echo or answer.
    pub fn retried(&self) -> u64 {
        self.session.retried()
    }

    /// Hands back the transport and the clock.
    pub fn into_inner(self) -> (T, C) {
        (self.transport, self.clock)
    }
}
