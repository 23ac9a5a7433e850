//! The pump: the one loop that moves bytes, lines and deadlines between a
//! [`Transport`] and a session's [`Operation`], waiting on a [`Clock`]. Every policy
//! decision (what to send, what a reply means, when to retry, reconnect, stop or give
//! up) is the operation's; the pump only does what it is told and reports what
//! happened, with the time it happened.
//!
//! It also writes the wire log: every line sent and received, at `trace` level under
//! the target `gonio_driver::wire`, with the port, the direction (`tx`, `rx`) and the
//! line with its control bytes escaped (`1PA12.5\r\n`).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use gonio_proto::link::{Deadline, Io, Operation};
use tracing::{debug, trace};

use crate::clock::Clock;
use crate::heartbeat::Heartbeat;
use crate::transport::{Escaped, Transport, TransportError};

/// A flag that, once raised from anywhere (a signal handler, a UI thread), makes the
/// running and every later wait stop all stages and return `AxisError::Aborted`.
/// The pump reads it at each of the session's abort points (the pauses between status
/// polls of a move or a home search).
#[derive(Clone, Debug, Default)]
pub struct AbortFlag(Arc<AtomicBool>);

impl AbortFlag {
    /// A lowered flag.
    pub fn new() -> Self {
        Self::default()
    }
    /// Raises it.
    pub fn raise(&self) {
        self.0.store(true, Ordering::SeqCst);
    }
    /// Lowers it again (after the operator acknowledged).
    pub fn clear(&self) {
        self.0.store(false, Ordering::SeqCst);
    }
    /// True when raised.
    pub fn is_raised(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }
}

/// Where a line's operation runs: its transport, the clock it waits on, the port's
/// name for the log, and the instrument's heartbeat, kept beating through every wait.
pub(crate) struct Pumped<'a, L: ?Sized, C> {
    pub(crate) link: &'a mut L,
    pub(crate) clock: &'a C,
    pub(crate) port: &'a str,
    pub(crate) beats: &'a Heartbeat,
}

/// The [`Pumped`] of a device struct with the fields `transport`, `clock`, `port`
/// and `beats`, borrowing only those (its session stays free for the operation).
macro_rules! pumped {
    ($d:expr) => {
        $crate::pump::Pumped {
            link: &mut $d.transport,
            clock: &$d.clock,
            port: &$d.port,
            beats: &$d.beats,
        }
    };
}
pub(crate) use pumped;

/// Runs `op` to its end over `at.link`, waiting on `at.clock`. At each abort point
/// ([`Deadline::Poll`]) a raised `abort` flag is handed to the operation instead of
/// the wait.
pub(crate) fn pump<L: Transport + ?Sized, C: Clock, O: Operation>(
    mut at: Pumped<'_, L, C>,
    abort: Option<&AbortFlag>,
    mut op: O,
) -> O::Output {
    loop {
        do_io(at.link, at.clock, at.port, &mut op);
        if let Some(out) = op.poll_output() {
            return out;
        }
        // With no I/O to do and no output, an operation always has a deadline.
        let Some(deadline) = op.poll_timeout() else {
            continue;
        };
        let aborting = abort.is_some_and(AbortFlag::is_raised);
        wait(&mut at, &mut op, deadline, aborting);
    }
}

/// One operation of a concurrent run over several lines: the line it runs on, the
/// line's name, the operation.
pub type Slot<'a, T> = (
    &'a mut dyn Transport,
    &'a str,
    Box<dyn Operation<Output = T> + 'a>,
);

