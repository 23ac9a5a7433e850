//! The simulated SMC100's configuration against the manual's PW and ZT commands: the
//! dump line by line, CONFIGURATION entered from NOT REFERENCED only, configuration
//! commands refused elsewhere with the state's letter, `PW0`'s silent save, saved
//! values kept across `RS` and power loss, unsaved ones lost; then the session's
//! `start_read_config` and `start_configure` driven against the twin on virtual time.

use crate::session_rig;

use gonio_proto::smc100::{Command, ErrorCode, Param, ReplyBody};
use gonio_sim::controller::{Controller, ControllerConfig};
use session_rig::*;

/// The factory dump of controller 1 with the default config, byte for byte: an
/// SMC100PP's lines, as hvl_ccb's driver (written against real controllers) requires
/// them: `PW1 ID AC BA BH FRM FRS HT JR OH OT QIL SA SL SR VA VB ZX PW0`.
const DUMP_1: &str = "1PW1\r\n1IDURS100PP\r\n1AC160.000000\r\n1BA0.000000\r\n\
1BH0.000000\r\n1FRM100\r\n1FRS0.050000\r\n1HT2\r\n1JR0.040000\r\n1OH10.000000\r\n\
1OT60.000000\r\n1QIL1.000000\r\n1SA2\r\n\
1SL-170.000000\r\n1SR170.000000\r\n1VA40.000000\r\n1VB0.000000\r\n1ZX3\r\n1PW0\r\n";

fn te(c: &mut Controller, t: f64) -> ErrorCode {
    match c.handle(t, &Command::TellError).map(|r| r.body) {
        Some(ReplyBody::Error(e)) => e,
        other => panic!("{other:?}"),
    }
}

fn run(c: &mut Controller, t: f64, cmd: Command) -> ErrorCode {
    assert!(c.handle(t, &cmd).is_none(), "{cmd:?} replies nothing");
    te(c, t)
}

fn state(c: &mut Controller, t: f64) -> ControllerState {
    c.state(t)
}

fn dump(c: &mut Controller, t: f64) -> String {
    c.respond(t, &Command::DumpConfiguration)
        .concat()
        .into_iter()
        .map(char::from)
        .collect()
}

#[test]
fn zt_lists_the_factory_configuration_line_by_line() {
    let mut c = Controller::new(ControllerConfig::default());
    let lines = c.respond(0.0, &Command::DumpConfiguration);
    assert_eq!(lines.len(), 19, "PW1, ID, 16 parameters, PW0");
    assert_eq!(lines[0], b"1PW1\r\n");
    assert_eq!(lines[18], b"1PW0\r\n");
    let want = "PW1 ID AC BA BH FRM FRS HT JR OH OT QIL SA SL SR VA VB ZX PW0";
    for (line, code) in lines.iter().zip(want.split(' ')) {
        assert!(line.starts_with(format!("1{code}").as_bytes()), "{line:?}");
    }
    assert_eq!(dump(&mut c, 0.0), DUMP_1);
    // Through the wire, in every state that allows it (here NOT REFERENCED and READY).
    let mut rig = Rig::new(1, |_| {});
    assert_eq!(rig.sim.motion_bytes(b"1ZT\r\n"), DUMP_1.as_bytes());
    let two = String::from_utf8(rig.sim.motion_bytes(b"2ZT\r\n")).expect("ascii");
    assert!(two.starts_with("2PW1\r\n2IDURS100PP\r\n") && two.contains("\r\n2SA2\r\n"));
    // ZT changes nothing and stores no error.
    assert_eq!(te(&mut c, 0.0), ErrorCode::None);
}

