//! The wheel's operations: set-up, a move, a position read.

use std::time::Duration;

use tracing::debug;

use super::Fw102cSession;
use super::script::{Answer, Next, Op};
use crate::fw102c::{Command, Fw102cError, Reply, SensorMode};
use crate::machine::Cx;

/// A reply of another kind than the query's: [`Reply::parse`] answers by query, so
/// this cannot happen; reported as a protocol error rather than a panic.
fn unexpected(query: Command, reply: Option<Reply>) -> Fw102cError {
    Fw102cError::Protocol {
        command: query.to_string(),
        reply: reply.map(|r| r.to_bytes()).unwrap_or_default(),
        source: crate::fw102c::ReplyError::BadValue,
    }
}

/// Set-up: `*idn?` (a FW102C or FW212C), `pcount?` (the configured count), `speed=`
/// then `speed?`, with `sensors_off_when_idle` `sensors=0` then `sensors?`, and `pos?`.
#[derive(Debug, Default)]
pub(super) struct Init {
    identity: String,
}

impl Op for Init {
    type Value = String;

    fn start(&mut self, _: &mut Fw102cSession, _: &mut Cx) -> Next<Self> {
        Next::send(Command::Identify, Init::identified)
    }
}

impl Init {
    fn identified(&mut self, s: &mut Fw102cSession, _: &mut Cx, a: Answer) -> Next<Self> {
        let identity = match a {
            Ok(Some(Reply::Identity(id))) => id,
            Ok(other) => return Next::Done(Err(unexpected(Command::Identify, other))),
            Err(e) => return Next::Done(Err(e)),
        };
        let upper = identity.to_ascii_uppercase();
        if !(upper.contains("FW102C") || upper.contains("FW212C")) {
            return Next::Done(Err(Fw102cError::NotAFilterWheel {
                port: s.port.clone(),
                identity,
            }));
        }
        debug!(identity = %identity, "fw102c: identified");
        self.identity = identity;
        Next::send(Command::QueryPositionCount, Init::counted)
    }

    fn counted(&mut self, s: &mut Fw102cSession, _: &mut Cx, a: Answer) -> Next<Self> {
        match a {
            Ok(Some(Reply::PositionCount(n))) if n == s.config.positions => {
                Next::send(Command::SetSpeed(s.config.speed), Init::speed_set)
            }
            Ok(Some(Reply::PositionCount(n))) => {
                Next::Done(Err(Fw102cError::PositionCountMismatch {
                    config: s.config.positions,
                    device: n,
                }))
            }
            Ok(other) => Next::Done(Err(unexpected(Command::QueryPositionCount, other))),
            Err(e) => Next::Done(Err(e)),
        }
    }

    fn speed_set(&mut self, s: &mut Fw102cSession, _: &mut Cx, a: Answer) -> Next<Self> {
        match a {
            Ok(_) => Next::read_back(
                Command::SetSpeed(s.config.speed),
                Command::QuerySpeed,
                Init::speed_read,
            ),
            Err(e) => Next::Done(Err(e)),
        }
    }

    fn speed_read(&mut self, s: &mut Fw102cSession, _: &mut Cx, a: Answer) -> Next<Self> {
        match a {
            Ok(Some(Reply::Speed(v))) if v == s.config.speed => {
                if s.config.sensors_off_when_idle {
                    Next::send(
                        Command::SetSensors(SensorMode::OffWhenIdle),
                        Init::sensors_set,
                    )
                } else {
                    Next::send(Command::QueryPosition, Init::positioned)
                }
            }
            Ok(Some(Reply::Speed(v))) => Next::Done(Err(Fw102cError::NotApplied {
                command: Command::SetSpeed(s.config.speed).to_string(),
                read: v.digit().to_string(),
            })),
            Ok(other) => Next::Done(Err(unexpected(Command::QuerySpeed, other))),
            Err(e) => Next::Done(Err(e)),
        }
    }

    fn sensors_set(&mut self, _: &mut Fw102cSession, _: &mut Cx, a: Answer) -> Next<Self> {
        match a {
            Ok(_) => Next::read_back(
                Command::SetSensors(SensorMode::OffWhenIdle),
                Command::QuerySensors,
                Init::sensors_read,
            ),
            Err(e) => Next::Done(Err(e)),
        }
    }

    fn sensors_read(&mut self, _: &mut Fw102cSession, _: &mut Cx, a: Answer) -> Next<Self> {
        match a {
            Ok(Some(Reply::Sensors(SensorMode::OffWhenIdle))) => {
                Next::send(Command::QueryPosition, Init::positioned)
            }
            Ok(Some(Reply::Sensors(SensorMode::AlwaysOn))) => {
                Next::Done(Err(Fw102cError::NotApplied {
                    command: Command::SetSensors(SensorMode::OffWhenIdle).to_string(),
                    read: "1".into(),
                }))
            }
            Ok(other) => Next::Done(Err(unexpected(Command::QuerySensors, other))),
            Err(e) => Next::Done(Err(e)),
        }
    }

