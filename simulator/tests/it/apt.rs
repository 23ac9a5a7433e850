//! The APT session of `gonio-proto` against the simulated APT controllers, in memory,
//! on virtual time: a small pump ([`Rig::run`]) hands the session's messages to
//! [`AptDevice`], frames what it sends back, and moves the clock to the next deadline
//! or the next thing the device will send. Nothing sleeps.

use std::collections::VecDeque;
use std::time::Duration;

use gonio_core::motion::trapezoid_time;
use gonio_proto::apt::{
    AptAxisConfig, AptFramer, AptSession, Direction, Message, Packet, StageKind, StopMode,
};
use gonio_proto::link::{Deadline, Io, Operation};
use gonio_proto::motion::{AxisError, MotionError};
use gonio_proto::smc100::ChainPolicy;
use gonio_proto::{FrameError, Framer, TransportError};
use gonio_sim::apt::{AptDevice, AptDeviceConfig, AptModel};
use gonio_sim::twin::TimedLine;

struct Rig {
    dev: AptDevice,
    framer: AptFramer,
    /// Frames received and not yet handed to the operation.
    inbox: VecDeque<Result<Vec<u8>, FrameError>>,
    now: Duration,
    /// What the host sent, with when.
    sent: Vec<(Duration, Message)>,
    /// Abort the operation at its first abort point at or after this time.
    abort_at: Option<Duration>,
    /// Power-cycle the device at this time.
    power_cycle_at: Option<Duration>,
}

fn secs(d: Duration) -> f64 {
    d.as_secs_f64()
}

/// `s` seconds as a duration, rounded up to the nanosecond, so that the device sees
/// its event as due.
fn dur(s: f64) -> Duration {
    let d = Duration::from_secs_f64(s);
    if d.as_secs_f64() < s {
        d + Duration::from_nanos(1)
    } else {
        d
    }
}

impl Rig {
    fn new(cfg: &AptDeviceConfig) -> Self {
        Rig {
            dev: AptDevice::new(cfg),
            framer: AptFramer::new(),
            inbox: VecDeque::new(),
            now: Duration::ZERO,
            sent: Vec::new(),
            abort_at: None,
            power_cycle_at: None,
        }
    }

    /// Moves the clock to `t`, letting the device send what falls due on the way.
    fn advance(&mut self, t: Duration) {
        if let Some(pc) = self.power_cycle_at
            && pc <= t
        {
            self.advance_plain(pc);
            self.dev.power_cycle(secs(pc));
            self.power_cycle_at = None;
        }
        self.advance_plain(t);
    }

    fn advance_plain(&mut self, t: Duration) {
        let t = t.max(self.now);
        let mut out = Vec::new();
        self.dev.poll(secs(t), &mut out);
        self.take(&out);
        self.now = t;
    }

    fn run<T>(&mut self, mut op: impl Operation<Output = T>) -> T {
        for _ in 0..1_000_000 {
            while let Some(io) = op.poll_io() {
                match io {
                    Io::Transmit(bytes) => {
                        let bytes = bytes.to_vec();
                        let m = Packet::parse(&bytes).map(|p| p.message);
                        self.sent
                            .push((self.now, m.unwrap_or_else(|e| panic!("{e}"))));
                        let mut out = Vec::new();
                        self.dev.receive(secs(self.now), &bytes, &mut out);
                        self.take(&out);
                        op.handle_sent(self.now, Ok(()));
                    }
                    Io::ClearInput => self.clear(),
                    Io::Reconnect => op.handle_reconnected(self.now, Ok(())),
                }
            }
            if let Some(out) = op.poll_output() {
                return out;
            }
            match op.poll_timeout() {
                Some(Deadline::Reply(deadline)) => {
                    if self.inbox.is_empty() {
                        match self.dev.next_event().map(dur).filter(|t| *t <= deadline) {
                            Some(t) => self.advance(t),
                            None => self.advance(deadline),
                        }
                    }
                    match self.inbox.pop_front() {
                        Some(Ok(f)) => op.handle_line(self.now, &f),
                        Some(Err(e)) => op.handle_link_error(self.now, TransportError::from(e)),
                        None if self.now >= deadline => op.handle_timeout(self.now),
                        None => {}
                    }
                }
                Some(Deadline::Poll(t)) => {
                    if self.abort_at.is_some_and(|a| a <= t) {
                        self.abort_at = None;
                        op.handle_abort(self.now);
                        continue;
                    }
                    self.advance(t);
                    op.handle_timeout(self.now);
                }
                Some(Deadline::Sleep(t)) => {
                    self.advance(t);
                    op.handle_timeout(self.now);
                }
                None => panic!("an operation with no I/O, no output and no deadline"),
            }
        }
        panic!("the operation never ended");
    }

