//! [`Fw102cSession`]: the manual's procedures (set-up, a move, a position read) as
//! `async fn`s the engine runs, and its receive rule (an echo, then a query's value).

use std::time::Duration;

use tracing::{debug, warn};

use super::reply::is_echo;
use super::{Command, Fw102cConfig, Fw102cError, Line, Reply, ReplyError, SensorMode};
use crate::TransportError;
use crate::engine::{self, Link, SessionCore, Task};

/// The FW102C as a sans-IO state machine; `gonio_driver::fw102c::Fw102c` pumps its
/// operations over a port.
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
#[derive(Clone, Debug, PartialEq)]
pub struct Fw102cSession {
    core: SessionCore<Fw102cConfig, String>,
    /// The position last read, `None` while unknown (during a move, after a fault).
    position: Option<u8>,
}

engine::line_session! {
    Fw102cSession: "fw102c", Fw102cConfig, String, Fw102cError; Command, Reply, ReplyError
}

/// A set whose read-back differs.
fn not_applied(set: Command, read: u8) -> Fw102cError {
    Fw102cError::NotApplied {
        command: set.to_string(),
        read: read.to_string(),
    }
}

impl Fw102cSession {
    /// The wheel may have been moved or power-cycled meanwhile.
    fn reopened(&mut self, _: Duration) {
        self.position = None;
    }

    /// A session on `port` (its name, for errors); fails if `config` does not validate.
    pub fn new(config: Fw102cConfig, port: impl Into<String>) -> Result<Self, Fw102cError> {
        config.validate()?;
        Ok(Fw102cSession {
            core: SessionCore::new(config, port),
            position: None,
        })
    }