#[test]
fn configuration_state_and_its_refusals() {
    let mut c = Controller::new(ControllerConfig::default());
    // Configuration commands outside CONFIGURATION: the state's letter.
    assert_eq!(
        run(&mut c, 0.0, Command::Set(Param::Backlash, 0.1)),
        ErrorCode::NotReferenced
    );
    assert_eq!(
        run(&mut c, 0.0, Command::ConfigurationMode(false)),
        ErrorCode::NotReferenced
    );
    // PW1 from NOT REFERENCED: CONFIGURATION, `14`; PW? says so.
    assert_eq!(
        run(&mut c, 0.0, Command::ConfigurationMode(true)),
        ErrorCode::None
    );
    assert_eq!(state(&mut c, 0.0), ControllerState::Configuration);
    match c
        .handle(0.0, &Command::Query(Param::ConfigurationMode))
        .map(|r| r.body)
    {
        Some(ReplyBody::Value(Param::ConfigurationMode, v)) => assert_eq!(v, 1.0),
        other => panic!("{other:?}"),
    }
    // In CONFIGURATION: no home search, no move, no reset (`I`); a value out of the
    // manual's range is `C`.
    assert_eq!(run(&mut c, 0.0, Command::Home), ErrorCode::InConfiguration);
    assert_eq!(
        run(&mut c, 0.0, Command::MoveAbsolute(1.0)),
        ErrorCode::InConfiguration
    );
    assert_eq!(run(&mut c, 0.0, Command::Reset), ErrorCode::InConfiguration);
    assert_eq!(
        run(&mut c, 0.0, Command::ConfigurationMode(true)),
        ErrorCode::InConfiguration
    );
    assert_eq!(
        run(&mut c, 0.0, Command::Set(Param::HomeType, 5.0)),
        ErrorCode::BadParameter
    );
    assert_eq!(
        run(&mut c, 0.0, Command::SetPositiveLimit(-1.0)),
        ErrorCode::BadParameter
    );
    // Accepted: the dump shows them at once.
    assert_eq!(
        run(&mut c, 0.0, Command::Set(Param::Backlash, 0.01)),
        ErrorCode::None
    );
    assert_eq!(
        run(&mut c, 0.0, Command::SetVelocity(30.0)),
        ErrorCode::None
    );
    assert_eq!(
        run(&mut c, 0.0, Command::SetStageId("URS75BPP".into())),
        ErrorCode::None
    );
    let d = dump(&mut c, 0.0);
    assert!(
        d.contains("\r\n1IDURS75BPP\r\n1AC160.000000\r\n1BA0.010000\r\n"),
        "{d}"
    );
    assert!(d.contains("\r\n1VA30.000000\r\n"), "{d}");
    // READY: PW1 refused with `K`, BA with `K`.
    let mut r = Controller::new(ControllerConfig::default());
    assert_eq!(run(&mut r, 0.0, Command::Home), ErrorCode::None);
    assert_eq!(state(&mut r, 5.0), ControllerState::ReadyFromHoming);
    assert_eq!(
        run(&mut r, 5.0, Command::ConfigurationMode(true)),
        ErrorCode::InReady
    );
    assert_eq!(
        run(&mut r, 5.0, Command::Set(Param::Backlash, 0.1)),
        ErrorCode::InReady
    );
    assert_eq!(
        run(&mut r, 5.0, Command::SetStageId("X".into())),
        ErrorCode::InReady
    );
}

/// PW0 saves: silent for the manual's 10 s, then NOT REFERENCED from CONFIGURATION.
#[test]
fn pw0_is_silent_for_ten_seconds() {
    let mut rig = Rig::new(2, |_| {});
    assert!(rig.sim.motion_bytes(b"1PW1\r\n1BA0.02\r\n").is_empty());
    assert_eq!(rig.sim.motion_bytes(b"1TE\r\n"), b"1TE@\r\n");
    rig.advance_to(Duration::from_secs(1));
    assert!(rig.sim.motion_bytes(b"1PW0\r\n").is_empty());
    rig.advance_to(Duration::from_millis(10_999));
    assert!(rig.sim.motion_bytes(b"1TS\r\n").is_empty(), "saving");
    assert!(rig.sim.motion_bytes(b"1ZT\r\n").is_empty(), "saving");
    rig.advance_to(Duration::from_secs(11));
    assert_eq!(rig.sim.motion_bytes(b"1TS\r\n"), b"1TS00000C\r\n");
    assert_eq!(rig.sim.motion_bytes(b"1TE\r\n"), b"1TE@\r\n");
    // Other controllers answered all along.
    let c = rig.sim.controller_mut(1).expect("controller 1");
    assert_eq!(c.saved_parameters().get(Param::Backlash), Some(0.02));
}

