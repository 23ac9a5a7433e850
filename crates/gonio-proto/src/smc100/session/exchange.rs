//! One command on the wire, with the chain's link policy: a vanished port is reopened
//! a bounded number of times; a lost, late or garbled reply is asked again only when
//! asking again is harmless; every set or action command is checked with `TE`; a stop
//! reaches every stage.

use std::time::Duration;

use tracing::{debug, warn};

use super::{Smc100Session, line_text};
use crate::TransportError;
use crate::machine::{Cx, Event, Machine, Pending, Step, drive};
use crate::smc100::{
    AxisError, Command, DumpReader, ErrorCode, Frame, MotionError, Param, Reply, ReplyBody,
    Smc100Parameters,
};

/// Sends one command line. When the port has vanished, reopens it (one attempt, then
/// up to `reconnect_attempts` more, `reconnect_delay` apart) and sends once more.
#[derive(Debug)]
pub(super) struct Transfer {
    bytes: Vec<u8>,
    state: TransferState,
}

#[derive(Debug, Clone, Copy)]
enum TransferState {
    /// The first send.
    First,
    /// Reopening; the number is the attempt (0 for the first).
    Reconnecting(usize),
    /// Waiting before the given attempt, until the given time.
    Pausing(usize, Duration),
    /// The send after the port was reopened.
    Again,
}

