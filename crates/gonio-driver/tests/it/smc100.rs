//! The SMC100 chain driver against scripted byte transcripts: the manual's exchanges,
//! and every fault the driver must survive — each asserting the error, the stop, and
//! that every scripted byte (and nothing else) went out.

use std::time::Duration;

use gonio_driver::script::ScriptHandle;
use gonio_driver::smc100::{AxisConfig, AxisError, ChainPolicy, MotionError, Smc100Chain};
use gonio_driver::{Clock, ManualClock, ScriptedTransport, TransportError};
use gonio_proto::smc100::{ControllerState, ErrorCode};

fn axis(name: &str, address: u8) -> AxisConfig {
    AxisConfig {
        name: name.into(),
        address,
        units: "deg".into(),
        min: -170.0,
        max: 170.0,
        velocity: Some(10.0),
        acceleration: Some(40.0),
        tolerance: 0.01,
        home_timeout_s: 60.0,
    }
}

type Chain = Smc100Chain<ScriptedTransport, ManualClock>;

fn chain(axes: Vec<AxisConfig>) -> (Chain, ScriptHandle, ManualClock) {
    let clock = ManualClock::new();
    let (t, h) = ScriptedTransport::new(b'\n', 128, clock.clone());
    let c = Smc100Chain::new(t, clock.clone(), axes, ChainPolicy::default()).expect("valid axes");
    (c, h, clock)
}

/// Drops the chain (which must send the broadcast stop) and checks the script.
fn finish(c: Chain, h: &ScriptHandle) {
    h.send("ST\r\n");
    drop(c);
    h.finish().expect("transcript");
}

fn axis_err(e: MotionError) -> AxisError {
    match e {
        MotionError::AtAxis { source, .. } => source,
        other => panic!("expected an axis error, got {other}"),
    }
}

/// Manual §1.8, start-up: version, stage, state.
#[test]
fn startup_identifies_each_controller() {
    let (mut c, h, _) = chain(vec![axis("source", 1)]);
    h.exchange(
        "1VE\r\n",
        "1VE SMC_CC - Controller-driver version  3. 1. 2\r\n",
    )
    .exchange("1ID?\r\n", "1IDURS100CC\r\n")
    .exchange("1TS\r\n", "1TS00000A\r\n");
    let info = c.identify().expect("answers");
    assert_eq!(
        info[0].version,
        "SMC_CC - Controller-driver version  3. 1. 2"
    );
    assert_eq!(info[0].stage, "URS100CC");
    assert_eq!(info[0].state, ControllerState::NotReferencedFromReset);
    finish(c, &h);
}