#[test]
fn saved_values_survive_resets_unsaved_ones_do_not() {
    let mut c = Controller::new(ControllerConfig::default());
    run(&mut c, 0.0, Command::ConfigurationMode(true));
    run(&mut c, 0.0, Command::Set(Param::HomeVelocity, 5.0));
    run(&mut c, 0.0, Command::SetNegativeLimit(-90.0));
    run(&mut c, 0.0, Command::ConfigurationMode(false));
    assert!(c.is_booting(9.9) && !c.is_booting(10.0));
    assert_eq!(
        state(&mut c, 10.0),
        ControllerState::NotReferencedFromConfiguration
    );
    // The new limit is in force at once, and after RS.
    match c
        .handle(10.0, &Command::Query(Param::NegativeLimit))
        .map(|r| r.body)
    {
        Some(ReplyBody::Value(_, v)) => assert_eq!(v, -90.0),
        other => panic!("{other:?}"),
    }
    run(&mut c, 10.0, Command::Reset);
    assert!(c.is_booting(12.0));
    let d = dump(&mut c, 14.0);
    assert!(
        d.contains("\r\n1OH5.000000\r\n") && d.contains("\r\n1SL-90.000000\r\n"),
        "{d}"
    );
    // Changed but not saved: gone after a power loss, in CONFIGURATION or not.
    run(&mut c, 14.0, Command::ConfigurationMode(true));
    run(&mut c, 14.0, Command::Set(Param::HomeVelocity, 2.0));
    assert!(dump(&mut c, 14.0).contains("\r\n1OH2.000000\r\n"));
    c.power_cycle(15.0);
    assert_eq!(state(&mut c, 20.0), ControllerState::NotReferencedFromReset);
    let d = dump(&mut c, 20.0);
    assert!(d.contains("\r\n1OH5.000000\r\n"), "{d}");
    // And the saved home velocity is the one a home search uses: 12.5° at 5°/s.
    let mut c = Controller::new(ControllerConfig {
        start_position: 12.5,
        ..ControllerConfig::default()
    });
    run(&mut c, 0.0, Command::ConfigurationMode(true));
    run(&mut c, 0.0, Command::Set(Param::HomeVelocity, 5.0));
    run(&mut c, 0.0, Command::ConfigurationMode(false));
    assert_eq!(run(&mut c, 10.0, Command::Home), ErrorCode::None);
    // 2·(5/80) + (12.5 − 25/80)/5 = 2.5625 s.
    assert_eq!(state(&mut c, 12.56), ControllerState::HomingRemote);
    assert_eq!(state(&mut c, 12.57), ControllerState::ReadyFromHoming);
}

