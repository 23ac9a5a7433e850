//! Operations as scripts of exchanges: an [`Op`] asks for one exchange or pause
//! ([`Next`]) and names the step that takes its result; [`Exec`] runs them.

use std::time::Duration;

use super::Fw102cSession;
use super::exchange::Exchange;
use crate::fw102c::{Command, Fw102cError, Reply};
use crate::machine::{Cx, Event, Machine, Pending, Step};

/// The result of one exchange.
pub(super) type Answer = Result<Option<Reply>, Fw102cError>;

/// A step taking the result `R` of what it asked for.
pub(super) type Then<O, R> = fn(&mut O, &mut Fw102cSession, &mut Cx, R) -> Next<O>;

/// An operation of the wheel.
pub(super) trait Op: Sized {
    /// Its result when it succeeds.
    type Value;
    /// The first step.
    fn start(&mut self, s: &mut Fw102cSession, cx: &mut Cx) -> Next<Self>;
}

/// What an operation asks for next.
pub(super) enum Next<O: Op> {
    /// A command sent, its echo and (for a query) its value read. `after` is the set
    /// command just sent whose refusal may arrive first; the echo may take until
    /// `until` (when later than the reply timeout).
    Exchange {
        command: Command,
        after: Option<Command>,
        until: Duration,
        then: Then<O, Answer>,
    },
    /// A pause until a time.
    Pause { until: Duration, then: Then<O, ()> },
    /// The end.
    Done(Result<O::Value, Fw102cError>),
}

impl<O: Op> Next<O> {
    /// `command` with the ordinary reply timeout.
    pub(super) fn send(command: Command, then: Then<O, Answer>) -> Self {
        Next::Exchange {
            command,
            after: None,
            until: Duration::ZERO,
            then,
        }
    }

    /// The query that reads back what `set` (just sent) changed.
    pub(super) fn read_back(set: Command, query: Command, then: Then<O, Answer>) -> Self {
        Next::Exchange {
            command: query,
            after: Some(set),
            until: Duration::ZERO,
            then,
        }
    }
}

enum Current<O: Op> {
    Idle,
    Exchange(Exchange, Then<O, Answer>),
    Pause(Duration, Then<O, ()>),
}

/// Runs an [`Op`]: the machine a session's operation is.
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

impl<O: Op> Machine<Fw102cSession> for Exec<O> {
    type Output = Result<O::Value, Fw102cError>;

    fn step(
        &mut self,
        s: &mut Fw102cSession,
        cx: &mut Cx,
        mut ev: Event<'_>,
    ) -> Step<Self::Output> {
        loop {
            let next = match std::mem::replace(&mut self.current, Current::Idle) {
                Current::Idle => self.op.start(s, cx),
                Current::Exchange(mut m, then) => match m.step(s, cx, ev) {
                    Step::Wait(p) => {
                        self.current = Current::Exchange(m, then);
                        return Step::Wait(p);
                    }
                    Step::Done(r) => then(&mut self.op, s, cx, r),
                },
                Current::Pause(until, then) => match ev {
                    Event::Timer => then(&mut self.op, s, cx, ()),
                    _ => {
                        self.current = Current::Pause(until, then);
                        return Step::Wait(Pending::Sleep(until));
                    }
                },
            };
            match next {
                Next::Done(out) => return Step::Done(out),
                Next::Exchange {
                    command,
                    after,
                    until,
                    then,
                } => {
                    let m = Exchange::new(s, command, after, until);
                    self.current = Current::Exchange(m, then);
                }
                Next::Pause { until, then } => {
                    self.current = Current::Pause(until, then);
                    return Step::Wait(Pending::Sleep(until));
                }
            }
            ev = Event::Start;
        }
    }
}
