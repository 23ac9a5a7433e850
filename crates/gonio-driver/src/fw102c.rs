//! The Thorlabs FW102C (FW212C) motorized filter wheel: the filter-based bands of a
//! spectral run, order sorting, and a dark blank as a shutter.
//!
//! [`Fw102c`] owns the transport, the clock and the wheel's session
//! ([`gonio_proto::fw102c::Fw102cSession`]); each method starts an operation on the
//! session and pumps it. The policy is the session's: [`Fw102c::init`] identifies the
//! wheel, checks its position count against the config, sets and reads back the speed
//! (and switches the position sensors off while idle); [`Fw102c::select`] refuses a
//! position outside the wheel before any byte, sends `pos=n` and polls `pos?` until
//! it reads n. The filter lookups ([`Fw102c::select_band`],
//! [`Fw102c::select_order_sorting`], [`Fw102c::select_dark`]) are the config's.
//!
//! The serial port: 115200 baud, 8N1, no flow control, lines cut at CR (see
//! [`gonio_proto::fw102c`]; UNCONFIRMED against the manual). Every wait goes through
//! the [`Clock`], so tests run on virtual time.

use gonio_proto::fw102c::Fw102cSession;
pub use gonio_proto::fw102c::{
    ConfigError, DEFAULT_BAND_TOLERANCE_NM, Filter, Fw102cConfig, Fw102cError, Speed,
};
use tracing::debug_span;

use crate::clock::Clock;
use crate::heartbeat::Heartbeat;
use crate::pump::{pump, pumped};
use crate::transport::Transport;

/// The wheel on a transport, waiting on a clock.
#[derive(Debug)]
pub struct Fw102c<T: Transport, C: Clock> {
    transport: T,
    clock: C,
    /// The instrument's heartbeat, kept beating through every wait.
    beats: Heartbeat,
    session: Fw102cSession,
    /// The port's name, for the wire log.
    port: String,
}

/// Runs one operation of the session, started with the clock's now.
macro_rules! run {
    ($d:ident, $start:ident($($arg:expr),*)) => {{
        let now = $d.clock.now();
        let op = $d.session.$start($($arg,)* now);
        pump(pumped!($d), None, op)
    }};
}

impl<T: Transport, C: Clock> Fw102c<T, C> {
    /// A driver for the wheel on `transport`; nothing is sent until an operation.
    /// Fails if `config` does not validate.
    pub fn new(transport: T, clock: C, config: Fw102cConfig) -> Result<Self, Fw102cError> {
        let port = transport.name();
        let session = Fw102cSession::new(config, port.clone())?;
        Ok(Fw102c {
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

    /// Identifies and configures the wheel; returns its identification string. See
    /// [`Fw102cSession::start_init`].
    pub fn init(&mut self) -> Result<String, Fw102cError> {
        let _span = debug_span!("fw102c.init", port = %self.port).entered();
        run!(self, start_init())
    }

    /// Turns the wheel to `position` (1-based) and returns once `pos?` reads it.
    pub fn select(&mut self, position: u8) -> Result<(), Fw102cError> {
        let _span = debug_span!("fw102c.select", port = %self.port, position).entered();
        run!(self, start_select(position))
    }

    /// Selects the band-pass filter for a channel at `nm` (see
    /// [`Fw102cConfig::position_for_band`]); returns its position. Nothing is sent if
    /// no filter matches.
    pub fn select_band(&mut self, nm: f64) -> Result<u8, Fw102cError> {
        let config = self.session.config();
        let position = config
            .position_for_band(nm)
            .ok_or(Fw102cError::NoFilterForBand {
                nm,
                tolerance_nm: config.band_tolerance_nm,
            })?;
        self.select(position)?;
        Ok(position)
    }

    /// Selects the long-pass filter that sorts orders at `nm` (see
    /// [`Fw102cConfig::position_for_order_sorting`]); returns its position.
    pub fn select_order_sorting(&mut self, nm: f64) -> Result<u8, Fw102cError> {
        let position = self
            .session
            .config()
            .position_for_order_sorting(nm)
            .ok_or(Fw102cError::NoOrderSortingFilter { nm })?;
        self.select(position)?;
        Ok(position)
    }

    /// Turns the opaque blank into the beam (the wheel as a shutter); returns its
    /// position.
    pub fn select_dark(&mut self) -> Result<u8, Fw102cError> {
        let position = self
            .session
            .config()
            .dark_position()
            .ok_or(Fw102cError::NoDarkPosition)?;
        self.select(position)?;
        Ok(position)
    }

    /// Reads the position (`pos?`).
    pub fn position(&mut self) -> Result<u8, Fw102cError> {
        let _span = debug_span!("fw102c.position", port = %self.port).entered();
        run!(self, start_read_position())
    }

    /// The position last read, without asking; `None` while unknown.
    pub fn last_position(&self) -> Option<u8> {
        self.session.position()
    }

    /// The configuration.
    pub fn config(&self) -> &Fw102cConfig {
        self.session.config()
    }

    /// The identification string `init` read, once it has run.
    pub fn identity(&self) -> Option<&str> {
        self.session.identity()
    }

    /// How many times the port was reopened.
    pub fn reconnects(&self) -> usize {
        self.session.reconnects()
    }

    /// Commands sent again after a lost, late or garbled answer.
    pub fn retried(&self) -> u64 {
        self.session.retried()
    }

    /// Hands back the transport and the clock.
    pub fn into_inner(self) -> (T, C) {
        (self.transport, self.clock)
    }
}