    /// Frames what the device sent.
    fn take(&mut self, bytes: &[u8]) {
        self.framer.push(bytes);
        while let Some(f) = self.framer.next_frame() {
            self.inbox.push_back(f);
        }
    }

    /// Forgets everything received.
    fn clear(&mut self) {
        self.framer.clear();
        self.inbox.clear();
    }

    /// Names of the messages the host sent from index `from` on.
    fn sent_names(&self, from: usize) -> Vec<&'static str> {
        self.sent[from..].iter().map(|(_, m)| m.name()).collect()
    }
}

/// The velocity and acceleration a PRM1-Z8 really runs at when 10°/s and 10°/s² are
/// asked for: whole APT units (429417 and 147) make them 10.000008 and 10.029.
fn prm_motion() -> (f64, f64) {
    let p = StageKind::Prm1Z8;
    (
        p.velocity_from_apt(p.velocity_to_apt(10.0)),
        p.acceleration_from_apt(p.acceleration_to_apt(10.0)),
    )
}

/// The home position's mechanical angle: the 4° offset in whole counts.
fn home_offset() -> f64 {
    let p = StageKind::Prm1Z8;
    p.to_deg(p.to_counts(4.0))
}

fn kdc(start: f64) -> AptDeviceConfig {
    AptDeviceConfig {
        start_position_deg: start,
        ..AptDeviceConfig::default()
    }
}

fn axis(stage: StageKind) -> AptAxisConfig {
    AptAxisConfig::new("rot", stage, -170.0, 170.0)
}

fn session(a: AptAxisConfig) -> AptSession {
    AptSession::new(a, ChainPolicy::default()).unwrap_or_else(|e| panic!("{e}"))
}

/// A device and session identified, set up and homed.
fn ready(dev: AptDeviceConfig, a: AptAxisConfig) -> (Rig, AptSession) {
    let mut rig = Rig::new(&dev);
    let mut s = session(a);
    rig.run(s.start_identify(rig.now))
        .unwrap_or_else(|e| panic!("{e}"));
    rig.run(s.start_setup(rig.now))
        .unwrap_or_else(|e| panic!("{e}"));
    rig.run(s.start_home(rig.now))
        .unwrap_or_else(|e| panic!("{e}"));
    (rig, s)
}

fn axis_error<T: std::fmt::Debug>(r: Result<T, MotionError>) -> AxisError {
    match r {
        Err(MotionError::AtAxis { source, .. }) => source,
        other => panic!("{other:?}"),
    }
}

