//! The FW102C driver (`gonio_driver::fw102c`) over an in-memory line talking to the
//! simulated wheel (`gonio_sim::filterwheel`) on virtual time: set-up, moves and
//! their modelled times, filter lookups, refusals before any byte, transmittance.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use gonio_driver::fw102c::{Filter, Fw102c, Fw102cConfig, Fw102cError, Speed};
use gonio_driver::{Clock, ManualClock, Transport, TransportError};
use gonio_proto::LineFramer;
use gonio_proto::fw102c::{ErrorCode, MAX_LINE, TERMINATOR};
use gonio_sim::filterwheel::{
    FilterWheelSim, Fw102cTwin, IDENTITY, bandpass_transmittance, longpass_transmittance,
};
use gonio_sim::twin::TimedLine;

/// The twin behind a CR-framed line, on a manual clock; every write and every byte
/// received is logged.
struct Line {
    twin: Arc<Mutex<Fw102cTwin>>,
    sent: Arc<Mutex<Vec<Vec<u8>>>>,
    received: Arc<Mutex<Vec<u8>>>,
    clock: ManualClock,
    framer: LineFramer,
}

fn secs(c: &ManualClock) -> f64 {
    c.now().as_secs_f64()
}

impl Line {
    fn deliver(&mut self, at: f64) {
        let mut out = Vec::new();
        self.twin.lock().expect("lock").poll(at, &mut out);
        self.received.lock().expect("lock").extend_from_slice(&out);
        self.framer.push(&out);
    }
}

impl Transport for Line {
    fn send(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        self.sent.lock().expect("lock").push(bytes.to_vec());
        let mut out = Vec::new();
        self.twin
            .lock()
            .expect("lock")
            .receive(secs(&self.clock), bytes, &mut out);
        self.received.lock().expect("lock").extend_from_slice(&out);
        self.framer.push(&out);
        Ok(())
    }

    fn receive_line(&mut self, timeout: Duration) -> Result<Vec<u8>, TransportError> {
        let until = self.clock.now() + timeout;
        loop {
            if let Some(line) = self.framer.next_line() {
                return line.map_err(TransportError::from);
            }
            let next = self.twin.lock().expect("lock").next_event();
            match next {
                Some(t) if t <= until.as_secs_f64() => {
                    let now = self.clock.now();
                    let at = Duration::from_secs_f64(t);
                    if at > now {
                        self.clock.advance(at - now);
                    }
                    self.deliver(t);
                }
                _ => {
                    let now = self.clock.now();
                    if until > now {
                        self.clock.advance(until - now);
                    }
                    return Err(TransportError::Timeout(timeout));
                }
            }
        }
    }

    fn clear_input(&mut self) -> Result<(), TransportError> {
        self.framer.clear();
        Ok(())
    }

    fn reconnect(&mut self) -> Result<(), TransportError> {
        Ok(())
    }

    fn name(&self) -> String {
        "sim-wheel".into()
    }
}

struct Rig {
    wheel: Fw102c<Line, ManualClock>,
    twin: Arc<Mutex<Fw102cTwin>>,
    sent: Arc<Mutex<Vec<Vec<u8>>>>,
    received: Arc<Mutex<Vec<u8>>>,
    clock: ManualClock,
}

fn filters() -> Vec<Filter> {
    vec![
        Filter::Open { position: 1 },
        Filter::Bandpass {
            position: 2,
            centre_nm: 450.0,
            fwhm_nm: 10.0,
            peak_transmittance: 0.7,
        },
        Filter::Bandpass {
            position: 3,
            centre_nm: 550.0,
            fwhm_nm: 10.0,
            peak_transmittance: 0.6,
        },
        Filter::Longpass {
            position: 4,
            cut_on_nm: 495.0,
            peak_transmittance: 0.95,
        },
        Filter::Dark { position: 6 },
    ]
}

fn rig(sim: FilterWheelSim, config: Fw102cConfig) -> Rig {
    sim.validate().expect("valid");
    let twin = Arc::new(Mutex::new(Fw102cTwin::new(&sim)));
    let sent = Arc::new(Mutex::new(Vec::new()));
    let received = Arc::new(Mutex::new(Vec::new()));
    let clock = ManualClock::new();
    let line = Line {
        twin: twin.clone(),
        sent: sent.clone(),
        received: received.clone(),
        clock: clock.clone(),
        framer: LineFramer::new(TERMINATOR, MAX_LINE),
    };
    let wheel = Fw102c::new(line, clock.clone(), config).expect("valid");
    Rig {
        wheel,
        twin,
        sent,
        received,
        clock,
    }
}

fn standard() -> Rig {
    let sim = FilterWheelSim {
        filters: filters(),
        ..FilterWheelSim::default()
    };
    let config = Fw102cConfig {
        filters: filters(),
        ..Fw102cConfig::default()
    };
    rig(sim, config)
}

