//! One command on the wire, with the picoammeter's link policy.

use std::time::Duration;

use tracing::{debug, warn};

use super::{K6485Session, is_transient};
use crate::TransportError;
use crate::k6485::{Command, K6485Error, Range, Reply};
use crate::machine::{Cx, Event, Machine, Pending, Step};

/// Sends a command and, for a query, reads its reply.
///
/// - The instrument runs commands in order, and `INIT` and `READ?` keep it measuring
///   for the integration time × the repeat filter's count: the session tracks when it
///   will be free (`busy_until`), and a reply is due the reply timeout after that.
/// - A vanished port (on send, on receive) is reopened after a pause and the command
///   sent again; `reconnect_attempts` reopenings are allowed per command. Nothing
///   needs re-sending on a reopened RS-232 link (unlike the SR830's `OUTX 0`).
/// - Any other fault clears the input (a late reply must not be read as the next
///   one's); a lost or garbled answer to a query that only reads (`*IDN?`,
///   `CURR:RANG?`, `SYST:LFR?`, `READ?`, `FETC?`) is asked again, up to `retries`
///   times. `SYST:ERR?` and `*ESR?` are never asked again: reading them clears what
///   they report.
/// - `CURR:RANG` and `*RST` update the range the session tracks and start the wait
///   after a range change.
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
}

/// Queries that read without side effects, so that asking again is harmless (`READ?`
/// takes a fresh reading, which is what was asked for).
fn rereadable(c: &Command) -> bool {
    c.is_query() && !matches!(c, Command::NextError | Command::EventStatus)
}

impl Exchange {
    pub(super) fn new(s: &K6485Session, command: Command) -> Self {
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
        }
    }

    /// The port vanished: pause before reopening it, or give up when the budget is
    /// spent.
    fn recover(
        &mut self,
        s: &K6485Session,
        cx: &Cx,
        lost: TransportError,
    ) -> Step<Result<Option<Reply>, K6485Error>> {
        if self.budget == 0 {
            warn!(
                port = %s.port,
                attempts = s.config.reconnect_attempts,
                "k6485: port lost; no reconnection left",
            );
            return Step::Done(Err(K6485Error::Disconnected {
                port: s.port.clone(),
                attempts: s.config.reconnect_attempts,
                source: lost,
            }));
        }
        self.budget -= 1;
        warn!(port = %s.port, error = %lost, "k6485: port lost; reopening it after a pause");
        self.state = State::Pausing(cx.now.saturating_add(s.config.reconnect_delay()));
        Step::Wait(self.pending())
    }

    /// A fault other than a vanished port: ask again if allowed, else fail.
    fn fault(
        &mut self,
        s: &mut K6485Session,
        cx: &mut Cx,
        e: K6485Error,
    ) -> Step<Result<Option<Reply>, K6485Error>> {
        cx.clear_input();
        if self.retries > 0 && is_transient(&e) {
            warn!(command = %self.name(), error = %e, "k6485: no usable reply; asking again");
            self.retries -= 1;
            s.retried += 1;
            self.state = State::Sending;
            return Step::Wait(self.pending());
        }
        warn!(command = %self.name(), error = %e, "k6485: command failed");
        Step::Done(Err(e))
    }

    /// Sent: the instrument is busy measuring for `INIT` and `READ?`; a query's reply
    /// is due the timeout after it is free.
    fn sent(&mut self, s: &mut K6485Session, cx: &Cx) -> Step<Result<Option<Reply>, K6485Error>> {
        let start = s.busy_until.max(cx.now);
        s.busy_until = match self.command {
            Command::Initiate | Command::Read => start.saturating_add(s.read_time()),
            _ => start,
        };
        if !self.command.is_query() {
            return self.finish(s, cx, None);
        }
        self.state = State::Receiving(s.busy_until.saturating_add(s.config.timeout()));
        Step::Wait(self.pending())
    }

    /// The exchange succeeded: track what it set.
    fn finish(
        &self,
        s: &mut K6485Session,
        cx: &Cx,
        reply: Option<Reply>,
    ) -> Step<Result<Option<Reply>, K6485Error>> {
        match self.command {
            Command::SetRange(r) => s.range_changed(cx.now, r),
            Command::Reset => s.range_changed(cx.now, Range::default()),
            _ => {}
        }
        Step::Done(Ok(reply))
    }
}

impl Machine<K6485Session> for Exchange {
    type Output = Result<Option<Reply>, K6485Error>;

    fn step(&mut self, s: &mut K6485Session, cx: &mut Cx, ev: Event<'_>) -> Step<Self::Output> {
        let transport = |name: String, source| K6485Error::Transport {
            command: name,
            source,
        };
        match (self.state, ev) {
            (_, Event::Start) => self.state = State::Sending,
            (State::Sending, Event::Sent(Ok(()))) => return self.sent(s, cx),
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
                        let e = K6485Error::Protocol {
                            command: self.name(),
                            reply: line.to_vec(),
                            source,
                        };
                        self.fault(s, cx, e)
                    }
                };
            }
            (State::Pausing(_), Event::Timer) => self.state = State::Reconnecting,
            (State::Reconnecting, Event::Reconnected(Ok(()))) => {
                s.reconnects += 1;
                debug!(port = %s.port, reconnects = s.reconnects, "k6485: port reopened");
                // Whatever the instrument was doing is unknown now.
                s.busy_until = cx.now;
                s.mark_unsettled(cx.now);
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
