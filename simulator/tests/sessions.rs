//! The sessions of `gonio-proto` against the simulator's device models, in memory, on
//! virtual time: no driver, no transport, no pty, no sleep. A tiny pump ([`Rig::run`])
//! hands a session's bytes to [`SimInstrument`], its replies back (after the link's
//! latency), and moves the simulated clock to the deadlines the session asks for. That
//! is all a session needs: bytes and time.
//!
//! Every fault class the simulator produces is covered, each asserting the typed
//! outcome, the exact lines on the wire where they are deterministic, the stops, and the
//! times on the virtual clock.

use std::collections::VecDeque;
use std::path::Path;
use std::time::Duration;

use gonio_proto::link::{Deadline, Io, Operation};
use gonio_proto::smc100::{
    AxisConfig, AxisError, ChainPolicy, ControllerState, MotionError, Smc100Session,
};
use gonio_proto::sr830::{
    FilterSlope, LiaStatus, Reading, Sensitivity, Sr830Config, Sr830Session, TimeConstant,
};
use gonio_proto::{LineFramer, TransportError};
use gonio_sim::controller::Profile;
use gonio_sim::faults::{PortOutage, PowerLoss, Stall, Window};
use gonio_sim::{Port, SimClock, SimConfig, SimInstrument};

// ---------------------------------------------------------------------------------
// The pump.

/// One serial line, in memory.
struct Line {
    framer: LineFramer,
    /// Replies on their way: (arrival time, bytes).
    in_flight: VecDeque<(Duration, Vec<u8>)>,
    open: bool,
}

type Injection = Box<dyn FnOnce(&mut SimInstrument, f64)>;

/// The simulated instrument, its clock, and a record of the wire.
struct Rig {
    sim: SimInstrument,
    clock: SimClock,
    /// The time; the simulator's clock is advanced with it.
    now: Duration,
    lines: [Line; 2],
    /// Every line that reached the instrument: (port, time, bytes).
    sent: Vec<(Port, Duration, Vec<u8>)>,
    /// Reconnection attempts: (port, succeeded).
    reopened: Vec<(Port, bool)>,
    /// NUL bytes received.
    nuls: usize,
    /// The operator aborts at the first abort point from this time on.
    abort_at: Option<Duration>,
    /// Faults injected through the simulator's API at a time.
    injections: Vec<(Duration, Injection)>,
}

fn slot(port: Port) -> usize {
    match port {
        Port::Motion => 0,
        Port::Detector => 1,
    }
}