/// Manual §1.8: OR from NOT REFERENCED, TE, poll HOMING until READY from HOMING; then
/// the configured velocity and acceleration, each checked with TE.
#[test]
fn homing_from_not_referenced() {
    let (mut c, h, clock) = chain(vec![axis("source", 1)]);
    h.exchange("1TS\r\n", "1TS00000A\r\n")
        .send("1OR\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .exchange("1TS\r\n", "1TS00001E\r\n")
        .exchange("1TS\r\n", "1TS00001E\r\n")
        .exchange("1TS\r\n", "1TS000032\r\n")
        .send("1VA10\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .send("1AC40\r\n")
        .exchange("1TE\r\n", "1TE@\r\n");
    c.home(&["source"]).expect("homes");
    // Three polls at the default 50 ms interval.
    assert_eq!(clock.now(), Duration::from_millis(150));
    finish(c, &h);
}

/// A lost acknowledgement of `OR`: the state says whether it ran. HOMING: it did,
/// and it is not sent again. Still NOT REFERENCED: it never arrived, and is sent again.
#[test]
fn lost_ack_of_home_is_resolved_by_the_state() {
    let (mut c, h, _) = chain(vec![axis("source", 1)]);
    h.exchange("1TS\r\n", "1TS00000A\r\n")
        .send("1OR\r\n")
        .send("1TE\r\n")
        .exchange("1TS\r\n", "1TS00001E\r\n")
        .exchange("1TS\r\n", "1TS000032\r\n")
        .send("1VA10\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .send("1AC40\r\n")
        .exchange("1TE\r\n", "1TE@\r\n");
    c.home(&["source"]).expect("homes");
    assert_eq!(c.retried(), 1);
    finish(c, &h);

    let (mut c, h, _) = chain(vec![axis("source", 1)]);
    h.exchange("1TS\r\n", "1TS00000A\r\n")
        .send("1OR\r\n")
        .send("1TE\r\n")
        .exchange("1TS\r\n", "1TS00000A\r\n")
        .send("1OR\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .exchange("1TS\r\n", "1TS000032\r\n")
        .send("1VA10\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .send("1AC40\r\n")
        .exchange("1TE\r\n", "1TE@\r\n");
    c.home(&["source"]).expect("homes after a second OR");
    finish(c, &h);
}

/// Manual §1.8, move and read cycle, with two stages moving at once.
#[test]
fn concurrent_absolute_moves() {
    let (mut c, h, _) = chain(vec![axis("source", 1), axis("detector", 2)]);
    h.exchange("1TP\r\n", "1TP0\r\n")
        .exchange("1PT10\r\n", "1PT2.25\r\n")
        .send("1PA10\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .exchange("2TP\r\n", "2TP5.000000\r\n")
        .exchange("2PT25\r\n", "2PT3.5\r\n")
        .send("2PA-20\r\n")
        .exchange("2TE\r\n", "2TE@\r\n")
        .exchange("1TS\r\n", "1TS000028\r\n")
        .exchange("2TS\r\n", "2TS000028\r\n")
        .exchange("1TS\r\n", "1TS000033\r\n")
        .exchange("2TS\r\n", "2TS000028\r\n")
        .exchange("2TS\r\n", "2TS000033\r\n")
        .exchange("1TP\r\n", "1TP10.0004\r\n")
        .exchange("2TP\r\n", "2TP-19.9998\r\n");
    let p = c
        .move_to(&[("source", 10.0), ("detector", -20.0)])
        .expect("moves");
    assert_eq!(p, vec![10.0004, -19.9998]);
    finish(c, &h);
}

/// Soft limits are enforced before any byte goes out, for every target of a request.
#[test]
fn soft_limits_refuse_before_sending() {
    let (mut c, h, _) = chain(vec![axis("source", 1), axis("detector", 2)]);
    let e = c
        .move_to(&[("source", 10.0), ("detector", 170.5)])
        .expect_err("outside");
    assert_eq!(
        axis_err(e),
        AxisError::OutOfLimits {
            target: 170.5,
            min: -170.0,
            max: 170.0,
            units: "deg".into()
        }
    );
    let e = c
        .move_to(&[("source", f64::NAN)])
        .expect_err("not a number");
    assert!(matches!(axis_err(e), AxisError::OutOfLimits { .. }));
    assert!(h.sent().is_empty(), "bytes went out: {:?}", h.sent());
    assert!(matches!(
        c.move_to(&[("nope", 1.0)]),
        Err(MotionError::UnknownAxis(_))
    ));
    finish(c, &h);
}

/// Manual §1.8, error path: a move refused in NOT REFERENCED gives TE `H`, a typed
/// error, and a stop of every stage.
#[test]
fn refused_command_is_a_typed_error_and_stops() {
    let (mut c, h, _) = chain(vec![axis("source", 1)]);
    h.exchange("1TP\r\n", "1TP0\r\n")
        .exchange("1PT10\r\n", "1PT2\r\n")
        .send("1PA10\r\n")
        .exchange("1TE\r\n", "1TEH\r\n")
        .send("ST\r\n");
    let e = c.move_to(&[("source", 10.0)]).expect_err("refused");
    assert_eq!(
        axis_err(e),
        AxisError::Controller {
            command: "1PA10".into(),
            code: ErrorCode::NotReferenced
        }
    );
    finish(c, &h);
}

/// No reply: an idempotent query is re-sent `retries` times, then the timeout is the
/// error; the stages are stopped.
#[test]
fn no_reply_times_out_after_retries() {
    let (mut c, h, clock) = chain(vec![axis("source", 1)]);
    h.send("1TP\r\n")
        .send("1TP\r\n")
        .send("1TP\r\n")
        .send("ST\r\n");
    let e = c.move_to(&[("source", 10.0)]).expect_err("silent");
    assert_eq!(
        axis_err(e),
        AxisError::Transport(TransportError::Timeout(Duration::from_millis(100)))
    );
    assert_eq!(clock.now(), Duration::from_millis(300));
    assert_eq!(c.retried(), 2);
    finish(c, &h);
}

/// Garbage and a truncated line: re-sent, and the good reply is used.
#[test]
fn garbage_and_truncated_replies_are_retried() {
    let (mut c, h, _) = chain(vec![axis("source", 1)]);
    h.exchange("1TP\r\n", "1TQ@@!\r\n")
        .exchange("1TP\r\n", "1TP1")
        .exchange("1TP\r\n", "2.5\r\n");
    // The truncated "1TP1" is completed by the next chunk into "1TP12.5", which the
    // driver must not take: it cleared its input after the timeout.
    let e = c.position("source").expect_err("never a clean reply");
    assert!(matches!(axis_err(e), AxisError::Protocol { .. }));

    h.exchange("1TP\r\n", "#garbage\r\n")
        .exchange("1TP\r\n", "1TP-3.25\r\n");
    assert_eq!(c.position("source").expect("second try"), -3.25);
    assert_eq!(c.retried(), 3);
    finish(c, &h);
}

/// A NUL byte: the controller lost power. Typed error, stop, no retry.
#[test]
fn nul_byte_means_power_loss() {
    let (mut c, h, _) = chain(vec![axis("source", 1)]);
    h.exchange("1TP\r\n", "1TP0\r\n")
        .exchange("1PT10\r\n", "1PT2\r\n")
        .send("1PA10\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .exchange("1TS\r\n", "\0\r\n")
        .send("ST\r\n");
    let e = c.move_to(&[("source", 10.0)]).expect_err("power loss");
    assert_eq!(axis_err(e), AxisError::ControllerReset);
    finish(c, &h);
}

/// NOT REFERENCED mid-run: from reset (`0A`, the controller rebooted) and from MOVING
/// (`0F`, e.g. an end-of-run switch). Both stop every stage.
#[test]
fn not_referenced_mid_move() {
    for (ts, want) in [
        ("1TS00000A\r\n", AxisError::ControllerReset),
        (
            "1TS00010F\r\n",
            AxisError::NotReferenced {
                state: ControllerState::NotReferencedFromMoving,
            },
        ),
    ] {
        let (mut c, h, _) = chain(vec![axis("source", 1), axis("detector", 2)]);
        h.exchange("1TP\r\n", "1TP0\r\n")
            .exchange("1PT10\r\n", "1PT2\r\n")
            .send("1PA10\r\n")
            .exchange("1TE\r\n", "1TE@\r\n")
            .exchange("1TS\r\n", "1TS000028\r\n")
            .exchange("1TS\r\n", ts)
            .send("ST\r\n");
        let e = c.move_to(&[("source", 10.0)]).expect_err("lost reference");
        assert_eq!(axis_err(e), want);
        finish(c, &h);
    }
}

/// A following error puts the controller in DISABLE (`3D`): typed error and stop.
#[test]
fn disable_during_move() {
    let (mut c, h, _) = chain(vec![axis("source", 1)]);
    h.exchange("1TP\r\n", "1TP0\r\n")
        .exchange("1PT10\r\n", "1PT2\r\n")
        .send("1PA10\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .exchange("1TS\r\n", "1TS00203D\r\n")
        .send("ST\r\n");
    let e = c.move_to(&[("source", 10.0)]).expect_err("disabled");
    assert_eq!(
        axis_err(e),
        AxisError::Disabled {
            state: ControllerState::DisableFromMoving,
            errors: 0x0020
        }
    );
    finish(c, &h);
}

/// A stage that does not reach its target: (a) it stays MOVING past the deadline
/// (PT estimate × 1.5 + 2 s): stopped, position read; (b) it ends READY away from the
/// target.
#[test]
fn stage_that_does_not_reach_its_target() {
    let (mut c, h, clock) = chain(vec![axis("source", 1)]);
    h.exchange("1TP\r\n", "1TP0\r\n")
        .exchange("1PT10\r\n", "1PT0.1\r\n")
        .send("1PA10\r\n")
        .exchange("1TE\r\n", "1TE@\r\n");
    // Deadline 2.15 s at 50 ms a poll: 43 polls still within, the 44th past it.
    for _ in 0..44 {
        h.exchange("1TS\r\n", "1TS000028\r\n");
    }
    h.send("ST\r\n").exchange("1TP\r\n", "1TP3.5\r\n");
    let e = c.move_to(&[("source", 10.0)]).expect_err("stuck");
    assert_eq!(
        axis_err(e),
        AxisError::Timeout {
            operation: "move",
            target: 10.0,
            position: Some(3.5),
            waited: Duration::from_millis(2150),
        }
    );
    assert_eq!(clock.now(), Duration::from_millis(2200));

    h.exchange("1TP\r\n", "1TP3.5\r\n")
        .exchange("1PT6.5\r\n", "1PT1\r\n")
        .send("1PA10\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .exchange("1TS\r\n", "1TS000033\r\n")
        .exchange("1TP\r\n", "1TP9.8\r\n");
    let e = c.move_to(&[("source", 10.0)]).expect_err("short");
    assert_eq!(
        axis_err(e),
        AxisError::TargetNotReached {
            target: 10.0,
            position: 9.8,
            tolerance: 0.01
        }
    );
    finish(c, &h);
}

/// The port disappears and returns: the driver reopens it (after two failed attempts
/// here) and carries on; if it never returns, a typed error.
#[test]
fn port_vanishes_and_returns() {
    let (mut c, h, clock) = chain(vec![axis("source", 1)]);
    h.vanish(2).exchange("1TP\r\n", "1TP4\r\n");
    assert_eq!(c.position("source").expect("after reconnect"), 4.0);
    assert_eq!(h.reconnects(), 1);
    // Two failed attempts, 500 ms apart.
    assert_eq!(clock.now(), Duration::from_millis(1000));

    h.vanish(99);
    let e = c.position("source").expect_err("gone for good");
    assert!(matches!(
        axis_err(e),
        AxisError::Transport(TransportError::Disconnected { .. })
    ));
    // The final stop cannot reach the stage either: the broadcast is tried, then the
    // controller's own stop.
    drop(c);
    let sent = h.sent();
    let n = sent.len();
    assert_eq!(&sent[n - 2..], &[b"ST\r\n".to_vec(), b"1ST\r\n".to_vec()]);
}

/// An absolute move whose TE answer is lost is re-sent; the controller, already
/// moving, refuses it with `M`; the driver checks the held target and carries on.
#[test]
fn lost_ack_of_absolute_move_is_resent() {
    let (mut c, h, _) = chain(vec![axis("source", 1)]);
    h.exchange("1TP\r\n", "1TP0\r\n")
        .exchange("1PT10\r\n", "1PT2\r\n")
        .send("1PA10\r\n")
        .send("1TE\r\n")
        .send("1PA10\r\n")
        .exchange("1TE\r\n", "1TEM\r\n")
        .exchange("1PA?\r\n", "1PA10\r\n")
        .exchange("1TS\r\n", "1TS000033\r\n")
        .exchange("1TP\r\n", "1TP10\r\n");
    assert_eq!(c.move_to(&[("source", 10.0)]).expect("moves"), vec![10.0]);
    finish(c, &h);
}

/// A relative move whose TE answer is lost is never re-sent: ambiguous, stopped.
#[test]
fn lost_ack_of_relative_move_is_never_resent() {
    let (mut c, h, _) = chain(vec![axis("source", 1)]);
    h.exchange("1TH\r\n", "1TH5\r\n")
        .exchange("1PT2\r\n", "1PT0.5\r\n")
        .send("1PR2\r\n")
        .send("1TE\r\n")
        .send("ST\r\n");
    let e = c.move_by("source", 2.0).expect_err("ambiguous");
    assert_eq!(
        axis_err(e),
        AxisError::Ambiguous {
            command: "1PR2".into()
        }
    );
    let prs = h.sent().iter().filter(|s| s.starts_with(b"1PR")).count();
    assert_eq!(prs, 1);
    finish(c, &h);
}

/// Relative moves are checked against the limits from the set-point.
#[test]
fn relative_move_limits() {
    let (mut c, h, _) = chain(vec![axis("source", 1)]);
    h.exchange("1TH\r\n", "1TH169\r\n");
    let e = c.move_by("source", 2.0).expect_err("would pass 170");
    assert!(matches!(axis_err(e), AxisError::OutOfLimits { target, .. } if target == 171.0));
    finish(c, &h);
}

/// A home search that ends NOT REFERENCED from HOMING with the time-out bit.
#[test]
fn homing_failure() {
    let (mut c, h, _) = chain(vec![axis("source", 1)]);
    h.exchange("1TS\r\n", "1TS00000A\r\n")
        .send("1OR\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .exchange("1TS\r\n", "1TS00001E\r\n")
        .exchange("1TS\r\n", "1TS00400B\r\n")
        .send("ST\r\n");
    let e = c.home(&["source"]).expect_err("failed");
    assert_eq!(
        axis_err(e),
        AxisError::HomingFailed {
            state: ControllerState::NotReferencedFromHoming,
            errors: 0x0040
        }
    );
    finish(c, &h);
}

/// The abort flag stops the stages at the next poll.
#[test]
fn abort_stops_everything() {
    let (mut c, h, _) = chain(vec![axis("source", 1)]);
    let abort = c.abort_flag();
    h.exchange("1TP\r\n", "1TP0\r\n")
        .exchange("1PT10\r\n", "1PT2\r\n")
        .send("1PA10\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .send("ST\r\n");
    abort.raise();
    let e = c.move_to(&[("source", 10.0)]).expect_err("aborted");
    assert_eq!(axis_err(e), AxisError::Aborted);
    finish(c, &h);
}

/// A late reply to an earlier command is skipped, not taken for the answer.
#[test]
fn stale_replies_are_skipped() {
    let (mut c, h, _) = chain(vec![axis("source", 1), axis("detector", 2)]);
    h.exchange("2TP\r\n", "1TP7\r\n2TP-1.5\r\n");
    assert_eq!(c.position("detector").expect("skips 1TP"), -1.5);
    finish(c, &h);
}

/// Bad chain configurations are refused with the axis named.
#[test]
fn chain_configuration_is_validated() {
    let clock = ManualClock::new();
    let (t, _) = ScriptedTransport::new(b'\n', 128, clock.clone());
    let mut bad = axis("a", 32);
    let e = Smc100Chain::new(t, clock.clone(), vec![bad.clone()], ChainPolicy::default())
        .expect_err("address");
    assert!(e.to_string().contains("address 32"), "{e}");
    bad.address = 1;
    bad.min = 10.0;
    bad.max = -10.0;
    let (t, _) = ScriptedTransport::new(b'\n', 128, clock.clone());
    let e =
        Smc100Chain::new(t, clock.clone(), vec![bad], ChainPolicy::default()).expect_err("limits");
    assert!(e.to_string().contains("min < max"), "{e}");
    let (t, _) = ScriptedTransport::new(b'\n', 128, clock.clone());
    let e = Smc100Chain::new(
        t,
        clock,
        vec![axis("a", 1), axis("b", 1)],
        ChainPolicy::default(),
    )
    .expect_err("shared address");
    assert!(e.to_string().contains("address 1"), "{e}");
}

/// Recovery after a controller reset: `RS`, silence while it boots (status queries
/// time out), NOT REFERENCED from reset, then a home search and the working settings.
#[test]
fn reset_and_home_recovers_a_controller() {
    let (mut c, h, clock) = chain(vec![axis("source", 1)]);
    h.send("1RS\r\n")
        // Booting: three silent TS attempts (one query with two retries).
        .send("1TS\r\n")
        .send("1TS\r\n")
        .send("1TS\r\n")
        .exchange("1TS\r\n", "1TS00000A\r\n")
        // home(): state, OR, TE, polls, settings.
        .exchange("1TS\r\n", "1TS00000A\r\n")
        .send("1OR\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .exchange("1TS\r\n", "1TS000032\r\n")
        .send("1VA10\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .send("1AC40\r\n")
        .exchange("1TE\r\n", "1TE@\r\n");
    c.reset_and_home("source").expect("recovers");
    // 500 ms, three 100 ms timeouts, 500 ms, then one 50 ms poll.
    assert_eq!(clock.now(), Duration::from_millis(1350));
    finish(c, &h);
}

/// The configuration (manual, ZT and PW commands): the dump read whole, then a change
/// made from NOT REFERENCED, saved with `PW0`, waited out through the controller's
/// silence, confirmed NOT REFERENCED from CONFIGURATION and by `TE`.
#[test]
fn configuration_read_and_changed() {
    use gonio_driver::smc100::Param;
    let (mut c, h, clock) = chain(vec![axis("source", 1)]);
    h.exchange(
        "1ZT\r\n",
        "1PW1\r\n1IDURS100PP\r\n1AC160.000000\r\n1BA0.000000\r\n1HT2\r\n1PW0\r\n",
    );
    let p = c.read_config("source").expect("a dump");
    assert_eq!(p.stage, "URS100PP");
    assert_eq!(
        p.values,
        vec![
            (Param::Acceleration, 160.0),
            (Param::Backlash, 0.0),
            (Param::HomeType, 2.0)
        ]
    );
    h.exchange("1TS\r\n", "1TS00000A\r\n")
        .send("1PW1\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .send("1BA0.01\r\n")
        .exchange("1TE\r\n", "1TE@\r\n")
        .send("1PW0\r\n")
        // Saving: silent twice, then NOT REFERENCED from CONFIGURATION.
        .send("1TS\r\n")
        .send("1TS\r\n")
        .exchange("1TS\r\n", "1TS00000C\r\n")
        .exchange("1TE\r\n", "1TE@\r\n");
    let t0 = clock.now();
    c.configure("source", &[(Param::Backlash, 0.01)])
        .expect("saved");
    // Three 500 ms pauses and two 100 ms silences at least.
    assert!(clock.now() - t0 >= Duration::from_millis(1700));
    // A change the controller would refuse: not a byte.
    let e = c
        .configure("source", &[(Param::HomeType, 9.0)])
        .expect_err("out of range");
    assert!(matches!(
        axis_err(e),
        AxisError::InvalidSetting { code: "HT", .. }
    ));
    finish(c, &h);
}
