//! One command on the wire, with the lock-in's link policy.

use std::time::Duration;

use tracing::{debug, warn};

use super::{Sr830Session, is_transient};
use crate::TransportError;
use crate::machine::{Cx, Event, Machine, Pending, Step};
use crate::sr830::{Command, FilterSlope, Interface, Reply, Sensitivity, Sr830Error, TimeConstant};

/// Sends a command and, for a query, reads its reply.
///
/// - A vanished port (on send, on receive, or while recovering) is reopened after a
///   pause, `OUTX 0` re-sent (replies go to GPIB otherwise), and the command sent
///   again; `reconnect_attempts` reopenings are allowed per command.
/// - Any other fault clears the input (a late or partial reply must not be read as
///   the next one's); a lost or garbled answer to a query that only reads is asked
///   again, up to `retries` times. The status bytes are never asked again: reading
///   them clears them, so a second read could report a latched overload as gone.
/// - `SENS`, `OFLT`, `OFSL` and `*RST` update the settings the session tracks and
///   restart the settling wait. (`AGAN`, whose settings are read back, is left to the
///   operation that sent it.)
#[derive(Debug)]
pub(super) struct Exchange {
    command: Command,
    bytes: Vec<u8>,
    /// Reopenings left.
    budget: u32,
    /// Re-asks left.
    retries: u32,
    state: State,
}

#[derive(Debug, Clone, Copy)]
enum State {
    /// The command's bytes are going out.
    Sending,
    /// Its reply is due by then.
    Receiving(Duration),
    /// Waiting before reopening the port, until then.
    Pausing(Duration),
    /// Reopening the port.
    Reconnecting,
    /// `OUTX 0` is going out on the reopened port.
    SendingOutx,
}

impl Exchange {
    pub(super) fn new(s: &Sr830Session, command: Command) -> Self {
        Exchange {
            bytes: command.to_bytes(),
            budget: s.config.reconnect_attempts,
            retries: if rereadable(&command) {
                s.config.retries
            } else {
                0
            },
            command,
            state: State::Sending,
        }
    }

    /// The command as sent, without terminator.
    fn name(&self) -> String {
        String::from_utf8_lossy(&self.bytes).trim_end().to_string()
    }

    fn pending(&self) -> Pending {
        match self.state {
            State::Sending => Pending::Transmit(self.bytes.clone()),
            State::Receiving(t) => Pending::Reply(t),
            State::Pausing(t) => Pending::Sleep(t),
            State::Reconnecting => Pending::Reconnect,
            State::SendingOutx => Pending::Transmit(outx()),
        }
    }

    /// The port vanished (`lost` is the last sign of it): pause before reopening it,
    /// or give up when the budget is spent.
    fn recover(
        &mut self,
        s: &Sr830Session,
        cx: &Cx,
        lost: TransportError,
    ) -> Step<Result<Option<Reply>, Sr830Error>> {
        if self.budget == 0 {
            warn!(
                port = %s.port,
                attempts = s.config.reconnect_attempts,
                "sr830: port lost; no reconnection left",
            );
            return Step::Done(Err(Sr830Error::Disconnected {
                port: s.port.clone(),
                attempts: s.config.reconnect_attempts,
                source: lost,
            }));
        }
        self.budget -= 1;
        warn!(port = %s.port, error = %lost, "sr830: port lost; reopening it after a pause");
        self.state = State::Pausing(cx.now.saturating_add(s.config.reconnect_delay()));
        Step::Wait(self.pending())
    }

    /// A fault other than a vanished port: ask again if allowed, else fail.
    fn fault(
        &mut self,
        s: &mut Sr830Session,
        cx: &mut Cx,
        e: Sr830Error,
    ) -> Step<Result<Option<Reply>, Sr830Error>> {
        cx.clear_input();
        if self.retries > 0 && is_transient(&e) {
            warn!(command = %self.name(), error = %e, "sr830: no usable reply; asking again");
            self.retries -= 1;
            s.retried += 1;
            self.state = State::Sending;
            return Step::Wait(self.pending());
        }
        warn!(command = %self.name(), error = %e, "sr830: command failed");
        Step::Done(Err(e))
    }