    /// `*idn?` (must name a FW102C or FW212C), `pcount?` (must equal `positions`),
    /// `speed=` and `speed?`, with `sensors_off_when_idle` `sensors=0` and `sensors?`,
    /// `pos?`. Each set is read back: its success has no line of its own (see
    /// [`crate::fw102c`]). Returns the identification string.
    pub fn start_init(&mut self, now: Duration) -> Task<'_, String, Fw102cError> {
        Task::run("fw102c.init", now, self, Self::init)
    }

    /// Refused before any byte outside 1..=`positions`; then `pos=n` and `pos?` every
    /// `poll_interval_ms` until it reads n, for at most `move_timeout_ms`
    /// ([`Fw102cError::MoveTimeout`]).
    pub fn start_select(&mut self, position: u8, now: Duration) -> Task<'_, (), Fw102cError> {
        Task::run("fw102c.select", now, self, async move |s, link| {
            s.select(link, position).await
        })
    }

    /// `pos?`.
    pub fn start_read_position(&mut self, now: Duration) -> Task<'_, u8, Fw102cError> {
        Task::run("fw102c.position", now, self, Self::read_position)
    }

    /// The position last read, `None` while unknown.
    pub fn position(&self) -> Option<u8> {
        self.position
    }

    /// What `*idn?` answered at set-up.
    pub fn identity(&self) -> Option<&str> {
        self.core.identity.as_deref()
    }

    /// `command`, its echo and, for a query, its value line.
    ///
    /// - A set ends at its echo: success is only the prompt, which carries no CR, and
    ///   a refusal comes as a line after the echo. So a set is followed by a query
    ///   (`after` names the set), and a `Command error` line before that query's echo
    ///   is the set's refusal.
    /// - The echo is due `timeout` after sending, or at `until` if later (a `pos?`
    ///   during a move may be answered only once the wheel stops), the value `timeout`
    ///   after the echo.
    /// - Every command Gonio sends is safe to repeat, up to `retries` times.
    async fn ask(
        &mut self,
        link: &Link,
        command: Command,
        after: Option<Command>,
        until: Duration,
    ) -> Result<Option<Reply>, Fw102cError> {
        let timeout = self.config.timeout();
        let refused = |command: Command, code| {
            // This command's own echo and answer may still come: the engine drops them.
            warn!(%command, %code, "fw102c: command refused");
            Fw102cError::Refused {
                command: command.to_string(),
                code,
            }
        };
        let receive = async |_: &mut Fw102cSession| {
            let due = link.now().saturating_add(timeout).max(until);
            engine::receive(link, due, |line| match Line::classify(line) {
                Line::Blank => None,
                // Before this command's echo: the refusal of the set sent before it.
                Line::Error(e) => Some(Err(refused(after.unwrap_or(command), e.code))),
                Line::Text(t) if is_echo(&command, t) => Some(Ok(())),
                Line::Text(_) => Some(Err(protocol(&command, line, ReplyError::BadValue))),
            })
            .await?;
            if !command.is_query() {
                return Ok(None);
            }
            let due = link.now().saturating_add(timeout);
            engine::receive(link, due, |line| match Line::classify(line) {
                Line::Blank => None,
                Line::Error(e) => Some(Err(refused(command, e.code))),
                Line::Text(t) => Some(
                    Reply::parse(&command, t)
                        .map(Some)
                        .map_err(|source| protocol(&command, line, source)),
                ),
            })
            .await
        };
        let (name, retries) = (name(&command), self.config.retries);
        engine::exchange(self, link, &name, &command.to_bytes(), retries, receive).await
    }

    /// `query`, whose reply must be there; `after` names the set it reads back.
    async fn query(
        &mut self,
        link: &Link,
        query: Command,
        after: Option<Command>,
    ) -> Result<Reply, Fw102cError> {
        match self.ask(link, query, after, Duration::ZERO).await? {
            Some(r) => Ok(r),
            None => Err(unexpected(&query, None)),
        }
    }

    /// `set`, then `query` to read back what it changed.
    async fn set(
        &mut self,
        link: &Link,
        set: Command,
        query: Command,
    ) -> Result<Reply, Fw102cError> {
        self.ask(link, set, None, Duration::ZERO).await?;
        self.query(link, query, Some(set)).await
    }

    async fn init(&mut self, link: &Link) -> Result<String, Fw102cError> {
        let identity = match self.query(link, Command::Identify, None).await? {
            Reply::Identity(id) => id,
            other => return Err(unexpected(&Command::Identify, Some(other))),
        };
        let upper = identity.to_ascii_uppercase();
        if !(upper.contains("FW102C") || upper.contains("FW212C")) {
            return Err(Fw102cError::NotAFilterWheel {
                port: self.port.clone(),
                identity,
            });
        }
        debug!(identity = %identity, "fw102c: identified");
        let positions = self.config.positions;
        match self.query(link, Command::QueryPositionCount, None).await? {
            Reply::PositionCount(n) if n == positions => {}
            Reply::PositionCount(device) => {
                return Err(Fw102cError::PositionCountMismatch {
                    config: positions,
                    device,
                });
            }
            other => return Err(unexpected(&Command::QueryPositionCount, Some(other))),
        }
        let speed = Command::SetSpeed(self.config.speed);
        match self.set(link, speed, Command::QuerySpeed).await? {
            Reply::Speed(v) if v == self.config.speed => {}
            Reply::Speed(v) => return Err(not_applied(speed, v.digit())),
            other => return Err(unexpected(&Command::QuerySpeed, Some(other))),
        }
        if self.config.sensors_off_when_idle {
            let sensors = Command::SetSensors(SensorMode::OffWhenIdle);
            match self.set(link, sensors, Command::QuerySensors).await? {
                Reply::Sensors(SensorMode::OffWhenIdle) => {}
                Reply::Sensors(SensorMode::AlwaysOn) => return Err(not_applied(sensors, 1)),
                other => return Err(unexpected(&Command::QuerySensors, Some(other))),
            }
        }
        self.read_position(link).await?;
        self.core.identity = Some(identity.clone());
        Ok(identity)
    }

    async fn select(&mut self, link: &Link, target: u8) -> Result<(), Fw102cError> {
        let positions = self.config.positions;
        if !(1..=positions).contains(&target) {
            return Err(Fw102cError::PositionOutOfRange {
                position: target,
                positions,
            });
        }
        let started = link.now();
        let deadline = started.saturating_add(self.config.move_timeout());
        self.position = None;
        let set = Command::SetPosition(target);
        self.ask(link, set, None, Duration::ZERO).await?;
        let mut after = Some(set);
        let mut last = None;
        loop {
            // A wheel that answers only once stopped may hold the reply until the
            // deadline.
            let read = self
                .ask(link, Command::QueryPosition, after, deadline)
                .await;
            after = None;
            match read {
                Ok(Some(Reply::Position(p))) if p == target => {
                    self.position = Some(p);
                    debug!(position = p, took = ?link.now().saturating_sub(started), "fw102c: in position");
                    return Ok(());
                }
                Ok(Some(Reply::Position(p))) => last = Some(p),
                Ok(other) => return Err(unexpected(&Command::QueryPosition, other)),
                Err(Fw102cError::Transport {
                    source: TransportError::Timeout(_),
                    ..
                }) if link.now() >= deadline => {}
                Err(e) => {
                    self.position = None;
                    return Err(e);
                }
            }
            if link.now() >= deadline {
                self.position = last;
                warn!(position = target, last = ?last, "fw102c: move timed out");
                return Err(Fw102cError::MoveTimeout {
                    position: target,
                    last,
                    waited: link.now().saturating_sub(started),
                });
            }
            let until = link.now().saturating_add(self.config.poll_interval());
            link.sleep(until.min(deadline)).await;
        }
    }

    async fn read_position(&mut self, link: &Link) -> Result<u8, Fw102cError> {
        match self.query(link, Command::QueryPosition, None).await? {
            Reply::Position(p) => {
                self.position = Some(p);
                Ok(p)
            }
            other => Err(unexpected(&Command::QueryPosition, Some(other))),
        }
    }
}