impl Transfer {
    pub(super) fn new(frame: &Frame) -> Self {
        Transfer {
            bytes: frame.to_bytes(),
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

impl Machine<Smc100Session> for Transfer {
    type Output = Result<(), AxisError>;

    fn step(&mut self, s: &mut Smc100Session, cx: &mut Cx, ev: Event<'_>) -> Step<Self::Output> {
        match (self.state, ev) {
            (_, Event::Start) => self.state = TransferState::First,
            (TransferState::First, Event::Sent(Err(e @ TransportError::Disconnected { .. }))) => {
                warn!(error = %e, "smc100: port lost; reopening it");
                self.state = TransferState::Reconnecting(0);
            }
            (TransferState::First | TransferState::Again, Event::Sent(r)) => {
                return Step::Done(r.map_err(AxisError::from));
            }
            (TransferState::Reconnecting(_), Event::Reconnected(Ok(()))) => {
                debug!("smc100: port reopened");
                self.state = TransferState::Again;
            }
            (TransferState::Reconnecting(attempt), Event::Reconnected(Err(e))) => {
                if attempt >= s.policy.reconnect_attempts {
                    warn!(attempts = attempt + 1, error = %e, "smc100: port still gone; giving up");
                    return Step::Done(Err(AxisError::Transport(e)));
                }
                warn!(attempt = attempt + 1, error = %e, "smc100: reopening the port failed");
                let until = cx.now.saturating_add(s.policy.reconnect_delay);
                self.state = TransferState::Pausing(attempt + 1, until);
            }
            (TransferState::Pausing(attempt, _), Event::Timer) => {
                self.state = TransferState::Reconnecting(attempt);
            }
            // Not what this step waits for: keep waiting.
            _ => {}
        }
        Step::Wait(self.pending())
    }
}

/// A query and its reply. Lines that answer another command (a late reply to an
/// earlier one, another controller's) are skipped until the reply timeout. A lost,
/// late or garbled reply clears the input and, when `retry`, the query is sent again,
/// up to `retries` times; a NUL byte means the controller lost power.
#[derive(Debug)]
pub(super) struct Query {
    frame: Frame,
    attempts: usize,
    attempt: usize,
    state: QueryState,
}

#[derive(Debug)]
enum QueryState {
    Sending(Transfer),
    Reading(Duration),
}

impl Query {
    pub(super) fn new(s: &Smc100Session, axis: usize, command: Command, retry: bool) -> Self {
        let frame = s.frame(axis, command);
        Query {
            state: QueryState::Sending(Transfer::new(&frame)),
            frame,
            attempts: if retry { s.policy.retries + 1 } else { 1 },
            attempt: 0,
        }
    }

    fn protocol(&self, line: &[u8], reason: String) -> AxisError {
        AxisError::Protocol {
            sent: line_text(&self.frame.to_bytes()),
            reply: line_text(line),
            reason,
        }
    }
}

impl Machine<Smc100Session> for Query {
    type Output = Result<ReplyBody, AxisError>;

    fn step(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        mut ev: Event<'_>,
    ) -> Step<Self::Output> {
        loop {
            let deadline = match &mut self.state {
                QueryState::Sending(t) => {
                    if let Err(e) = drive!(t, s, cx, ev) {
                        return Step::Done(Err(e));
                    }
                    let deadline = cx.now.saturating_add(s.policy.reply_timeout);
                    self.state = QueryState::Reading(deadline);
                    return Step::Wait(Pending::Reply(deadline));
                }
                QueryState::Reading(deadline) => *deadline,
            };
            let failure = match ev {
                Event::Line(line) => match Reply::parse(line) {
                    Ok(r) if r.answers(&self.frame) => return Step::Done(Ok(r.body)),
                    Ok(_) if cx.now < deadline => {
                        debug!(
                            reply = %line_text(line),
                            "smc100: skipping a reply to another command",
                        );
                        return Step::Wait(Pending::Reply(deadline));
                    }
                    Ok(_) => self.protocol(line, "answers another command".into()),
                    Err(e) => self.protocol(line, e.to_string()),
                },
                Event::LinkError(TransportError::Nul) => {
                    warn!("smc100: NUL byte on the line: a controller lost power");
                    return Step::Done(Err(AxisError::ControllerReset));
                }
                Event::LinkError(
                    e @ (TransportError::Timeout(_)
                    | TransportError::LineTooLong
                    | TransportError::Garbled(_)),
                ) => AxisError::Transport(e),
                Event::LinkError(e) => return Step::Done(Err(AxisError::Transport(e))),
                _ => return Step::Wait(Pending::Reply(deadline)),
            };
            // A late or partial reply must not be read as the next one's.
            cx.clear_input();
            self.attempt += 1;
            if self.attempt >= self.attempts {
                let sent = line_text(&self.frame.to_bytes());
                if self.attempts > 1 {
                    warn!(
                        %sent,
                        attempts = self.attempts,
                        error = %failure,
                        "smc100: no usable reply",
                    );
                } else {
                    // Asked once: the caller judges what the silence means.
                    debug!(%sent, error = %failure, "smc100: no usable reply");
                }
                return Step::Done(Err(failure));
            }
            warn!(
                sent = %line_text(&self.frame.to_bytes()),
                error = %failure,
                "smc100: no usable reply; asking again",
            );
            s.retried += 1;
            self.state = QueryState::Sending(Transfer::new(&self.frame));
            ev = Event::Start;
        }
    }
}

/// `ZT` and its dump (manual, ZT command): lines up to the dump's `PW1` answer earlier
/// commands and are skipped until the reply timeout; from `PW1` on, each line must
/// come within the reply timeout of the one before, and `PW0` ends it. `ZT` changes
/// nothing, so a lost, late or garbled line clears the input and asks again, up to
/// `retries` times; a NUL byte means the controller lost power.
#[derive(Debug)]
pub(super) struct Dump {
    frame: Frame,
    attempts: usize,
    attempt: usize,
    reader: DumpReader,
    state: QueryState,
}

impl Dump {
    pub(super) fn new(s: &Smc100Session, axis: usize) -> Self {
        let frame = s.frame(axis, Command::DumpConfiguration);
        Dump {
            state: QueryState::Sending(Transfer::new(&frame)),
            reader: DumpReader::new(s.axes[axis].address),
            frame,
            attempts: s.policy.retries + 1,
            attempt: 0,
        }
    }
}

impl Machine<Smc100Session> for Dump {
    type Output = Result<Smc100Parameters, AxisError>;

    fn step(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        mut ev: Event<'_>,
    ) -> Step<Self::Output> {
        loop {
            let deadline = match &mut self.state {
                QueryState::Sending(t) => {
                    if let Err(e) = drive!(t, s, cx, ev) {
                        return Step::Done(Err(e));
                    }
                    let deadline = cx.now.saturating_add(s.policy.reply_timeout);
                    self.state = QueryState::Reading(deadline);
                    return Step::Wait(Pending::Reply(deadline));
                }
                QueryState::Reading(deadline) => *deadline,
            };
            let failure = match ev {
                Event::Line(line) => match self.reader.push(line) {
                    Ok(Some(params)) => return Step::Done(Ok(params)),
                    Ok(None) => {
                        // A line of the dump restarts the wait; a skipped one does not.
                        let next = if self.reader.started() {
                            cx.now.saturating_add(s.policy.reply_timeout)
                        } else {
                            deadline
                        };
                        self.state = QueryState::Reading(next);
                        return Step::Wait(Pending::Reply(next));
                    }
                    Err(e) => AxisError::Protocol {
                        sent: line_text(&self.frame.to_bytes()),
                        reply: line_text(line),
                        reason: e.to_string(),
                    },
                },
                Event::LinkError(TransportError::Nul) => {
                    warn!("smc100: NUL byte on the line: a controller lost power");
                    return Step::Done(Err(AxisError::ControllerReset));
                }
                Event::LinkError(
                    e @ (TransportError::Timeout(_)
                    | TransportError::LineTooLong
                    | TransportError::Garbled(_)),
                ) => AxisError::Transport(e),
                Event::LinkError(e) => return Step::Done(Err(AxisError::Transport(e))),
                _ => return Step::Wait(Pending::Reply(deadline)),
            };
            // The rest of a broken dump must not be read as the next one.
            cx.clear_input();
            self.attempt += 1;
            if self.attempt >= self.attempts {
                warn!(
                    attempts = self.attempts,
                    error = %failure,
                    "smc100: no complete ZT dump",
                );
                return Step::Done(Err(failure));
            }
            warn!(error = %failure, "smc100: ZT dump broken off; asking again");
            s.retried += 1;
            self.reader = DumpReader::new(self.frame.address.unwrap_or(0));
            self.state = QueryState::Sending(Transfer::new(&self.frame));
            ev = Event::Start;
        }
    }
}

/// A set or action command, then `TE`. An idempotent command whose `TE` answer is lost
/// is sent again with a new `TE`; any other is [`AxisError::Ambiguous`]. A re-sent
/// absolute move that `TE` refuses as not allowed while moving (the first one was
/// accepted and the stage is moving) is fine if the controller holds this very target.
///
/// Which letter a `PA` sent while MOVING stores is not in the manual (the PA page,
/// p. 41-42, lists A, B, C, D, G, H, I, J only): `M` ("not allowed in MOVING") by
/// analogy with the other commands, or `D` ("execution not allowed"), is as likely; both
/// are taken as that refusal ([`refused_while_moving`]).
#[derive(Debug)]
pub(super) struct Checked {
    axis: usize,
    frame: Frame,
    attempts: usize,
    attempt: usize,
    state: CheckedState,
}

#[derive(Debug)]
enum CheckedState {
    Sending(Transfer),
    AskingError(Query),
    /// Reading the held target of an absolute move to this target, after the re-sent
    /// move was refused with this letter.
    CheckingTarget(Query, f64, ErrorCode),
}

/// Whether `code` is what a `PA` sent while the stage moves may store: `M` or `D`
/// (UNCONFIRMED which; see [`Checked`]).
fn refused_while_moving(code: ErrorCode) -> bool {
    matches!(code, ErrorCode::InMoving | ErrorCode::NotAllowed)
}

impl Checked {
    pub(super) fn new(s: &Smc100Session, axis: usize, command: Command) -> Self {
        let frame = s.frame(axis, command);
        Checked {
            axis,
            state: CheckedState::Sending(Transfer::new(&frame)),
            attempts: if frame.command.is_idempotent() {
                s.policy.retries + 1
            } else {
                1
            },
            attempt: 0,
            frame,
        }
    }

    fn refused(&self, code: ErrorCode) -> AxisError {
        AxisError::Controller {
            command: line_text(&self.frame.to_bytes()),
            code,
        }
    }
}

impl Machine<Smc100Session> for Checked {
    type Output = Result<(), AxisError>;

    fn step(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        mut ev: Event<'_>,
    ) -> Step<Self::Output> {
        loop {
            match &mut self.state {
                CheckedState::Sending(t) => {
                    if let Err(e) = drive!(t, s, cx, ev) {
                        return Step::Done(Err(e));
                    }
                    let te = Query::new(s, self.axis, Command::TellError, false);
                    self.state = CheckedState::AskingError(te);
                }
                CheckedState::AskingError(q) => match drive!(q, s, cx, ev) {
                    Ok(ReplyBody::Error(ErrorCode::None)) => return Step::Done(Ok(())),
                    Ok(ReplyBody::Error(code))
                        if self.attempt > 0 && refused_while_moving(code) =>
                    {
                        let Command::MoveAbsolute(t) = self.frame.command else {
                            return Step::Done(Err(self.refused(code)));
                        };
                        let pa = Command::Query(Param::AbsoluteTarget);
                        let q = Query::new(s, self.axis, pa, true);
                        self.state = CheckedState::CheckingTarget(q, t, code);
                    }
                    Ok(ReplyBody::Error(code)) => {
                        warn!(
                            command = %line_text(&self.frame.to_bytes()),
                            %code,
                            "smc100: command refused",
                        );
                        return Step::Done(Err(self.refused(code)));
                    }
                    Ok(other) => {
                        return Step::Done(Err(AxisError::Protocol {
                            sent: format!("{}TE", s.axes[self.axis].address),
                            reply: format!("{other:?}"),
                            reason: "not an error letter".into(),
                        }));
                    }
                    Err(
                        e @ (AxisError::Transport(
                            TransportError::Timeout(_)
                            | TransportError::LineTooLong
                            | TransportError::Garbled(_),
                        )
                        | AxisError::Protocol { .. }),
                    ) => {
                        let command = line_text(&self.frame.to_bytes());
                        self.attempt += 1;
                        if self.attempt >= self.attempts {
                            if self.frame.command.is_idempotent() {
                                return Step::Done(Err(e));
                            }
                            warn!(
                                %command,
                                "smc100: acknowledgement lost; the command must not be sent again",
                            );
                            return Step::Done(Err(AxisError::Ambiguous { command }));
                        }
                        warn!(
                            %command,
                            error = %e,
                            "smc100: acknowledgement lost; sending the command again",
                        );
                        s.retried += 1;
                        self.state = CheckedState::Sending(Transfer::new(&self.frame));
                    }
                    Err(e) => return Step::Done(Err(e)),
                },
                CheckedState::CheckingTarget(q, target, code) => {
                    let (target, code) = (*target, *code);
                    let r = drive!(q, s, cx, ev);
                    let held = match s.number(self.axis, "PA", r) {
                        Ok(held) => held,
                        Err(e) => return Step::Done(Err(e)),
                    };
                    return Step::Done(if (held - target).abs() <= s.axes[self.axis].tolerance {
                        debug!(target, "smc100: the first absolute move was accepted");
                        Ok(())
                    } else {
                        Err(self.refused(code))
                    });
                }
            }
            ev = Event::Start;
        }
    }
}

/// Stops every stage: the broadcast `ST`, then, if it could not be sent, each
/// controller's own `ST`, collecting the first failure and going on.
#[derive(Debug)]
pub(super) struct StopAll {
    /// The controller whose stop is being sent; `None` for the broadcast.
    each: Option<usize>,
    transfer: Transfer,
    first: Option<MotionError>,
}

impl StopAll {
    pub(super) fn new() -> Self {
        StopAll {
            each: None,
            transfer: Transfer::new(&Frame::broadcast(Command::Stop)),
            first: None,
        }
    }
}

impl Machine<Smc100Session> for StopAll {
    type Output = Result<(), MotionError>;

    fn step(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        mut ev: Event<'_>,
    ) -> Step<Self::Output> {
        loop {
            let r = drive!(self.transfer, s, cx, ev);
            let next = match (self.each, r) {
                (None, Ok(())) => return Step::Done(Ok(())),
                (None, Err(e)) => {
                    warn!(error = %e, "smc100: broadcast stop not sent; stopping each controller");
                    0
                }
                (Some(k), r) => {
                    if let Err(e) = r {
                        let e = s.at(k, e);
                        self.first.get_or_insert(e);
                    }
                    k + 1
                }
            };
            if next >= s.axes.len() {
                return Step::Done(self.first.take().map_or(Ok(()), Err));
            }
            self.each = Some(next);
            self.transfer = Transfer::new(&s.frame(next, Command::Stop));
            ev = Event::Start;
        }
    }
}
