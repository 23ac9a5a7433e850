//! An in-memory [`Transport`] into the simulator: the driver's bytes go straight to
//! [`SimInstrument`], on simulated time. Each exchange costs the physical time the
//! bytes take on the wire at the configured baud rate plus the instrument's reply
//! latency, so the simulated run's duration is that of the lab's.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use gonio_driver::{Clock, Transport, TransportError};
use gonio_proto::apt::AptFramer;
use gonio_proto::{Framer, LineFramer};

use crate::clock::SimClock;
use crate::faults::Port;
use crate::instrument::SimInstrument;

/// A shared handle on the simulated instrument (tests inject faults through it).
pub type SharedSim = Arc<Mutex<SimInstrument>>;

/// Locks the simulator; a panic elsewhere cannot leave it unusable.
pub fn lock(sim: &SharedSim) -> MutexGuard<'_, SimInstrument> {
    sim.lock().unwrap_or_else(|p| p.into_inner())
}

/// One of the simulator's two serial lines, in memory.
pub struct SimTransport {
    sim: SharedSim,
    port: Port,
    clock: SimClock,
    framer: Box<dyn Framer>,
    /// Reply lines not yet arrived: (arrival time, bytes).
    in_flight: VecDeque<(f64, Vec<u8>)>,
    open: bool,
}

impl std::fmt::Debug for SimTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimTransport")
            .field("port", &self.port)
            .finish()
    }
}

impl SimTransport {
    /// The `port` line of `sim`.
    pub fn new(sim: SharedSim, port: Port) -> Self {
        let clock = lock(&sim).clock().clone();
        let framer: Box<dyn Framer> = match port {
            Port::Motion => Box::new(LineFramer::new(b'\n', gonio_proto::smc100::MAX_LINE)),
            // Lines ended by CR, and the SR830's binary traces by their length.
            Port::Detector => Box::new(gonio_proto::sr830::Sr830Framer::new(
                gonio_proto::sr830::MAX_LINE.max(gonio_proto::k6485::MAX_LINE),
            )),
            Port::Apt(_) => Box::new(AptFramer::new()),
            Port::Monochromator => Box::new(LineFramer::new(
                gonio_proto::cs130::REPLY_TERMINATOR,
                gonio_proto::cs130::MAX_LINE,
            )),
            Port::FilterWheel => Box::new(LineFramer::new(
                gonio_proto::fw102c::TERMINATOR,
                gonio_proto::fw102c::MAX_LINE,
            )),
        };
        SimTransport {
            sim,
            port,
            clock,
            framer,
            in_flight: VecDeque::new(),
            open: true,
        }
    }

    /// Waits on the clock until `t`, if it is later.
    fn sleep_until(&self, t: f64) {
        let now = self.clock.seconds();
        if t > now {
            self.clock.sleep(crate::clock::secs(t - now));
        }
    }

    fn gone(&self) -> TransportError {
        TransportError::Disconnected {
            port: self.name(),
            reason: "simulated outage".into(),
        }
    }
}

impl Transport for SimTransport {
    fn send(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        let sim = lock(&self.sim);
        if !self.open || sim.port_closed(self.port) {
            self.open = false;
            return Err(self.gone());
        }
        let out_time = sim.wire_time(self.port, bytes.len());
        drop(sim);
        self.framer.sent(bytes);
        self.clock.advance(crate::clock::secs(out_time));
        let mut sim = lock(&self.sim);
        let reply = sim.port_bytes(self.port, bytes);
        if reply.is_empty() {
            return Ok(());
        }
        let latency = sim.latency(self.port);
        let arrive = self.clock.seconds().max(sim.busy_until(self.port))
            + latency
            + sim.faults().reply_delay_s
            + sim.wire_time(self.port, reply.len());
        self.in_flight.push_back((arrive, reply));
        Ok(())
    }

    fn receive_line(&mut self, timeout: Duration) -> Result<Vec<u8>, TransportError> {
        if !self.open {
            return Err(self.gone());
        }
        let deadline = self.clock.seconds() + timeout.as_secs_f64();
        let mut stale = None;
        loop {
            if let Some(line) = self.framer.next_frame() {
                return line.map_err(TransportError::from);
            }
            // What the instrument sends unasked (an APT controller's move completed)
            // arrives when it happens, if that is before the next reply.
            let next_reply = self.in_flight.front().map_or(f64::INFINITY, |(t, _)| *t);
            let unasked = lock(&self.sim).next_unsolicited(self.port);
            if let Some(t) = unasked
                && t <= deadline
                && t < next_reply
                && stale != Some(t)
            {
                self.sleep_until(t);
                let bytes = lock(&self.sim).unsolicited(self.port, t);
                // A device that had nothing to send at `t` after all is not asked
                // about `t` again: the wait goes on to its replies or its deadline.
                stale = bytes.is_empty().then_some(t);
                self.framer.push(&bytes);
                continue;
            }
            match self.in_flight.front() {
                Some((t, _)) if *t <= deadline => {
                    let (t, bytes) = self.in_flight.pop_front().unwrap_or_default();
                    self.sleep_until(t);
                    self.framer.push(&bytes);
                }
                _ => {
                    self.sleep_until(deadline);
                    return Err(TransportError::Timeout(timeout));
                }
            }
        }
    }

    fn clear_input(&mut self) -> Result<(), TransportError> {
        // What has arrived is discarded; what is still on its way is not.
        let now = self.clock.seconds();
        self.in_flight.retain(|(t, _)| *t > now);
        self.framer.clear();
        Ok(())
    }

    fn reconnect(&mut self) -> Result<(), TransportError> {
        self.framer.clear();
        self.in_flight.clear();
        if lock(&self.sim).port_closed(self.port) {
            return Err(self.gone());
        }
        self.open = true;
        Ok(())
    }

    fn name(&self) -> String {
        format!("sim:{}", self.port.name())
    }
}