/// The commands sent since the last call, as text.
fn sent(r: &Rig) -> Vec<String> {
    std::mem::take(&mut *r.sent.lock().expect("lock"))
        .into_iter()
        .map(|b| String::from_utf8_lossy(&b).into_owned())
        .collect()
}

#[test]
fn init_identifies_checks_the_count_and_sets_speed_and_sensors() {
    let mut r = standard();
    assert_eq!(r.wheel.init().unwrap(), IDENTITY);
    assert_eq!(
        sent(&r),
        [
            "*idn?\r",
            "pcount?\r",
            "speed=1\r",
            "speed?\r",
            "sensors=0\r",
            "sensors?\r",
            "pos?\r"
        ]
    );
    assert_eq!(r.wheel.last_position(), Some(1));
    assert_eq!(
        r.twin.lock().unwrap().sensors(),
        gonio_proto::fw102c::SensorMode::OffWhenIdle
    );
    assert_eq!(r.wheel.retried(), 0);
    // No move: set-up takes no virtual time on an instant line.
    assert_eq!(r.clock.now(), Duration::ZERO);
}

#[test]
fn a_wheel_of_another_size_is_refused_at_init() {
    let mut r = rig(
        FilterWheelSim::default(),
        Fw102cConfig {
            positions: 12,
            ..Fw102cConfig::default()
        },
    );
    assert_eq!(
        r.wheel.init(),
        Err(Fw102cError::PositionCountMismatch {
            config: 12,
            device: 6
        })
    );
}

#[test]
fn select_waits_for_the_modelled_move() {
    let mut r = standard();
    r.wheel.init().unwrap();
    sent(&r);
    // 1 → 5: two slots the short way round, 0.5 s each at high speed.
    let t0 = r.clock.now();
    r.wheel.select(5).unwrap();
    let took = (r.clock.now() - t0).as_secs_f64();
    assert!((took - 1.0).abs() < 1e-6, "took {took} s");
    assert_eq!(sent(&r), ["pos=5\r", "pos?\r"]);
    assert_eq!(r.wheel.last_position(), Some(5));
    assert_eq!(r.wheel.position().unwrap(), 5);
    assert_eq!(r.twin.lock().unwrap().position_at(secs(&r.clock)), Some(5));
    // 5 → 2: three slots either way.
    let t0 = r.clock.now();
    r.wheel.select(2).unwrap();
    assert!(((r.clock.now() - t0).as_secs_f64() - 1.5).abs() < 1e-6);
    // Selecting where it stands takes no time.
    let t0 = r.clock.now();
    r.wheel.select(2).unwrap();
    assert_eq!(r.clock.now(), t0);
}

#[test]
fn low_speed_moves_take_the_low_slot_time() {
    let sim = FilterWheelSim {
        slot_time_low_s: 1.25,
        ..FilterWheelSim::default()
    };
    let mut r = rig(
        sim,
        Fw102cConfig {
            speed: Speed::Low,
            ..Fw102cConfig::default()
        },
    );
    r.wheel.init().unwrap();
    assert_eq!(r.twin.lock().unwrap().speed(), Speed::Low);
    let t0 = r.clock.now();
    r.wheel.select(4).unwrap();
    // 1 → 4 on six positions: three slots.
    assert!(((r.clock.now() - t0).as_secs_f64() - 3.75).abs() < 1e-6);
}

#[test]
fn out_of_range_positions_are_refused_before_any_byte() {
    let mut r = standard();
    r.wheel.init().unwrap();
    sent(&r);
    for p in [0, 7, 12, 255] {
        assert_eq!(
            r.wheel.select(p),
            Err(Fw102cError::PositionOutOfRange {
                position: p,
                positions: 6
            })
        );
    }
    assert!(sent(&r).is_empty(), "nothing may reach the wire");
    assert!(matches!(
        r.wheel.select_band(700.0),
        Err(Fw102cError::NoFilterForBand { .. })
    ));
    assert!(matches!(
        r.wheel.select_order_sorting(480.0),
        Err(Fw102cError::NoOrderSortingFilter { .. })
    ));
    assert!(sent(&r).is_empty());
}

#[test]
fn a_firmware_count_below_the_target_is_a_refusal_read_from_the_wire() {
    // The firmware counts 6 while the driver was told 12 and init is skipped: the
    // wheel refuses pos=9 and the refusal arrives before the pos? echo.
    let mut r = rig(
        FilterWheelSim::default(),
        Fw102cConfig {
            positions: 12,
            ..Fw102cConfig::default()
        },
    );
    assert_eq!(
        r.wheel.select(9),
        Err(Fw102cError::Refused {
            command: "pos=9".into(),
            code: ErrorCode::ArgInvalid
        })
    );
    assert_eq!(sent(&r), ["pos=9\r", "pos?\r"]);
}

