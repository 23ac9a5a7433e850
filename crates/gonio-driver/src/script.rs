//! A transport that replays a transcript: the exact bytes a driver must send, and what
//! the instrument answers (lines, silence, garbage, a NUL, a vanished port).
//!
//! Tests at the driver level are written as these transcripts, the manuals' exchanges
//! byte for byte. Any byte the driver sends that the script does not expect is
//! recorded as a failure, and [`ScriptHandle::finish`] reports every unmet or
//! unexpected exchange.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use gonio_proto::LineFramer;

use crate::clock::{Clock, ManualClock};
use crate::transport::{Transport, TransportError};

#[derive(Debug, Clone)]
enum Step {
    /// The driver sends these bytes; the instrument then answers `reply` (raw bytes,
    /// any number of lines, possibly broken) or stays silent (`None`).
    Exchange {
        send: Vec<u8>,
        reply: Option<Vec<u8>>,
    },
    /// The port disappears: every operation fails until `failed_reconnects`
    /// reconnection attempts have failed and the next one succeeds.
    Vanish { failed_reconnects: usize },
}

#[derive(Debug)]
struct State {
    steps: VecDeque<Step>,
    framer: LineFramer,
    /// Bytes of the current reply not yet handed to the framer.
    pending: Vec<u8>,
    sent: Vec<Vec<u8>>,
    failures: Vec<String>,
    vanished: bool,
    reconnects: usize,
}

/// The builder and checker side of a [`ScriptedTransport`].
#[derive(Debug, Clone)]
pub struct ScriptHandle {
    state: Arc<Mutex<State>>,
}

/// A [`Transport`] that plays a script; see the module docs.
#[derive(Debug)]
pub struct ScriptedTransport {
    state: Arc<Mutex<State>>,
    clock: ManualClock,
    name: String,
}

fn lock(m: &Mutex<State>) -> MutexGuard<'_, State> {
    // A panic while holding the lock can only come from a failing test thread;
    // the state is still usable for its report.
    m.lock().unwrap_or_else(|p| p.into_inner())
}

impl ScriptedTransport {
    /// A transport framing lines on `terminator`, advancing `clock` by the timeout
    /// whenever a read times out, and the handle to script and check it.
    pub fn new(terminator: u8, max_line: usize, clock: ManualClock) -> (Self, ScriptHandle) {
        let state = Arc::new(Mutex::new(State {
            steps: VecDeque::new(),
            framer: LineFramer::new(terminator, max_line),
            pending: Vec::new(),
            sent: Vec::new(),
            failures: Vec::new(),
            vanished: false,
            reconnects: 0,
        }));
        (
            ScriptedTransport {
                state: state.clone(),
                clock,
                name: "script".into(),
            },
            ScriptHandle { state },
        )
    }
}

impl ScriptHandle {
    /// The driver must send `send`; the instrument answers `reply` (raw bytes).
    pub fn exchange(&self, send: impl AsRef<[u8]>, reply: impl AsRef<[u8]>) -> &Self {
        lock(&self.state).steps.push_back(Step::Exchange {
            send: send.as_ref().to_vec(),
            reply: Some(reply.as_ref().to_vec()),
        });
        self
    }

    /// The driver must send `send`; the instrument answers nothing (a set command, or
    /// a lost reply).
    pub fn send(&self, send: impl AsRef<[u8]>) -> &Self {
        lock(&self.state).steps.push_back(Step::Exchange {
            send: send.as_ref().to_vec(),
            reply: None,
        });
        self
    }

    /// The port vanishes; `failed_reconnects` attempts to reopen it fail before one
    /// succeeds.
    pub fn vanish(&self, failed_reconnects: usize) -> &Self {
        lock(&self.state)
            .steps
            .push_back(Step::Vanish { failed_reconnects });
        self
    }

    /// Everything the driver sent, in order.
    pub fn sent(&self) -> Vec<Vec<u8>> {
        lock(&self.state).sent.clone()
    }

    /// How many times the driver reopened the port.
    pub fn reconnects(&self) -> usize {
        lock(&self.state).reconnects
    }

    /// `Ok` when every scripted exchange happened and nothing else was sent;
    /// otherwise the list of differences.
    pub fn finish(&self) -> Result<(), String> {
        let s = lock(&self.state);
        let mut problems = s.failures.clone();
        for step in &s.steps {
            problems.push(format!("scripted but not happened: {}", describe(step)));
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(problems.join("\n"))
        }
    }
}

fn describe(step: &Step) -> String {
    match step {
        Step::Exchange { send, .. } => format!("send {:?}", String::from_utf8_lossy(send)),
        Step::Vanish { .. } => "port vanishes".into(),
    }
}

impl Transport for ScriptedTransport {
    fn send(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        let mut s = lock(&self.state);
        s.sent.push(bytes.to_vec());
        if let Some(Step::Vanish { .. }) = s.steps.front() {
            s.vanished = true;
        }
        if s.vanished {
            return Err(TransportError::Disconnected {
                port: self.name.clone(),
                reason: "scripted: port vanished".into(),
            });
        }
        match s.steps.pop_front() {
            Some(Step::Exchange { send, reply }) if send == bytes => {
                if let Some(r) = reply {
                    s.pending.extend_from_slice(&r);
                }
                Ok(())
            }
            Some(step) => {
                let msg = format!(
                    "driver sent {:?}, script expected {}",
                    String::from_utf8_lossy(bytes),
                    describe(&step)
                );
                s.steps.push_front(step);
                s.failures.push(msg.clone());
                Err(TransportError::Script(msg))
            }
            None => {
                let msg = format!(
                    "driver sent {:?} after the end of the script",
                    String::from_utf8_lossy(bytes)
                );
                s.failures.push(msg.clone());
                Err(TransportError::Script(msg))
            }
        }
    }

    fn receive_line(&mut self, timeout: Duration) -> Result<Vec<u8>, TransportError> {
        let mut s = lock(&self.state);
        if s.vanished {
            return Err(TransportError::Disconnected {
                port: self.name.clone(),
                reason: "scripted: port vanished".into(),
            });
        }
        let pending = std::mem::take(&mut s.pending);
        s.framer.push(&pending);
        match s.framer.next_line() {
            Some(line) => line.map_err(TransportError::from),
            None => {
                drop(s);
                self.clock.sleep(timeout);
                Err(TransportError::Timeout(timeout))
            }
        }
    }

    fn clear_input(&mut self) -> Result<(), TransportError> {
        let mut s = lock(&self.state);
        s.pending.clear();
        s.framer.clear();
        Ok(())
    }

    fn reconnect(&mut self) -> Result<(), TransportError> {
        let mut s = lock(&self.state);
        s.pending.clear();
        s.framer.clear();
        if let Some(Step::Vanish { failed_reconnects }) = s.steps.front_mut() {
            if *failed_reconnects > 0 {
                *failed_reconnects -= 1;
                s.vanished = true;
                return Err(TransportError::Disconnected {
                    port: self.name.clone(),
                    reason: "scripted: port still absent".into(),
                });
            }
            s.steps.pop_front();
        }
        s.vanished = false;
        s.reconnects += 1;
        Ok(())
    }

    fn name(&self) -> String {
        self.name.clone()
    }
}
