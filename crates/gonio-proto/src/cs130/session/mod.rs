//! [`Cs130Session`]: the manual's procedures (set-up, a move, the shutter, a
//! read-back) as `async fn`s the engine runs, and the hold after `*WAI`.

use std::time::Duration;

use tracing::{debug, warn};

use super::{
    Command, Cs130Config, Cs130Error, MonoState, NO_FILTER_WHEEL, Reply, ReplyError, Units, is_echo,
};
use crate::engine::{self, Fault, Link, SessionCore, Task};

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

/// The Cornerstone 130 as a sans-IO state machine. Each `start_*` returns an
/// [`Operation`](crate::link::Operation) that borrows the session until it finishes;
/// `gonio_driver::cs130::Cs130` pumps them over a serial port.
#[derive(Clone, Debug, PartialEq)]
pub struct Cs130Session {
    /// Its identity is what `INFO?` answered at init.
    core: SessionCore<Cs130Config, String>,
    known: Known,
    /// A `*WAI` or a statement that moves was echoed and no query has been answered
    /// since: the instrument may hold statements until its move is done (§15.8).
    held: bool,
}

engine::line_session! {
    Cs130Session: "cs130", Cs130Config, String, Cs130Error; Command, Reply, ReplyError
}

impl Cs130Session {
    /// Counted only: every operation ends with the settings read back or checked
    /// through `STB?`, and a failed one forgets them.
    fn reopened(&mut self, _: Duration) {}

    /// A session on `port` (its name, for errors); fails if `config` does not
    /// [`validate`](Cs130Config::validate).
    pub fn new(config: Cs130Config, port: impl Into<String>) -> Result<Self, Cs130Error> {
        config.validate()?;
        Ok(Cs130Session {
            known: Known::fresh(config.filter_wheel),
            core: SessionCore::new(config, port),
            held: false,
        })
    }