/// The session against the twin: read, configure (the manual's sequence and its
/// time), read back, and the saved values after a reset.
#[test]
fn session_configures_the_twin() {
    let mut rig = Rig::new(3, |_| {});
    let mut chain = Smc100Session::new(axes(), ChainPolicy::default()).expect("valid axes");
    let before = rig
        .run(Port::Motion, chain.start_read_config("detector", rig.now))
        .expect("read");
    let twin = rig
        .sim
        .controller_mut(2)
        .expect("controller 2")
        .parameters()
        .clone();
    // The dump lists what an SMC100PP lists: QIR and QIT are held, not listed.
    assert_eq!(before.stage, twin.stage);
    let listed: Vec<(Param, f64)> = Param::CONFIGURATION
        .iter()
        .filter(|p| p.in_pp_dump())
        .map(|p| (*p, twin.get(*p).expect("held")))
        .collect();
    assert_eq!(before.values, listed);
    assert!(twin.get(Param::RmsCurrent).is_some() && before.get(Param::RmsCurrent).is_none());
    assert_eq!(before.stage, "URS100PP");
    assert_eq!(before.get(Param::RsAddress), Some(2.0));
    assert_eq!(before.get(Param::Backlash), Some(0.0));

    let from = rig.sent.len();
    let changes = [(Param::Backlash, 0.01), (Param::HomeVelocity, 5.0)];
    rig.run(
        Port::Motion,
        chain.start_configure("detector", &changes, rig.now),
    )
    .expect("configured");
    let lines = rig.lines_since(from, Port::Motion);
    assert_eq!(
        &lines[..8],
        [
            "2TS\r\n",
            "2PW1\r\n",
            "2TE\r\n",
            "2BA0.01\r\n",
            "2TE\r\n",
            "2OH5\r\n",
            "2TE\r\n",
            "2PW0\r\n"
        ]
    );
    assert_eq!(lines.last().map(String::as_str), Some("2TE\r\n"));
    // The save took the twin's 10 s; the session noticed within a poll.
    let pw0 = rig.sent[from + 7].1;
    let took = rig.now - pw0;
    assert!(
        took >= Duration::from_secs(10) && took < Duration::from_millis(10_800),
        "{took:?}"
    );
    let t = rig.secs();
    let c = rig.sim.controller_mut(2).expect("controller 2");
    assert_eq!(c.state(t), ControllerState::NotReferencedFromConfiguration);
    assert_eq!(c.saved_parameters().get(Param::Backlash), Some(0.01));

    let after = rig
        .run(Port::Motion, chain.start_read_config("detector", rig.now))
        .expect("read");
    assert_eq!(after.get(Param::Backlash), Some(0.01));
    assert_eq!(after.get(Param::HomeVelocity), Some(5.0));
    assert_eq!(
        after.get(Param::Acceleration),
        before.get(Param::Acceleration)
    );

    // Reading and configuring asked nothing twice (the save's silence is no retry).
    assert_eq!(chain.retried(), 0);
    // After a reset the saved values are still there, and the home search uses OH:
    // 40° at 5°/s rather than 10°/s.
    let t0 = rig.now;
    rig.run(
        Port::Motion,
        chain.start_reset_and_home("detector", rig.now),
    )
    .expect("reset and homed");
    let took = rig.now - t0;
    assert!(
        took > Duration::from_secs(11),
        "3 s boot + 8 s search: {took:?}"
    );
    let again = rig
        .run(Port::Motion, chain.start_read_config("detector", rig.now))
        .expect("read");
    assert_eq!(again, after);
    // READY now: configuring is refused without a byte beyond the status.
    let from = rig.sent.len();
    let e = rig
        .run(
            Port::Motion,
            chain.start_configure("detector", &changes, rig.now),
        )
        .expect_err("READY");
    assert!(matches!(at_axis(e).1, AxisError::WrongState { .. }));
    assert_eq!(rig.lines_since(from, Port::Motion), ["2TS\r\n"]);
}

/// What the third-party drivers on PyPI send at start-up, answered as a controller
/// does: yaqd-newport 2025.12.0 (`SL?`, `SR?`, `RS`, then `TS`/`TE` polls, `OR`,
/// `PA`, `TP`) and pymodaq-plugins-newport 5.3.0 (`OR`, `ID?`, `PA?`). Neither reads
/// `ZT` or sends `PW`.
#[test]
fn third_party_start_up_sequences() {
    let mut rig = Rig::new(4, |_| {});
    let say = |rig: &mut Rig, line: &str| -> String {
        String::from_utf8(rig.sim.motion_bytes(format!("{line}\r\n").as_bytes())).expect("ascii")
    };
    assert_eq!(say(&mut rig, "1SL?"), "1SL-170\r\n");
    assert_eq!(say(&mut rig, "1SR?"), "1SR170\r\n");
    assert_eq!(say(&mut rig, "1RS"), "");
    rig.advance_to(Duration::from_secs(5));
    assert_eq!(say(&mut rig, "1TS"), "1TS00000A\r\n");
    assert_eq!(say(&mut rig, "1TE"), "1TE@\r\n");
    assert_eq!(say(&mut rig, "1OR"), "");
    rig.advance_to(Duration::from_secs(10));
    assert_eq!(say(&mut rig, "1TS"), "1TS000032\r\n");
    assert_eq!(say(&mut rig, "1PA0"), "");
    assert_eq!(say(&mut rig, "1TP"), "1TP0\r\n");
    assert_eq!(say(&mut rig, "1TE"), "1TE@\r\n");
    assert_eq!(say(&mut rig, "2OR"), "");
    assert_eq!(say(&mut rig, "2ID?"), "2IDURS100PP\r\n");
    assert_eq!(say(&mut rig, "2PA?"), "2PA0\r\n");
}