impl Rig {
    /// The simulator of `config/sim-example.toml` with `seed`, edited by `edit`.
    fn new(seed: u64, edit: impl FnOnce(&mut SimConfig)) -> Rig {
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

    fn secs(&self) -> f64 {
        self.clock.seconds()
    }

    fn advance_to(&mut self, t: Duration) {
        if t > self.now {
            self.clock.advance(t - self.now);
            self.now = t;
        }
    }

    /// Runs `op`, a session's operation on `port`, to its end.
    fn run<O: Operation>(&mut self, port: Port, mut op: O) -> O::Output {
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

    fn gone(port: Port) -> TransportError {
        TransportError::Disconnected {
            port: format!("{port:?}"),
            reason: "simulated outage".into(),
        }
    }

    fn transmit(&mut self, port: Port, bytes: &[u8]) -> Result<(), TransportError> {
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
        let reply = match port {
            Port::Motion => self.sim.motion_bytes(bytes),
            Port::Detector => self.sim.lockin_bytes(bytes),
        };
        if !reply.is_empty() {
            let latency = match port {
                Port::Motion => self.sim.link().motion_latency_s,
                Port::Detector => self.sim.link().detector_latency_s,
            };
            let delay = Duration::from_secs_f64(latency + self.sim.faults().reply_delay_s);
            line.in_flight.push_back((self.now + delay, reply));
        }
        Ok(())
    }

    /// The next line by `deadline`, the clock moved to its arrival; `None` (the clock at
    /// the deadline) when none comes.
    fn receive(
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

    fn clear(&mut self, port: Port) {
        let now = self.now;
        let line = &mut self.lines[slot(port)];
        line.in_flight.retain(|(t, _)| *t > now);
        line.framer.clear();
    }

    fn reopen(&mut self, port: Port) -> Result<(), TransportError> {
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
    fn lines_since(&self, from: usize, port: Port) -> Vec<String> {
        self.sent[from..]
            .iter()
            .filter(|(p, _, _)| *p == port)
            .map(|(_, _, b)| String::from_utf8_lossy(b).into_owned())
            .collect()
    }

    /// True when no stage is moving (ten seconds from now, when any stop has ended).
    fn all_stopped(&mut self) -> bool {
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

fn axis(name: &str, address: u8, min: f64, max: f64, velocity: f64) -> AxisConfig {
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

fn axes() -> Vec<AxisConfig> {
    vec![
        axis("source", 1, -170.0, 170.0, 20.0),
        axis("detector", 2, -170.0, 170.0, 20.0),
        axis("sample_rot", 3, -180.0, 180.0, 30.0),
        axis("sample_tilt", 4, -5.0, 85.0, 10.0),
    ]
}

fn lockin_config() -> Sr830Config {
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

const POINT: [(&str, f64); 4] = [
    ("source", 30.0),
    ("detector", -40.0),
    ("sample_rot", 10.0),
    ("sample_tilt", 5.0),
];

/// The chain identified and homed, the lock-in set up, on a simulator made by `edit`.
fn ready(seed: u64, edit: impl FnOnce(&mut SimConfig)) -> (Rig, Smc100Session, Sr830Session) {
    ready_with(seed, edit, ChainPolicy::default(), axes())
}

fn ready_with(
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

fn at_axis(e: MotionError) -> (String, AxisError) {
    match e {
        MotionError::AtAxis { axis, source } => (axis, source),
        other => panic!("expected an axis error, got {other}"),
    }
}

/// The standard deviation of one lock-in sample of R at the session's settings: the
/// simulator's noise density √(amplifier² + shot²·R) times √ENBW.
fn noise_sigma(rig: &mut SimInstrument, r: f64, slope: FilterSlope, tc: TimeConstant) -> f64 {
    let c = rig.lockin_mut().config().clone();
    let density = (c.amplifier_noise.powi(2) + c.shot_noise.powi(2) * r).sqrt();
    density * slope.enbw_hz(tc).sqrt()
}

// ---------------------------------------------------------------------------------
// Motion: the happy path, then each fault.

/// Homing brings every stage READY at its home, and a move ends within tolerance at
/// every target; the positions the session reports are the simulated counters.
#[test]
fn home_then_move_reaches_every_target() {
    let (mut rig, mut chain, _) = ready(1, |_| {});
    assert!(
        rig.now > Duration::from_secs(3),
        "homing from -40° at 10°/s takes 4 s"
    );
    let from = rig.sent.len();
    let positions = rig
        .run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect("moved");
    for ((_, target), p) in POINT.iter().zip(&positions) {
        assert!((p - target).abs() <= 0.0005, "{p} vs {target}");
    }
    let t = rig.secs();
    let angles = rig.sim.stage_angles(t);
    for (k, (_, target)) in POINT.iter().enumerate() {
        assert!((angles[k] - target).abs() < 1e-9, "{angles:?}");
    }
    // Per axis TP, PT, PA, TE; then polls; then TP each: no retry, no stop.
    let lines = rig.lines_since(from, Port::Motion);
    assert_eq!(
        &lines[..4],
        ["1TP\r\n", "1PT30\r\n", "1PA30\r\n", "1TE\r\n"]
    );
    assert_eq!(lines.iter().filter(|l| l.contains("PA")).count(), 4);
    assert!(!lines.iter().any(|l| l == "ST\r\n"));
    assert_eq!(chain.retried(), 0);
}

/// Soft limits: a target outside them is refused before a single byte goes out.
#[test]
fn out_of_limits_target_sends_nothing() {
    let (mut rig, mut chain, _) = ready(2, |_| {});
    let (sent, lines_in) = (rig.sent.len(), rig.sim.stats().motion_lines);
    let mut op = chain.start_move(&[("source", 10.0), ("detector", 170.5)], rig.now);
    assert_eq!(op.poll_io(), None, "no byte to send");
    match op.poll_output() {
        Some(Err(e)) => assert_eq!(
            at_axis(e),
            (
                "detector".to_string(),
                AxisError::OutOfLimits {
                    target: 170.5,
                    min: -170.0,
                    max: 170.0,
                    units: "deg".into()
                }
            )
        ),
        other => panic!("{other:?}"),
    }
    drop(op);
    let e = rig
        .run(
            Port::Motion,
            chain.start_move(&[("sample_tilt", f64::NAN)], rig.now),
        )
        .expect_err("NaN");
    assert!(matches!(at_axis(e).1, AxisError::OutOfLimits { .. }));
    assert_eq!(rig.sent.len(), sent, "zero bytes sent");
    assert_eq!(
        rig.sim.stats().motion_lines,
        lines_in,
        "zero lines received"
    );
}

/// A reply that never comes: the query is asked `retries` + 1 times, each after the
/// 100 ms reply timeout, then the timeout is the error.
#[test]
fn silent_controller_times_out_after_retries() {
    let (mut rig, mut chain, _) = ready(3, |c| c.faults.silent = vec!["2TP".into()]);
    let (from, t0) = (rig.sent.len(), rig.now);
    let e = rig
        .run(Port::Motion, chain.start_position("detector", rig.now))
        .expect_err("silent");
    assert_eq!(
        at_axis(e),
        (
            "detector".into(),
            AxisError::Transport(TransportError::Timeout(Duration::from_millis(100)))
        )
    );
    assert_eq!(rig.lines_since(from, Port::Motion), ["2TP\r\n"; 3]);
    assert_eq!(rig.now - t0, Duration::from_millis(300));
    assert_eq!(chain.retried(), 2);
}

/// Dropped replies: each lost reply costs exactly one retry of an exchange that may be
/// repeated, and the move still ends at its targets.
#[test]
fn dropped_replies_are_retried_one_for_one() {
    let (mut rig, mut chain, _) = ready(4, |_| {});
    rig.sim.faults_mut().drop_reply = 0.05;
    let positions = rig
        .run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect("the retries get through");
    for ((_, target), p) in POINT.iter().zip(&positions) {
        assert!((p - target).abs() <= 0.0005);
    }
    let dropped = rig.sim.stats().dropped;
    assert!(dropped > 0, "the fault fired");
    assert_eq!(chain.retried(), dropped);
}

/// Garbled replies (a byte replaced by line noise) never parse: each costs one retry;
/// when every reply is garbled, the session refuses them all.
#[test]
fn corrupted_replies_are_retried_or_refused() {
    let (mut rig, mut chain, _) = ready(5, |_| {});
    rig.sim.faults_mut().corrupt_reply = 0.05;
    rig.run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect("the retries get through");
    let corrupted = rig.sim.stats().corrupted;
    assert!(corrupted > 0);
    assert_eq!(chain.retried(), corrupted);

    rig.sim.faults_mut().corrupt_reply = 1.0;
    let from = rig.sent.len();
    let e = rig
        .run(Port::Motion, chain.start_position("source", rig.now))
        .expect_err("never a clean reply");
    assert!(matches!(at_axis(e).1, AxisError::Protocol { .. }));
    assert_eq!(rig.lines_since(from, Port::Motion), ["1TP\r\n"; 3]);
}

/// A reply later than the timeout arrives while the query is asked again: it answers
/// the same query and is taken; one later than every attempt is a timeout.
#[test]
fn late_replies() {
    let (mut rig, mut chain, _) = ready(6, |_| {});
    rig.sim.faults_mut().reply_delay_s = 0.15;
    let t0 = rig.now;
    let p = rig
        .run(Port::Motion, chain.start_position("source", rig.now))
        .expect("late but answered");
    assert!(p.abs() < 1e-9);
    // Asked at 0 and at 100 ms; the first answer arrives at 10 + 150 ms.
    assert_eq!(rig.now - t0, Duration::from_millis(160));
    assert_eq!(chain.retried(), 1);
    rig.sim.faults_mut().reply_delay_s = 1.0;
    let e = rig
        .run(Port::Motion, chain.start_position("detector", rig.now))
        .expect_err("too late");
    assert!(matches!(
        at_axis(e).1,
        AxisError::Transport(TransportError::Timeout(_))
    ));
}

/// Power loss mid-move: a NUL byte on the line, every stage stopped; then reset, the
/// boot waited out, a home search, and the point measured again.
#[test]
fn power_loss_mid_move_then_recovery_by_homing() {
    let (mut rig, mut chain, _) = ready(7, |_| {});
    let t = rig.secs();
    rig.sim.faults_mut().power_loss.push(PowerLoss {
        address: 2,
        at_s: t + 0.5,
    });
    let from = rig.sent.len();
    let e = rig
        .run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect_err("power loss");
    assert_eq!(at_axis(e).1, AxisError::ControllerReset);
    assert_eq!(rig.nuls, 1);
    assert_eq!(rig.sim.stats().power_losses, 1);
    assert_eq!(
        rig.lines_since(from, Port::Motion)
            .last()
            .map(String::as_str),
        Some("ST\r\n")
    );
    assert!(rig.all_stopped());

    let t0 = rig.now;
    rig.run(
        Port::Motion,
        chain.start_reset_and_home("detector", rig.now),
    )
    .expect("recovers");
    assert!(
        rig.now - t0 > Duration::from_secs(3),
        "the controller boots for 3 s"
    );
    let positions = rig
        .run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect("moves after recovery");
    assert!((positions[1] + 40.0).abs() <= 0.0005);
}

/// A controller that restarts without a NUL on the line (here through the simulator's
/// API, booting at once) shows NOT REFERENCED from reset (`0A`) mid-move: the session
/// tells it from the state, and stops every stage.
#[test]
fn controller_reset_is_seen_in_the_state() {
    let (mut rig, mut chain, _) = ready(8, |c| {
        for k in &mut c.controllers {
            k.boot_time_s = 0.0;
        }
    });
    let at = rig.now + Duration::from_millis(500);
    rig.injections.push((
        at,
        Box::new(|sim: &mut SimInstrument, t: f64| {
            sim.controller_mut(1).expect("controller 1").power_cycle(t);
        }),
    ));
    let from = rig.sent.len();
    let e = rig
        .run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect_err("reset");
    assert_eq!(at_axis(e), ("source".into(), AxisError::ControllerReset));
    assert_eq!(rig.nuls, 0, "seen in the state, not as a NUL");
    let lines = rig.lines_since(from, Port::Motion);
    assert_eq!(lines.last().map(String::as_str), Some("ST\r\n"));
    assert!(rig.all_stopped());
}

/// A stage that sticks: the controller's following error puts it in DISABLE (`3D`,
/// bit 0x20); every stage is stopped and the stage stays where it stuck.
#[test]
fn stall_is_a_following_error_in_disable() {
    let (mut rig, mut chain, _) = ready(9, |c| {
        c.faults.stall = vec![Stall {
            address: 1,
            at: 20.0,
        }];
    });
    let from = rig.sent.len();
    let e = rig
        .run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect_err("stalled");
    assert_eq!(
        at_axis(e),
        (
            "source".into(),
            AxisError::Disabled {
                state: ControllerState::DisableFromMoving,
                errors: 0x0020
            }
        )
    );
    assert_eq!(
        rig.lines_since(from, Port::Motion)
            .last()
            .map(String::as_str),
        Some("ST\r\n")
    );
    assert!(rig.all_stopped());
    let t = rig.secs();
    assert!((rig.sim.stage_angles(t)[0] - 20.0).abs() < 1e-9);
}

/// A move that outlasts its deadline (here the policy allows half the controller's own
/// estimate): every stage stopped, then the position read and reported.
#[test]
fn move_past_its_deadline_is_stopped() {
    let policy = ChainPolicy {
        move_margin: Duration::ZERO,
        move_factor: 0.5,
        ..ChainPolicy::default()
    };
    let (mut rig, mut chain, _) = ready_with(10, |_| {}, policy, axes());
    let from = rig.sent.len();
    let e = rig
        .run(Port::Motion, chain.start_move(&[("source", 60.0)], rig.now))
        .expect_err("too long");
    let estimate = Profile::duration_for(60.0, 20.0, 80.0);
    let waited = Duration::from_secs_f64(estimate * 0.5);
    match at_axis(e) {
        (
            axis,
            AxisError::Timeout {
                operation,
                target,
                position,
                waited: w,
            },
        ) => {
            assert_eq!(
                (axis.as_str(), operation, target, w),
                ("source", "move", 60.0, waited)
            );
            let p = position.expect("read after the stop");
            assert!(p > 0.0 && p < 60.0, "{p}");
        }
        other => panic!("{other:?}"),
    }
    let lines = rig.lines_since(from, Port::Motion);
    assert_eq!(&lines[lines.len() - 2..], ["ST\r\n", "1TP\r\n"]);
}

/// A stage that ends READY away from its target: the encoder counts (2000 a degree)
/// cannot hit 10.0003°, and a 1e-4° tolerance refuses 10.0005°.
#[test]
fn target_not_reached() {
    let mut tight = axes();
    tight[0].tolerance = 1e-4;
    let (mut rig, mut chain, _) = ready_with(11, |_| {}, ChainPolicy::default(), tight);
    let e = rig
        .run(
            Port::Motion,
            chain.start_move(&[("source", 10.0003)], rig.now),
        )
        .expect_err("short");
    assert_eq!(
        at_axis(e).1,
        AxisError::TargetNotReached {
            target: 10.0003,
            position: 10.0005,
            tolerance: 1e-4
        }
    );
}

/// A relative move whose acknowledgement is lost may or may not have run: it is never
/// sent again. Here it did run, which is why re-sending would have moved twice.
#[test]
fn lost_ack_of_a_relative_move_is_ambiguous() {
    let (mut rig, mut chain, _) = ready(12, |_| {});
    rig.sim.faults_mut().silent = vec!["1TE".into()];
    let from = rig.sent.len();
    let e = rig
        .run(Port::Motion, chain.start_move_by("source", 2.0, rig.now))
        .expect_err("ambiguous");
    assert_eq!(
        at_axis(e),
        (
            "source".into(),
            AxisError::Ambiguous {
                command: "1PR2".into()
            }
        )
    );
    assert_eq!(
        rig.lines_since(from, Port::Motion),
        ["1TH\r\n", "1PT2\r\n", "1PR2\r\n", "1TE\r\n", "ST\r\n"]
    );
    assert!(rig.all_stopped());
    let t = rig.secs() + 10.0;
    let moved = rig.sim.stage_angles(t)[0];
    assert!(
        moved > 0.0 && moved < 2.0,
        "the PR ran, then the stop: {moved}"
    );
}

/// The operator aborts mid-move: at the next pause between polls the session stops
/// every stage, and the stages stop short of their targets.
#[test]
fn abort_mid_move_stops_every_stage() {
    let (mut rig, mut chain, _) = ready(13, |_| {});
    rig.abort_at = Some(rig.now + Duration::from_secs(1));
    let from = rig.sent.len();
    let e = rig
        .run(Port::Motion, chain.start_move(&[("source", 60.0)], rig.now))
        .expect_err("aborted");
    assert_eq!(at_axis(e), ("source".into(), AxisError::Aborted));
    assert_eq!(
        rig.lines_since(from, Port::Motion)
            .last()
            .map(String::as_str),
        Some("ST\r\n")
    );
    assert!(rig.all_stopped());
    let t = rig.secs() + 10.0;
    let p = rig.sim.stage_angles(t)[0];
    assert!(
        p > 10.0 && p < 40.0,
        "stopped about 1 s into a 3 s move: {p}"
    );
}

/// The motion line vanishes for 1.2 s: the session reopens it at 0, 0.5, 1.0 (all
/// refused) and 1.5 s, then asks once.
#[test]
fn motion_port_outage_and_reconnection() {
    let (mut rig, mut chain, _) = ready(14, |_| {});
    let t = rig.secs();
    rig.sim.faults_mut().outage.push(PortOutage {
        port: Port::Motion,
        window: Window {
            from_s: t,
            to_s: t + 1.2,
        },
    });
    let (from, t0) = (rig.sent.len(), rig.now);
    let p = rig
        .run(Port::Motion, chain.start_position("source", rig.now))
        .expect("reconnects");
    assert!(p.abs() < 1e-9);
    let attempts: Vec<bool> = rig.reopened.iter().map(|(_, ok)| *ok).collect();
    assert_eq!(attempts, [false, false, false, true]);
    assert_eq!(rig.lines_since(from, Port::Motion), ["1TP\r\n"]);
    // Three 500 ms pauses, then the 10 ms reply latency.
    assert_eq!(rig.now - t0, Duration::from_millis(1510));

    // An outage longer than the budget (5 attempts after the first, 500 ms apart).
    let t = rig.secs();
    rig.sim.faults_mut().outage.push(PortOutage {
        port: Port::Motion,
        window: Window {
            from_s: t,
            to_s: t + 60.0,
        },
    });
    let e = rig
        .run(Port::Motion, chain.start_position("source", rig.now))
        .expect_err("gone for good");
    assert!(matches!(
        at_axis(e).1,
        AxisError::Transport(TransportError::Disconnected { .. })
    ));
}

// ---------------------------------------------------------------------------------
// Detection.

/// A settled reading after a move agrees with the simulator's optics (R = chop gain ×
/// detector signal) within its noise model.
#[test]
fn reading_matches_the_optics_within_the_noise() {
    let (mut rig, mut chain, mut lockin) = ready(15, |_| {});
    rig.run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect("moved");
    lockin.input_changed(rig.now);
    let r: Reading = rig
        .run(Port::Detector, lockin.start_read(rig.now))
        .expect("reading");
    let t = rig.secs();
    let chop = rig.sim.lockin_mut().config().chop_gain;
    let expected = chop * rig.sim.signal(t);
    assert!(expected > 1e-4, "a real signal: {expected}");
    let sigma = noise_sigma(&mut rig.sim, expected, r.slope, r.time_constant);
    assert!(r.is_valid(), "{r:?}");
    assert!(
        (r.r_mean - expected).abs() < 6.0 * sigma + 2e-4 * expected,
        "R {} vs {expected} (σ {sigma})",
        r.r_mean
    );
    assert!(
        r.r_std > 0.0 && r.r_std < 6.0 * sigma,
        "{} vs σ {sigma}",
        r.r_std
    );
    assert_eq!(r.n, 10);
    // Autoranging from 1 V stopped at a range where R is 10 % to 100 % of full scale.
    let fs = r.sensitivity.volts();
    assert!(
        r.r_mean >= 0.1 * fs && r.r_mean <= fs,
        "{} on {fs}",
        r.r_mean
    );
    assert_eq!(usize::from(26 - r.sensitivity.index()), r.autorange_steps);
    assert_eq!(lockin.sensitivity(), r.sensitivity);
}

/// The settling wait, measured on the virtual clock: the first `LIAS?` of a reading
/// goes out exactly the filter's settling time after the input changed, and the
/// snapshots one time constant apart. The settling time is checked against the
/// manual's table at 1 % and against the step response of the RC cascade otherwise.
#[test]
fn settling_wait_follows_the_filter_formula() {
    let mut rig = Rig::new(16, |_| {});
    for (slope, residual, factor) in [
        (FilterSlope::Db6, 0.01, 5.0),
        (FilterSlope::Db12, 0.01, 7.0),
        (FilterSlope::Db18, 0.01, 9.0),
        (FilterSlope::Db24, 0.01, 10.0),
        (FilterSlope::Db24, 1e-4, cascade_time(4, 1e-4)),
        (FilterSlope::Db12, 1e-3, cascade_time(2, 1e-3)),
    ] {
        let tc = TimeConstant::new(9).expect("300 ms");
        let config = Sr830Config {
            slope,
            time_constant: tc,
            settle_residual: residual,
            samples: 3,
            autorange: false,
            ..lockin_config()
        };
        let mut lockin = Sr830Session::new(config, "sim", rig.now).expect("valid");
        rig.run(Port::Detector, lockin.start_setup(rig.now))
            .expect("set up");
        let changed = rig.now;
        lockin.input_changed(changed);
        let from = rig.sent.len();
        rig.run(Port::Detector, lockin.start_read(rig.now))
            .expect("reading");
        let times: Vec<(String, Duration)> = rig.sent[from..]
            .iter()
            .map(|(_, t, b)| (String::from_utf8_lossy(b).into_owned(), *t))
            .collect();
        assert_eq!(times[0].0, "LIAS?\n");
        let wait = (times[0].1 - changed).as_secs_f64();
        assert!(
            (wait - factor * 0.3).abs() < 2e-9,
            "{slope} to {residual}: waited {wait} s, expected {factor} T"
        );
        let snaps: Vec<Duration> = times
            .iter()
            .filter(|(l, _)| l == "SNAP? 1,2\n")
            .map(|(_, t)| *t)
            .collect();
        assert_eq!(snaps.len(), 3);
        for w in snaps.windows(2) {
            // One time constant, after the 5 ms reply latency of the snapshot before.
            assert_eq!(w[1] - w[0], Duration::from_millis(305));
        }
    }
}

/// The time, in time constants, for `n` cascaded RC stages to come within `residual`
/// of a step: the root of e^-a Σ_{j<n} a^j/j! = residual, by Newton's method (the
/// derivative of the left side is -e^-a a^(n-1)/(n-1)!).
fn cascade_time(n: u32, residual: f64) -> f64 {
    let left = |a: f64| {
        let (mut term, mut sum) = (1.0, 1.0);
        for j in 1..n {
            term *= a / f64::from(j);
            sum += term;
        }
        (-a).exp() * sum
    };
    let fact: f64 = (1..n).map(f64::from).product();
    let mut a: f64 = 10.0;
    for _ in 0..50 {
        let d = -(-a).exp() * a.powi(i32::try_from(n).expect("small") - 1) / fact;
        a -= (left(a) - residual) / d;
    }
    a
}

/// An overloaded output steps one range less sensitive and reads again, until the
/// reading is clean: every range change is one `SENS` line, upward only.
#[test]
fn output_overload_autoranges_up() {
    let (mut rig, mut chain, mut lockin) = ready(17, |_| {});
    rig.run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect("moved");
    let t = rig.secs();
    let r_true = rig.sim.lockin_mut().config().chop_gain * rig.sim.signal(t);
    // Start three ranges too sensitive: full scale about R / 10.
    let start = Sensitivity::all()
        .filter(|s| s.volts() < r_true / 5.0)
        .last()
        .expect("a range below R");
    rig.run(Port::Detector, lockin.start_set_sensitivity(start, rig.now))
        .expect("SENS");
    let from = rig.sent.len();
    let r = rig
        .run(Port::Detector, lockin.start_read(rig.now))
        .expect("reading");
    assert!(r.is_valid(), "{r:?}");
    assert!(r.sensitivity > start);
    let sens: Vec<String> = rig
        .lines_since(from, Port::Detector)
        .into_iter()
        .filter(|l| l.starts_with("SENS"))
        .collect();
    let expected: Vec<String> = (start.index() + 1..=r.sensitivity.index())
        .map(|i| format!("SENS {i}\n"))
        .collect();
    assert_eq!(sens, expected);
    assert_eq!(r.autorange_steps, sens.len());
    assert!(r.r_mean < 1.09 * r.sensitivity.volts() && r.r_mean >= 0.1 * r.sensitivity.volts());
}

/// An input overload that no range cures (forced by the simulator) climbs to 1 V and
/// is returned flagged, never valid.
#[test]
fn input_overload_is_flagged_at_the_least_sensitive_range() {
    let (mut rig, _, mut lockin) = ready(18, |_| {});
    let t = rig.secs();
    rig.sim.faults_mut().overload.push(Window {
        from_s: t,
        to_s: t + 1e6,
    });
    rig.run(
        Port::Detector,
        lockin.start_set_sensitivity(Sensitivity::new(20).expect("10 mV"), rig.now),
    )
    .expect("SENS");
    let r = rig
        .run(Port::Detector, lockin.start_read(rig.now))
        .expect("a reading, flagged");
    assert!(r.flags.input_overload && !r.is_valid());
    assert_eq!(r.r(), None);
    assert_eq!(r.sensitivity, Sensitivity::LEAST);
    assert_eq!(r.autorange_steps, 6);
}

/// A reference unlock flags the reading: not valid, and not ranged on (its small R is
/// not a measurement).
#[test]
fn unlock_flags_the_reading() {
    let (mut rig, mut chain, mut lockin) = ready(19, |_| {});
    rig.run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect("moved");
    let t = rig.secs();
    rig.sim.faults_mut().unlock.push(Window {
        from_s: t,
        to_s: t + 1e6,
    });
    let before = lockin.sensitivity();
    let from = rig.sent.len();
    let r = rig
        .run(Port::Detector, lockin.start_read(rig.now))
        .expect("a reading, flagged");
    assert!(r.flags.unlock && !r.is_valid());
    assert!(r.status.has(LiaStatus::UNLOCK));
    assert_eq!(r.r(), None);
    assert_eq!((r.sensitivity, r.autorange_steps), (before, 0));
    assert!(
        !rig.lines_since(from, Port::Detector)
            .iter()
            .any(|l| l.starts_with("SENS"))
    );
}

/// Lost and garbled lock-in replies: snapshots are asked again, a lost flags answer
/// restarts the cycle (its bits were cleared by the read), and the reading is still
/// clean; each lost or garbled line is one retry.
#[test]
fn lockin_faults_on_the_line_are_retried() {
    let (mut rig, mut chain, mut lockin) = ready(20, |_| {});
    rig.run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect("moved");
    rig.sim.faults_mut().drop_reply = 0.05;
    rig.sim.faults_mut().corrupt_reply = 0.05;
    lockin.input_changed(rig.now);
    let r = rig
        .run(Port::Detector, lockin.start_read(rig.now))
        .expect("retries get through");
    assert!(r.is_valid(), "{r:?}");
    let s = rig.sim.stats();
    assert!(s.dropped + s.corrupted > 0, "the faults fired");
    assert_eq!(lockin.retried(), s.dropped + s.corrupted);
}

/// The detector line vanishes mid-reading: the session pauses, reopens it, re-sends
/// `OUTX 0` (replies would go to GPIB otherwise), and starts the cycle again after a
/// new settling wait.
#[test]
fn detector_port_outage_restarts_the_reading() {
    let (mut rig, mut chain, mut lockin) = ready(21, |_| {});
    rig.run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect("moved");
    // A first reading settles and ranges; the faulted one starts settled.
    rig.run(Port::Detector, lockin.start_read(rig.now))
        .expect("reading");
    let t = rig.secs();
    rig.sim.faults_mut().outage.push(PortOutage {
        port: Port::Detector,
        window: Window {
            from_s: t + 0.2,
            to_s: t + 0.9,
        },
    });
    let from = rig.sent.len();
    let r = rig
        .run(Port::Detector, lockin.start_read(rig.now))
        .expect("reconnects");
    assert!(r.is_valid(), "{r:?}");
    assert_eq!(lockin.reconnects(), 1);
    assert_eq!(rig.reopened, [(Port::Detector, true)]);
    let lines = rig.lines_since(from, Port::Detector);
    let outx = lines
        .iter()
        .position(|l| l == "OUTX 0\n")
        .expect("OUTX 0 re-sent");
    // Cleared twice: the interrupted cycle and the one after the reconnection.
    assert_eq!(lines.iter().filter(|l| *l == "LIAS?\n").count(), 3);
    assert_eq!(lines[outx + 1], "SNAP? 1,2\n");
}
