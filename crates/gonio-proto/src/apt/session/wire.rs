//! One message on the wire, with the link policy: a vanished port is reopened a
//! bounded number of times; while a reply is awaited, the controller's status updates
//! and completion messages are noted; a lost, late or garbled reply is asked again
//! only for queries. The keep-alive is not an exchange: the pump sends it on its
//! clock ([`AptSession::keepalive`]).

use std::time::Duration;

use tracing::{debug, warn};

use super::AptSession;
use crate::TransportError;
use crate::apt::{Message, Packet};
use crate::machine::{Cx, Event, Machine, Pending, Step, drive};
use crate::motion::AxisError;

/// Sends one message. When the port has vanished, reopens it (one attempt, then up to
/// `reconnect_attempts` more, `reconnect_delay` apart) and sends once more: the bytes
/// never left, so even a relative move may go.
#[derive(Debug)]
pub(super) struct Transfer {
    bytes: Vec<u8>,
    state: TransferState,
}

#[derive(Debug, Clone, Copy)]
enum TransferState {
    First,
    Reconnecting(usize),
    Pausing(usize, Duration),
    Again,
}

impl Transfer {
    pub(super) fn new(m: &Message) -> Self {
        Transfer {
            bytes: m.to_bytes(),
            state: TransferState::First,
        }
    }

    fn pending(&self) -> Pending {
        match self.state {
            TransferState::First | TransferState::Again => Pending::Transmit(self.bytes.clone()),
            TransferState::Reconnecting(_) => Pending::Reconnect,
            TransferState::Pausing(_, until) => Pending::Sleep(until),
        }
    }
}

impl Machine<AptSession> for Transfer {
    type Output = Result<(), AxisError>;

    fn step(&mut self, s: &mut AptSession, cx: &mut Cx, ev: Event<'_>) -> Step<Self::Output> {
        match (self.state, ev) {
            (_, Event::Start) => self.state = TransferState::First,
            (TransferState::First, Event::Sent(Err(e @ TransportError::Disconnected { .. }))) => {
                warn!(error = %e, "apt: port lost; reopening it");
                self.state = TransferState::Reconnecting(0);
            }
            (TransferState::First | TransferState::Again, Event::Sent(r)) => {
                return Step::Done(r.map_err(AxisError::from));
            }
            (TransferState::Reconnecting(_), Event::Reconnected(Ok(()))) => {
                debug!("apt: port reopened");
                self.state = TransferState::Again;
            }
            (TransferState::Reconnecting(attempt), Event::Reconnected(Err(e))) => {
                if attempt >= s.policy.reconnect_attempts {
                    warn!(attempts = attempt + 1, error = %e, "apt: port still gone; giving up");
                    return Step::Done(Err(AxisError::Transport(e)));
                }
                warn!(attempt = attempt + 1, error = %e, "apt: reopening the port failed");
                let until = cx.now.saturating_add(s.policy.reconnect_delay);
                self.state = TransferState::Pausing(attempt + 1, until);
            }
            (TransferState::Pausing(attempt, _), Event::Timer) => {
                self.state = TransferState::Reconnecting(attempt);
            }
            _ => {}
        }
        Step::Wait(self.pending())
    }
}

/// Which messages a wait takes as its answer.
pub(super) type Want = fn(&Message) -> bool;

/// Waits until `until` for a message that `want` accepts. On the way: a status update
/// is counted; `MOVE_COMPLETED`, `MOVE_STOPPED` and `MOVE_HOMED` are noted for the
/// operation; an error report (`HW_RESPONSE`, `HW_RICHRESPONSE`) ends the wait with
/// [`AxisError::Device`]; anything else is skipped.
#[derive(Debug)]
pub(super) struct Wait {
    want: Want,
    until: Duration,
    /// What the wait answers, by name, for errors.
    after: &'static str,
}

impl Wait {
    pub(super) fn new(want: Want, until: Duration, after: &'static str) -> Self {
        Wait { want, until, after }
    }
}

impl Machine<AptSession> for Wait {
    type Output = Result<Message, AxisError>;

