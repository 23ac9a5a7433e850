//! Operations as scripts of exchanges, as in the SMC100 session: an [`Op`] asks for
//! one exchange or pause ([`Next`]), naming the step that takes its result; [`Exec`]
//! runs the exchanges and calls the steps.

use std::time::Duration;

use tracing::warn;

use super::AptSession;
use super::wire::{Query, Transfer, Wait, Want};
use crate::apt::{Message, StopMode};
use crate::machine::{Cx, Event, Machine, Pending, Step};
use crate::motion::{AxisError, MotionError};

/// A step taking the result `R` of the exchange it asked for.
pub(super) type Then<O, R> = fn(&mut O, &mut AptSession, &mut Cx, R) -> Next<O>;

/// The operator aborted during a pause between polls.
#[derive(Debug)]
pub(super) struct Aborted;

/// An operation of the session.
pub(super) trait Op: Sized {
    /// Its result when it succeeds.
    type Value;
    /// The first step.
    fn start(&mut self, s: &mut AptSession, cx: &mut Cx) -> Next<Self>;
}

/// What an operation asks for next.
pub(super) enum Next<O: Op> {
    /// A message sent, no answer read.
    Send {
        message: Message,
        then: Then<O, Result<(), AxisError>>,
    },
    /// A request and its answer, asked again when lost if `retry`.
    Query {
        request: Message,
        want: Want,
        retry: bool,
        then: Then<O, Result<Message, AxisError>>,
    },
    /// A wait for a message, until a time.
    Await {
        want: Want,
        until: Duration,
        after: &'static str,
        then: Then<O, Result<Message, AxisError>>,
    },
    /// A pause until a time; when `abortable`, an abort point.
    Pause {
        until: Duration,
        abortable: bool,
        then: Then<O, Result<(), Aborted>>,
    },
    /// Stop the stage, then end with `error`.
    Fail(AxisError),
    /// A move or home search past its deadline: stop the stage, read its position and
    /// end with [`AxisError::Timeout`].
    Overdue(Overdue),
    /// The end.
    Done(Result<O::Value, MotionError>),
}

impl<O: Op> Next<O> {
    pub(super) fn send(message: Message, then: Then<O, Result<(), AxisError>>) -> Self {
        Next::Send { message, then }
    }

    pub(super) fn query(
        request: Message,
        want: Want,
        then: Then<O, Result<Message, AxisError>>,
    ) -> Self {
        Next::Query {
            request,
            want,
            retry: true,
            then,
        }
    }

    /// Ends with `e` on the axis, nothing stopped (nothing was moving).
    pub(super) fn error(s: &AptSession, e: AxisError) -> Self {
        Next::Done(Err(s.at(e)))
    }
}

/// A move or home search that outlasted its deadline.
#[derive(Debug, Clone, Copy)]
pub(super) struct Overdue {
    /// `move` or `home`.
    pub(super) operation: &'static str,
    pub(super) target: f64,
    pub(super) waited: Duration,
}

enum Current<O: Op> {
    Idle,
    Send(Transfer, Then<O, Result<(), AxisError>>),
    Query(Query, Then<O, Result<Message, AxisError>>),
    Await(Wait, Then<O, Result<Message, AxisError>>),
    Pause(Pending, Then<O, Result<(), Aborted>>),
    /// Stopping the stage before ending with this error.
    Failing(Transfer, MotionError),
    /// Stopping after a deadline, then reading the position.
    Stopping(Transfer, Overdue),
    Locating(Query, Overdue),
}

/// Runs an [`Op`]: the machine an operation is.
pub(super) struct Exec<O: Op> {
    op: O,
    current: Current<O>,
}

impl<O: Op> Exec<O> {
    pub(super) fn new(op: O) -> Self {
        Exec {
            op,
            current: Current::Idle,
        }
    }
}

impl<O: Op> std::fmt::Debug for Exec<O> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Exec").finish_non_exhaustive()
    }
}

