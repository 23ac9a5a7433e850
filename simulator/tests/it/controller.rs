//! The simulated SMC100 against the manual: states, error letters, the trapezoidal
//! profile, quantisation, stop, power cycling, stalls.

use gonio_proto::smc100::{
    Command, ControllerState, ErrorCode, Param, PositionerErrors, ReplyBody,
};
use gonio_sim::controller::{Controller, ControllerConfig, Profile};

fn ctl() -> Controller {
    Controller::new(ControllerConfig {
        start_position: 12.5,
        ..ControllerConfig::default()
    })
}

fn ask(c: &mut Controller, t: f64, cmd: Command) -> ReplyBody {
    c.handle(t, &cmd).expect("a query replies").body
}

fn te(c: &mut Controller, t: f64) -> ErrorCode {
    match ask(c, t, Command::TellError) {
        ReplyBody::Error(e) => e,
        other => panic!("{other:?}"),
    }
}

fn state(c: &mut Controller, t: f64) -> ControllerState {
    match ask(c, t, Command::TellStatus) {
        ReplyBody::Status(s) => s.state,
        other => panic!("{other:?}"),
    }
}

fn tp(c: &mut Controller, t: f64) -> f64 {
    match ask(c, t, Command::TellPosition) {
        ReplyBody::Position(p) => p,
        other => panic!("{other:?}"),
    }
}

/// Homes from 12.5° at 10°/s with 80°/s²: a trapezoid of 0.125 s ramps and
/// (12.5 − 1.25)/10 s of cruise, 1.375 s in all.
fn homed() -> Controller {
    let mut c = ctl();
    assert!(c.handle(0.0, &Command::Home).is_none());
    assert_eq!(te(&mut c, 0.0), ErrorCode::None);
    c
}

