//! The monochromator's policy as a sans-IO state machine: [`Cs130Session`].
//!
//! `ops` holds the exchange (a statement, its echo and answer, the hold after
//! `*WAI`) and the operations (set-up, a move, the shutter, a read-back), each an
//! `async fn` the engine runs.

mod ops;

use std::time::Duration;

use super::{Command, Cs130Config, Cs130Error, MonoState, NO_FILTER_WHEEL};
use crate::engine::Task;

/// What the session knows the instrument is set to; `None` until read or set.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Known {
    pub(crate) wavelength_nm: Option<f64>,
    pub(crate) grating: Option<u8>,
    pub(crate) filter: Option<u8>,
    pub(crate) shutter_open: Option<bool>,
}

impl Known {
    /// Nothing known, except the filter position of a unit without a wheel, which
    /// never changes and is never asked (`FILTER?` would flag an error, Model 74000
    /// command table).
    fn fresh(filter_wheel: bool) -> Self {
        Known {
            filter: (!filter_wheel).then_some(NO_FILTER_WHEEL),
            ..Known::default()
        }
    }

    fn state(&self) -> Option<MonoState> {
        Some(MonoState {
            wavelength_nm: self.wavelength_nm?,
            grating: self.grating?,
            filter: self.filter?,
            shutter_open: self.shutter_open?,
        })
    }
}

/// The Cornerstone 130 as a state machine: its configuration, what it is set to as far
/// as the session knows, whether a `*WAI` holds it, and every decision of its
/// operations. It does no I/O and reads no clock.
///
/// Each `start_*` method starts an [`Operation`](crate::link::Operation) that borrows the session until it
/// finishes; see [`Operation`](crate::link::Operation) for the order in which a caller drives it:
///
/// ```
/// use std::time::Duration;
/// use gonio_proto::link::{Io, Operation};
/// use gonio_proto::cs130::{Cs130Config, Cs130Error, Cs130Session};
///
/// let mut session = Cs130Session::new(Cs130Config::default(), "sim").unwrap();
/// // Outside every grating's range: refused before any byte.
/// let mut op = session.start_go(2500.0, Duration::ZERO);
/// assert_eq!(op.poll_io(), None);
/// assert!(matches!(op.poll_output(), Some(Err(Cs130Error::Select(_)))));
/// drop(op);
/// let mut op = session.start_shutter(false, Duration::ZERO);
/// assert_eq!(op.poll_io(), Some(Io::Transmit(b"SHUTTER C\r\n")));
/// ```
///
/// `gonio_driver::cs130::Cs130` is the pump that runs these operations over a serial
/// port.
#[derive(Clone, Debug, PartialEq)]
pub struct Cs130Session {
    config: Cs130Config,
    /// The port's name, for errors.
    port: String,
    known: Known,
    /// A `*WAI` or a statement that moves was echoed and no query has been answered
    /// since: the instrument may hold statements until its move is done (§15.8).
    held: bool,
    reconnects: usize,
    retried: u64,
    info: Option<String>,
}

impl Cs130Session {
    /// A session for the monochromator on `port` (its name, for errors); nothing is
    /// sent until an operation starts. Fails if `config` does not
    /// [`validate`](Cs130Config::validate).
    pub fn new(config: Cs130Config, port: impl Into<String>) -> Result<Self, Cs130Error> {
        config.validate()?;
        Ok(Cs130Session {
            known: Known::fresh(config.filter_wheel),
            config,
            port: port.into(),
            held: false,
            reconnects: 0,
            retried: 0,
            info: None,
        })
    }

    /// Takes the instrument over: input cleared; `INFO?` (any answer is accepted and
    /// kept); `UNITS NM`; `GRAT?`, `FILTER?` (only with `filter_wheel`), `SHUTTER?`,
    /// `WAVE?`; then `STB?`, which must show no error (else `ERROR?`, and
    /// [`Cs130Error::Rejected`]).
    ///
    /// A unit without a filter wheel answers `FILTER?` with `0` and flags an error
    /// (Model 74000 command table), so a config with `filter_wheel = false` does not
    /// ask; with a wheel configured, a `0` is read back through `STB?` and `ERROR?`
    /// and reported as [`Cs130Error::NoFilterWheel`], which names the config field.
    pub fn start_init(&mut self, now: Duration) -> Task<'_, MonoState, Cs130Error> {
        Task::new(
            "cs130.init",
            now,
            |link| async move { self.init(&link).await },
        )
    }

    /// Goes to `nm`. Before any byte: the grating whose range holds `nm`
    /// ([`Cs130Config::grating_for`]) and, with `auto_order_filter`, the filter
    /// ([`Cs130Config::order_filter_for`]); a wavelength either refuses ends the
    /// operation with [`Cs130Error::Select`] and nothing sent. Then, in order:
    /// `GRAT n` if the grating differs from the one in use (or is unknown),
    /// `FILTER n` likewise (never without `filter_wheel`), `GOWAVE nm`, `*WAI` (later
    /// statements wait for the move,
    /// §15.8), `WAVE?` (answered once the move is done, within `move_timeout`), the
    /// queries of any setting still unknown, and `STB?`: an error bit is reported
    /// with `ERROR?`'s code. The read-back wavelength must lie within
    /// `position_tolerance_nm` of `nm`; it is what the returned state carries.
    pub fn start_go(&mut self, nm: f64, now: Duration) -> Task<'_, MonoState, Cs130Error> {
        Task::new("cs130.go", now, move |link| async move {
            self.go(&link, nm).await
        })
    }

    /// Opens (`SHUTTER O`) or closes (`SHUTTER C`) the shutter, reads any unknown
    /// setting, and checks `STB?`.
    pub fn start_shutter(&mut self, open: bool, now: Duration) -> Task<'_, MonoState, Cs130Error> {
        Task::new("cs130.shutter", now, move |link| async move {
            self.shutter(&link, open).await
        })
    }

    /// Reads every setting back: `GRAT?`, `FILTER?` (only with `filter_wheel`),
    /// `SHUTTER?`, `WAVE?`.
    pub fn start_read_state(&mut self, now: Duration) -> Task<'_, MonoState, Cs130Error> {
        Task::new("cs130.read_state", now, |link| async move {
            self.read_state(&link).await
        })
    }

    /// Sends any statement and, for a query, reads its answer, with the link policy
    /// of every exchange. The session's idea of the settings is forgotten when the
    /// statement may change them, so the next operation reads them again.
    pub fn start_execute<'s>(
        &'s mut self,
        command: &Command,
        now: Duration,
    ) -> Task<'s, Option<super::Reply>, Cs130Error> {
        let command = command.clone();
        Task::new("cs130.execute", now, move |link| async move {
            self.execute(&link, &command).await
        })
    }

    /// What the session knows the instrument is set to, when it knows every setting.
    pub fn state(&self) -> Option<MonoState> {
        self.known.state()
    }

    /// The configuration.
    pub fn config(&self) -> &Cs130Config {
        &self.config
    }

    /// What `INFO?` answered at init.
    pub fn info(&self) -> Option<&str> {
        self.info.as_deref()
    }

    /// How many times the port was reopened.
    pub fn reconnects(&self) -> usize {
        self.reconnects
    }

    /// Statements sent again after a lost, late or garbled echo or answer.
    pub fn retried(&self) -> u64 {
        self.retried
    }

    /// Forgets every setting (after an error, or a statement that may change them),
    /// so that the next operation reads or sets them again.
    fn forget(&mut self) {
        self.known = Known::fresh(self.config.filter_wheel);
    }
}