/// Runs several operations, each on its own line, to their ends together on one
/// thread: the way a move of stages on different controllers runs concurrently.
///
/// An operation waiting for a reply is served first (replies take milliseconds);
/// otherwise the earliest pause or sleep is waited out. Once the `abort` flag is
/// raised, or one operation has ended in `failed`, every other operation is aborted at
/// its next abort point, so that a fault on one line stops the stages on every line.
/// With one operation this is [`pump`], event for event.
pub(crate) fn pump_many<T>(
    mut slots: Vec<Slot<'_, T>>,
    clock: &impl Clock,
    beats: &Heartbeat,
    abort: Option<&AbortFlag>,
    failed: impl Fn(&T) -> bool,
) -> Vec<T> {
    let mut out: Vec<Option<T>> = slots.iter().map(|_| None).collect();
    let mut peer_failed = false;
    loop {
        for (slot, done) in slots.iter_mut().zip(out.iter_mut()) {
            if done.is_some() {
                continue;
            }
            let (link, port, op) = slot;
            do_io(&mut **link, clock, port, op.as_mut());
            if let Some(o) = op.poll_output() {
                peer_failed |= failed(&o);
                *done = Some(o);
            }
        }
        if out.iter().all(Option::is_some) {
            return out.into_iter().flatten().collect();
        }
        let deadlines: Vec<(usize, Deadline)> = slots
            .iter()
            .zip(&out)
            .enumerate()
            .filter(|(_, (_, done))| done.is_none())
            .filter_map(|(i, ((_, _, op), _))| Some((i, op.poll_timeout()?)))
            .collect();
        let aborting = peer_failed || abort.is_some_and(AbortFlag::is_raised);
        let polls: Vec<usize> = deadlines
            .iter()
            .filter(|(_, d)| matches!(d, Deadline::Poll(_)))
            .map(|(i, _)| *i)
            .collect();
        if aborting && !polls.is_empty() {
            for i in polls {
                slots[i].2.handle_abort(clock.now());
            }
            continue;
        }
        let next = deadlines
            .iter()
            .find(|(_, d)| matches!(d, Deadline::Reply(_)))
            .or_else(|| deadlines.iter().min_by_key(|(_, d)| d.at()));
        let Some(&(i, deadline)) = next else {
            continue;
        };
        let (link, port, op) = &mut slots[i];
        let mut at = Pumped {
            link: &mut **link,
            clock,
            port,
            beats,
        };
        wait(&mut at, op.as_mut(), deadline, aborting);
    }
}

/// An operation whose output is mapped by a function: slots of different families
/// share one output type.
pub(crate) struct Mapped<O, F> {
    op: O,
    map: Option<F>,
}

impl<O, F> Mapped<O, F> {
    /// `op`, its output mapped by `map`.
    pub(crate) fn new(op: O, map: F) -> Self {
        Mapped { op, map: Some(map) }
    }
}

impl<O: Operation, T, F: FnOnce(O::Output) -> T> Operation for Mapped<O, F> {
    type Output = T;
    fn poll_io(&mut self) -> Option<Io<'_>> {
        self.op.poll_io()
    }
    fn poll_timeout(&self) -> Option<Deadline> {
        self.op.poll_timeout()
    }
    fn poll_output(&mut self) -> Option<T> {
        let out = self.op.poll_output()?;
        // An operation yields its output once; `map` is there until then.
        self.map.take().map(|f| f(out))
    }
    fn handle_sent(&mut self, now: Duration, r: Result<(), TransportError>) {
        self.op.handle_sent(now, r);
    }
    fn handle_reconnected(&mut self, now: Duration, r: Result<(), TransportError>) {
        self.op.handle_reconnected(now, r);
    }
    fn handle_line(&mut self, now: Duration, line: &[u8]) {
        self.op.handle_line(now, line);
    }
    fn handle_link_error(&mut self, now: Duration, e: TransportError) {
        self.op.handle_link_error(now, e);
    }
    fn handle_timeout(&mut self, now: Duration) {
        self.op.handle_timeout(now);
    }
    fn handle_abort(&mut self, now: Duration) {
        self.op.handle_abort(now);
    }
}

/// Does every I/O the operation asks for, until it asks for none.
fn do_io<L: Transport + ?Sized, O: Operation + ?Sized>(
    link: &mut L,
    clock: &impl Clock,
    port: &str,
    op: &mut O,
) {
    while let Some(io) = op.poll_io() {
        match io {
            Io::Transmit(bytes) => {
                trace!(target: "gonio_driver::wire", port, dir = "tx", line = %Escaped(bytes));
                let r = link.send(bytes);
                if let Err(e) = &r {
                    debug!(port, error = %e, "send failed");
                }
                op.handle_sent(clock.now(), r);
            }
            Io::ClearInput => {
                // A failure to flush changes nothing the next exchange relies on:
                // a vanished port shows on the next send.
                let _ = link.clear_input();
            }
            Io::Reconnect => {
                let r = link.reconnect();
                debug!(port, ok = r.is_ok(), "reconnect attempted");
                op.handle_reconnected(clock.now(), r);
            }
        }
    }
}

