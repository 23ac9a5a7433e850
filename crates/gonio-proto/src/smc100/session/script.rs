//! Operations as scripts of exchanges. An [`Op`] starts by asking for one exchange or
//! pause ([`Next`]), naming the step (a method of the operation) that takes its
//! result; that step asks for the next, and so on until one returns [`Next::Done`].
//! [`Exec`] runs the exchanges and calls the steps. Where the old blocking code had a
//! call that waited, an operation has a step boundary; its loops keep their counters
//! in the operation's fields.

use std::time::Duration;

use tracing::warn;

use super::Smc100Session;
use super::exchange::{Checked, Dump, Query, StopAll, Transfer};
use crate::machine::{Cx, Event, Machine, Pending, Step};
use crate::smc100::{AxisError, Command, Frame, MotionError, ReplyBody, Smc100Parameters};

/// A step taking the result `R` of the exchange it asked for.
pub(super) type Then<O, R> = fn(&mut O, &mut Smc100Session, &mut Cx, R) -> Next<O>;

/// The operator aborted during a pause between polls.
#[derive(Debug)]
pub(super) struct Aborted;

/// An operation of the chain.
pub(super) trait Op: Sized {
    /// Its result when it succeeds.
    type Value;
    /// The first step.
    fn start(&mut self, s: &mut Smc100Session, cx: &mut Cx) -> Next<Self>;
}

/// What an operation asks for next.
pub(super) enum Next<O: Op> {
    /// A query to an axis, asked again after a lost or garbled reply.
    Query {
        axis: usize,
        command: Command,
        then: Then<O, Result<ReplyBody, AxisError>>,
    },
    /// A query to an axis asked once: silence is the step's to judge (a controller
    /// that is saving or booting), not a retry.
    Probe {
        axis: usize,
        command: Command,
        then: Then<O, Result<ReplyBody, AxisError>>,
    },
    /// A set or action command to an axis, checked with `TE`.
    Command {
        axis: usize,
        command: Command,
        then: Then<O, Result<(), AxisError>>,
    },
    /// `ZT` to an axis and its dump, read whole (asked again after a lost or garbled
    /// line).
    Dump {
        axis: usize,
        then: Then<O, Result<Smc100Parameters, AxisError>>,
    },
    /// A frame sent with no reply read and no `TE` (`RS`, `PW0`).
    Send {
        frame: Frame,
        then: Then<O, Result<(), AxisError>>,
    },
    /// Every stage stopped.
    StopAll {
        then: Then<O, Result<(), MotionError>>,
    },
    /// A pause until a time; when `abortable`, an abort point.
    Pause {
        until: Duration,
        abortable: bool,
        then: Then<O, Result<(), Aborted>>,
    },
    /// Stop every stage, then end with `error` at `axis`.
    Fail { axis: usize, error: AxisError },
    /// A move or home search past its deadline: stop every stage, read the axis'
    /// position, and end with [`AxisError::Timeout`].
    Overdue(Overdue),
    /// The end.
    Done(Result<O::Value, MotionError>),
}

impl<O: Op> Next<O> {
    pub(super) fn query(
        axis: usize,
        command: Command,
        then: Then<O, Result<ReplyBody, AxisError>>,
    ) -> Self {
        Next::Query {
            axis,
            command,
            then,
        }
    }

    pub(super) fn command(
        axis: usize,
        command: Command,
        then: Then<O, Result<(), AxisError>>,
    ) -> Self {
        Next::Command {
            axis,
            command,
            then,
        }
    }

    pub(super) fn fail(axis: usize, error: AxisError) -> Self {
        Next::Fail { axis, error }
    }
}

/// A move or home search that outlasted its deadline.
#[derive(Debug, Clone, Copy)]
pub(super) struct Overdue {
    pub(super) axis: usize,
    /// `move` or `home`.
    pub(super) operation: &'static str,
    pub(super) target: f64,
    /// How long was allowed.
    pub(super) waited: Duration,
}

/// The exchange or pause under way, with the step that takes its result.
enum Current<O: Op> {
    /// Not started yet.
    Idle,
    Query(Query, Then<O, Result<ReplyBody, AxisError>>),
    Command(Checked, Then<O, Result<(), AxisError>>),
    Dump(Dump, Then<O, Result<Smc100Parameters, AxisError>>),
    Send(Transfer, Then<O, Result<(), AxisError>>),
    StopAll(StopAll, Then<O, Result<(), MotionError>>),
    Pause(Pending, Then<O, Result<(), Aborted>>),
    /// Stopping every stage before ending with this error.
    Failing(StopAll, MotionError),
    /// Stopping every stage after a deadline, then reading the position.
    Stopping(StopAll, Overdue),
    Locating(Query, Overdue),
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

/// Steps the machine of a `Current` variant; on `Wait`, puts it back and returns;
/// on `Done`, evaluates to the next request from the step it names.
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

impl<O: Op> Machine<Smc100Session> for Exec<O> {
    type Output = Result<O::Value, MotionError>;

    fn step(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        mut ev: Event<'_>,
    ) -> Step<Self::Output> {
        loop {
            let next = match std::mem::replace(&mut self.current, Current::Idle) {
                Current::Idle => self.op.start(s, cx),
                Current::Query(m, then) => resume!(self, s, cx, ev, Query, m, then),
                Current::Command(m, then) => resume!(self, s, cx, ev, Command, m, then),
                Current::Send(m, then) => resume!(self, s, cx, ev, Send, m, then),
                Current::Dump(m, then) => resume!(self, s, cx, ev, Dump, m, then),
                Current::StopAll(m, then) => resume!(self, s, cx, ev, StopAll, m, then),
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
                    Step::Done(_) => return Step::Done(Err(error)),
                },
                Current::Stopping(mut m, overdue) => match m.step(s, cx, ev) {
                    Step::Wait(p) => {
                        self.current = Current::Stopping(m, overdue);
                        return Step::Wait(p);
                    }
                    Step::Done(_) => {
                        let q = Query::new(s, overdue.axis, Command::TellPosition, true);
                        self.current = Current::Locating(q, overdue);
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
                        let e = AxisError::Timeout {
                            operation: o.operation,
                            target: o.target,
                            position: s.number(o.axis, "TP", r).ok(),
                            waited: o.waited,
                        };
                        return Step::Done(Err(s.at(o.axis, e)));
                    }
                },
            };
            self.current = match next {
                Next::Done(out) => return Step::Done(out),
                Next::Query {
                    axis,
                    command,
                    then,
                } => Current::Query(Query::new(s, axis, command, true), then),
                Next::Probe {
                    axis,
                    command,
                    then,
                } => Current::Query(Query::new(s, axis, command, false), then),
                Next::Command {
                    axis,
                    command,
                    then,
                } => Current::Command(Checked::new(s, axis, command), then),
                Next::Send { frame, then } => Current::Send(Transfer::new(&frame), then),
                Next::Dump { axis, then } => Current::Dump(Dump::new(s, axis), then),
                Next::StopAll { then } => Current::StopAll(StopAll::new(), then),
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
                Next::Fail { axis, error } => {
                    let error = s.at(axis, error);
                    warn!(%error, "smc100: stopping every stage after a fault");
                    Current::Failing(StopAll::new(), error)
                }
                Next::Overdue(overdue) => {
                    warn!(
                        axis = %s.axes[overdue.axis].name,
                        operation = overdue.operation,
                        waited = ?overdue.waited,
                        "smc100: past the deadline; stopping every stage",
                    );
                    Current::Stopping(StopAll::new(), overdue)
                }
            };
            ev = Event::Start;
        }
    }
}