    /// Input cleared; `INFO?` (any answer kept); `UNITS NM`; `GRAT?`, `FILTER?` (only
    /// with `filter_wheel`), `SHUTTER?`, `WAVE?`; `STB?`, which must show no error
    /// (else `ERROR?`, and [`Cs130Error::Rejected`]).
    ///
    /// A unit without a wheel answers `FILTER?` with `0` and flags an error (Model
    /// 74000 command table); with a wheel configured, a `0` is read back through
    /// `STB?` and `ERROR?` and reported as [`Cs130Error::NoFilterWheel`].
    pub fn start_init(&mut self, now: Duration) -> Task<'_, MonoState, Cs130Error> {
        Task::run("cs130.init", now, self, Self::init)
    }

    /// Goes to `nm`. Before any byte, [`Cs130Config::grating_for`] and (with
    /// `auto_order_filter`) [`Cs130Config::order_filter_for`]; a refusal is
    /// [`Cs130Error::Select`] with nothing sent. Then `GRAT n` and `FILTER n` where
    /// they differ from what is known (never `FILTER` without `filter_wheel`),
    /// `GOWAVE nm`, `*WAI` (later statements wait for the move, §15.8), `WAVE?`
    /// (answered once the move is done, within `move_timeout`), queries of unknown
    /// settings, `STB?` (an error bit is reported with `ERROR?`'s code). The read-back
    /// wavelength must lie within `position_tolerance_nm` of `nm`.
    pub fn start_go(&mut self, nm: f64, now: Duration) -> Task<'_, MonoState, Cs130Error> {
        Task::run("cs130.go", now, self, async move |s, link| {
            s.go(link, nm).await
        })
    }

    /// `SHUTTER O` or `SHUTTER C`, any unknown setting read, `STB?` checked.
    pub fn start_shutter(&mut self, open: bool, now: Duration) -> Task<'_, MonoState, Cs130Error> {
        Task::run("cs130.shutter", now, self, async move |s, link| {
            s.shutter(link, open).await
        })
    }

    /// Reads every setting back: `GRAT?`, `FILTER?` (only with `filter_wheel`),
    /// `SHUTTER?`, `WAVE?`.
    pub fn start_read_state(&mut self, now: Duration) -> Task<'_, MonoState, Cs130Error> {
        Task::run("cs130.read_state", now, self, Self::read_state)
    }

    /// Any statement and, for a query, its answer. The known settings are forgotten
    /// when it may change them or fails, so the next operation reads them again.
    pub fn start_execute<'s>(
        &'s mut self,
        command: &Command,
        now: Duration,
    ) -> Task<'s, Option<super::Reply>, Cs130Error> {
        let command = command.clone();
        Task::run("cs130.execute", now, self, async move |s, link| {
            s.execute(link, &command).await
        })
    }

    /// The instrument's settings, when every one is known.
    pub fn state(&self) -> Option<MonoState> {
        self.known.state()
    }

    /// What `INFO?` answered at init.
    pub fn info(&self) -> Option<&str> {
        self.core.identity.as_deref()
    }

    fn forget(&mut self) {
        self.known = Known::fresh(self.config.filter_wheel);
    }

    /// A statement, its echo (when configured, §15.4) and, for a query, its answer.
    ///
    /// - Each is due `timeout` after sending. After `*WAI` (§15.8) the instrument
    ///   holds later statements until the move is done, and after `GRAT`, `FILTER` or
    ///   `GOWAVE` it may be busy (whether it echoes meanwhile: **UNCONFIRMED**), so
    ///   until a query is answered they are due `move_timeout` after.
    /// - Every statement but `STB?` and `ERROR?`, whose reading clears what they
    ///   report (§15.9), is resent after a lost, late or garbled line, up to `retries`
    ///   times: set statements are absolute, so twice is harmless.
    async fn ask(&mut self, link: &Link, command: &Command) -> Result<Option<Reply>, Cs130Error> {
        let c = &self.config;
        let wait = if self.held {
            c.move_timeout()
        } else {
            c.timeout()
        };
        let echo = c.echo;
        let retries = if command.is_repeatable() {
            c.retries
        } else {
            0
        };
        let receive = async |_: &mut Cs130Session| {
            let due = link.now().saturating_add(wait);
            if echo {
                let line = link.line(due).await?;
                if !is_echo(command, &line) {
                    return Err(Fault::Answer(protocol(command, &line, ReplyError::BadEcho)));
                }
            }
            if !command.is_query() {
                return Ok(None);
            }
            let line = link.line(due).await?;
            Reply::parse(command, &line)
                .map(Some)
                .map_err(|source| Fault::Answer(protocol(command, &line, source)))
        };
        let bytes = command.to_bytes();
        let reply = engine::exchange(self, link, &name(command), &bytes, retries, receive).await?;
        if reply.is_some() {
            // A query has been answered: whatever `*WAI` held is done.
            self.held = false;
        } else if echo && command.moves() {
            // After `*WAI` every later statement waits for the move (§15.8); after a
            // statement that starts one, whether the instrument echoes while it moves
            // is not documented.
            self.held = true;
        }
        Ok(reply)
    }

    /// One statement and what its answer means for the known settings. A failure
    /// forgets them all (whatever was being set is unknown).
    async fn step(&mut self, link: &Link, command: Command) -> Result<(), Cs130Error> {
        let reply = match self.ask(link, &command).await {
            Ok(reply) => reply,
            Err(e) => {
                self.forget();
                return Err(e);
            }
        };
        let wheel = self.config.filter_wheel;
        let k = &mut self.known;
        match (&command, reply) {
            (Command::Wave, Some(Reply::Wavelength(v))) => k.wavelength_nm = Some(v),
            (Command::GratQuery, Some(Reply::Grating { number, .. })) => k.grating = Some(number),
            (Command::FilterQuery, Some(Reply::Filter(0))) if wheel => {
                return Err(self.no_wheel(link).await);
            }
            (Command::FilterQuery, Some(Reply::Filter(n))) => k.filter = Some(n),
            (Command::ShutterQuery, Some(Reply::Shutter(o))) => k.shutter_open = Some(o),
            (Command::Info, Some(Reply::Info(text))) => {
                debug!(info = %text, "cs130: identified");
                self.core.identity = Some(text);
            }
            (Command::Stb, Some(Reply::Status(sb))) if sb.error() => {
                warn!(status = %sb, "cs130: status byte reports an error");
                let read = self.ask(link, &Command::Error).await;
                // Which statement failed is unknown: forget every setting.
                self.forget();
                return Err(match read? {
                    Some(Reply::Error(code)) => Cs130Error::Rejected(code),
                    other => unexpected(&Command::Error, other),
                });
            }
            (Command::Stb, Some(Reply::Status(_))) => {}
            // Set at the echo; the status byte at the end confirms them all.
            (Command::Grat(n), None) => k.grating = Some(*n),
            (Command::Filter(n), None) => k.filter = Some(*n),
            (Command::Shutter(o), None) => k.shutter_open = Some(*o),
            (Command::GoWave(_), None) => k.wavelength_nm = None,
            (Command::Units(_) | Command::Wai | Command::Abort, None) => {}
            (c, other) => return Err(unexpected(c, other)),
        }
        Ok(())
    }

    /// `FILTER?` answered 0 with a wheel configured ([`Command::FilterQuery`]): the
    /// error it set is read back (`STB?`, `ERROR?`) so the unit is left clean.
    async fn no_wheel(&mut self, link: &Link) -> Cs130Error {
        warn!("cs130: a filter wheel is configured but FILTER? answered 0");
        self.forget();
        // A clean status byte (the unit set no error) or an unread one: the wheel is
        // missing all the same, which is the error worth reporting.
        let code = match self.ask(link, &Command::Stb).await {
            Ok(Some(Reply::Status(sb))) if sb.error() => {
                match self.ask(link, &Command::Error).await {
                    Ok(Some(Reply::Error(code))) => Some(code),
                    other => {
                        warn!(answer = ?other, "cs130: the error after FILTER? 0 was not read");
                        None
                    }
                }
            }
            Ok(_) => None,
            Err(e) => {
                warn!(error = %e, "cs130: the status byte after FILTER? 0 was not read");
                None
            }
        };
        Cs130Error::NoFilterWheel { code }
    }

    /// After a set: the settings still unknown read, then `STB?`, then the state.
    async fn confirm(
        &mut self,
        link: &Link,
        asked_nm: Option<f64>,
    ) -> Result<MonoState, Cs130Error> {
        self.read_unknown(link).await?;
        self.step(link, Command::Stb).await?;
        self.reached(asked_nm)
    }

    /// `GRAT?`, `FILTER?`, `SHUTTER?`, `WAVE?`, each for a setting still unknown
    /// (without a wheel the filter is known from the start).
    async fn read_unknown(&mut self, link: &Link) -> Result<(), Cs130Error> {
        let k = self.known;
        let queries = [
            (k.grating.is_none(), Command::GratQuery),
            (k.filter.is_none(), Command::FilterQuery),
            (k.shutter_open.is_none(), Command::ShutterQuery),
            (k.wavelength_nm.is_none(), Command::Wave),
        ];
        for (unknown, query) in queries {
            if unknown {
                self.step(link, query).await?;
            }
        }
        Ok(())
    }

    /// The state, with the wavelength within `position_tolerance_nm` of `asked_nm`.
    fn reached(&self, asked_nm: Option<f64>) -> Result<MonoState, Cs130Error> {
        let Some(state) = self.known.state() else {
            return Err(unexpected(&Command::Wave, None));
        };
        if let Some(asked) = asked_nm {
            let tol = self.config.position_tolerance_nm;
            if (state.wavelength_nm - asked).abs() > tol {
                warn!(
                    asked,
                    read = state.wavelength_nm,
                    "cs130: wavelength not reached"
                );
                return Err(Cs130Error::NotReached {
                    asked_nm: asked,
                    read_nm: state.wavelength_nm,
                    tolerance_nm: tol,
                });
            }
        }
        debug!(?state, "cs130: state");
        Ok(state)
    }

    async fn init(&mut self, link: &Link) -> Result<MonoState, Cs130Error> {
        link.clear_input();
        self.forget();
        self.step(link, Command::Info).await?;
        self.step(link, Command::Units(Units::Nm)).await?;
        self.confirm(link, None).await
    }

    async fn read_state(&mut self, link: &Link) -> Result<MonoState, Cs130Error> {
        self.forget();
        self.read_unknown(link).await?;
        self.reached(None)
    }

    async fn shutter(&mut self, link: &Link, open: bool) -> Result<MonoState, Cs130Error> {
        self.step(link, Command::Shutter(open)).await?;
        self.confirm(link, None).await
    }

    async fn go(&mut self, link: &Link, nm: f64) -> Result<MonoState, Cs130Error> {
        let c = &self.config;
        let (grating, min_nm, filter) = c
            .grating_for(nm)
            .and_then(|g| {
                // Never a `FILTER n` without a wheel: it would only flag an error
                // (§15.9's code 6). The config refuses `auto_order_filter` without
                // `filter_wheel`.
                let filter = (c.auto_order_filter && c.filter_wheel)
                    .then(|| c.order_filter_for(nm))
                    .transpose()?;
                Ok((g.index, g.min_nm, filter))
            })
            .inspect_err(|e| warn!(error = %e, "cs130: refused before any byte"))?;
        // A drive's backlash leaves it short when it comes down onto a wavelength:
        // every wavelength is approached from below, so the slack is always taken up
        // the same way (an unknown position counts as above).
        let below = (nm - c.approach_nm).max(min_nm);
        let approach =
            c.approach_nm > 0.0 && below < nm && self.known.wavelength_nm.is_none_or(|at| at > nm);
        if self.known.grating != Some(grating) {
            self.step(link, Command::Grat(grating)).await?;
        }
        if let Some(f) = filter
            && self.known.filter != Some(f)
        {
            self.step(link, Command::Filter(f)).await?;
        }
        if approach {
            self.step(link, Command::GoWave(below)).await?;
        }
        self.step(link, Command::GoWave(nm)).await?;
        self.step(link, Command::Wai).await?;
        self.step(link, Command::Wave).await?;
        self.confirm(link, Some(nm)).await
    }

    async fn execute(
        &mut self,
        link: &Link,
        command: &Command,
    ) -> Result<Option<Reply>, Cs130Error> {
        let reply = self.ask(link, command).await;
        if !command.is_query() || reply.is_err() {
            self.forget();
        }
        reply
    }
}
