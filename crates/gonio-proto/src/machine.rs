//! The core the sessions are built on: state machines that take one event at a time
//! and answer with what they wait for next, and [`Run`], which exposes a machine as an
//! [`Operation`].
//!
//! A [`Machine`] is stepped with an [`Event`] and returns [`Step::Wait`] with exactly
//! one [`Pending`] (bytes to send, a reconnection, a reply by a deadline, a pause), or
//! [`Step::Done`] with its output. Input clearing needs no answer, so it is queued on
//! the [`Cx`] instead. Machines nest: a parent steps its child with the event, passes
//! the child's `Wait` up unchanged, and continues on the child's `Done`. Because every
//! step ends in exactly one `Wait` or `Done`, a running operation can never be left
//! waiting for nothing.

use std::time::Duration;

use crate::link::{Deadline, Io, Operation, TransportError};

/// What happened since the machine last returned [`Step::Wait`].
#[derive(Debug)]
pub(crate) enum Event<'a> {
    /// The machine has just been created: emit its first wait.
    Start,
    /// The outcome of [`Pending::Transmit`].
    Sent(Result<(), TransportError>),
    /// The outcome of [`Pending::Reconnect`].
    Reconnected(Result<(), TransportError>),
    /// A line, while [`Pending::Reply`].
    Line(&'a [u8]),
    /// A link fault or a timeout, while [`Pending::Reply`].
    LinkError(TransportError),
    /// A [`Pending::Poll`] or [`Pending::Sleep`] ended.
    Timer,
    /// The operator aborted at a [`Pending::Poll`].
    Abort,
}

/// What a machine waits for.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Pending {
    /// These bytes to be sent.
    Transmit(Vec<u8>),
    /// The port to be reopened.
    Reconnect,
    /// A reply line by this time.
    Reply(Duration),
    /// The end of a pause between polls at this time; an abort point.
    Poll(Duration),
    /// The end of a pause at this time.
    Sleep(Duration),
}

/// The result of one step.
#[derive(Debug)]
pub(crate) enum Step<T> {
    /// Finished, with this output.
    Done(T),
    /// Waiting for this.
    Wait(Pending),
}

/// Steps the child machine `$m`; returns its wait from the enclosing function, or
/// evaluates to its output.
macro_rules! drive {
    ($m:expr, $s:expr, $cx:expr, $ev:expr) => {
        match $m.step($s, $cx, $ev) {
            $crate::machine::Step::Wait(p) => return $crate::machine::Step::Wait(p),
            $crate::machine::Step::Done(r) => r,
        }
    };
}
pub(crate) use drive;

/// The time of the event being handled, and the input clearings asked for.
#[derive(Debug, Default)]
pub(crate) struct Cx {
    /// When the event happened.
    pub(crate) now: Duration,
    clears: usize,
}

impl Cx {
    /// Asks for the received input to be discarded before the next I/O.
    pub(crate) fn clear_input(&mut self) {
        self.clears += 1;
    }
}

/// A state machine over a session's state `S`.
pub(crate) trait Machine<S> {
    /// What it finishes with.
    type Output;
    /// Advances on `ev`.
    fn step(&mut self, s: &mut S, cx: &mut Cx, ev: Event<'_>) -> Step<Self::Output>;
}

#[derive(Debug)]
enum RunState<T> {
    Waiting(Pending),
    Done(T),
    Taken,
}

/// A machine running on a borrowed session: the [`Operation`] a session's `start_*`
/// methods return. It logs the operation's start and end at `debug`.
#[derive(Debug)]
pub(crate) struct Run<'s, S, M: Machine<S>> {
    /// The operation's name, for the log (`smc100.move`, `sr830.read`).
    name: &'static str,
    session: &'s mut S,
    machine: M,
    cx: Cx,
    state: RunState<M::Output>,
    /// When the current wait began (what a reply timeout reports as waited).
    since: Duration,
}