    fn positioned(&mut self, s: &mut Fw102cSession, _: &mut Cx, a: Answer) -> Next<Self> {
        match a {
            Ok(Some(Reply::Position(p))) => {
                s.position = Some(p);
                s.identity = Some(self.identity.clone());
                Next::Done(Ok(std::mem::take(&mut self.identity)))
            }
            Ok(other) => Next::Done(Err(unexpected(Command::QueryPosition, other))),
            Err(e) => Next::Done(Err(e)),
        }
    }
}

/// A move: the position checked against the wheel's count before any byte, `pos=n`,
/// then `pos?` every `poll_interval` until it reads n, for at most `move_timeout`.
#[derive(Debug)]
pub(super) struct Select {
    target: u8,
    started: Duration,
    deadline: Duration,
    last: Option<u8>,
}

impl Select {
    pub(super) fn new(target: u8) -> Self {
        Select {
            target,
            started: Duration::ZERO,
            deadline: Duration::ZERO,
            last: None,
        }
    }

    fn poll(&self, after: Option<Command>) -> Next<Self> {
        // A wheel that answers only once stopped may hold the reply until the deadline.
        Next::Exchange {
            command: Command::QueryPosition,
            after,
            until: self.deadline,
            then: Select::read,
        }
    }

    fn sent(&mut self, _: &mut Fw102cSession, _: &mut Cx, a: Answer) -> Next<Self> {
        match a {
            Ok(_) => self.poll(Some(Command::SetPosition(self.target))),
            Err(e) => Next::Done(Err(e)),
        }
    }

    fn read(&mut self, s: &mut Fw102cSession, cx: &mut Cx, a: Answer) -> Next<Self> {
        match a {
            Ok(Some(Reply::Position(p))) if p == self.target => {
                s.position = Some(p);
                debug!(position = p, took = ?cx.now.saturating_sub(self.started), "fw102c: in position");
                Next::Done(Ok(()))
            }
            Ok(Some(Reply::Position(p))) => {
                self.last = Some(p);
                if cx.now >= self.deadline {
                    return self.timed_out(s, cx);
                }
                let until = cx
                    .now
                    .saturating_add(s.config.poll_interval())
                    .min(self.deadline);
                Next::Pause {
                    until,
                    then: Select::again,
                }
            }
            Ok(other) => Next::Done(Err(unexpected(Command::QueryPosition, other))),
            Err(Fw102cError::Transport {
                source: crate::TransportError::Timeout(_),
                ..
            }) if cx.now >= self.deadline => self.timed_out(s, cx),
            Err(e) => {
                s.position = None;
                Next::Done(Err(e))
            }
        }
    }

    fn again(&mut self, _: &mut Fw102cSession, _: &mut Cx, (): ()) -> Next<Self> {
        self.poll(None)
    }

    fn timed_out(&mut self, s: &mut Fw102cSession, cx: &mut Cx) -> Next<Self> {
        s.position = self.last;
        tracing::warn!(position = self.target, last = ?self.last, "fw102c: move timed out");
        Next::Done(Err(Fw102cError::MoveTimeout {
            position: self.target,
            last: self.last,
            waited: cx.now.saturating_sub(self.started),
        }))
    }
}

impl Op for Select {
    type Value = ();

    fn start(&mut self, s: &mut Fw102cSession, cx: &mut Cx) -> Next<Self> {
        let positions = s.config.positions;
        if !(1..=positions).contains(&self.target) {
            return Next::Done(Err(Fw102cError::PositionOutOfRange {
                position: self.target,
                positions,
            }));
        }
        self.started = cx.now;
        self.deadline = cx.now.saturating_add(s.config.move_timeout());
        s.position = None;
        Next::send(Command::SetPosition(self.target), Select::sent)
    }
}

/// `pos?`.
#[derive(Debug, Default)]
pub(super) struct ReadPosition;

impl Op for ReadPosition {
    type Value = u8;

    fn start(&mut self, _: &mut Fw102cSession, _: &mut Cx) -> Next<Self> {
        Next::send(Command::QueryPosition, ReadPosition::read)
    }
}

impl ReadPosition {
    fn read(&mut self, s: &mut Fw102cSession, _: &mut Cx, a: Answer) -> Next<Self> {
        match a {
            Ok(Some(Reply::Position(p))) => {
                s.position = Some(p);
                Next::Done(Ok(p))
            }
            Ok(other) => Next::Done(Err(unexpected(Command::QueryPosition, other))),
            Err(e) => Next::Done(Err(e)),
        }
    }
}