#[test]
fn identify_and_setup() {
    let mut rig = Rig::new(&kdc(0.0));
    let mut a = axis(StageKind::Prm1Z8);
    a.velocity = Some(5.0);
    a.acceleration = Some(8.0);
    a.backlash_deg = Some(0.5);
    let mut s = session(a);
    let info = rig.run(s.start_identify(rig.now)).unwrap();
    assert_eq!((info.model.as_str(), info.serial), ("KDC101", 27_000_001));
    assert_eq!(info.firmware, [3, 0, 10]);
    rig.run(s.start_setup(rig.now)).unwrap();
    assert_eq!(
        rig.sent_names(1),
        [
            "HW_NO_FLASH_PROGRAMMING",
            "MOD_SET_CHANENABLESTATE",
            "MOD_REQ_CHANENABLESTATE",
            "MOT_SET_VELPARAMS",
            "MOT_REQ_VELPARAMS",
            "MOT_SET_HOMEPARAMS",
            "MOT_REQ_HOMEPARAMS",
            "MOT_SET_GENMOVEPARAMS",
            "MOT_REQ_GENMOVEPARAMS",
        ]
    );
    let (v, acc) = rig.run(s.start_velocity_params(rig.now)).unwrap();
    assert!((v - 5.0).abs() < 1e-4, "{v}");
    // 8 deg/s² is 117.3 APT units, sent as 117.
    assert!((acc - 117.0 / 14.657_3).abs() < 1e-3, "{acc}");

    // A K10CR1 session on a KDC101 refuses it.
    let mut wrong = session(axis(StageKind::K10cr1));
    match axis_error(rig.run(wrong.start_identify(rig.now))) {
        AxisError::Device { reason, .. } => assert!(reason.contains("K10CR1"), "{reason}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn home_takes_the_trapezoid_time_and_zeroes_the_counter() {
    let mut rig = Rig::new(&kdc(30.0));
    let mut s = session(axis(StageKind::Prm1Z8));
    rig.run(s.start_setup(rig.now)).unwrap();
    let t0 = rig.now;
    let at = rig.run(s.start_home(rig.now)).unwrap();
    // Reverse 30° onto the switch at 0°, forward to the 4° offset: 26° at 10°/s with
    // 10°/s² takes 26/10 + 10/10 = 3.6 s; MOVE_HOMED arrives then, and the session
    // sees it at its next poll (every 50 ms).
    let (v, a) = prm_motion();
    let want = trapezoid_time(30.0 - home_offset(), v, a);
    assert!((want - 3.6).abs() < 0.01);
    let took = secs(rig.now - t0);
    assert!((want..want + 0.16).contains(&took), "{took} vs {want}");
    assert!(at.abs() < 1e-9, "{at}");
    assert!(rig.dev.is_homed());
    assert!((rig.dev.mechanical(secs(rig.now)) - home_offset()).abs() < 1e-9);
}

#[test]
fn absolute_and_relative_moves_land_in_tolerance_on_time() {
    let (mut rig, mut s) = ready(kdc(0.0), axis(StageKind::Prm1Z8));
    let t0 = rig.now;
    let p = rig.run(s.start_move(90.0, rig.now)).unwrap();
    assert!((p - 90.0).abs() <= 0.5 / 1919.6418, "{p}");
    // 90° at 10°/s, 10°/s²: 9 + 1 = 10 s (9.997 s with the whole-unit acceleration).
    let (v, a) = prm_motion();
    let want = trapezoid_time(90.0, v, a);
    assert!((want - 10.0).abs() < 0.01);
    let took = secs(rig.now - t0);
    assert!((want..want + 0.16).contains(&took), "{took} vs {want}");
    // The mechanical angle is the home offset (4°) plus the counter.
    assert!((rig.dev.mechanical(secs(rig.now)) - 94.0).abs() < 1e-3);
    let last = rig
        .sent
        .iter()
        .rev()
        .find(|(_, m)| m.name() == "MOT_MOVE_ABSOLUTE");
    assert_eq!(
        last.map(|(_, m)| m.clone()),
        Some(Message::MoveAbsolute {
            chan: 1,
            position: Some(172_768)
        })
    );

    let t1 = rig.now;
    let p = rig.run(s.start_move_by(-30.0, rig.now)).unwrap();
    assert!((p - 60.0).abs() <= 1.0 / 1919.6418, "{p}");
    // 30° takes 3 + 1 = 4 s.
    let took = secs(rig.now - t1);
    let want = trapezoid_time(30.0, v, a);
    assert!((want..want + 0.16).contains(&took), "{took} vs {want}");
    let pos = rig.run(s.start_position(rig.now)).unwrap();
    assert_eq!(pos, p);

    // A short move never reaches full speed: 0.4° takes 2·sqrt(0.4/10) = 0.4 s.
    let t2 = rig.now;
    let p = rig.run(s.start_move(60.4, rig.now)).unwrap();
    assert!((p - 60.4).abs() <= 0.5 / 1919.6418, "{p}");
    let took = secs(rig.now - t2);
    let want = trapezoid_time(0.4, v, a);
    assert!((want - 0.4).abs() < 0.01);
    assert!((want..want + 0.16).contains(&took), "{took} vs {want}");
}

#[test]
fn k10cr1_moves_in_microsteps() {
    let dev = AptDeviceConfig {
        model: AptModel::K10cr1,
        serial_number: 55_000_123,
        ..AptDeviceConfig::default()
    };
    let (mut rig, mut s) = ready(dev, axis(StageKind::K10cr1));
    let t0 = rig.now;
    let p = rig.run(s.start_move(-45.0, rig.now)).unwrap();
    assert!((p + 45.0).abs() <= 0.5 / 136_533.33, "{p}");
    assert!((5.5..5.66).contains(&secs(rig.now - t0)));
    let st = rig.run(s.start_status(rig.now)).unwrap();
    assert!(st.is_homed() && st.is_enabled() && !st.is_moving());
    assert_eq!(st.velocity_raw, None);
    assert_eq!(
        rig.sent.last().map(|(_, m)| m.name()),
        Some("MOT_REQ_STATUSUPDATE")
    );
}

#[test]
fn limits_are_refused_before_any_byte() {
    let (mut rig, mut s) = ready(kdc(0.0), axis(StageKind::Prm1Z8));
    let n = rig.sent.len();
    let e = axis_error(rig.run(s.start_move(200.0, rig.now)));
    assert!(
        matches!(e, AxisError::OutOfLimits { target: 200.0, .. }),
        "{e:?}"
    );
    // A relative move reads the position first, then refuses.
    let e = axis_error(rig.run(s.start_move_by(-171.0, rig.now)));
    assert!(matches!(e, AxisError::OutOfLimits { .. }), "{e:?}");
    assert_eq!(rig.sent_names(n), ["MOT_REQ_DCSTATUSUPDATE"]);
}

#[test]
fn abort_mid_move_stops_with_the_deceleration() {
    let (mut rig, mut s) = ready(kdc(0.0), axis(StageKind::Prm1Z8));
    let t0 = rig.now;
    rig.abort_at = Some(t0 + Duration::from_secs(2));
    let e = axis_error(rig.run(s.start_move(90.0, rig.now)));
    assert_eq!(e, AxisError::Aborted);
    assert_eq!(
        rig.sent.last().map(|(_, m)| m.clone()),
        Some(Message::MoveStop {
            chan: 1,
            mode: StopMode::Profiled
        })
    );
    let stopped_at = secs(rig.now - t0);
    // At the abort the stage cruises at 10°/s; it stops 1 s and 5° later.
    let (v, a) = prm_motion();
    let at = rig.dev.mechanical(secs(rig.now)) - home_offset();
    let cruising = v * v / (2.0 * a) + v * (stopped_at - v / a);
    assert!((at - cruising).abs() < 1e-6, "{at} vs {cruising}");
    rig.advance(rig.now + Duration::from_secs(2));
    let p = rig.run(s.start_position(rig.now)).unwrap();
    let rest = cruising + v * v / (2.0 * a);
    assert!((p - rest).abs() < 1e-3, "{p} vs {rest}");
}

#[test]
fn stop_waits_for_move_stopped() {
    let (mut rig, mut s) = ready(kdc(0.0), axis(StageKind::Prm1Z8));
    // Another client set the stage turning.
    let mut out = Vec::new();
    let jog = Message::MoveVelocity {
        chan: 1,
        direction: Direction::Reverse,
    };
    rig.dev.receive(secs(rig.now), &jog.to_bytes(), &mut out);
    rig.advance(rig.now + Duration::from_secs(3));
    rig.clear();
    let t0 = rig.now;
    rig.run(s.start_stop(true, rig.now)).unwrap();
    // From 10°/s, a profiled stop takes 1 s (0.997 s at 10.029°/s²).
    let (v, a) = prm_motion();
    assert!(
        (secs(rig.now - t0) - v / a).abs() < 1e-6,
        "{:?}",
        rig.now - t0
    );
    let p = rig.run(s.start_position(rig.now)).unwrap();
    // 0.5·10·1² + 10·2 in reverse, then 5° more to rest.
    assert!((p + 30.0).abs() < 1e-3, "{p}");
    // An immediate stop of a still stage answers at once.
    let t1 = rig.now;
    rig.run(s.start_stop(false, rig.now)).unwrap();
    assert_eq!(rig.now, t1);
}

// This rig is a pump without a heartbeat: a driver that never sends the server-alive
// message. The twin holds it to the manual (APT Issue 28, p. 130): after 50 status
// messages unanswered by one, the controller sends no more.

/// Moves back and forth between ±`amp` until one fails; returns the moves that
/// succeeded and the failure.
fn moves_until_failure(
    rig: &mut Rig,
    s: &mut AptSession,
    amp: f64,
    max: usize,
) -> (usize, Option<AxisError>) {
    for i in 0..max {
        let target = if i % 2 == 0 { amp } else { -amp };
        if let Err(e) = rig.run(s.start_move(target, rig.now)) {
            return (i, Some(axis_error::<f64>(Err(e))));
        }
    }
    (max, None)
}

#[test]
fn without_the_server_alive_the_controller_falls_silent_after_50_status_messages() {
    // Counting only what it sends unasked (the default rule): the homing's MOVE_HOMED
    // and one MOVE_COMPLETED a move. The 49th move's completion is the 50th; after it
    // nothing of the status kind goes out, so the poll that would see that move settled
    // goes unanswered.
    let (mut rig, mut s) = ready(kdc(0.0), axis(StageKind::Prm1Z8));
    let (done, err) = moves_until_failure(&mut rig, &mut s, 5.0, 200);
    assert_eq!(done, 48, "{err:?}");
    assert!(
        matches!(err, Some(AxisError::Transport(TransportError::Timeout(_)))),
        "{err:?}"
    );
    assert!(rig.dev.is_silenced());
    assert!(rig.dev.keepalive().withheld > 0);
    assert_eq!(rig.dev.keepalive().acks, 0);

    // Read literally (every status message counts, the replies to status requests
    // too), it happens within a few moves.
    let dev = AptDeviceConfig {
        keepalive_rule: gonio_sim::apt::KeepAliveRule::All,
        ..kdc(0.0)
    };
    let (mut rig, mut s) = ready(dev, axis(StageKind::Prm1Z8));
    let (done, _) = moves_until_failure(&mut rig, &mut s, 5.0, 200);
    assert!(done < 20, "{done}");

    // One server-alive and the controller speaks again (assumed: the manual says only
    // that it stops).
    let mut out = Vec::new();
    rig.dev.receive(
        secs(rig.now),
        &Message::AckDcStatusUpdate.to_bytes(),
        &mut out,
    );
    assert!(!rig.dev.is_silenced());
    rig.clear();
    let p = rig.run(s.start_position(rig.now)).unwrap();
    assert!(p.abs() <= 5.0 + 1e-3, "{p}");
    rig.run(s.start_move(0.0, rig.now)).unwrap();
}

#[test]
fn periodic_updates_stop_after_50_without_the_server_alive() {
    let mut a = axis(StageKind::Prm1Z8);
    a.status_updates = true;
    let (mut rig, mut s) = ready(kdc(0.0), a);
    assert!(rig.dev.updates_on());
    // HW_START_UPDATEMSGS: one every 100 ms (p. 51); unanswered, the 50th is the last.
    // The session hears them while it waits: a status request is answered by the next.
    let u0 = s.updates_received();
    let t0 = rig.now;
    rig.run(s.start_move(150.0, rig.now)).ok();
    let heard = s.updates_received() - u0;
    assert!(heard > 0 && heard <= 50, "{heard}");
    rig.advance(t0 + Duration::from_secs(20));
    rig.clear();
    assert!(rig.dev.is_silenced());
    let withheld = rig.dev.keepalive().withheld;
    assert!(withheld >= 100, "{withheld}");
    // The twin records the host's obligation too: no server-alive in 20 s.
    let k = rig.dev.keepalive();
    assert_eq!(k.acks, 0);
    assert!(k.longest_gap_until(secs(rig.now)) >= 20.0);
}

#[test]
fn stall_is_a_device_fault_and_the_stage_is_stopped() {
    let (mut rig, mut s) = ready(kdc(0.0), axis(StageKind::Prm1Z8));
    rig.dev.stall_at(Some(54.0));
    let e = axis_error(rig.run(s.start_move(90.0, rig.now)));
    match e {
        AxisError::Device { command, reason } => {
            assert_eq!(command, "MOT_MOVE_ABSOLUTE");
            assert_eq!(reason, "motion error");
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(
        rig.sent.last().map(|(_, m)| m.name()),
        Some("MOT_MOVE_STOP")
    );
    assert!((rig.dev.mechanical(secs(rig.now)) - 54.0).abs() < 1e-6);
}

#[test]
fn limit_switch_mid_move_is_a_device_fault() {
    let dev = AptDeviceConfig {
        limit_switches_deg: Some([-20.0, 100.0]),
        ..kdc(0.0)
    };
    let (mut rig, mut s) = ready(dev, axis(StageKind::Prm1Z8));
    match axis_error(rig.run(s.start_move(120.0, rig.now))) {
        AxisError::Device { reason, .. } => assert_eq!(reason, "forward limit switch"),
        other => panic!("{other:?}"),
    }
    assert!((rig.dev.mechanical(secs(rig.now)) - 100.0).abs() < 1e-9);
}

#[test]
fn power_cycle_mid_move_is_not_homed() {
    let (mut rig, mut s) = ready(kdc(0.0), axis(StageKind::Prm1Z8));
    rig.power_cycle_at = Some(rig.now + Duration::from_secs(3));
    let e = axis_error(rig.run(s.start_move(90.0, rig.now)));
    assert_eq!(e, AxisError::NotHomed);
    assert!(!rig.dev.is_homed());
    // The next move is refused before it is sent; homing again recovers.
    let n = rig.sent.len();
    assert_eq!(
        axis_error(rig.run(s.start_move(10.0, rig.now))),
        AxisError::NotHomed
    );
    assert_eq!(rig.sent_names(n), ["MOT_REQ_DCSTATUSUPDATE"]);
    rig.run(s.start_home(rig.now)).unwrap();
    let p = rig.run(s.start_move(10.0, rig.now)).unwrap();
    assert!((p - 10.0).abs() < 0.001);
}

#[test]
fn device_answers_what_a_polling_python_client_sends() {
    // thorlabs-apt-device's KDC101 at open: velocity, general move, jog and home
    // parameters requested, the channel enabled, then a home and polled DC status.
    let mut dev = AptDevice::new(&kdc(10.0));
    let mut out = Vec::new();
    let host = [
        Message::ReqVelParams { chan: 1 },
        Message::ReqGenMoveParams { chan: 1 },
        Message::ReqJogParams { chan: 1 },
        Message::ReqHomeParams { chan: 1 },
        // That client sends 1 to enable, and 0 (not the manual's 2) to disable.
        Message::SetChanEnableState {
            chan: 1,
            enable: true,
        },
        Message::MoveHome { chan: 1 },
        Message::ReqDcStatusUpdate { chan: 1 },
    ];
    let mut bytes = Vec::new();
    for m in &host {
        m.encode(&mut bytes);
    }
    dev.receive(0.0, &bytes, &mut out);
    let mut f = AptFramer::new();
    f.push(&out);
    let names: Vec<_> = std::iter::from_fn(|| f.next_frame())
        .map(|m| Message::parse(&m.unwrap()).unwrap().name())
        .collect();
    assert_eq!(
        names,
        [
            "MOT_GET_VELPARAMS",
            "MOT_GET_GENMOVEPARAMS",
            "MOT_GET_JOGPARAMS",
            "MOT_GET_HOMEPARAMS",
            "MOT_GET_DCSTATUSUPDATE"
        ]
    );
    // Home: 10° reverse to the switch, 4° forward: 6° at 10°/s, 10°/s² takes
    // 2·sqrt(0.6) s; MOVE_HOMED then, as a header-only message from the unit.
    let end = dev.motion_end().unwrap();
    let (v, a) = prm_motion();
    assert!((end - trapezoid_time(10.0 - home_offset(), v, a)).abs() < 1e-9);
    assert!((end - 2.0 * 0.6f64.sqrt()).abs() < 0.01);
    out.clear();
    dev.poll(end, &mut out);
    assert_eq!(out, [0x44, 0x04, 1, 0, 0x01, 0x50]);
    // Its prepared moves: MOVEABSPARAMS, then a short-form MOVE_ABSOLUTE; and a jog
    // step (1°, the power-up jog step) in reverse; each ends with MOVE_COMPLETED.
    for (m, to) in [
        (
            Message::SetMoveAbsParams {
                chan: 1,
                position: StageKind::Prm1Z8.to_counts(20.0),
            },
            None,
        ),
        (
            Message::MoveAbsolute {
                chan: 1,
                position: None,
            },
            Some(20.0),
        ),
        (
            Message::MoveJog {
                chan: 1,
                direction: Direction::Reverse,
            },
            Some(19.0),
        ),
    ] {
        out.clear();
        let t = dev.motion_end().unwrap_or(end);
        dev.receive(t, &m.to_bytes(), &mut out);
        assert!(out.is_empty(), "{out:02x?}");
        if let Some(to) = to {
            let done = dev.motion_end().unwrap();
            dev.poll(done, &mut out);
            match Message::parse(&out).unwrap() {
                Message::MoveCompleted {
                    status: Some(st), ..
                } => assert!((StageKind::Prm1Z8.to_deg(st.position) - to).abs() < 1e-3),
                other => panic!("{other:?}"),
            }
        }
    }
    let end = dev.motion_end().unwrap_or(end);
    // The raw disable byte that client sends (0) disables.
    out.clear();
    dev.receive(
        end,
        &[0x10, 0x02, 1, 0, 0x50, 0x01, 0x11, 0x02, 1, 0, 0x50, 0x01],
        &mut out,
    );
    assert_eq!(
        Message::parse(&out).unwrap(),
        Message::GetChanEnableState {
            chan: 1,
            enabled: false
        }
    );
}

#[test]
fn home_past_its_deadline_is_a_timeout_and_the_stage_is_stopped() {
    let mut rig = Rig::new(&kdc(90.0));
    let mut a = axis(StageKind::Prm1Z8);
    a.home_timeout_s = 2.0;
    let mut s = session(a);
    rig.run(s.start_setup(rig.now)).unwrap();
    let t0 = rig.now;
    match axis_error(rig.run(s.start_home(rig.now))) {
        AxisError::Timeout {
            operation,
            position,
            waited,
            ..
        } => {
            assert_eq!(operation, "home");
            assert_eq!(waited, Duration::from_secs(2));
            // Counter 0 at power-up at 90°; about 15° turned in reverse by then.
            let p = position.unwrap();
            assert!((-17.0..-13.0).contains(&p), "{p}");
        }
        other => panic!("{other:?}"),
    }
    assert!(secs(rig.now - t0) < 2.1);
    let names = rig.sent_names(rig.sent.len() - 2);
    assert_eq!(names, ["MOT_MOVE_STOP", "MOT_REQ_POSCOUNTER"]);
    assert!(!rig.dev.is_homed());
}