#[test]
fn boots_not_referenced_and_refuses_moves_with_h() {
    let mut c = ctl();
    assert_eq!(state(&mut c, 0.0), ControllerState::NotReferencedFromReset);
    // The counter reads 0 wherever the stage stands.
    assert_eq!(tp(&mut c, 0.0), 0.0);
    assert_eq!(c.mechanical(0.0), 12.5);
    c.handle(0.0, &Command::MoveAbsolute(10.0));
    assert_eq!(te(&mut c, 0.0), ErrorCode::NotReferenced);
    assert_eq!(te(&mut c, 0.0), ErrorCode::None, "reading TE clears it");
    c.handle(0.0, &Command::SetVelocity(5.0));
    assert_eq!(te(&mut c, 0.0), ErrorCode::NotReferenced);
    match ask(&mut c, 0.0, Command::Query(Param::StageId)) {
        ReplyBody::StageId(s) => assert_eq!(s, "URS100PP"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn homing_drives_to_the_switch_and_references() {
    let mut c = homed();
    assert_eq!(state(&mut c, 0.5), ControllerState::HomingRemote);
    c.handle(0.5, &Command::Home);
    assert_eq!(te(&mut c, 0.5), ErrorCode::HomeStarted);
    let expected: f64 = 2.0 * 10.0 / 80.0 + (12.5 - 100.0 / 80.0) / 10.0;
    assert!((expected - 1.375).abs() < 1e-12);
    assert_eq!(state(&mut c, 1.374), ControllerState::HomingRemote);
    assert_eq!(state(&mut c, 1.376), ControllerState::ReadyFromHoming);
    assert_eq!(tp(&mut c, 1.376), 0.0);
    assert_eq!(c.mechanical(1.376), 0.0);
    c.handle(2.0, &Command::Home);
    assert_eq!(te(&mut c, 2.0), ErrorCode::InReady);
}

#[test]
fn trapezoidal_move_with_readback_during_motion() {
    let mut c = homed();
    let t0 = 2.0;
    // 20°/s, 80°/s²: ramps of 0.25 s covering 2.5° each; 10° takes 0.75 s.
    match ask(&mut c, t0, Command::MotionTime(10.0)) {
        ReplyBody::MotionTime(d) => assert!((d - 0.75).abs() < 1e-12, "{d}"),
        other => panic!("{other:?}"),
    }
    // A triangle when the distance is short: 1° takes 2·√(1/80) s.
    assert!((Profile::duration_for(1.0, 20.0, 80.0) - 2.0 * (1.0f64 / 80.0).sqrt()).abs() < 1e-12);
    c.handle(t0, &Command::MoveAbsolute(10.0));
    assert_eq!(te(&mut c, t0), ErrorCode::None);
    assert_eq!(state(&mut c, t0 + 0.1), ControllerState::Moving);
    // ½·80·0.1² = 0.4° after 0.1 s; 2.5 + 20·0.25 = 7.5° after 0.5 s.
    assert!((tp(&mut c, t0 + 0.1) - 0.4).abs() < 1e-9);
    assert!((tp(&mut c, t0 + 0.5) - 7.5).abs() < 1e-9);
    c.handle(t0 + 0.5, &Command::MoveAbsolute(20.0));
    assert_eq!(te(&mut c, t0 + 0.5), ErrorCode::InMoving);
    assert_eq!(state(&mut c, t0 + 0.76), ControllerState::ReadyFromMoving);
    assert_eq!(tp(&mut c, t0 + 0.76), 10.0);
    // Limits: G, and nothing moves.
    c.handle(3.0, &Command::MoveAbsolute(171.0));
    assert_eq!(te(&mut c, 3.0), ErrorCode::OutOfLimits);
    assert_eq!(state(&mut c, 3.0), ControllerState::ReadyFromMoving);
}

#[test]
fn positions_are_quantised_to_steps() {
    let mut c = homed();
    c.handle(2.0, &Command::MoveAbsolute(10.00031));
    // 2000 counts a degree: the nearest count is 10.0005.
    match ask(&mut c, 2.0, Command::Query(Param::AbsoluteTarget)) {
        ReplyBody::Value(_, v) => assert_eq!(v, 10.0005),
        other => panic!("{other:?}"),
    }
    assert_eq!(tp(&mut c, 5.0), 10.0005);
}

#[test]
fn stop_decelerates_with_the_acceleration() {
    let mut c = homed();
    let t0 = 2.0;
    c.handle(t0, &Command::MoveAbsolute(100.0));
    // At t0 + 1 s: cruising at 20°/s, at 2.5 + 20·0.75 = 17.5°.
    c.handle(t0 + 1.0, &Command::Stop);
    assert_eq!(te(&mut c, t0 + 1.0), ErrorCode::None);
    // Stops after 20/80 = 0.25 s, 20²/(2·80) = 2.5° further.
    assert_eq!(state(&mut c, t0 + 1.2), ControllerState::Moving);
    assert_eq!(state(&mut c, t0 + 1.26), ControllerState::ReadyFromMoving);
    assert!((tp(&mut c, t0 + 2.0) - 20.0).abs() < 1e-9);
}

#[test]
fn velocity_limits_and_disable() {
    let mut c = homed();
    c.handle(2.0, &Command::SetVelocity(50.0));
    assert_eq!(te(&mut c, 2.0), ErrorCode::BadParameter);
    c.handle(2.0, &Command::SetVelocity(5.0));
    assert_eq!(te(&mut c, 2.0), ErrorCode::None);
    match ask(&mut c, 2.0, Command::Query(Param::Velocity)) {
        ReplyBody::Value(_, v) => assert_eq!(v, 5.0),
        other => panic!("{other:?}"),
    }
    c.handle(2.0, &Command::Enable(false));
    assert_eq!(state(&mut c, 2.0), ControllerState::DisableFromReady);
    c.handle(2.0, &Command::MoveAbsolute(1.0));
    assert_eq!(te(&mut c, 2.0), ErrorCode::InDisable);
    c.handle(2.0, &Command::Enable(true));
    assert_eq!(state(&mut c, 2.0), ControllerState::ReadyFromDisable);
}

#[test]
fn power_cycle_loses_the_reference() {
    let mut c = homed();
    c.handle(2.0, &Command::MoveAbsolute(30.0));
    c.power_cycle(2.5);
    assert!(c.is_booting(3.0) && !c.is_booting(5.6));
    assert_eq!(state(&mut c, 6.0), ControllerState::NotReferencedFromReset);
    // The stage stopped where the power went; the counter starts again at 0.
    let m = c.mechanical(6.0);
    assert!(m > 0.0 && m < 30.0, "{m}");
    assert_eq!(tp(&mut c, 6.0), 0.0);
    // Reset from READY also reboots (after homing again).
    let mut c = homed();
    c.handle(2.0, &Command::Reset);
    assert!(c.is_booting(2.0));
}

#[test]
fn stall_becomes_a_following_error() {
    let mut c = homed();
    c.stall_at(Some(5.0));
    c.handle(2.0, &Command::MoveAbsolute(10.0));
    // The set-point passes 5° at 2 + 0.25 + 2.5/20 = 2.375 s; 0.5 s later: DISABLE.
    assert_eq!(state(&mut c, 2.8), ControllerState::Moving);
    match ask(&mut c, 2.9, Command::TellStatus) {
        ReplyBody::Status(s) => {
            assert_eq!(s.state, ControllerState::DisableFromMoving);
            assert!(s.errors.has(PositionerErrors::FOLLOWING_ERROR));
        }
        other => panic!("{other:?}"),
    }
    // Reading TS cleared the latched bit.
    match ask(&mut c, 2.9, Command::TellStatus) {
        ReplyBody::Status(s) => assert!(s.errors.is_empty()),
        other => panic!("{other:?}"),
    }
    assert_eq!(c.mechanical(3.0), 5.0);
}

/// Each refusal the manual names, with its letter (TE p. 59): `PT` and `PA` in NOT
/// REFERENCED (`PT`: no reply, §5.3), `OR` outside NOT REFERENCED (p. 39) and `E`
/// during a search, `PA` in DISABLE (p. 41), `PW1` outside NOT REFERENCED (p. 44),
/// `PA` while MOVING (`M`, assumed: the PA page names no letter), `RS` while MOVING
/// (assumed, the RS page contradicts itself), a `PA` outside [SL, SR] (`G`), `PT`
/// outside (1e-6, 1e12) (`C`).
#[test]
fn every_state_refuses_with_its_letter() {
    let mut c = ctl();
    assert!(
        c.handle(0.0, &Command::MotionTime(10.0)).is_none(),
        "no reply"
    );
    assert_eq!(te(&mut c, 0.0), ErrorCode::NotReferenced);
    let mut c = homed();
    // HOMING: OR again is `E`; PA is `L`.
    assert!(c.handle(0.1, &Command::Home).is_none());
    assert_eq!(te(&mut c, 0.1), ErrorCode::HomeStarted);
    assert!(c.handle(0.1, &Command::MoveAbsolute(1.0)).is_none());
    assert_eq!(te(&mut c, 0.1), ErrorCode::InHoming);
    // READY: OR and PW1 are `K`; out of limits `G`; a PT of 0 is `C`.
    let t = 2.0;
    assert_eq!(state(&mut c, t), ControllerState::ReadyFromHoming);
    for cmd in [Command::Home, Command::ConfigurationMode(true)] {
        assert!(c.handle(t, &cmd).is_none());
        assert_eq!(te(&mut c, t), ErrorCode::InReady, "{cmd:?}");
    }
    assert!(c.handle(t, &Command::MoveAbsolute(171.0)).is_none());
    assert_eq!(te(&mut c, t), ErrorCode::OutOfLimits);
    assert!(c.handle(t, &Command::MotionTime(0.0)).is_none());
    assert_eq!(te(&mut c, t), ErrorCode::BadParameter);
    // MOVING: PA and RS are `M`; PT still answers.
    assert!(c.handle(t, &Command::MoveAbsolute(20.0)).is_none());
    assert_eq!(te(&mut c, t), ErrorCode::None);
    assert_eq!(state(&mut c, t + 0.1), ControllerState::Moving);
    for cmd in [Command::MoveAbsolute(30.0), Command::Reset] {
        assert!(c.handle(t + 0.1, &cmd).is_none());
        assert_eq!(te(&mut c, t + 0.1), ErrorCode::InMoving, "{cmd:?}");
    }
    assert!(matches!(
        ask(&mut c, t + 0.1, Command::MotionTime(5.0)),
        ReplyBody::MotionTime(_)
    ));
    // DISABLE: PA is `J`, PT answers.
    let t = 10.0;
    assert_eq!(state(&mut c, t), ControllerState::ReadyFromMoving);
    assert!(c.handle(t, &Command::Enable(false)).is_none());
    assert_eq!(state(&mut c, t), ControllerState::DisableFromReady);
    assert!(c.handle(t, &Command::MoveAbsolute(0.0)).is_none());
    assert_eq!(te(&mut c, t), ErrorCode::InDisable);
    assert!(matches!(
        ask(&mut c, t, Command::MotionTime(5.0)),
        ReplyBody::MotionTime(_)
    ));
}
