//! The wheel's operations as its manual's procedures: set-up, a move, a position
//! read; and its exchange (a command, its echo and, for a query, its value), run by
//! the engine's link policy.

use std::time::Duration;

use tracing::{debug, warn};

use super::Fw102cSession;
use crate::TransportError;
use crate::engine::{self, Fault, Link, Wire};
use crate::fw102c::reply::is_echo;
use crate::fw102c::{Command, Fw102cError, Line, Reply, ReplyError, SensorMode};

impl Wire for Fw102cSession {
    engine::line_wire!(Fw102cError, "fw102c");

    fn reopened(&mut self, _: Duration) {
        self.reconnects += 1;
        // The wheel may have been moved or power-cycled meanwhile.
        self.position = None;
    }
}

/// A reply of another kind than the query's: [`Reply::parse`] answers by query, so
/// this cannot happen; reported as a protocol error rather than a panic.
fn unexpected(query: Command, reply: Option<Reply>) -> Fw102cError {
    Fw102cError::Protocol {
        command: query.to_string(),
        reply: reply.map(|r| r.to_bytes()).unwrap_or_default(),
        source: ReplyError::BadValue,
    }
}

impl Fw102cSession {
    /// Sends `command`, reads its echo and, for a query, its value line.
    ///
    /// - A set command ends at its echo: success is only the prompt, which carries no
    ///   CR, and a refusal comes as a line after the echo. So a set is followed by a
    ///   query (`after` names the set), and a `Command error` line that arrives before
    ///   that query's echo is the set's refusal.
    /// - Lines holding only the prompt are skipped; the prompt is stripped from the
    ///   start of every line.
    /// - The echo is due `timeout` after sending, or at `until` if later (a `pos?`
    ///   during a move may be answered only once the wheel stops), the value `timeout`
    ///   after the echo.
    /// - Every command Gonio sends is safe to repeat: a lost, late or garbled line
    ///   sends it again, up to `retries` times.
    async fn ask(
        &mut self,
        link: &Link,
        command: Command,
        after: Option<Command>,
        until: Duration,
    ) -> Result<Option<Reply>, Fw102cError> {
        let timeout = self.config.timeout();
        let retries = self.config.retries;
        let name = command.to_string();
        let refused = |command: Command, code| {
            // This command's own echo and answer may still come: the engine drops them.
            warn!(%command, %code, "fw102c: command refused");
            Fault::Answer(Fw102cError::Refused {
                command: command.to_string(),
                code,
            })
        };
        let garbled = |line: &[u8], source| {
            Fault::Answer(Fw102cError::Protocol {
                command: command.to_string(),
                reply: line.to_vec(),
                source,
            })
        };
        let receive = async |_: &mut Fw102cSession| {
            let due = link.now().saturating_add(timeout).max(until);
            loop {
                let line = link.line(due).await?;
                match Line::classify(&line) {
                    Line::Blank => continue,
                    // Before this command's echo: the refusal of the set sent before it.
                    Line::Error(e) => return Err(refused(after.unwrap_or(command), e.code)),
                    Line::Text(t) if is_echo(&command, t) => break,
                    Line::Text(_) => return Err(garbled(&line, ReplyError::BadValue)),
                }
            }
            if !command.is_query() {
                return Ok(None);
            }
            let due = link.now().saturating_add(timeout);
            loop {
                let line = link.line(due).await?;
                match Line::classify(&line) {
                    Line::Blank => continue,
                    Line::Error(e) => return Err(refused(command, e.code)),
                    Line::Text(t) => {
                        return Reply::parse(&command, t)
                            .map(Some)
                            .map_err(|source| garbled(&line, source));
                    }
                }
            }
        };
        engine::exchange(self, link, &name, &command.to_bytes(), retries, receive).await
    }

    /// `query`, whose reply must be there.
    async fn query(&mut self, link: &Link, query: Command) -> Result<Reply, Fw102cError> {
        match self.ask(link, query, None, Duration::ZERO).await? {
            Some(r) => Ok(r),
            None => Err(unexpected(query, None)),
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
        match self.ask(link, query, Some(set), Duration::ZERO).await? {
            Some(r) => Ok(r),
            None => Err(unexpected(query, None)),
        }
    }

    /// Set-up: `*idn?` (a FW102C or FW212C), `pcount?` (the configured count),
    /// `speed=` then `speed?`, with `sensors_off_when_idle` `sensors=0` then
    /// `sensors?`, and `pos?`.
    pub(super) async fn init(&mut self, link: &Link) -> Result<String, Fw102cError> {
        let identity = match self.query(link, Command::Identify).await? {
            Reply::Identity(id) => id,
            other => return Err(unexpected(Command::Identify, Some(other))),
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
        match self.query(link, Command::QueryPositionCount).await? {
            Reply::PositionCount(n) if n == positions => {}
            Reply::PositionCount(device) => {
                return Err(Fw102cError::PositionCountMismatch {
                    config: positions,
                    device,
                });
            }
            other => return Err(unexpected(Command::QueryPositionCount, Some(other))),
        }
        let speed = Command::SetSpeed(self.config.speed);
        match self.set(link, speed, Command::QuerySpeed).await? {
            Reply::Speed(v) if v == self.config.speed => {}
            Reply::Speed(v) => return Err(not_applied(speed, v.digit())),
            other => return Err(unexpected(Command::QuerySpeed, Some(other))),
        }
        if self.config.sensors_off_when_idle {
            let sensors = Command::SetSensors(SensorMode::OffWhenIdle);
            match self.set(link, sensors, Command::QuerySensors).await? {
                Reply::Sensors(SensorMode::OffWhenIdle) => {}
                Reply::Sensors(SensorMode::AlwaysOn) => return Err(not_applied(sensors, 1)),
                other => return Err(unexpected(Command::QuerySensors, Some(other))),
            }
        }
        self.read_position(link).await?;
        self.identity = Some(identity.clone());
        Ok(identity)
    }

    /// A move: the position checked against the wheel's count before any byte,
    /// `pos=n`, then `pos?` every `poll_interval` until it reads n, for at most
    /// `move_timeout`.
    pub(super) async fn select(&mut self, link: &Link, target: u8) -> Result<(), Fw102cError> {
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
                Ok(other) => return Err(unexpected(Command::QueryPosition, other)),
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

    /// `pos?`.
    pub(super) async fn read_position(&mut self, link: &Link) -> Result<u8, Fw102cError> {
        match self.query(link, Command::QueryPosition).await? {
            Reply::Position(p) => {
                self.position = Some(p);
                Ok(p)
            }
            other => Err(unexpected(Command::QueryPosition, Some(other))),
        }
    }
}

/// A set whose read-back differs.
fn not_applied(set: Command, read: u8) -> Fw102cError {
    Fw102cError::NotApplied {
        command: set.to_string(),
        read: read.to_string(),
    }
}
