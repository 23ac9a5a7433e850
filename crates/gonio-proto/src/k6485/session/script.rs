//! Operations as scripts of exchanges, as for the SR830: an [`Op`] asks for one
//! exchange or pause ([`Next`]) and names the step that takes its result; [`Exec`] runs
//! the exchanges and calls the steps.

use std::time::Duration;

use super::K6485Session;
use super::exchange::Exchange;
use crate::k6485::{Command, K6485Error, Reply};
use crate::machine::{Cx, Event, Machine, Pending, Step};

/// The result of one exchange.
pub(super) type Answer = Result<Option<Reply>, K6485Error>;

/// A step taking the result `R` of what it asked for.
pub(super) type Then<O, R> = fn(&mut O, &mut K6485Session, &mut Cx, R) -> Next<O>;

/// An operation of the picoammeter.
pub(super) trait Op: Sized {
    /// Its result when it succeeds.
    type Value;
    /// The first step.
    fn start(&mut self, s: &mut K6485Session, cx: &mut Cx) -> Next<Self>;
}

/// What an operation asks for next.
pub(super) enum Next<O: Op> {
    /// A command sent and, for a query, its reply read.
    Exchange {
        command: Command,
        then: Then<O, Answer>,
    },
    /// A pause until a time.
    Pause { until: Duration, then: Then<O, ()> },
    /// The end.
    Done(Result<O::Value, K6485Error>),
}

impl<O: Op> Next<O> {
    pub(super) fn exchange(command: Command, then: Then<O, Answer>) -> Self {
        Next::Exchange { command, then }
    }
}

/// The exchange or pause under way, with the step that takes its result.
enum Current<O: Op> {
    /// Not started yet.
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

impl<O: Op> Machine<K6485Session> for Exec<O> {
    type Output = Result<O::Value, K6485Error>;

    fn step(&mut self, s: &mut K6485Session, cx: &mut Cx, mut ev: Event<'_>) -> Step<Self::Output> {
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
                Next::Exchange { command, then } => {
                    self.current = Current::Exchange(Exchange::new(s, command), then);
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
