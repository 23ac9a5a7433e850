//! Operations as scripts of exchanges, as for the 6485: an [`Op`] asks for one
//! exchange ([`Next`]) and names the step that takes its result; [`Exec`] runs the
//! exchanges and calls the steps.

use super::Cs130Session;
use super::exchange::Exchange;
use crate::cs130::{Command, Cs130Error, Reply};
use crate::machine::{Cx, Event, Machine, Step};

/// The result of one exchange: the answer of a query, `None` for a command.
pub(super) type Answer = Result<Option<Reply>, Cs130Error>;

/// A step taking the result of an exchange.
pub(super) type Then<O> = fn(&mut O, &mut Cs130Session, &mut Cx, Answer) -> Next<O>;

/// An operation of the monochromator.
pub(super) trait Op: Sized {
    /// Its result when it succeeds.
    type Value;
    /// The first step.
    fn start(&mut self, s: &mut Cs130Session, cx: &mut Cx) -> Next<Self>;
}

/// What an operation asks for next.
pub(super) enum Next<O: Op> {
    /// A statement sent, its echo read and, for a query, its answer.
    Exchange { command: Command, then: Then<O> },
    /// The end.
    Done(Result<O::Value, Cs130Error>),
}

/// The exchange under way, with the step that takes its result.
enum Current<O: Op> {
    /// Not started yet.
    Idle,
    Exchange(Exchange, Then<O>),
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

impl<O: Op> Machine<Cs130Session> for Exec<O> {
    type Output = Result<O::Value, Cs130Error>;

    fn step(&mut self, s: &mut Cs130Session, cx: &mut Cx, mut ev: Event<'_>) -> Step<Self::Output> {
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
            };
            match next {
                Next::Done(out) => return Step::Done(out),
                Next::Exchange { command, then } => {
                    self.current = Current::Exchange(Exchange::new(s, command), then);
                }
            }
            ev = Event::Start;
        }
    }
}