#[test]
fn select_band_and_the_other_lookups_pick_their_filters() {
    let mut r = standard();
    r.wheel.init().unwrap();
    assert_eq!(r.wheel.select_band(551.0).unwrap(), 3);
    let now = secs(&r.clock);
    let twin = r.twin.lock().unwrap().clone();
    assert_eq!(twin.position_at(now), Some(3));
    assert!((twin.transmittance(550.0, now) - 0.6).abs() < 1e-12);
    assert!(
        (twin.transmittance(553.0, now) - bandpass_transmittance(553.0, 550.0, 10.0, 0.6)).abs()
            < 1e-15
    );
    assert_eq!(r.wheel.select_band(449.0).unwrap(), 2);
    assert_eq!(r.wheel.select_order_sorting(600.0).unwrap(), 4);
    let now = secs(&r.clock);
    let t = r.twin.lock().unwrap().transmittance(600.0, now);
    assert!((t - longpass_transmittance(600.0, 495.0, 10.0, 0.95)).abs() < 1e-15);
    assert!(t > 0.94, "well above the cut-on: {t}");
    assert_eq!(r.wheel.select_dark().unwrap(), 6);
    let now = secs(&r.clock);
    assert_eq!(r.twin.lock().unwrap().transmittance(550.0, now), 0.0);
}

#[test]
fn the_beam_is_blocked_while_the_wheel_turns() {
    let mut r = standard();
    r.wheel.init().unwrap();
    let t0 = secs(&r.clock);
    r.wheel.select(4).unwrap();
    let twin = r.twin.lock().unwrap().clone();
    // 1 → 4: three slots, 1.5 s.
    assert_eq!(twin.position_at(t0 + 0.75), None);
    assert_eq!(twin.transmittance(600.0, t0 + 0.75), 0.0);
    assert_eq!(
        twin.transmittance(600.0, t0 - 0.1),
        1.0,
        "open before the move"
    );
    assert!(twin.transmittance(600.0, t0 + 1.5) > 0.9);
}

#[test]
fn same_commands_same_bytes() {
    let run = || {
        let mut w = Fw102cTwin::new(&FilterWheelSim::default());
        let mut out = Vec::new();
        let mut q: VecDeque<(f64, &[u8])> = VecDeque::from([
            (0.0, &b"pos=3\r"[..]),
            (0.1, b"pos?\r"),
            (2.0, b"speed=0\r"),
            (2.1, b"pos=6\r"),
            (2.2, b"bogus\r"),
        ]);
        while let Some((t, b)) = q.pop_front() {
            w.receive(t, b, &mut out);
        }
        w.poll(100.0, &mut out);
        out
    };
    let a = run();
    assert_eq!(a, run());
    assert_eq!(
        a,
        b"> pos=3\r> pos?\r3\r> speed=0\r> pos=6\r> bogus\rCommand error CMD_NOT_DEFINED\r> "
    );
}

/// The manual's hazards against Gonio's session (through the driver):
///
/// - The power-up prompt: "The prompt symbol '>' will appear on power-up and after a
///   command is accepted" (User Guide Rev M). A freshly powered wheel has `"> "`
///   waiting before anything is asked; a session that took it for the end of its first
///   answer (as a reader splitting on the prompt would) would read an empty identity
///   and be one answer out of step from then on. Gonio's must identify the wheel and
///   read every later answer in step.
/// - Lower case: "All commands and queries are in lower case letters" (p. 11). The
///   twin refuses upper case, so a session sending `*IDN?` would fail to identify.
#[test]
fn the_session_copes_with_the_power_up_prompt_and_sends_lower_case_only() {
    let mut r = standard();
    assert_eq!(r.wheel.init().unwrap(), IDENTITY);
    let received = r.received.lock().unwrap().clone();
    // The prompt came first, then the echo of the first command.
    assert!(
        received.starts_with(b"> *idn?\r"),
        "{:?}",
        String::from_utf8_lossy(&received)
    );
    // Every answer read in step: the last query of the set-up read the position.
    assert_eq!(r.wheel.last_position(), Some(1));
    assert_eq!(r.wheel.retried(), 0, "no answer was lost or misread");
    r.wheel.select(3).unwrap();
    assert_eq!(r.wheel.position().unwrap(), 3);
    let all: Vec<u8> = sent(&r).concat().into_bytes();
    assert!(!all.is_empty());
    assert!(
        !all.iter().any(u8::is_ascii_uppercase),
        "upper case sent: {:?}",
        String::from_utf8_lossy(&all)
    );
    // And the twin does refuse upper case, with the error string before the prompt.
    let mut out = Vec::new();
    let t = secs(&r.clock);
    r.twin.lock().unwrap().receive(t, b"*IDN?\r", &mut out);
    assert_eq!(out, b"*IDN?\rCommand error CMD_NOT_DEFINED\r> ");
}
