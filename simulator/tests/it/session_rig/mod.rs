//! The in-test pump and instrument shared by `sessions_motion.rs` and
//! `sessions_detector.rs`: a session's bytes handed to `SimInstrument` and its replies
//! back, the simulated clock moved to the deadlines the session asks for.

// Each test file uses part of it.
#![allow(dead_code, unused_imports)]

pub use std::collections::VecDeque;
pub use std::path::Path;
pub use std::time::Duration;

pub use gonio_proto::link::{Deadline, Io, Operation};
pub use gonio_proto::smc100::{
    AxisConfig, AxisError, ChainPolicy, ControllerState, MotionError, Smc100Session,
};
pub use gonio_proto::sr830::{
    FilterSlope, LiaStatus, Reading, Sensitivity, Sr830Config, Sr830Session, TimeConstant,
};
pub use gonio_proto::{LineFramer, TransportError};
pub use gonio_sim::controller::Profile;
pub use gonio_sim::faults::{PortOutage, PowerLoss, Stall, Window};
pub use gonio_sim::{Port, SimClock, SimConfig, SimInstrument};

// ---------------------------------------------------------------------------------
// The pump.

/// One serial line, in memory.
pub struct Line {
    pub framer: LineFramer,
    /// Replies on their way: (arrival time, bytes).
    pub in_flight: VecDeque<(Duration, Vec<u8>)>,
    pub open: bool,
}

type Injection = Box<dyn FnOnce(&mut SimInstrument, f64)>;

/// The simulated instrument, its clock, and a record of the wire.
pub struct Rig {
    pub sim: SimInstrument,
    pub clock: SimClock,
    /// The time; the simulator's clock is advanced with it.
    pub now: Duration,
    pub lines: [Line; 2],
    /// Every line that reached the instrument: (port, time, bytes).
    pub sent: Vec<(Port, Duration, Vec<u8>)>,
    /// Reconnection attempts: (port, succeeded).
    pub reopened: Vec<(Port, bool)>,
    /// NUL bytes received.
    pub nuls: usize,
    /// The operator aborts at the first abort point from this time on.
    pub abort_at: Option<Duration>,
    /// Faults injected through the simulator's API at a time.
    pub injections: Vec<(Duration, Injection)>,
}

pub fn slot(port: Port) -> usize {
    match port {
        Port::Motion => 0,
        Port::Detector => 1,
        Port::Apt(_) | Port::Monochromator | Port::FilterWheel => {
            unreachable!("the rig has only the motion and detector lines")
        }
    }
}

impl Rig {
    /// The simulator of `config/sim-example.toml` with `seed`, edited by `edit`.
    pub fn new(seed: u64, edit: impl FnOnce(&mut SimConfig)) -> Rig {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config");
        let mut cfg = SimConfig::load(&root.join("sim-example.toml")).expect("sim config");
        cfg.seed = seed;
        cfg.time_scale = 0.0;
        edit(&mut cfg);
        let clock = SimClock::driven(0.0);
        let sim = SimInstrument::new(&cfg, clock.clone()).expect("simulator");
        let line = |terminator, max| Line {
            framer: LineFramer::new(terminator, max),
            in_flight: VecDeque::new(),
            open: true,
        };
        Rig {
            sim,
            clock,
            now: Duration::ZERO,
            lines: [
                line(b'\n', gonio_proto::smc100::MAX_LINE),
                line(b'\r', gonio_proto::sr830::MAX_LINE),
            ],
            sent: Vec::new(),
            reopened: Vec::new(),
            nuls: 0,
            abort_at: None,
            injections: Vec::new(),
        }
    }

    pub fn secs(&self) -> f64 {
        self.clock.seconds()
    }

    pub fn advance_to(&mut self, t: Duration) {
        if t > self.now {
            self.clock.advance(t - self.now);
            self.now = t;
        }
    }