    fn step(&mut self, s: &mut AptSession, _cx: &mut Cx, ev: Event<'_>) -> Step<Self::Output> {
        let message = match ev {
            Event::Line(bytes) => match Packet::parse(bytes) {
                Ok(p) => {
                    s.heard(
                        &p.message,
                        bytes.len().saturating_sub(crate::apt::HEADER_LEN),
                    );
                    p.message
                }
                Err(e) => {
                    debug!(error = %e, "apt: skipping a message that does not parse");
                    return Step::Wait(Pending::Reply(self.until));
                }
            },
            Event::LinkError(e) => return Step::Done(Err(AxisError::Transport(e))),
            _ => return Step::Wait(Pending::Reply(self.until)),
        };
        let update = s.status_of(&message).is_some();
        let wanted = (self.want)(&message);
        if update && (s.updates_on || !wanted) {
            s.updates += 1;
        }
        if wanted {
            return Step::Done(Ok(message));
        }
        match &message {
            Message::GetDcStatusUpdate(_) | Message::GetStatusUpdate(_) if update => {
                // Updates flow only when asked for (or left on by another host).
                s.updates_on = true;
            }
            Message::MoveCompleted { status, .. } => {
                debug!("apt: move completed");
                s.seen.completed = Some(*status);
                s.completions += 1;
            }
            Message::MoveStopped { status, .. } => {
                debug!("apt: move stopped");
                s.seen.stopped = Some(*status);
            }
            Message::MoveHomed { .. } => {
                debug!("apt: homed");
                s.seen.homed = true;
            }
            Message::HwResponse => {
                warn!(after = self.after, "apt: the controller reported an error");
                return Step::Done(Err(AxisError::Device {
                    command: self.after.into(),
                    reason: "HW_RESPONSE (an unspecified error)".into(),
                }));
            }
            Message::HwRichResponse {
                msg_id,
                code,
                notes,
            } => {
                warn!(after = self.after, code, %notes, "apt: the controller reported an error");
                return Step::Done(Err(AxisError::Device {
                    command: self.after.into(),
                    reason: format!("error {code} on message {msg_id:#06x}: {notes}"),
                }));
            }
            other => debug!(
                message = other.name(),
                "apt: skipping an unsolicited message"
            ),
        }
        Step::Wait(Pending::Reply(self.until))
    }
}

/// A request and its answer, asked again after a lost, late or garbled answer when
/// `retry`, up to `retries` times.
#[derive(Debug)]
pub(super) struct Query {
    request: Message,
    want: Want,
    attempts: usize,
    attempt: usize,
    state: QueryState,
}

#[derive(Debug)]
enum QueryState {
    /// While status updates flow, a status request is not sent: the next update is
    /// the answer (a reply to a request would queue behind the updates and be stale).
    /// This is the wait for it, made on the first event.
    Listen(Option<Wait>),
    Sending(Transfer),
    Waiting(Wait),
}

impl Query {
    pub(super) fn new(s: &AptSession, request: Message, want: Want, retry: bool) -> Self {
        let listen = s.updates_on
            && matches!(
                request,
                Message::ReqDcStatusUpdate { .. } | Message::ReqStatusUpdate { .. }
            );
        Query {
            state: if listen {
                QueryState::Listen(None)
            } else {
                QueryState::Sending(Transfer::new(&request))
            },
            request,
            want,
            attempts: if retry { s.policy.retries + 1 } else { 1 },
            attempt: 0,
        }
    }
}

impl Machine<AptSession> for Query {
    type Output = Result<Message, AxisError>;

    fn step(&mut self, s: &mut AptSession, cx: &mut Cx, mut ev: Event<'_>) -> Step<Self::Output> {
        loop {
            let failure = match &mut self.state {
                QueryState::Listen(w) => {
                    let w = w.get_or_insert_with(|| {
                        // Three reply timeouts: longer than the 100 ms update period.
                        let until = cx
                            .now
                            .saturating_add(s.policy.reply_timeout.saturating_mul(3));
                        Wait::new(self.want, until, self.request.name())
                    });
                    match drive!(w, s, cx, ev) {
                        Ok(m) => return Step::Done(Ok(m)),
                        Err(AxisError::Transport(TransportError::Timeout(_))) => {
                            debug!("apt: no status update came; asking for the status");
                            s.updates_on = false;
                            self.state = QueryState::Sending(Transfer::new(&self.request));
                            ev = Event::Start;
                            continue;
                        }
                        Err(e) => return Step::Done(Err(e)),
                    }
                }
                QueryState::Sending(t) => {
                    if let Err(e) = drive!(t, s, cx, ev) {
                        return Step::Done(Err(e));
                    }
                    let until = cx.now.saturating_add(s.policy.reply_timeout);
                    self.state =
                        QueryState::Waiting(Wait::new(self.want, until, self.request.name()));
                    ev = Event::Start;
                    continue;
                }
                QueryState::Waiting(w) => match drive!(w, s, cx, ev) {
                    Ok(m) => return Step::Done(Ok(m)),
                    Err(
                        e @ AxisError::Transport(
                            TransportError::Timeout(_)
                            | TransportError::Garbled(_)
                            | TransportError::LineTooLong,
                        ),
                    ) => e,
                    Err(e) => return Step::Done(Err(e)),
                },
            };
            cx.clear_input();
            self.attempt += 1;
            if self.attempt >= self.attempts {
                if self.attempts > 1 {
                    warn!(request = self.request.name(), error = %failure, "apt: no usable reply");
                }
                return Step::Done(Err(failure));
            }
            warn!(
                request = self.request.name(),
                error = %failure,
                "apt: no usable reply; asking again",
            );
            s.retried += 1;
            self.state = QueryState::Sending(Transfer::new(&self.request));
            ev = Event::Start;
        }
    }
}
