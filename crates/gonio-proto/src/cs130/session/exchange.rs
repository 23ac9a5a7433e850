//! One statement on the wire, with the monochromator's link policy.

use std::time::Duration;

use tracing::{debug, warn};

use super::{Cs130Session, is_transient};
use crate::TransportError;
use crate::cs130::{Command, Cs130Error, Reply, ReplyError, is_echo};
use crate::machine::{Cx, Event, Machine, Pending, Step};

/// Sends a statement, reads its echo (when the config says the instrument echoes,
/// §15.4) and, for a query, its answer.
///
/// - Echo and answer are each due `timeout` after the statement was sent. After a
///   `*WAI` (§15.8) the instrument holds later statements until the move is done,
///   and after `GRAT`, `FILTER` or `GOWAVE` it may be busy (the manual does not say
///   whether it echoes meanwhile: **UNCONFIRMED**), so until a query has been
///   answered they are due `move_timeout` after.
/// - A line that is not the echo, or not a valid answer, is a protocol fault.
/// - A vanished port (on send, on receive) is reopened after a pause and the
///   statement sent again; `reconnect_attempts` reopenings are allowed per statement.
/// - Any other fault clears the input (a late line must not be taken for the next
///   statement's) and re-sends a repeatable statement up to `retries` times: every
///   statement but `STB?` and `ERROR?`, whose reading clears what they report
///   (§15.9). Set statements are absolute, so sending one twice is harmless.
#[derive(Debug)]
pub(super) struct Exchange {
    command: Command,
    bytes: Vec<u8>,
    /// Reopenings left.
    budget: u32,
    /// Re-sends left.
    retries: u32,
    state: State,
}

#[derive(Debug, Clone, Copy)]
enum State {
    /// The statement's bytes are going out.
    Sending,
    /// Its echo is due by then.
    Echo(Duration),
    /// Its answer is due by then.
    Answer(Duration),
    /// Waiting before reopening the port, until then.
    Pausing(Duration),
    /// Reopening the port.
    Reconnecting,
}

type Out = Step<Result<Option<Reply>, Cs130Error>>;

impl Exchange {
    pub(super) fn new(s: &Cs130Session, command: Command) -> Self {
        Exchange {
            bytes: command.to_bytes(),
            budget: s.config.reconnect_attempts,
            retries: if command.is_repeatable() {
                s.config.retries
            } else {
                0
            },
            command,
            state: State::Sending,
        }
    }

    /// The statement as sent, without terminator.
    fn name(&self) -> String {
        String::from_utf8_lossy(&self.bytes).trim_end().to_string()
    }

    fn pending(&self) -> Pending {
        match self.state {
            State::Sending => Pending::Transmit(self.bytes.clone()),
            State::Echo(t) | State::Answer(t) => Pending::Reply(t),
            State::Pausing(t) => Pending::Sleep(t),
            State::Reconnecting => Pending::Reconnect,
        }
    }

    fn recover(&mut self, s: &Cs130Session, cx: &Cx, lost: TransportError) -> Out {
        if self.budget == 0 {
            warn!(port = %s.port, attempts = s.config.reconnect_attempts, "cs130: port lost; no reconnection left");
            return Step::Done(Err(Cs130Error::Disconnected {
                port: s.port.clone(),
                attempts: s.config.reconnect_attempts,
                source: lost,
            }));
        }
        self.budget -= 1;
        warn!(port = %s.port, error = %lost, "cs130: port lost; reopening it after a pause");
        self.state = State::Pausing(cx.now.saturating_add(s.config.reconnect_delay()));
        Step::Wait(self.pending())
    }

    fn fault(&mut self, s: &mut Cs130Session, cx: &mut Cx, e: Cs130Error) -> Out {
        cx.clear_input();
        if self.retries > 0 && is_transient(&e) {
            warn!(command = %self.name(), error = %e, "cs130: no usable echo or answer; sending again");
            self.retries -= 1;
            s.retried += 1;
            self.state = State::Sending;
            return Step::Wait(self.pending());
        }
        warn!(command = %self.name(), error = %e, "cs130: statement failed");
        Step::Done(Err(e))
    }

    fn protocol(&self, line: &[u8], source: ReplyError) -> Cs130Error {
        Cs130Error::Protocol {
            command: self.name(),
            reply: line.to_vec(),
            source,
        }
    }

    /// Sent: the echo (or the answer, without echo) is due.
    fn sent(&mut self, s: &Cs130Session, cx: &Cx) -> Out {
        let wait = if s.held {
            s.config.move_timeout()
        } else {
            s.config.timeout()
        };
        let due = cx.now.saturating_add(wait);
        self.state = if s.config.echo {
            State::Echo(due)
        } else if self.command.is_query() {
            State::Answer(due)
        } else {
            return Self::finish(None);
        };
        Step::Wait(self.pending())
    }

    fn finish(reply: Option<Reply>) -> Out {
        Step::Done(Ok(reply))
    }
}

impl Machine<Cs130Session> for Exchange {
    type Output = Result<Option<Reply>, Cs130Error>;

    fn step(&mut self, s: &mut Cs130Session, cx: &mut Cx, ev: Event<'_>) -> Step<Self::Output> {
        let transport = |command: String, source| Cs130Error::Transport { command, source };
        match (self.state, ev) {
            (_, Event::Start) => self.state = State::Sending,
            (State::Sending, Event::Sent(Ok(()))) => return self.sent(s, cx),
            (State::Sending, Event::Sent(Err(e @ TransportError::Disconnected { .. })))
            | (
                State::Echo(_) | State::Answer(_),
                Event::LinkError(e @ TransportError::Disconnected { .. }),
            ) => return self.recover(s, cx, e),
            (State::Sending, Event::Sent(Err(e)))
            | (State::Echo(_) | State::Answer(_), Event::LinkError(e)) => {
                return self.fault(s, cx, transport(self.name(), e));
            }
            (State::Echo(due), Event::Line(line)) => {
                if !is_echo(&self.command, line) {
                    let e = self.protocol(line, ReplyError::BadEcho);
                    return self.fault(s, cx, e);
                }
                if !self.command.is_query() {
                    if self.command.moves() {
                        // After `*WAI` every later statement waits for the move
                        // (§15.8); after a statement that starts one, whether the
                        // instrument echoes while it moves is not documented.
                        s.held = true;
                    }
                    return Self::finish(None);
                }
                self.state = State::Answer(due);
            }
            (State::Answer(_), Event::Line(line)) => {
                return match Reply::parse(&self.command, line) {
                    Ok(r) => {
                        // A query has been answered: whatever `*WAI` held is done.
                        s.held = false;
                        Self::finish(Some(r))
                    }
                    Err(source) => {
                        let e = self.protocol(line, source);
                        self.fault(s, cx, e)
                    }
                };
            }
            (State::Pausing(_), Event::Timer) => self.state = State::Reconnecting,
            (State::Reconnecting, Event::Reconnected(Ok(()))) => {
                s.reconnects += 1;
                debug!(port = %s.port, reconnects = s.reconnects, "cs130: port reopened");
                self.state = State::Sending;
            }
            (
                State::Reconnecting,
                Event::Reconnected(Err(e @ TransportError::Disconnected { .. })),
            ) => return self.recover(s, cx, e),
            (State::Reconnecting, Event::Reconnected(Err(e))) => {
                return Step::Done(Err(transport(self.name(), e)));
            }
            // Not what this step waits for: keep waiting.
            _ => {}
        }
        Step::Wait(self.pending())
    }
}