macro_rules! resume {
    ($self:ident, $s:ident, $cx:ident, $ev:ident, $variant:ident, $m:ident, $then:ident) => {{
        let mut m = $m;
        match m.step($s, $cx, $ev) {
            Step::Wait(p) => {
                $self.current = Current::$variant(m, $then);
                return Step::Wait(p);
            }
            Step::Done(r) => $then(&mut $self.op, $s, $cx, r),
        }
    }};
}

fn stop_message() -> Message {
    Message::MoveStop {
        chan: 1,
        mode: StopMode::Profiled,
    }
}

impl<O: Op> Machine<AptSession> for Exec<O> {
    type Output = Result<O::Value, MotionError>;

    fn step(&mut self, s: &mut AptSession, cx: &mut Cx, mut ev: Event<'_>) -> Step<Self::Output> {
        loop {
            let next = match std::mem::replace(&mut self.current, Current::Idle) {
                Current::Idle => self.op.start(s, cx),
                Current::Send(m, then) => resume!(self, s, cx, ev, Send, m, then),
                Current::Query(m, then) => resume!(self, s, cx, ev, Query, m, then),
                Current::Await(m, then) => resume!(self, s, cx, ev, Await, m, then),
                Current::Pause(p, then) => match ev {
                    Event::Timer => then(&mut self.op, s, cx, Ok(())),
                    Event::Abort => then(&mut self.op, s, cx, Err(Aborted)),
                    _ => {
                        self.current = Current::Pause(p.clone(), then);
                        return Step::Wait(p);
                    }
                },
                Current::Failing(mut m, error) => match m.step(s, cx, ev) {
                    Step::Wait(p) => {
                        self.current = Current::Failing(m, error);
                        return Step::Wait(p);
                    }
                    Step::Done(r) => {
                        if let Err(e) = r {
                            warn!(error = %e, "apt: the stop after a fault was not sent");
                        }
                        return Step::Done(Err(error));
                    }
                },
                Current::Stopping(mut m, o) => match m.step(s, cx, ev) {
                    Step::Wait(p) => {
                        self.current = Current::Stopping(m, o);
                        return Step::Wait(p);
                    }
                    Step::Done(_) => {
                        let q = Query::new(
                            s,
                            Message::ReqPosCounter { chan: 1 },
                            |m| matches!(m, Message::GetPosCounter { .. }),
                            true,
                        );
                        self.current = Current::Locating(q, o);
                        ev = Event::Start;
                        continue;
                    }
                },
                Current::Locating(mut m, o) => match m.step(s, cx, ev) {
                    Step::Wait(p) => {
                        self.current = Current::Locating(m, o);
                        return Step::Wait(p);
                    }
                    Step::Done(r) => {
                        let position = match r {
                            Ok(Message::GetPosCounter { position, .. }) => {
                                Some(s.stage().to_deg(position))
                            }
                            _ => None,
                        };
                        let e = AxisError::Timeout {
                            operation: o.operation,
                            target: o.target,
                            position,
                            waited: o.waited,
                        };
                        return Step::Done(Err(s.at(e)));
                    }
                },
            };
            self.current = match next {
                Next::Done(out) => return Step::Done(out),
                Next::Send { message, then } => Current::Send(Transfer::new(&message), then),
                Next::Query {
                    request,
                    want,
                    retry,
                    then,
                } => Current::Query(Query::new(s, request, want, retry), then),
                Next::Await {
                    want,
                    until,
                    after,
                    then,
                } => Current::Await(Wait::new(want, until, after), then),
                Next::Pause {
                    until,
                    abortable,
                    then,
                } => {
                    let p = if abortable {
                        Pending::Poll(until)
                    } else {
                        Pending::Sleep(until)
                    };
                    self.current = Current::Pause(p.clone(), then);
                    return Step::Wait(p);
                }
                Next::Fail(error) => {
                    let error = s.at(error);
                    warn!(%error, "apt: stopping the stage after a fault");
                    Current::Failing(Transfer::new(&stop_message()), error)
                }
                Next::Overdue(o) => {
                    warn!(
                        axis = %s.axis.name,
                        operation = o.operation,
                        waited = ?o.waited,
                        "apt: past the deadline; stopping the stage",
                    );
                    Current::Stopping(Transfer::new(&stop_message()), o)
                }
            };
            ev = Event::Start;
        }
    }
}
