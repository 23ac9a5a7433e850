//! The sessions of `gonio-proto` against the simulator's device models, in memory, on
//! virtual time: no driver, no transport, no pty, no sleep. A tiny pump ([`Rig::run`])
//! hands a session's bytes to [`SimInstrument`], its replies back (after the link's
//! latency), and moves the simulated clock to the deadlines the session asks for. That
//! is all a session needs: bytes and time.
//!
//! Every fault class the simulator produces is covered, each asserting the typed
//! outcome, the exact lines on the wire where they are deterministic, the stops, and the
//! times on the virtual clock.

//!
//! This file: the SMC100 session — homing and moves, then each motion fault.

use crate::session_rig;

use session_rig::*;

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
// The manual's refusals: a command the controller's state does not allow is not
// executed and stores the state's letter for `TE` (manual §5.3, TE p. 59). The twin
// models them; each test would fail against a session that ignored the refusal (and,
// say, polled `TS` as if the move had started).

/// A controller reset behind the session's back (another program's `RS`) is NOT
/// REFERENCED. `PT` is accepted only in DISABLE, READY and MOVING (§5.5 table), so the
/// twin refuses it silently and stores `H`: the session asks `PT` its `retries` + 1
/// times, then `TE`, and ends with the controller's refusal, typed, not a link
/// timeout; no `PA` goes out, and every stage is stopped.
#[test]
fn a_move_after_a_reset_behind_its_back_is_refused_with_h() {
    let (mut rig, mut chain, _) = ready(21, |_| {});
    assert_eq!(rig.sim.motion_bytes(b"1RS\r\n"), b"", "RS replies nothing");
    // The controller boots (3 s) before the session asks anything.
    rig.advance_to(rig.now + Duration::from_secs(4));
    let t = rig.secs();
    let c = rig.sim.controller_mut(1).expect("controller 1");
    assert_eq!(c.state(t), ControllerState::NotReferencedFromReset);
    let from = rig.sent.len();
    let e = rig
        .run(Port::Motion, chain.start_move(&[("source", 30.0)], rig.now))
        .expect_err("refused");
    assert_eq!(
        at_axis(e),
        (
            "source".into(),
            AxisError::Controller {
                command: "1PT30".into(),
                code: gonio_proto::smc100::ErrorCode::NotReferenced
            }
        )
    );
    assert_eq!(
        rig.lines_since(from, Port::Motion),
        [
            "1TP\r\n",
            "1PT30\r\n",
            "1PT30\r\n",
            "1PT30\r\n",
            "1TE\r\n",
            "ST\r\n"
        ]
    );
    assert!(rig.all_stopped());
    let t = rig.secs() + 10.0;
    assert_eq!(rig.sim.stage_angles(t)[0], 0.0, "the stage never moved");
}

/// A controller put in DISABLE behind the session's back (`MM0` from the keypad or
/// another program): `PT` is allowed there, `PA` is not (PA page, p. 41: READY only),
/// so the `PA`'s `TE` reads `J` and the session ends with that refusal and stops every
/// stage, rather than polling a move that never started.
#[test]
fn a_move_on_a_controller_disabled_behind_its_back_is_refused_with_j() {
    let (mut rig, mut chain, _) = ready(22, |_| {});
    assert_eq!(rig.sim.motion_bytes(b"1MM0\r\n"), b"");
    let from = rig.sent.len();
    let e = rig
        .run(Port::Motion, chain.start_move(&[("source", 30.0)], rig.now))
        .expect_err("refused");
    assert_eq!(
        at_axis(e),
        (
            "source".into(),
            AxisError::Controller {
                command: "1PA30".into(),
                code: gonio_proto::smc100::ErrorCode::InDisable
            }
        )
    );
    assert_eq!(
        rig.lines_since(from, Port::Motion),
        ["1TP\r\n", "1PT30\r\n", "1PA30\r\n", "1TE\r\n", "ST\r\n"]
    );
    let t = rig.secs();
    let c = rig.sim.controller_mut(1).expect("controller 1");
    assert_eq!(c.state(t), ControllerState::DisableFromReady);
}

/// The acknowledgement (`TE`) of a `PA` is lost, so the session sends the move again;
/// the first one was accepted and the stage moves, so the twin refuses the second with
/// `M` (the letter is assumed: the PA page names none for MOVING). The session reads
/// the held target (`PA?`), finds its own, and waits for the move as usual.
#[test]
fn a_resent_move_refused_while_moving_is_taken_when_the_target_is_held() {
    let (mut rig, mut chain, _) = ready(23, |_| {});
    rig.sim.faults_mut().silent = vec!["1TE".into()];
    // The first TE goes unanswered; by the time the move is re-sent (100 ms later) the
    // line is clean again.
    let at = rig.now + Duration::from_millis(50);
    rig.injections.push((
        at,
        Box::new(|sim: &mut SimInstrument, _: f64| sim.faults_mut().silent.clear()),
    ));
    let from = rig.sent.len();
    let positions = rig
        .run(Port::Motion, chain.start_move(&[("source", 30.0)], rig.now))
        .expect("the first move stands");
    assert!((positions[0] - 30.0).abs() <= 0.0005, "{positions:?}");
    let lines = rig.lines_since(from, Port::Motion);
    assert_eq!(
        &lines[..7],
        [
            "1TP\r\n",
            "1PT30\r\n",
            "1PA30\r\n",
            "1TE\r\n",
            "1PA30\r\n",
            "1TE\r\n",
            "1PA?\r\n"
        ]
    );
    assert!(!lines.iter().any(|l| l == "ST\r\n"));
    assert_eq!(chain.retried(), 1);
}

/// `PW1` is accepted only in NOT REFERENCED (PW page, p. 44). The session reads the
/// state first; if it changes between that `TS` and the `PW1` (a home search started
/// from the keypad), the twin refuses `PW1` with `L` and the session ends with that
/// refusal before sending a single configuration value.
#[test]
fn configure_is_refused_when_the_state_changes_behind_its_back() {
    use gonio_proto::smc100::{Command, ErrorCode, Param};
    let mut rig = Rig::new(24, |_| {});
    let mut chain = Smc100Session::new(axes(), ChainPolicy::default()).expect("valid axes");
    // Between the TS (sent at once, answered 10 ms later) and the PW1.
    let at = rig.now + Duration::from_millis(5);
    rig.injections.push((
        at,
        Box::new(|sim: &mut SimInstrument, t: f64| {
            let c = sim.controller_mut(2).expect("controller 2");
            assert!(c.handle(t, &Command::Home).is_none());
        }),
    ));
    let from = rig.sent.len();
    let e = rig
        .run(
            Port::Motion,
            chain.start_configure("detector", &[(Param::Backlash, 0.01)], rig.now),
        )
        .expect_err("refused");
    assert_eq!(
        at_axis(e),
        (
            "detector".into(),
            AxisError::Controller {
                command: "2PW1".into(),
                code: ErrorCode::InHoming
            }
        )
    );
    assert_eq!(
        rig.lines_since(from, Port::Motion),
        ["2TS\r\n", "2PW1\r\n", "2TE\r\n"]
    );
    let t = rig.secs();
    let c = rig.sim.controller_mut(2).expect("controller 2");
    assert_eq!(c.saved_parameters().get(Param::Backlash), Some(0.0));
    assert!(c.state(t).is_homing());
}