    /// Runs `op`, a session's operation on `port`, to its end.
    pub fn run<O: Operation>(&mut self, port: Port, mut op: O) -> O::Output {
        loop {
            while let Some(io) = op.poll_io() {
                match io {
                    Io::Transmit(bytes) => {
                        let r = self.transmit(port, bytes);
                        op.handle_sent(self.now, r);
                    }
                    Io::ClearInput => self.clear(port),
                    Io::Reconnect => {
                        let r = self.reopen(port);
                        op.handle_reconnected(self.now, r);
                    }
                }
            }
            if let Some(out) = op.poll_output() {
                return out;
            }
            match op
                .poll_timeout()
                .expect("an unfinished operation waits for something")
            {
                Deadline::Reply(at) => match self.receive(port, at) {
                    Some(Ok(line)) => op.handle_line(self.now, &line),
                    Some(Err(e)) => op.handle_link_error(self.now, e),
                    None => op.handle_timeout(self.now),
                },
                Deadline::Poll(_) if self.abort_at.is_some_and(|t| self.now >= t) => {
                    op.handle_abort(self.now);
                }
                Deadline::Poll(at) | Deadline::Sleep(at) => {
                    self.advance_to(at);
                    op.handle_timeout(self.now);
                }
            }
        }
    }

    pub fn gone(port: Port) -> TransportError {
        TransportError::Disconnected {
            port: format!("{port:?}"),
            reason: "simulated outage".into(),
        }
    }

    pub fn transmit(&mut self, port: Port, bytes: &[u8]) -> Result<(), TransportError> {
        let t = self.secs();
        let due: Vec<Injection> = {
            let (due, later) = std::mem::take(&mut self.injections)
                .into_iter()
                .partition(|(at, _)| *at <= self.now);
            self.injections = later;
            due.into_iter().map(|(_, f)| f).collect()
        };
        for f in due {
            f(&mut self.sim, t);
        }
        let line = &mut self.lines[slot(port)];
        if !line.open || self.sim.port_closed(port) {
            line.open = false;
            return Err(Self::gone(port));
        }
        self.sent.push((port, self.now, bytes.to_vec()));
        let reply = self.sim.port_bytes(port, bytes);
        if !reply.is_empty() {
            let latency = self.sim.latency(port);
            let delay = Duration::from_secs_f64(latency + self.sim.faults().reply_delay_s);
            line.in_flight.push_back((self.now + delay, reply));
        }
        Ok(())
    }

    /// The next line by `deadline`, the clock moved to its arrival; `None` (the clock at
    /// the deadline) when none comes.
    pub fn receive(
        &mut self,
        port: Port,
        deadline: Duration,
    ) -> Option<Result<Vec<u8>, TransportError>> {
        if !self.lines[slot(port)].open {
            return Some(Err(Self::gone(port)));
        }
        loop {
            let line = &mut self.lines[slot(port)];
            if let Some(l) = line.framer.next_line() {
                if l.is_err() {
                    self.nuls += 1;
                }
                return Some(l.map_err(TransportError::from));
            }
            match line.in_flight.front() {
                Some((t, _)) if *t <= deadline => {
                    let (t, bytes) = line.in_flight.pop_front().expect("a reply in flight");
                    line.framer.push(&bytes);
                    self.advance_to(t);
                }
                _ => {
                    self.advance_to(deadline);
                    return None;
                }
            }
        }
    }

    pub fn clear(&mut self, port: Port) {
        let now = self.now;
        let line = &mut self.lines[slot(port)];
        line.in_flight.retain(|(t, _)| *t > now);
        line.framer.clear();
    }

    pub fn reopen(&mut self, port: Port) -> Result<(), TransportError> {
        let closed = self.sim.port_closed(port);
        let line = &mut self.lines[slot(port)];
        line.framer.clear();
        line.in_flight.clear();
        self.reopened.push((port, !closed));
        if closed {
            return Err(Self::gone(port));
        }
        line.open = true;
        Ok(())
    }