/// Waits as `deadline` says and hands in what happened; at an abort point with
/// `aborting`, hands in the abort instead. The keep-alives due meanwhile go out on
/// time: the wait is cut at each, and a reply still on its way is waited for again.
fn wait<L: Transport + ?Sized, C: Clock, O: Operation + ?Sized>(
    at: &mut Pumped<'_, L, C>,
    op: &mut O,
    deadline: Deadline,
    aborting: bool,
) {
    let (clock, port) = (at.clock, at.port);
    at.beats.beat(clock.now());
    match deadline {
        Deadline::Reply(end) => {
            let r = receive(at, end);
            let now = clock.now();
            match r {
                Ok(line) => {
                    trace!(
                        target: "gonio_driver::wire",
                        port,
                        dir = "rx",
                        line = %Escaped(&line),
                    );
                    op.handle_line(now, &line);
                }
                Err(e) => {
                    trace!(target: "gonio_driver::wire", port, dir = "rx", error = %e);
                    op.handle_link_error(now, e);
                }
            }
        }
        Deadline::Poll(_) if aborting => op.handle_abort(clock.now()),
        Deadline::Poll(end) | Deadline::Sleep(end) => {
            at.beats.sleep_until(clock, end);
            op.handle_timeout(clock.now());
        }
    }
}