    /// The exchange succeeded: track what it set.
    fn finish(
        &self,
        s: &mut Sr830Session,
        cx: &Cx,
        reply: Option<Reply>,
    ) -> Step<Result<Option<Reply>, Sr830Error>> {
        match self.command {
            Command::SetSensitivity(x) => s.sensitivity = x,
            Command::SetTimeConstant(t) => s.time_constant = t,
            Command::SetSlope(x) => s.slope = x,
            Command::Reset => {
                s.sensitivity = Sensitivity::default();
                s.time_constant = TimeConstant::default();
                s.slope = FilterSlope::default();
            }
            _ => return Step::Done(Ok(reply)),
        }
        s.mark_unsettled(cx.now);
        Step::Done(Ok(reply))
    }
}

/// `OUTX 0`, the line that takes the link.
fn outx() -> Vec<u8> {
    Command::SetInterface(Interface::Rs232).to_bytes()
}

/// Queries that read without side effects, so that asking again is harmless.
fn rereadable(c: &Command) -> bool {
    c.expects_reply()
        && !matches!(
            c,
            Command::LiaStatus(_) | Command::ErrorStatus(_) | Command::EventStatus(_)
        )
}

impl Machine<Sr830Session> for Exchange {
    type Output = Result<Option<Reply>, Sr830Error>;

    fn step(&mut self, s: &mut Sr830Session, cx: &mut Cx, ev: Event<'_>) -> Step<Self::Output> {
        let transport = |name: String, source| Sr830Error::Transport {
            command: name,
            source,
        };
        match (self.state, ev) {
            (_, Event::Start) => self.state = State::Sending,
            (State::Sending, Event::Sent(Ok(()))) => {
                if !self.command.expects_reply() {
                    return self.finish(s, cx, None);
                }
                self.state = State::Receiving(cx.now.saturating_add(s.config.timeout()));
            }
            (State::Sending, Event::Sent(Err(e @ TransportError::Disconnected { .. })))
            | (State::Receiving(_), Event::LinkError(e @ TransportError::Disconnected { .. })) => {
                return self.recover(s, cx, e);
            }
            (State::Sending, Event::Sent(Err(e))) | (State::Receiving(_), Event::LinkError(e)) => {
                return self.fault(s, cx, transport(self.name(), e));
            }
            (State::Receiving(_), Event::Line(line)) => {
                return match Reply::parse(&self.command, line) {
                    Ok(r) => self.finish(s, cx, Some(r)),
                    Err(source) => {
                        let e = Sr830Error::Protocol {
                            command: self.name(),
                            reply: line.to_vec(),
                            source,
                        };
                        self.fault(s, cx, e)
                    }
                };
            }
            (State::Pausing(_), Event::Timer) => self.state = State::Reconnecting,
            (State::Reconnecting, Event::Reconnected(Ok(()))) => self.state = State::SendingOutx,
            (
                State::Reconnecting,
                Event::Reconnected(Err(e @ TransportError::Disconnected { .. })),
            )
            | (State::SendingOutx, Event::Sent(Err(e @ TransportError::Disconnected { .. }))) => {
                return self.recover(s, cx, e);
            }
            (State::Reconnecting, Event::Reconnected(Err(e)))
            | (State::SendingOutx, Event::Sent(Err(e))) => {
                return Step::Done(Err(transport("OUTX 0".into(), e)));
            }
            (State::SendingOutx, Event::Sent(Ok(()))) => {
                s.reconnects += 1;
                debug!(
                    port = %s.port,
                    reconnects = s.reconnects,
                    "sr830: port reopened; OUTX 0 re-sent",
                );
                // The instrument may have restarted: let its filters settle again.
                s.mark_unsettled(cx.now);
                self.state = State::Sending;
            }
            // Not what this step waits for: keep waiting.
            _ => {}
        }
        Step::Wait(self.pending())
    }
}