    /// The lines sent on `port` from index `from` of the record, as text.
    pub fn lines_since(&self, from: usize, port: Port) -> Vec<String> {
        self.sent[from..]
            .iter()
            .filter(|(p, _, _)| *p == port)
            .map(|(_, _, b)| String::from_utf8_lossy(b).into_owned())
            .collect()
    }

    /// True when no stage is moving (ten seconds from now, when any stop has ended).
    pub fn all_stopped(&mut self) -> bool {
        let t = self.secs() + 10.0;
        (1..=4).all(|a| {
            self.sim
                .controller_mut(a)
                .is_some_and(|c| !c.state(t).is_moving())
        })
    }
}

// ---------------------------------------------------------------------------------
// The instrument: the axes of config/instrument-sim.toml, a lock-in config.

pub fn axis(name: &str, address: u8, min: f64, max: f64, velocity: f64) -> AxisConfig {
    AxisConfig {
        name: name.into(),
        address,
        units: "deg".into(),
        min,
        max,
        velocity: Some(velocity),
        acceleration: (address <= 2).then_some(80.0),
        tolerance: 0.01,
        home_timeout_s: 120.0,
    }
}

pub fn axes() -> Vec<AxisConfig> {
    vec![
        axis("source", 1, -170.0, 170.0, 20.0),
        axis("detector", 2, -170.0, 170.0, 20.0),
        axis("sample_rot", 3, -180.0, 180.0, 30.0),
        axis("sample_tilt", 4, -5.0, 85.0, 10.0),
    ]
}

pub fn lockin_config() -> Sr830Config {
    Sr830Config {
        sensitivity: Sensitivity::LEAST,
        time_constant: TimeConstant::new(8).expect("100 ms"),
        slope: FilterSlope::Db24,
        samples: 10,
        autorange: true,
        min_fraction: 0.1,
        retries: 2,
        settle_residual: 1e-4,
        ..Sr830Config::default()
    }
}

pub const POINT: [(&str, f64); 4] = [
    ("source", 30.0),
    ("detector", -40.0),
    ("sample_rot", 10.0),
    ("sample_tilt", 5.0),
];

/// The chain identified and homed, the lock-in set up, on a simulator made by `edit`.
pub fn ready(seed: u64, edit: impl FnOnce(&mut SimConfig)) -> (Rig, Smc100Session, Sr830Session) {
    ready_with(seed, edit, ChainPolicy::default(), axes())
}

pub fn ready_with(
    seed: u64,
    edit: impl FnOnce(&mut SimConfig),
    policy: ChainPolicy,
    axes: Vec<AxisConfig>,
) -> (Rig, Smc100Session, Sr830Session) {
    let mut rig = Rig::new(seed, edit);
    let mut chain = Smc100Session::new(axes, policy).expect("valid axes");
    let infos = rig
        .run(Port::Motion, chain.start_identify(rig.now))
        .expect("identified");
    assert!(
        infos
            .iter()
            .all(|i| i.state == ControllerState::NotReferencedFromReset)
    );
    rig.run(Port::Motion, chain.start_home_all(rig.now))
        .expect("homed");
    let mut lockin =
        Sr830Session::new(lockin_config(), "sim:detector", rig.now).expect("valid config");
    let id = rig
        .run(Port::Detector, lockin.start_setup(rig.now))
        .expect("set up");
    assert_eq!(id.model, "SR830");
    (rig, chain, lockin)
}

pub fn at_axis(e: MotionError) -> (String, AxisError) {
    match e {
        MotionError::AtAxis { axis, source } => (axis, source),
        other => panic!("expected an axis error, got {other}"),
    }
}

/// The standard deviation of one lock-in sample of R at the session's settings: the
/// simulator's noise density √(amplifier² + shot²·R) times √ENBW.
pub fn noise_sigma(rig: &mut SimInstrument, r: f64, slope: FilterSlope, tc: TimeConstant) -> f64 {
    let c = rig.lockin_mut().config().clone();
    let density = (c.amplifier_noise.powi(2) + c.shot_noise.powi(2) * r).sqrt();
    density * slope.enbw_hz(tc).sqrt()
}
