//! The one engine every session runs on: an operation is an `async fn` over a
//! [`Link`], and [`Task`] polls it as the pump hands events in.
//!
//! Why `async`: an instrument's procedure (query the identity, check it, set the
//! speed, read it back, ...) is straight-line code with `?`, and the compiler turns it
//! into the state machine the pump drives, instead of one hand-written continuation
//! per reply. There is no runtime: [`Task`] polls the future with a no-op waker
//! exactly once per event the pump hands in, and every `await` on the link parks the
//! future with exactly one [`Pending`] (bytes to send, a reconnection, a reply by a
//! deadline, a pause). So a running operation can never be left waiting for nothing,
//! time is only what the pump says it is, and a test drives an operation on virtual
//! time byte by byte.
//!
//! [`exchange`] is the link policy of every line family, written once: send, receive,
//! clear the input and send again after a fault that may be retried, reopen a vanished
//! port after a pause.

mod exchange;
pub(crate) mod motion;
mod session;

pub(crate) use exchange::{Fault, Policy, Wire, exchange, reopen_at_once, send_reopening};
pub use session::SessionCore;
pub(crate) use session::{Read, line_session, receive};

use std::cell::{Cell, RefCell};
use std::future::Future;
use std::pin::Pin;
use std::rc::Rc;
use std::task::{Context, Poll, Waker};
use std::time::Duration;

use crate::link::{Deadline, Io, Operation, TransportError};

/// What happened while the operation waited: the answer to its [`Pending`].
#[derive(Debug)]
enum Event {
    /// The outcome of [`Pending::Transmit`] or [`Pending::Reconnect`] (no bytes), or
    /// of [`Pending::Reply`]: a line, a link fault or the reply's timeout.
    Io(Result<Vec<u8>, TransportError>),
    /// A [`Pending::Poll`] or [`Pending::Sleep`] ended.
    Timer,
    /// The operator aborted at a [`Pending::Poll`].
    Abort,
}

/// What an operation waits for.
#[derive(Debug, Clone, PartialEq)]
enum Pending {
    Transmit(Vec<u8>),
    Reconnect,
    Reply(Duration),
    Poll(Duration),
    Sleep(Duration),
}

/// The operator's abort, at a [`Link::poll_pause`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Aborted;

#[derive(Debug, Default)]
struct Shared {
    /// When the event being handled happened.
    now: Cell<Duration>,
    /// Input clearings asked for and not yet polled out.
    clears: Cell<usize>,
    /// What the parked future waits for, set by the `await` that parked it.
    wait: RefCell<Option<Pending>>,
    /// The event handed in, taken by the `await` it answers.
    event: RefCell<Option<Event>>,
}

/// The link as an operation sees it: the time, and one `await` per thing it waits for.
/// Cheap to clone; every clone is the same link.
#[derive(Debug, Clone, Default)]
pub(crate) struct Link(Rc<Shared>);

/// Parks the operation on one [`Pending`] and resolves to the event that answers it.
struct Wait<'a> {
    link: &'a Link,
    pending: Option<Pending>,
}

impl Future for Wait<'_> {
    type Output = Event;

    fn poll(mut self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<Event> {
        if let Some(p) = self.pending.take() {
            *self.link.0.wait.borrow_mut() = Some(p);
            return Poll::Pending;
        }
        match self.link.0.event.borrow_mut().take() {
            Some(ev) => Poll::Ready(ev),
            None => Poll::Pending,
        }
    }
}

impl Link {
    fn wait(&self, pending: Pending) -> Wait<'_> {
        Wait {
            link: self,
            pending: Some(pending),
        }
    }

    /// When the last event happened (the operation's start, at first).
    pub(crate) fn now(&self) -> Duration {
        self.0.now.get()
    }

    /// Asks for the received input to be discarded before the next I/O, so that a late
    /// or partial reply is not taken for the next one.
    pub(crate) fn clear_input(&self) {
        self.0.clears.set(self.0.clears.get() + 1);
    }

    /// Waits on an I/O `pending` and returns its outcome.
    async fn io(&self, pending: Pending) -> Result<Vec<u8>, TransportError> {
        match self.wait(pending).await {
            Event::Io(r) => r,
            other => unreachable!("I/O answered by {other:?}"),
        }
    }

    /// Sends `bytes`.
    pub(crate) async fn send(&self, bytes: Vec<u8>) -> Result<(), TransportError> {
        self.io(Pending::Transmit(bytes)).await.map(drop)
    }

    /// Reopens the port.
    pub(crate) async fn reconnect(&self) -> Result<(), TransportError> {
        self.io(Pending::Reconnect).await.map(drop)
    }

    /// The next line, due by `due`: a link fault, or [`TransportError::Timeout`] of the
    /// time waited when none came.
    pub(crate) async fn line(&self, due: Duration) -> Result<Vec<u8>, TransportError> {
        self.io(Pending::Reply(due)).await
    }

    /// Waits until `until`.
    pub(crate) async fn sleep(&self, until: Duration) {
        self.wait(Pending::Sleep(until)).await;
    }

    /// Waits until `until` at an abort point: `Err` if the operator aborted meanwhile.
    pub(crate) async fn poll_pause(&self, until: Duration) -> Result<(), Aborted> {
        match self.wait(Pending::Poll(until)).await {
            Event::Abort => Err(Aborted),
            _ => Ok(()),
        }
    }
}

#[derive(Debug)]
enum State<T> {
    Waiting(Pending),
    Done(T),
    Taken,
}