impl<'s, S, M: Machine<S>> Run<'s, S, M>
where
    M::Output: Outcome,
{
    /// Starts `machine`, the operation `name`, on `session` at `now`.
    pub(crate) fn new(name: &'static str, session: &'s mut S, machine: M, now: Duration) -> Self {
        tracing::debug!(operation = name, "operation started");
        let mut run = Run {
            name,
            session,
            machine,
            cx: Cx::default(),
            state: RunState::Taken,
            since: now,
        };
        run.feed(now, Event::Start);
        run
    }

    fn feed(&mut self, now: Duration, ev: Event<'_>) {
        self.cx.now = now;
        self.since = now;
        self.state = match self.machine.step(self.session, &mut self.cx, ev) {
            Step::Done(out) => {
                match out.failure() {
                    None => tracing::debug!(operation = self.name, "operation finished"),
                    Some(error) => {
                        tracing::debug!(operation = self.name, %error, "operation failed");
                    }
                }
                RunState::Done(out)
            }
            Step::Wait(p) => RunState::Waiting(p),
        };
    }

    fn waiting(&self) -> Option<&Pending> {
        match &self.state {
            RunState::Waiting(p) if self.cx.clears == 0 => Some(p),
            _ => None,
        }
    }

    fn ignored(&self, what: &str) {
        tracing::warn!(
            event = what,
            waiting = ?self.waiting(),
            "session: an event the operation does not wait for, ignored"
        );
    }
}

impl<S, M: Machine<S>> Operation for Run<'_, S, M>
where
    M::Output: Outcome,
{
    type Output = M::Output;

    fn poll_io(&mut self) -> Option<Io<'_>> {
        if self.cx.clears > 0 {
            self.cx.clears -= 1;
            return Some(Io::ClearInput);
        }
        match &self.state {
            RunState::Waiting(Pending::Transmit(bytes)) => Some(Io::Transmit(bytes)),
            RunState::Waiting(Pending::Reconnect) => Some(Io::Reconnect),
            _ => None,
        }
    }

    fn poll_timeout(&self) -> Option<Deadline> {
        match self.waiting()? {
            Pending::Reply(t) => Some(Deadline::Reply(*t)),
            Pending::Poll(t) => Some(Deadline::Poll(*t)),
            Pending::Sleep(t) => Some(Deadline::Sleep(*t)),
            Pending::Transmit(_) | Pending::Reconnect => None,
        }
    }

    fn poll_output(&mut self) -> Option<Self::Output> {
        if self.cx.clears > 0 {
            return None;
        }
        match std::mem::replace(&mut self.state, RunState::Taken) {
            RunState::Done(out) => Some(out),
            other => {
                self.state = other;
                None
            }
        }
    }

    fn handle_sent(&mut self, now: Duration, result: Result<(), TransportError>) {
        match self.waiting() {
            Some(Pending::Transmit(_)) => self.feed(now, Event::Sent(result)),
            _ => self.ignored("sent"),
        }
    }

    fn handle_reconnected(&mut self, now: Duration, result: Result<(), TransportError>) {
        match self.waiting() {
            Some(Pending::Reconnect) => self.feed(now, Event::Reconnected(result)),
            _ => self.ignored("reconnected"),
        }
    }

    fn handle_line(&mut self, now: Duration, line: &[u8]) {
        match self.waiting() {
            Some(Pending::Reply(_)) => self.feed(now, Event::Line(line)),
            _ => self.ignored("line"),
        }
    }

    fn handle_link_error(&mut self, now: Duration, error: TransportError) {
        match self.waiting() {
            Some(Pending::Reply(_)) => self.feed(now, Event::LinkError(error)),
            _ => self.ignored("link error"),
        }
    }

    fn handle_timeout(&mut self, now: Duration) {
        match self.waiting() {
            Some(Pending::Reply(deadline)) => {
                let waited = deadline.saturating_sub(self.since);
                self.feed(now, Event::LinkError(TransportError::Timeout(waited)));
            }
            Some(Pending::Poll(_) | Pending::Sleep(_)) => self.feed(now, Event::Timer),
            _ => self.ignored("timeout"),
        }
    }

    fn handle_abort(&mut self, now: Duration) {
        match self.waiting() {
            Some(Pending::Poll(_)) => self.feed(now, Event::Abort),
            _ => self.ignored("abort"),
        }
    }
}

/// An operation's result, as the log reports it.
pub(crate) trait Outcome {
    /// The error, when it failed.
    fn failure(&self) -> Option<&dyn std::fmt::Display>;
}

impl<T, E: std::fmt::Display> Outcome for Result<T, E> {
    fn failure(&self) -> Option<&dyn std::fmt::Display> {
        self.as_ref().err().map(|e| e as &dyn std::fmt::Display)
    }
}

/// `s` seconds as a duration: 0 for a negative or NaN value, saturating for one too
/// large.
pub(crate) fn secs(s: f64) -> Duration {
    Duration::try_from_secs_f64(s.max(0.0)).unwrap_or(Duration::MAX)
}