/// The next line by `end`, the wait cut at each keep-alive due meanwhile; a timeout
/// reports the whole wait.
fn receive<L: Transport + ?Sized, C: Clock>(
    at: &mut Pumped<'_, L, C>,
    end: Duration,
) -> Result<Vec<u8>, TransportError> {
    let started = at.clock.now();
    loop {
        // The deadline may already have passed (another line was served first, or a
        // write took the time): then one last look at what has arrived.
        let now = at.clock.now();
        let end = end.max(now);
        let until = at.beats.due().map_or(end, |d| d.max(now).min(end));
        match at.link.receive_line(until.saturating_sub(now)) {
            Err(TransportError::Timeout(_)) if until < end => at.beats.beat(at.clock.now()),
            Err(TransportError::Timeout(_)) => {
                return Err(TransportError::Timeout(end.saturating_sub(started)));
            }
            r => return r,
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::transport::Escaped;

    #[test]
    fn escapes_control_bytes() {
        assert_eq!(Escaped(b"1PA12.5\r\n").to_string(), "1PA12.5\\r\\n");
        assert_eq!(Escaped(b"SNAP? 1,2\n").to_string(), "SNAP? 1,2\\n");
        assert_eq!(Escaped(b"\0\xff\\").to_string(), "\\0\\xff\\\\");
    }
}

#[cfg(test)]
mod beats {
    //! A wait cut at each keep-alive: the reply still arrives, a timeout reports the
    //! whole wait, and a deadline already past is one last look, not a panic.

    use std::collections::VecDeque;
    use std::sync::{Arc, Mutex};
    use std::time::Duration;

    use gonio_proto::link::{Deadline, Io, KeepAlive, Operation};

    use super::{Pumped, pump};
    use crate::clock::{Clock, ManualClock};
    use crate::heartbeat::{Heartbeat, SharedLink};
    use crate::transport::{Transport, TransportError};

    type Log = Arc<Mutex<Vec<(Duration, Vec<u8>)>>>;

    /// A line whose frames arrive at set times on a manual clock; what is sent is
    /// logged with its time.
    struct Timed {
        clock: ManualClock,
        frames: VecDeque<(Duration, Vec<u8>)>,
        sent: Log,
    }

    impl Transport for Timed {
        fn send(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
            let mut sent = self.sent.lock().unwrap_or_else(|p| p.into_inner());
            sent.push((self.clock.now(), bytes.to_vec()));
            Ok(())
        }
        fn receive_line(&mut self, timeout: Duration) -> Result<Vec<u8>, TransportError> {
            let now = self.clock.now();
            match self.frames.front() {
                Some((t, _)) if *t <= now + timeout => {
                    let (t, f) = self.frames.pop_front().unwrap_or_default();
                    self.clock.advance(t.saturating_sub(now));
                    Ok(f)
                }
                _ => {
                    self.clock.advance(timeout);
                    Err(TransportError::Timeout(timeout))
                }
            }
        }
        fn clear_input(&mut self) -> Result<(), TransportError> {
            Ok(())
        }
        fn reconnect(&mut self) -> Result<(), TransportError> {
            Ok(())
        }
        fn name(&self) -> String {
            "timed".into()
        }
    }

    /// An operation that waits for one line until `until`.
    struct WaitLine {
        until: Duration,
        out: Option<Result<Vec<u8>, TransportError>>,
    }

    impl Operation for WaitLine {
        type Output = Result<Vec<u8>, TransportError>;
        fn poll_io(&mut self) -> Option<Io<'_>> {
            None
        }
        fn poll_timeout(&self) -> Option<Deadline> {
            self.out.is_none().then_some(Deadline::Reply(self.until))
        }
        fn poll_output(&mut self) -> Option<Self::Output> {
            self.out.take()
        }
        fn handle_sent(&mut self, _: Duration, _: Result<(), TransportError>) {}
        fn handle_reconnected(&mut self, _: Duration, _: Result<(), TransportError>) {}
        fn handle_line(&mut self, _: Duration, line: &[u8]) {
            self.out = Some(Ok(line.to_vec()));
        }
        fn handle_link_error(&mut self, _: Duration, e: TransportError) {
            self.out = Some(Err(e));
        }
        fn handle_timeout(&mut self, _: Duration) {}
        fn handle_abort(&mut self, _: Duration) {}
    }

    const MS: Duration = Duration::from_millis(1);

    /// A detector line with `frames`, and an APT line's keep-alive every 0.5 s.
    fn rig(clock: &ManualClock, frames: &[(Duration, &[u8])]) -> (Timed, Heartbeat, Log) {
        let line = Timed {
            clock: clock.clone(),
            frames: frames.iter().map(|(t, f)| (*t, f.to_vec())).collect(),
            sent: Log::default(),
        };
        let apt_log = Log::default();
        let apt = Timed {
            clock: clock.clone(),
            frames: VecDeque::new(),
            sent: apt_log.clone(),
        };
        let beats = Heartbeat::new();
        let duty = KeepAlive {
            bytes: vec![0x92, 0x04, 0, 0, 0x50, 0x01],
            every: 500 * MS,
            name: "MOT_ACK_DCSTATUSUPDATE",
        };
        beats.add("apt", Box::new(SharedLink::new(apt)), duty);
        (line, beats, apt_log)
    }

    fn run(
        clock: &ManualClock,
        line: &mut Timed,
        beats: &Heartbeat,
        until: Duration,
    ) -> Result<Vec<u8>, TransportError> {
        let at = Pumped {
            link: line,
            clock,
            port: "detector",
            beats,
        };
        pump(at, None, WaitLine { until, out: None })
    }

    fn times(log: &Log) -> Vec<Duration> {
        let log = log.lock().unwrap_or_else(|p| p.into_inner());
        log.iter().map(|(t, _)| *t).collect()
    }

    #[test]
    fn a_reply_after_the_cuts_still_arrives_and_the_keepalives_went_out_on_time() {
        let clock = ManualClock::new();
        let (mut line, beats, apt) = rig(&clock, &[(2300 * MS, b"0.951359")]);
        let got = run(&clock, &mut line, &beats, 3000 * MS);
        assert_eq!(got, Ok(b"0.951359".to_vec()));
        assert_eq!(clock.now(), 2300 * MS);
        assert_eq!(
            times(&apt),
            [0, 500, 1000, 1500, 2000].map(|m| m * MS).to_vec()
        );
    }

    #[test]
    fn a_timeout_reports_the_whole_wait() {
        let clock = ManualClock::new();
        let (mut line, beats, apt) = rig(&clock, &[]);
        let got = run(&clock, &mut line, &beats, 1200 * MS);
        assert_eq!(got, Err(TransportError::Timeout(1200 * MS)));
        assert_eq!(clock.now(), 1200 * MS);
        assert_eq!(times(&apt), [0, 500, 1000].map(|m| m * MS).to_vec());
    }

    #[test]
    fn a_deadline_already_past_is_one_last_look() {
        let clock = ManualClock::new();
        clock.advance(5000 * MS);
        let (mut line, beats, apt) = rig(&clock, &[(4000 * MS, b"late")]);
        // The line that came in meanwhile is still taken.
        assert_eq!(
            run(&clock, &mut line, &beats, 4000 * MS),
            Ok(b"late".to_vec())
        );
        // Nothing more: a timeout of nothing waited, at once.
        assert_eq!(
            run(&clock, &mut line, &beats, 4000 * MS),
            Err(TransportError::Timeout(Duration::ZERO))
        );
        assert_eq!(clock.now(), 5000 * MS);
        assert_eq!(times(&apt), [5000 * MS]);
        // The heartbeat's own account: one sent, five seconds without one before it.
        let r = beats.report(Duration::ZERO, clock.now());
        assert_eq!(r, [("apt".to_string(), 1, 5000 * MS)]);
        assert_eq!(
            beats.report(4800 * MS, clock.now()),
            [("apt".to_string(), 1, 200 * MS)]
        );
    }
}