/// The [`Operation`] every session's `start_*` returns: it runs on the borrowed session
/// `'s`, ends with `T` or `E`, and logs its start and end at `debug`.
pub struct Task<'s, T, E> {
    /// The operation's name, for the log (`smc100.move`, `sr830.read`).
    name: &'static str,
    future: Pin<Box<dyn Future<Output = Result<T, E>> + 's>>,
    link: Link,
    state: State<Result<T, E>>,
    /// When the current wait began (what a reply timeout reports as waited).
    since: Duration,
}

impl<T: std::fmt::Debug, E: std::fmt::Debug> std::fmt::Debug for Task<'_, T, E> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Task")
            .field("name", &self.name)
            .field("state", &self.state)
            .finish_non_exhaustive()
    }
}

impl<'s, T, E: std::fmt::Display> Task<'s, T, E> {
    /// Starts the operation `name` at `now`: `body` receives the link and returns the
    /// operation's future, which runs to its first wait here.
    pub(crate) fn new<F>(name: &'static str, now: Duration, body: impl FnOnce(Link) -> F) -> Self
    where
        F: Future<Output = Result<T, E>> + 's,
    {
        tracing::debug!(operation = name, "operation started");
        let link = Link::default();
        let mut task = Task {
            name,
            future: Box::pin(body(link.clone())),
            link,
            state: State::Taken,
            since: now,
        };
        task.feed(now, None);
        task
    }

    /// Starts the operation `name` at `now` on the session `s`: `op` is its `async fn`
    /// (or an `async` closure), given the session and the link.
    pub(crate) fn run<S: 's>(
        name: &'static str,
        now: Duration,
        s: &'s mut S,
        op: impl AsyncFnOnce(&mut S, &Link) -> Result<T, E> + 's,
    ) -> Self
    where
        T: 's,
        E: 's,
    {
        Task::new(name, now, move |link| async move { op(s, &link).await })
    }

    fn feed(&mut self, now: Duration, event: Option<Event>) {
        self.link.0.now.set(now);
        self.since = now;
        *self.link.0.event.borrow_mut() = event;
        let mut cx = Context::from_waker(Waker::noop());
        self.state = match self.future.as_mut().poll(&mut cx) {
            Poll::Ready(out) => {
                match &out {
                    Ok(_) => tracing::debug!(operation = self.name, "operation finished"),
                    Err(error) => {
                        tracing::debug!(operation = self.name, %error, "operation failed");
                    }
                }
                State::Done(out)
            }
            Poll::Pending => match self.link.0.wait.borrow_mut().take() {
                Some(p) => State::Waiting(p),
                None => unreachable!("an operation parked without waiting on its link"),
            },
        };
    }

    fn waiting(&self) -> Option<&Pending> {
        match &self.state {
            State::Waiting(p) if self.link.0.clears.get() == 0 => Some(p),
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

    /// Hands `event` in if the operation waits for what `fits`; else logs it ignored.
    fn answer(&mut self, now: Duration, what: &str, fits: fn(&Pending) -> bool, event: Event) {
        if self.waiting().is_some_and(fits) {
            self.feed(now, Some(event));
        } else {
            self.ignored(what);
        }
    }
}

impl<T, E: std::fmt::Display> Operation for Task<'_, T, E> {
    type Output = Result<T, E>;

    fn poll_io(&mut self) -> Option<Io<'_>> {
        let clears = self.link.0.clears.get();
        if clears > 0 {
            self.link.0.clears.set(clears - 1);
            return Some(Io::ClearInput);
        }
        match &self.state {
            State::Waiting(Pending::Transmit(bytes)) => Some(Io::Transmit(bytes)),
            State::Waiting(Pending::Reconnect) => Some(Io::Reconnect),
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

    fn poll_output(&mut self) -> Option<Result<T, E>> {
        if self.link.0.clears.get() > 0 {
            return None;
        }
        match std::mem::replace(&mut self.state, State::Taken) {
            State::Done(out) => Some(out),
            other => {
                self.state = other;
                None
            }
        }
    }

    fn handle_sent(&mut self, now: Duration, result: Result<(), TransportError>) {
        let fits = |p: &Pending| matches!(p, Pending::Transmit(_));
        self.answer(now, "sent", fits, Event::Io(result.map(|()| vec![])));
    }

    fn handle_reconnected(&mut self, now: Duration, result: Result<(), TransportError>) {
        let fits = |p: &Pending| matches!(p, Pending::Reconnect);
        self.answer(now, "reconnected", fits, Event::Io(result.map(|()| vec![])));
    }

    fn handle_line(&mut self, now: Duration, line: &[u8]) {
        let fits = |p: &Pending| matches!(p, Pending::Reply(_));
        self.answer(now, "line", fits, Event::Io(Ok(line.to_vec())));
    }

    fn handle_link_error(&mut self, now: Duration, error: TransportError) {
        let fits = |p: &Pending| matches!(p, Pending::Reply(_));
        self.answer(now, "link error", fits, Event::Io(Err(error)));
    }

    fn handle_timeout(&mut self, now: Duration) {
        match self.waiting() {
            Some(Pending::Reply(deadline)) => {
                let waited = deadline.saturating_sub(self.since);
                self.feed(now, Some(Event::Io(Err(TransportError::Timeout(waited)))));
            }
            Some(Pending::Poll(_) | Pending::Sleep(_)) => self.feed(now, Some(Event::Timer)),
            _ => self.ignored("timeout"),
        }
    }

    fn handle_abort(&mut self, now: Duration) {
        let fits = |p: &Pending| matches!(p, Pending::Poll(_));
        self.answer(now, "abort", fits, Event::Abort);
    }
}

/// `s` seconds as a duration: 0 for a negative or NaN value, saturating for one too
/// large.
pub(crate) fn secs(s: f64) -> Duration {
    Duration::try_from_secs_f64(s.max(0.0)).unwrap_or(Duration::MAX)
}
