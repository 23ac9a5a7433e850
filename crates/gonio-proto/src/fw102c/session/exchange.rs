//! One command on the wire, with the wheel's link policy.

use std::time::Duration;

use tracing::{debug, warn};

use super::Fw102cSession;
use crate::TransportError;
use crate::fw102c::reply::is_echo;
use crate::fw102c::{Command, Fw102cError, Line, Reply};
use crate::machine::{Cx, Event, Machine, Pending, Step};

/// Sends a command, reads its echo and, for a query, its value line.
///
/// - A set command ends at its echo: success is only the prompt, which carries no CR,
///   and a refusal comes as a line after the echo. So the caller follows a set with a
///   query (`after` names the set), and a `Command error` line that arrives before
///   that query's echo is the set's refusal.
/// - Lines holding only the prompt are skipped; the prompt is stripped from the
///   start of every line.
/// - The echo is due `timeout` after sending, or at `until` if later (a `pos?` during
///   a move may be answered only once the wheel stops), the value `timeout` after the
///   echo.
/// - A lost, late or garbled line clears the input and sends the command again, up to
///   `retries` times; every command Gonio sends is safe to repeat. A vanished port is
///   reopened after a pause, `reconnect_attempts` times per command.
#[derive(Debug)]
pub(super) struct Exchange {
    command: Command,
    after: Option<Command>,
    until: Duration,
    budget: u32,
    retries: u32,
    state: State,
}

#[derive(Debug, Clone, Copy)]
enum State {
    Sending,
    /// The echo is due by then.
    Echo(Duration),
    /// The value line is due by then.
    Value(Duration),
    Pausing(Duration),
    Reconnecting,
}

type Out = Result<Option<Reply>, Fw102cError>;

impl Exchange {
    pub(super) fn new(
        s: &Fw102cSession,
        command: Command,
        after: Option<Command>,
        until: Duration,
    ) -> Self {
        Exchange {
            command,
            after,
            until,
            budget: s.config.reconnect_attempts,
            retries: s.config.retries,
            state: State::Sending,
        }
    }

    fn pending(&self) -> Pending {
        match self.state {
            State::Sending => Pending::Transmit(self.command.to_bytes()),
            State::Echo(t) | State::Value(t) => Pending::Reply(t),
            State::Pausing(t) => Pending::Sleep(t),
            State::Reconnecting => Pending::Reconnect,
        }
    }

    fn recover(&mut self, s: &Fw102cSession, cx: &Cx, lost: TransportError) -> Step<Out> {
        if self.budget == 0 {
            warn!(port = %s.port, "fw102c: port lost; no reconnection left");
            return Step::Done(Err(Fw102cError::Disconnected {
                port: s.port.clone(),
                attempts: s.config.reconnect_attempts,
                source: lost,
            }));
        }
        self.budget -= 1;
        warn!(port = %s.port, error = %lost, "fw102c: port lost; reopening it after a pause");
        self.state = State::Pausing(cx.now.saturating_add(s.config.reconnect_delay()));
        Step::Wait(self.pending())
    }

    fn fault(&mut self, s: &mut Fw102cSession, cx: &mut Cx, e: Fw102cError) -> Step<Out> {
        cx.clear_input();
        if self.retries > 0 && e.is_transient() {
            warn!(command = %self.command, error = %e, "fw102c: no usable reply; sending again");
            self.retries -= 1;
            s.retried += 1;
            self.state = State::Sending;
            return Step::Wait(self.pending());
        }
        warn!(command = %self.command, error = %e, "fw102c: command failed");
        Step::Done(Err(e))
    }

    fn garbled(
        &mut self,
        s: &mut Fw102cSession,
        cx: &mut Cx,
        line: &[u8],
        source: crate::fw102c::ReplyError,
    ) -> Step<Out> {
        let e = Fw102cError::Protocol {
            command: self.command.to_string(),
            reply: line.to_vec(),
            source,
        };
        self.fault(s, cx, e)
    }

    fn line(&mut self, s: &mut Fw102cSession, cx: &mut Cx, line: &[u8]) -> Step<Out> {
        match (self.state, Line::classify(line)) {
            (_, Line::Blank) => Step::Wait(self.pending()),
            (State::Echo(_), Line::Error(e)) => {
                // Before this command's echo: the refusal of the set sent before it.
                let refused = self.after.unwrap_or(self.command);
                // This command's own echo and answer may still come: drop them.
                cx.clear_input();
                warn!(command = %refused, error = %e, "fw102c: command refused");
                Step::Done(Err(Fw102cError::Refused {
                    command: refused.to_string(),
                    code: e.code,
                }))
            }
            (State::Value(_), Line::Error(e)) => {
                cx.clear_input();
                warn!(command = %self.command, error = %e, "fw102c: command refused");
                Step::Done(Err(Fw102cError::Refused {
                    command: self.command.to_string(),
                    code: e.code,
                }))
            }
            (State::Echo(_), Line::Text(t)) if is_echo(&self.command, t) => {
                if self.command.is_query() {
                    self.state = State::Value(cx.now.saturating_add(s.config.timeout()));
                    Step::Wait(self.pending())
                } else {
                    Step::Done(Ok(None))
                }
            }
            (State::Echo(_), Line::Text(_)) => {
                self.garbled(s, cx, line, crate::fw102c::ReplyError::BadValue)
            }
            (State::Value(_), Line::Text(t)) => match Reply::parse(&self.command, t) {
                Ok(r) => Step::Done(Ok(Some(r))),
                Err(source) => self.garbled(s, cx, line, source),
            },
            _ => Step::Wait(self.pending()),
        }
    }
}

impl Machine<Fw102cSession> for Exchange {
    type Output = Out;

    fn step(&mut self, s: &mut Fw102cSession, cx: &mut Cx, ev: Event<'_>) -> Step<Out> {
        let transport = |command: Command, source| Fw102cError::Transport {
            command: command.to_string(),
            source,
        };
        match (self.state, ev) {
            (_, Event::Start) => self.state = State::Sending,
            (State::Sending, Event::Sent(Ok(()))) => {
                let due = cx.now.saturating_add(s.config.timeout()).max(self.until);
                self.state = State::Echo(due);
            }
            (State::Sending, Event::Sent(Err(e @ TransportError::Disconnected { .. })))
            | (
                State::Echo(_) | State::Value(_),
                Event::LinkError(e @ TransportError::Disconnected { .. }),
            ) => return self.recover(s, cx, e),
            (State::Sending, Event::Sent(Err(e)))
            | (State::Echo(_) | State::Value(_), Event::LinkError(e)) => {
                return self.fault(s, cx, transport(self.command, e));
            }
            (State::Echo(_) | State::Value(_), Event::Line(line)) => return self.line(s, cx, line),
            (State::Pausing(_), Event::Timer) => self.state = State::Reconnecting,
            (State::Reconnecting, Event::Reconnected(Ok(()))) => {
                s.reconnects += 1;
                // The wheel may have been moved or power-cycled meanwhile.
                s.position = None;
                debug!(port = %s.port, reconnects = s.reconnects, "fw102c: port reopened");
                self.state = State::Sending;
            }
            (
                State::Reconnecting,
                Event::Reconnected(Err(e @ TransportError::Disconnected { .. })),
            ) => return self.recover(s, cx, e),
            (State::Reconnecting, Event::Reconnected(Err(e))) => {
                return Step::Done(Err(transport(self.command, e)));
            }
            _ => {}
        }
        Step::Wait(self.pending())
    }
}
