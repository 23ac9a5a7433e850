//! SMC100 codec: golden transcripts from the user's manual (§5) byte for byte, every
//! state code and error letter, the controller's lenient command syntax, and property
//! tests (format → parse round trips; no input makes a parser panic).

use gonio_proto::smc100::{
    Command, CommandError, ControllerState, ErrorCode, Frame, Param, PositionerErrors, Reply,
    ReplyBody, Status, fuzz,
};
use proptest::prelude::*;

fn enc(address: Option<u8>, command: Command) -> Vec<u8> {
    Frame { address, command }.to_bytes()
}

#[test]
fn commands_encode_byte_for_byte() {
    let cases: Vec<(Option<u8>, Command, &[u8])> = vec![
        (Some(1), Command::Home, b"1OR\r\n"),
        (Some(1), Command::MoveAbsolute(10.0), b"1PA10\r\n"),
        (Some(2), Command::MoveAbsolute(1.436), b"2PA1.436\r\n"),
        (Some(1), Command::MoveRelative(-2.5), b"1PR-2.5\r\n"),
        (Some(1), Command::Stop, b"1ST\r\n"),
        (None, Command::Stop, b"ST\r\n"),
        (None, Command::Enable(false), b"MM0\r\n"),
        (Some(3), Command::Enable(true), b"3MM1\r\n"),
        (Some(1), Command::Reset, b"1RS\r\n"),
        (Some(1), Command::SetNegativeLimit(-170.0), b"1SL-170\r\n"),
        (Some(1), Command::SetPositiveLimit(170.0), b"1SR170\r\n"),
        (Some(1), Command::SetVelocity(5.0), b"1VA5\r\n"),
        (Some(1), Command::SetAcceleration(40.0), b"1AC40\r\n"),
        (Some(1), Command::MotionTime(2.2), b"1PT2.2\r\n"),
        (Some(1), Command::TellPosition, b"1TP\r\n"),
        (Some(1), Command::TellSetpoint, b"1TH\r\n"),
        (Some(1), Command::TellStatus, b"1TS\r\n"),
        (Some(1), Command::TellError, b"1TE\r\n"),
        (Some(1), Command::Version, b"1VE\r\n"),
        (Some(1), Command::Query(Param::StageId), b"1ID?\r\n"),
        (Some(1), Command::Query(Param::Velocity), b"1VA?\r\n"),
        (Some(1), Command::Query(Param::Acceleration), b"1AC?\r\n"),
        (Some(1), Command::Query(Param::NegativeLimit), b"1SL?\r\n"),
        (Some(1), Command::Query(Param::PositiveLimit), b"1SR?\r\n"),
        (Some(1), Command::Query(Param::AbsoluteTarget), b"1PA?\r\n"),
        (Some(1), Command::Query(Param::RelativeTarget), b"1PR?\r\n"),
        (Some(12), Command::Query(Param::Enabled), b"12MM?\r\n"),
    ];
    for (a, c, want) in cases {
        assert_eq!(enc(a, c.clone()), want, "{c:?}");
        // And the controller's parser reads it back.
        assert_eq!(
            Frame::parse(&want[..want.len() - 2]),
            Ok(Frame {
                address: a,
                command: c
            })
        );
    }
}

/// The manual's reply examples (§5.5 and the command pages) and real units' `VE`.
#[test]
fn manual_replies_parse() {
    let ok = |line: &str, address: u8, body: ReplyBody| {
        assert_eq!(
            Reply::parse(line.as_bytes()),
            Ok(Reply { address, body }),
            "{line}"
        );
    };
    ok("1VA10", 1, ReplyBody::Value(Param::Velocity, 10.0));
    ok("1PT0.25", 1, ReplyBody::MotionTime(0.25));
    ok("1TP0", 1, ReplyBody::Position(0.0));
    ok("1TH0", 1, ReplyBody::Setpoint(0.0));
    ok("1AC500", 1, ReplyBody::Value(Param::Acceleration, 500.0));
    ok(
        "1AC320.000000",
        1,
        ReplyBody::Value(Param::Acceleration, 320.0),
    );
    ok("1VA80.000000", 1, ReplyBody::Value(Param::Velocity, 80.0));
    ok("1TE@", 1, ReplyBody::Error(ErrorCode::None));
    ok("2TEH", 2, ReplyBody::Error(ErrorCode::NotReferenced));
    ok("1IDURS100CC", 1, ReplyBody::StageId("URS100CC".into()));
    ok(
        "1VE SMC_CC - Controller-driver version  3. 1. 2",
        1,
        ReplyBody::Version("SMC_CC - Controller-driver version  3. 1. 2".into()),
    );
    ok(
        "1VE SMC -  Controller -driver version 1.00r.",
        1,
        ReplyBody::Version("SMC -  Controller -driver version 1.00r.".into()),
    );
    ok(
        "1TS00000A",
        1,
        ReplyBody::Status(Status {
            errors: PositionerErrors(0),
            state: ControllerState::NotReferencedFromReset,
        }),
    );
    ok(
        "1TS000033",
        1,
        ReplyBody::Status(Status {
            errors: PositionerErrors(0),
            state: ControllerState::ReadyFromMoving,
        }),
    );
    ok("12TP-1.5e-3", 12, ReplyBody::Position(-1.5e-3));
}

/// The manual's TS error examples: `0013` and `004C`.
#[test]
fn positioner_error_bits() {
    let e = PositionerErrors(0x0013);
    assert!(e.has(PositionerErrors::SHORT_CIRCUIT));
    assert!(e.has(PositionerErrors::POSITIVE_END_OF_RUN));
    assert!(e.has(PositionerErrors::NEGATIVE_END_OF_RUN));
    assert!(!e.has(PositionerErrors::FOLLOWING_ERROR));
    let e = PositionerErrors(0x004C);
    assert!(e.has(PositionerErrors::HOMING_TIMEOUT));
    assert!(e.has(PositionerErrors::RMS_CURRENT));
    assert!(e.has(PositionerErrors::PEAK_CURRENT));
    assert!(!e.has(PositionerErrors::SHORT_CIRCUIT));
    let r = Reply::parse(b"1TS004C32").expect("valid");
    assert_eq!(
        r.body,
        ReplyBody::Status(Status {
            errors: PositionerErrors(0x004C),
            state: ControllerState::ReadyFromHoming
        })
    );
}

/// Every state code of the manual's table, its class, and its round trip.
#[test]
fn every_state_code() {
    let classes: [(u8, &str); 21] = [
        (0x0A, "NR"),
        (0x0B, "NR"),
        (0x0C, "NR"),
        (0x0D, "NR"),
        (0x0E, "NR"),
        (0x0F, "NR"),
        (0x10, "NR"),
        (0x11, "NR"),
        (0x14, "CF"),
        (0x1E, "HOM"),
        (0x1F, "HOM"),
        (0x28, "MOV"),
        (0x32, "RDY"),
        (0x33, "RDY"),
        (0x34, "RDY"),
        (0x35, "RDY"),
        (0x3C, "DIS"),
        (0x3D, "DIS"),
        (0x3E, "DIS"),
        (0x46, "JOG"),
        (0x47, "JOG"),
    ];
    for (code, class) in classes {
        let s = ControllerState::from_code(code).expect("defined");
        assert_eq!(s.code(), code);
        let got = [
            (s.is_not_referenced(), "NR"),
            (s.is_configuration(), "CF"),
            (s.is_homing(), "HOM"),
            (s.is_moving(), "MOV"),
            (s.is_ready(), "RDY"),
            (s.is_disabled(), "DIS"),
            (s.is_jogging(), "JOG"),
        ];
        let classes: Vec<&str> = got.iter().filter(|(b, _)| *b).map(|(_, n)| *n).collect();
        assert_eq!(classes, vec![class], "{code:02X}");
        let line = format!("7TS0000{code:02X}");
        let r = Reply::parse(line.as_bytes()).expect("parses");
        assert_eq!(
            String::from_utf8(r.to_bytes()).expect("ascii"),
            format!("{line}\r\n")
        );
    }
    assert_eq!(
        Reply::parse(b"1TS000029"),
        Err(gonio_proto::smc100::ReplyError::UnknownState(0x29))
    );
}

/// Every TE letter the manual defines; the others are refused.
#[test]
fn every_error_letter() {
    let letters = "@ABCDEFGHIJKLMNSUVWX";
    for l in letters.bytes() {
        let e = ErrorCode::from_letter(l).expect("defined");
        assert_eq!(e.letter() as u8, l);
        assert!(!e.description().is_empty());
    }
    for l in "OPQRTYZ".bytes() {
        assert_eq!(ErrorCode::from_letter(l), None);
        assert!(Reply::parse(format!("1TE{}", l as char).as_bytes()).is_err());
    }
}

/// The controller's syntax: blanks anywhere (the manual's `2P A1.43 6`), either case,
/// trailing characters ignored (`1TS?`), and the error letters for bad lines.
#[test]
fn controller_side_parsing() {
    assert_eq!(
        Frame::parse(b"2P A1.43 6"),
        Ok(Frame::addressed(2, Command::MoveAbsolute(1.436)))
    );
    assert_eq!(
        Frame::parse(b"1ts?"),
        Ok(Frame::addressed(1, Command::TellStatus))
    );
    assert_eq!(
        Frame::parse(b"1TP?"),
        Ok(Frame::addressed(1, Command::TellPosition))
    );
    assert_eq!(
        Frame::parse(b"1pa-5.25xyz"),
        Ok(Frame::addressed(1, Command::MoveAbsolute(-5.25)))
    );
    assert_eq!(Frame::parse(b"0ST"), Ok(Frame::broadcast(Command::Stop)));
    assert_eq!(
        Frame::parse(b"MM0"),
        Ok(Frame::broadcast(Command::Enable(false)))
    );
    assert_eq!(
        Frame::parse(b"1.5TS").map_err(|e| e.error_code()),
        Err(ErrorCode::UnknownCommand)
    );
    assert_eq!(
        Frame::parse(b"32TS").map_err(|e| e.error_code()),
        Err(ErrorCode::BadAddress)
    );
    assert_eq!(Frame::parse(b"TS"), Err(CommandError::BadAddress));
    assert_eq!(Frame::parse(b"0TP"), Err(CommandError::BadAddress));
    assert_eq!(
        Frame::parse(b"1PA").map_err(|e| e.error_code()),
        Err(ErrorCode::BadParameter)
    );
    assert_eq!(Frame::parse(b"1MM2"), Err(CommandError::BadParameter));
    assert_eq!(Frame::parse(b"1XX"), Err(CommandError::Unknown));
    assert_eq!(Frame::parse(b""), Err(CommandError::Unknown));
}

#[test]
fn command_properties() {
    assert!(Command::MoveAbsolute(1.0).is_idempotent());
    assert!(!Command::MoveRelative(1.0).is_idempotent());
    assert!(!Command::TellError.is_idempotent());
    assert!(Command::TellPosition.expects_reply());
    assert!(!Command::MoveAbsolute(1.0).expects_reply());
    assert!(Command::MotionTime(2.2).expects_reply());
    let f = Frame::addressed(1, Command::TellPosition);
    assert!(Reply::parse(b"1TP3").expect("ok").answers(&f));
    assert!(!Reply::parse(b"2TP3").expect("ok").answers(&f));
    assert!(!Reply::parse(b"1TH3").expect("ok").answers(&f));
}

fn any_command() -> impl Strategy<Value = Command> {
    let v = -1e6..1e6f64;
    prop_oneof![
        Just(Command::Home),
        v.clone().prop_map(Command::MoveAbsolute),
        v.clone().prop_map(Command::MoveRelative),
        Just(Command::Stop),
        Just(Command::Reset),
        any::<bool>().prop_map(Command::Enable),
        v.clone().prop_map(Command::SetNegativeLimit),
        v.clone().prop_map(Command::SetPositiveLimit),
        (1e-6..1e6f64).prop_map(Command::SetVelocity),
        (1e-6..1e6f64).prop_map(Command::SetAcceleration),
        (1e-6..1e6f64).prop_map(Command::MotionTime),
        Just(Command::TellPosition),
        Just(Command::TellSetpoint),
        Just(Command::TellStatus),
        Just(Command::TellError),
        Just(Command::Version),
        prop_oneof![
            Just(Param::Acceleration),
            Just(Param::Velocity),
            Just(Param::NegativeLimit),
            Just(Param::PositiveLimit),
            Just(Param::AbsoluteTarget),
            Just(Param::RelativeTarget),
            Just(Param::Enabled),
            Just(Param::StageId),
        ]
        .prop_map(Command::Query),
        (0usize..23, any::<bool>()).prop_map(|(k, _)| Command::Query(any_param(k))),
        Just(Command::DumpConfiguration),
        any::<bool>().prop_map(Command::ConfigurationMode),
        "[A-Z0-9_.-]{1,31}".prop_map(Command::SetStageId),
        (0usize..18, -1e6..1e6f64).prop_map(|(k, v)| Command::set(Param::CONFIGURATION[k], v)),
    ]
}

/// Every parameter, by index.
fn any_param(k: usize) -> Param {
    let others = [
        Param::AbsoluteTarget,
        Param::RelativeTarget,
        Param::Enabled,
        Param::StageId,
        Param::ConfigurationMode,
    ];
    Param::CONFIGURATION
        .get(k)
        .copied()
        .unwrap_or_else(|| others[(k - 18) % others.len()])
}

fn any_reply_body() -> impl Strategy<Value = ReplyBody> {
    let v = -1e6..1e6f64;
    prop_oneof![
        v.clone().prop_map(ReplyBody::Position),
        v.clone().prop_map(ReplyBody::Setpoint),
        (0usize..21, any::<u16>()).prop_map(|(k, e)| ReplyBody::Status(Status {
            errors: PositionerErrors(e),
            state: ControllerState::ALL[k].1,
        })),
        (0usize..20).prop_map(|k| {
            let l = b"@ABCDEFGHIJKLMNSUVWX"[k];
            ReplyBody::Error(ErrorCode::from_letter(l).expect("defined"))
        }),
        "[A-Za-z0-9_.-][ A-Za-z0-9_.-]{0,40}[A-Za-z0-9_.-]".prop_map(ReplyBody::Version),
        "[A-Z0-9]{1,31}".prop_map(ReplyBody::StageId),
        v.clone().prop_map(ReplyBody::MotionTime),
        (0usize..23, v).prop_map(|(k, x)| match any_param(k) {
            Param::StageId => ReplyBody::Value(Param::Velocity, x),
            p => ReplyBody::Value(p, x),
        }),
    ]
}

fn any_parameters() -> impl Strategy<Value = Smc100Parameters> {
    (
        "[A-Z0-9]{1,31}",
        proptest::collection::vec((0usize..18, -1e6..1e6f64), 0..20),
        proptest::collection::vec("(KP|KI|SC|SU)[0-9.]{1,8}", 0..3),
    )
        .prop_map(|(stage, values, other)| Smc100Parameters {
            stage,
            values: values
                .into_iter()
                .map(|(k, v)| (Param::CONFIGURATION[k], v))
                .collect(),
            other,
        })
}

proptest! {
    #[test]
    fn command_round_trip(c in any_command(), a in 1u8..=31) {
        let f = Frame::addressed(a, c);
        let b = f.to_bytes();
        prop_assert!(b.ends_with(b"\r\n"));
        prop_assert_eq!(Frame::parse(&b[..b.len() - 2]), Ok(f));
    }

    #[test]
    fn reply_round_trip(body in any_reply_body(), a in 1u8..=31) {
        let r = Reply { address: a, body };
        let b = r.to_bytes();
        prop_assert_eq!(Reply::parse(&b[..b.len() - 2]), Ok(r));
    }

    #[test]
    fn dump_round_trip(p in any_parameters(), a in 1u8..=31) {
        let mut b = Vec::new();
        p.encode_dump(a, &mut b);
        let text = String::from_utf8(b).expect("ascii");
        prop_assert_eq!(Smc100Parameters::parse_dump(a, lines(&text)), Ok(p));
    }

    #[test]
    fn parsers_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..160)) {
        fuzz::command_line(&bytes);
        fuzz::reply_line(&bytes);
        fuzz::stream(&bytes);
    }

    #[test]
    fn parsers_never_panic_on_protocol_like_text(s in "[0-9]{0,3}[A-Za-z?@ .+-]{0,4}[0-9A-Fa-f.e+-]{0,12}") {
        fuzz::command_line(s.as_bytes());
        fuzz::reply_line(s.as_bytes());
    }
}

// ---------------------------------------------------------------------------------
// Configuration: `ZT`, `PW`, and the configuration parameters (manual, ZT and PW
// commands and the pages of each parameter).

use gonio_proto::link::{Deadline, Io, Operation};
use gonio_proto::smc100::{
    AxisConfig, AxisError, ChainPolicy, DumpError, DumpReader, MotionError, Smc100Parameters,
    Smc100Session,
};
use std::collections::VecDeque;
use std::time::Duration;

#[test]
fn configuration_commands_encode_byte_for_byte() {
    let cases: Vec<(Command, &[u8])> = vec![
        (Command::DumpConfiguration, b"1ZT\r\n"),
        (Command::ConfigurationMode(true), b"1PW1\r\n"),
        (Command::ConfigurationMode(false), b"1PW0\r\n"),
        (Command::Query(Param::ConfigurationMode), b"1PW?\r\n"),
        (Command::Set(Param::Backlash, 0.01), b"1BA0.01\r\n"),
        (Command::Set(Param::Hysteresis, 0.0), b"1BH0\r\n"),
        (Command::Set(Param::MicroSteps, 100.0), b"1FRM100\r\n"),
        (Command::Set(Param::FullStep, 0.05), b"1FRS0.05\r\n"),
        (Command::Set(Param::HomeType, 1.0), b"1HT1\r\n"),
        (Command::Set(Param::JerkTime, 0.04), b"1JR0.04\r\n"),
        (Command::Set(Param::HomeVelocity, 5.0), b"1OH5\r\n"),
        (Command::Set(Param::HomeTimeout, 30.0), b"1OT30\r\n"),
        (Command::Set(Param::PeakCurrent, 1.2), b"1QIL1.2\r\n"),
        (Command::Set(Param::RmsCurrent, 0.5), b"1QIR0.5\r\n"),
        (Command::Set(Param::RmsTime, 1.0), b"1QIT1\r\n"),
        (Command::Set(Param::RsAddress, 2.0), b"1SA2\r\n"),
        (Command::Set(Param::BaseVelocity, 0.5), b"1VB0.5\r\n"),
        (Command::Set(Param::StageCheck, 3.0), b"1ZX3\r\n"),
        (Command::SetStageId("URS100BPP".into()), b"1IDURS100BPP\r\n"),
        (Command::Query(Param::PeakCurrent), b"1QIL?\r\n"),
        (Command::Query(Param::HomeType), b"1HT?\r\n"),
    ];
    for (c, want) in cases {
        let f = Frame::addressed(1, c.clone());
        assert_eq!(f.to_bytes(), want, "{c:?}");
        assert_eq!(Frame::parse(&want[..want.len() - 2]), Ok(f));
    }
    // The dedicated variants stay what the parser reads for SL, SR, VA, AC.
    assert_eq!(
        Command::set(Param::Velocity, 30.0),
        Command::SetVelocity(30.0)
    );
    assert_eq!(
        Command::set(Param::NegativeLimit, -90.0),
        Command::SetNegativeLimit(-90.0)
    );
    assert_eq!(
        Command::set(Param::Backlash, 0.5),
        Command::Set(Param::Backlash, 0.5)
    );
    // Lenient as the controller is: case and blanks.
    assert_eq!(
        Frame::parse(b"1 qil 0.7"),
        Ok(Frame::addressed(1, Command::Set(Param::PeakCurrent, 0.7)))
    );
    assert_eq!(Frame::parse(b"1PW2"), Err(CommandError::BadParameter));
    assert_eq!(Frame::parse(b"1ID"), Err(CommandError::BadParameter));
    assert_eq!(Frame::parse(b"1QIX1"), Err(CommandError::Unknown));
    assert!(!Command::ConfigurationMode(true).is_idempotent());
    assert!(Command::DumpConfiguration.is_idempotent());
    assert!(Command::Set(Param::Backlash, 0.1).is_idempotent());
}

#[test]
fn parameter_ranges_follow_the_manual() {
    assert!(Param::HomeType.accepts(4.0) && !Param::HomeType.accepts(5.0));
    assert!(!Param::HomeType.accepts(1.5));
    assert!(Param::HomeTimeout.accepts(2.0) && !Param::HomeTimeout.accepts(1.0));
    assert!(!Param::HomeTimeout.accepts(1000.0));
    assert!(Param::NegativeLimit.accepts(-170.0) && !Param::NegativeLimit.accepts(1.0));
    assert!(Param::PositiveLimit.accepts(0.0) && !Param::PositiveLimit.accepts(-1.0));
    assert!(!Param::Velocity.accepts(0.0) && Param::Velocity.accepts(1e-5));
    assert!(!Param::StageCheck.accepts(0.0) && Param::StageCheck.accepts(2.0));
    assert!(!Param::Backlash.accepts(f64::NAN));
    assert!(Param::Backlash.is_configuration() && !Param::AbsoluteTarget.is_configuration());
    assert!(!Param::ConfigurationMode.is_configuration());
    let codes: Vec<&str> = Param::CONFIGURATION.iter().map(|p| p.code()).collect();
    let mut sorted = codes.clone();
    sorted.sort_unstable();
    assert_eq!(
        codes, sorted,
        "a ZT dump lists its parameters alphabetically"
    );
}

/// The dump of an SMC100PP with a rotation stage, byte for byte: `PW1`, `ID`, the
/// parameters hvl_ccb's SMC100PP driver (written against real controllers) requires,
/// in its order (`AC BA BH FRM FRS HT JR OH OT QIL SA SL SR VA VB ZX`), reals with six
/// decimals (as the manual's `1AC320.000000`, p. 67), whole numbers without, `PW0`.
const PP_DUMP: &str = "1PW1\r\n1IDURS100PP\r\n1AC160.000000\r\n1BA0.000000\r\n\
1BH0.000000\r\n1FRM100\r\n1FRS0.050000\r\n1HT2\r\n1JR0.040000\r\n1OH10.000000\r\n\
1OT60.000000\r\n1QIL1.000000\r\n1SA2\r\n\
1SL-170.000000\r\n1SR170.000000\r\n1VA40.000000\r\n1VB0.000000\r\n1ZX3\r\n1PW0\r\n";

fn pp_parameters() -> Smc100Parameters {
    let v = [
        160.0, 0.0, 0.0, 100.0, 0.05, 2.0, 0.04, 10.0, 60.0, 1.0, 2.0, -170.0, 170.0, 40.0, 0.0,
        3.0,
    ];
    Smc100Parameters {
        stage: "URS100PP".into(),
        values: Param::CONFIGURATION
            .iter()
            .copied()
            .filter(|p| p.in_pp_dump())
            .zip(v)
            .collect(),
        other: Vec::new(),
    }
}

fn lines(text: &str) -> Vec<&[u8]> {
    text.split("\r\n")
        .filter(|l| !l.is_empty())
        .map(str::as_bytes)
        .collect()
}

#[test]
fn zt_dump_encodes_and_parses_byte_for_byte() {
    let p = pp_parameters();
    let mut out = Vec::new();
    p.encode_dump(1, &mut out);
    assert_eq!(String::from_utf8(out).expect("ascii"), PP_DUMP);
    let read = Smc100Parameters::parse_dump(1, lines(PP_DUMP)).expect("a dump");
    assert_eq!(read, p);
    assert_eq!(read.get(Param::HomeType), Some(2.0));
    assert_eq!(read.get(Param::PeakCurrent), Some(1.0));
    assert_eq!(read.get(Param::AbsoluteTarget), None);
    // Each line is also a reply on its own.
    assert_eq!(
        Reply::parse(b"1QIL1.000000"),
        Ok(Reply {
            address: 1,
            body: ReplyBody::Value(Param::PeakCurrent, 1.0)
        })
    );
    // A CC controller's lines this codec has no name for are kept, in order.
    let cc = "1PW1\r\n1IDURS100CC\r\n1AC320.000000\r\n1KP0.100000\r\n1SC1\r\n1PW0\r\n";
    let read = Smc100Parameters::parse_dump(1, lines(cc)).expect("a dump");
    assert_eq!(read.values, vec![(Param::Acceleration, 320.0)]);
    assert_eq!(
        read.other,
        vec!["KP0.100000".to_string(), "SC1".to_string()]
    );
    let mut again = Vec::new();
    read.encode_dump(1, &mut again);
    assert_eq!(again, cc.as_bytes());
    // A late reply before the dump is skipped; a cut dump is incomplete; another
    // controller's line inside it is an error.
    let late = format!("1TP5\r\n{PP_DUMP}");
    assert_eq!(Smc100Parameters::parse_dump(1, lines(&late)), Ok(p));
    let cut = &PP_DUMP[..PP_DUMP.len() - 6];
    assert_eq!(
        Smc100Parameters::parse_dump(1, lines(cut)),
        Err(DumpError::Incomplete)
    );
    assert_eq!(
        Smc100Parameters::parse_dump(1, lines("1PW1\r\n2AC1\r\n1PW0\r\n")),
        Err(DumpError::OtherAddress(2))
    );
}

#[test]
fn the_manuals_zt_example_closing_with_pw1_is_a_whole_dump() {
    // ZT page (p. 67), the manual's only example, as printed: it ends with a second
    // `1PW1`, where real SMC100PPs (hvl_ccb) end with `1PW0`. Either closes the dump;
    // before, this waited for a `PW0` that never came.
    let manual = "1PW1\r\n1AC320.000000\r\n1BA0.000000\r\n1VA80.000000\r\n1ZX3\r\n1PW1\r\n";
    let read = Smc100Parameters::parse_dump(1, lines(manual)).expect("a dump");
    assert_eq!(
        read.values,
        vec![
            (Param::Acceleration, 320.0),
            (Param::Backlash, 0.0),
            (Param::Velocity, 80.0),
            (Param::StageCheck, 3.0)
        ]
    );
    // Line by line, as the session reads it: done at the closing line, not before.
    let mut r = DumpReader::new(1);
    let ls = lines(manual);
    for l in &ls[..ls.len() - 1] {
        assert_eq!(r.push(l), Ok(None));
    }
    assert!(r.push(ls[ls.len() - 1]).expect("ends").is_some());
}

#[test]
fn configuration_ranges_are_the_manuals() {
    // QI page (p. 45), JR (p. 32), SA (p. 49), FR (p. 27): each bound in and out.
    let cases = [
        (Param::PeakCurrent, 0.05, true),
        (Param::PeakCurrent, 3.0, true),
        (Param::PeakCurrent, 0.049, false),
        (Param::PeakCurrent, 3.01, false),
        (Param::RmsCurrent, 1.5, true),
        (Param::RmsCurrent, 1.51, false),
        (Param::RmsTime, 100.0, true),
        (Param::RmsTime, 0.01, false),
        (Param::JerkTime, 0.001, false),
        (Param::JerkTime, 0.0011, true),
        (Param::RsAddress, 1.0, false),
        (Param::RsAddress, 2.0, true),
        (Param::RsAddress, 31.0, true),
        (Param::RsAddress, 32.0, false),
        (Param::MicroSteps, 2000.0, true),
        (Param::MicroSteps, 2001.0, false),
    ];
    for (p, v, ok) in cases {
        assert_eq!(p.accepts(v), ok, "{} {v}", p.code());
    }
}

// --- session transcripts, against a controller played by a closure ---

fn stage() -> AxisConfig {
    AxisConfig {
        name: "source".into(),
        address: 1,
        units: "deg".into(),
        min: -170.0,
        max: 170.0,
        velocity: None,
        acceleration: None,
        tolerance: 0.01,
        home_timeout_s: 60.0,
    }
}

/// Runs `op`; `answer(line, now)` gives the controller's reply lines to each line
/// sent (each arrives 12 ms later). Returns the output and every line sent, with its
/// time.
fn transcript<O: Operation>(
    mut op: O,
    mut answer: impl FnMut(&str, Duration) -> Vec<String>,
) -> (O::Output, Vec<(Duration, String)>) {
    let mut now = Duration::ZERO;
    let mut sent = Vec::new();
    let mut inbox: VecDeque<String> = VecDeque::new();
    for _ in 0..10_000 {
        while let Some(io) = op.poll_io() {
            match io {
                Io::Transmit(b) => {
                    let line = String::from_utf8_lossy(b).trim_end().to_string();
                    inbox.extend(answer(&line, now));
                    sent.push((now, line));
                    op.handle_sent(now, Ok(()));
                }
                Io::ClearInput => inbox.clear(),
                Io::Reconnect => panic!("no reconnection expected"),
            }
        }
        if let Some(out) = op.poll_output() {
            return (out, sent);
        }
        match op.poll_timeout().expect("waits for something") {
            Deadline::Reply(at) => match inbox.pop_front() {
                Some(l) => {
                    now += Duration::from_millis(12);
                    op.handle_line(now, l.as_bytes());
                }
                None => {
                    now = at;
                    op.handle_timeout(now);
                }
            },
            Deadline::Poll(at) | Deadline::Sleep(at) => {
                now = at;
                op.handle_timeout(now);
            }
        }
    }
    panic!("the operation never ended");
}

fn session() -> Smc100Session {
    Smc100Session::new(vec![stage()], ChainPolicy::default()).expect("valid")
}

#[test]
fn read_config_transcript() {
    let mut s = session();
    let op = s.start_read_config("source", Duration::ZERO);
    let (out, sent) = transcript(op, |line, _| match line {
        // A late reply to an earlier command arrives first, and is skipped.
        "1ZT" => std::iter::once("1TP0".to_string())
            .chain(
                lines(PP_DUMP)
                    .iter()
                    .map(|l| String::from_utf8_lossy(l).into()),
            )
            .collect(),
        other => panic!("unexpected {other}"),
    });
    assert_eq!(out, Ok(pp_parameters()));
    assert_eq!(sent, vec![(Duration::ZERO, "1ZT".to_string())]);
    assert_eq!(s.retried(), 0);
}

#[test]
fn read_config_asks_again_after_a_lost_line() {
    let mut s = session();
    let mut first = true;
    let op = s.start_read_config("source", Duration::ZERO);
    let (out, sent) = transcript(op, |line, _| {
        assert_eq!(line, "1ZT");
        let all: Vec<String> = lines(PP_DUMP)
            .iter()
            .map(|l| String::from_utf8_lossy(l).into())
            .collect();
        if std::mem::take(&mut first) {
            // The closing PW0 is lost.
            all[..all.len() - 1].to_vec()
        } else {
            all
        }
    });
    assert_eq!(out, Ok(pp_parameters()));
    let texts: Vec<&str> = sent.iter().map(|(_, l)| l.as_str()).collect();
    assert_eq!(texts, ["1ZT", "1ZT"]);
    assert_eq!(s.retried(), 1);
}

/// The manual's sequence: from NOT REFERENCED, `PW1`, each set checked with `TE`,
/// `PW0`, silence while it saves (10 s here), NOT REFERENCED from CONFIGURATION, `TE`.
#[test]
fn configure_transcript() {
    let mut s = session();
    let changes = [
        (Param::Backlash, 0.01),
        (Param::HomeType, 1.0),
        (Param::Velocity, 30.0),
    ];
    let mut saved_at: Option<Duration> = None;
    let op = s.start_configure("source", &changes, Duration::ZERO);
    let (out, sent) = transcript(op, |line, now| {
        let busy = saved_at.is_some_and(|t| now < t + Duration::from_secs(10));
        let r: &[&str] = match line {
            _ if busy => &[],
            "1TS" if saved_at.is_some() => &["1TS00000C"],
            "1TS" => &["1TS00000A"],
            "1TE" => &["1TE@"],
            "1PW0" => {
                saved_at = Some(now);
                &[]
            }
            "1PW1" | "1BA0.01" | "1HT1" | "1VA30" => &[],
            other => panic!("unexpected {other}"),
        };
        r.iter().map(|l| l.to_string()).collect()
    });
    assert_eq!(out, Ok(()));
    let texts: Vec<&str> = sent.iter().map(|(_, l)| l.as_str()).collect();
    assert_eq!(
        &texts[..10],
        [
            "1TS", "1PW1", "1TE", "1BA0.01", "1TE", "1HT1", "1TE", "1VA30", "1TE", "1PW0"
        ]
    );
    // Then status polls until the save ends, and the save's own TE.
    assert!(texts[10..texts.len() - 1].iter().all(|l| *l == "1TS"));
    assert_eq!(texts.last(), Some(&"1TE"));
    let pw0 = sent[9].0;
    let answered = sent[sent.len() - 2].0;
    assert!(answered >= pw0 + Duration::from_secs(10), "{answered:?}");
    assert!(
        answered <= pw0 + Duration::from_millis(10_600),
        "{answered:?}"
    );
}

#[test]
fn configure_refuses_before_sending() {
    let mut s = session();
    // Not a configuration parameter, or out of the manual's range: not a byte.
    for change in [(Param::AbsoluteTarget, 1.0), (Param::HomeType, 7.0)] {
        let mut op = s.start_configure("source", &[change], Duration::ZERO);
        assert_eq!(op.poll_io(), None);
        match op.poll_output() {
            Some(Err(MotionError::AtAxis {
                source: AxisError::InvalidSetting { code, .. },
                ..
            })) => assert_eq!(code, change.0.code()),
            other => panic!("{other:?}"),
        }
    }
    // READY: PW1 needs NOT REFERENCED, and the session does not reset on its own.
    let op = s.start_configure("source", &[(Param::Backlash, 0.1)], Duration::ZERO);
    let (out, sent) = transcript(op, |line, _| match line {
        "1TS" => vec!["1TS000032".into()],
        other => panic!("unexpected {other}"),
    });
    match out {
        Err(MotionError::AtAxis {
            source: AxisError::WrongState { state, .. },
            ..
        }) => assert_eq!(state, ControllerState::ReadyFromHoming),
        other => panic!("{other:?}"),
    }
    assert_eq!(sent.len(), 1);
}

/// A refused set still leaves CONFIGURATION with `PW0` (the only way out), then the
/// refusal is the result.
#[test]
fn configure_leaves_configuration_after_a_refusal() {
    let mut s = session();
    let mut saving = false;
    let op = s.start_configure(
        "source",
        &[(Param::Backlash, 0.01), (Param::PeakCurrent, 2.0)],
        Duration::ZERO,
    );
    let mut last = String::new();
    let (out, sent) = transcript(op, |line, _| {
        let r: Vec<String> = match line {
            "1TS" if saving => vec!["1TS00000C".into()],
            "1TS" => vec!["1TS00000A".into()],
            "1TE" if last == "1QIL2" => vec!["1TEC".into()],
            "1TE" => vec!["1TE@".into()],
            "1PW0" => {
                saving = true;
                vec![]
            }
            _ => vec![],
        };
        last = line.to_string();
        r
    });
    match out {
        Err(MotionError::AtAxis {
            source: AxisError::Controller { command, code },
            ..
        }) => {
            assert_eq!(command, "1QIL2");
            assert_eq!(code, ErrorCode::BadParameter);
        }
        other => panic!("{other:?}"),
    }
    let texts: Vec<&str> = sent.iter().map(|(_, l)| l.as_str()).collect();
    assert_eq!(
        &texts[..8],
        [
            "1TS", "1PW1", "1TE", "1BA0.01", "1TE", "1QIL2", "1TE", "1PW0"
        ]
    );
}

// --- the manual's refusals against the session ---

/// A `PA` whose `TE` answer is lost is sent again; the first was accepted and the stage
/// moves, so the controller refuses the second. Which letter it stores is not in the
/// manual (PA page, p. 41-42: no letter for MOVING): `M` by analogy, or `D`, "execution
/// not allowed". With either, the session reads the held target and, finding its own,
/// waits for the move; a different held target is the refusal.
#[test]
fn a_resent_move_refused_with_m_or_d_is_taken_when_the_target_is_held() {
    for (letter, code) in [("M", ErrorCode::InMoving), ("D", ErrorCode::NotAllowed)] {
        for held in ["10", "12"] {
            let mut s = session();
            let mut tes = 0;
            let op = s.start_move(&[("source", 10.0)], Duration::ZERO);
            let (out, sent) = transcript(op, |line, _| -> Vec<String> {
                match line {
                    "1TP" if tes < 2 => vec!["1TP0".into()],
                    "1TP" => vec!["1TP10".into()],
                    "1PT10" => vec!["1PT2".into()],
                    "1PA10" | "ST" => vec![],
                    // The first acknowledgement is lost.
                    "1TE" => {
                        tes += 1;
                        if tes == 1 {
                            vec![]
                        } else {
                            vec![format!("1TE{letter}")]
                        }
                    }
                    "1PA?" => vec![format!("1PA{held}")],
                    "1TS" => vec!["1TS000033".into()],
                    other => panic!("unexpected {other}"),
                }
            });
            let texts: Vec<&str> = sent.iter().map(|(_, l)| l.as_str()).collect();
            assert_eq!(
                &texts[..7],
                ["1TP", "1PT10", "1PA10", "1TE", "1PA10", "1TE", "1PA?"],
                "{letter} {held}"
            );
            if held == "10" {
                assert_eq!(out, Ok(vec![10.0]), "{letter}");
                assert!(!texts.contains(&"ST"));
            } else {
                match out {
                    Err(MotionError::AtAxis {
                        source: AxisError::Controller { command, code: c },
                        ..
                    }) => assert_eq!((command.as_str(), c), ("1PA10", code)),
                    other => panic!("{letter} {held}: {other:?}"),
                }
                assert_eq!(texts.last(), Some(&"ST"));
            }
        }
    }
}

/// `PT` outside DISABLE, READY and MOVING (§5.5 table) is refused like any command:
/// no answer, the state's letter stored (manual §5.3). When every `PT` goes
/// unanswered the session reads `TE`: a letter makes the refusal the error (typed,
/// naming the `PT`), `@` leaves the timeout; either way every stage is stopped and no
/// `PA` is sent.
#[test]
fn an_unanswered_pt_is_read_as_the_refusal_te_reports() {
    for (te, refused) in [("1TEH", true), ("1TE@", false)] {
        let mut s = session();
        let op = s.start_move(&[("source", 10.0)], Duration::ZERO);
        let (out, sent) = transcript(op, |line, _| match line {
            "1TP" => vec!["1TP0".into()],
            "1PT10" | "ST" => vec![],
            "1TE" => vec![te.into()],
            other => panic!("unexpected {other}"),
        });
        let texts: Vec<&str> = sent.iter().map(|(_, l)| l.as_str()).collect();
        assert_eq!(texts, ["1TP", "1PT10", "1PT10", "1PT10", "1TE", "ST"]);
        let source = match out {
            Err(MotionError::AtAxis { source, .. }) => source,
            other => panic!("{other:?}"),
        };
        if refused {
            assert_eq!(
                source,
                AxisError::Controller {
                    command: "1PT10".into(),
                    code: ErrorCode::NotReferenced
                }
            );
        } else {
            assert_eq!(
                source,
                AxisError::Transport(gonio_proto::TransportError::Timeout(Duration::from_millis(
                    100
                )))
            );
        }
    }
}

/// The line framer (`LineFramer`), which the SMC100 chain reads its replies through.
mod line_framer {
    use gonio_proto::{FrameError, LineFramer};
    use proptest::prelude::*;

    #[test]
    fn crlf_lines_split_across_chunks() {
        let mut f = LineFramer::new(b'\n', 64);
        f.push(b"1TP1");
        assert!(f.next_line().is_none());
        f.push(b"2.5\r\n1TS00");
        assert_eq!(f.next_line(), Some(Ok(b"1TP12.5".to_vec())));
        assert!(f.next_line().is_none());
        f.push(b"0033\r\n");
        assert_eq!(f.next_line(), Some(Ok(b"1TS000033".to_vec())));
    }

    #[test]
    fn cr_terminated_replies() {
        let mut f = LineFramer::new(b'\r', 64);
        f.push(b"26\r8\r1\r");
        let lines: Vec<_> = std::iter::from_fn(|| f.next_line()).collect();
        assert_eq!(
            lines,
            vec![Ok(b"26".to_vec()), Ok(b"8".to_vec()), Ok(b"1".to_vec())]
        );
    }

    #[test]
    fn nul_and_overlong_lines_are_errors_and_resynchronise() {
        let mut f = LineFramer::new(b'\n', 8);
        f.push(b"1T\0P12\r\n1TE@\r\n");
        assert_eq!(f.next_line(), Some(Err(FrameError::Nul)));
        assert_eq!(f.next_line(), Some(Ok(b"1TE@".to_vec())));
        f.push(b"0123456789ABCDEF\r\nok\r\n");
        assert_eq!(f.next_line(), Some(Err(FrameError::TooLong(8))));
        assert_eq!(f.next_line(), Some(Ok(b"ok".to_vec())));
        assert!(!f.has_partial());
    }

    proptest! {
        #[test]
        fn never_panics_and_never_exceeds_max_len(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
            let mut f = LineFramer::new(b'\n', 32);
            f.push(&bytes);
            while let Some(l) = f.next_line() {
                if let Ok(l) = l {
                    prop_assert!(l.len() <= 32);
                    prop_assert!(!l.contains(&b'\n') && !l.contains(&0));
                }
            }
        }
    }
}

/// What the chain's operations cost on the wire (`smc100::timing`).
mod timing {
    use std::time::Duration;

    use gonio_proto::smc100::AxisConfig;
    use gonio_proto::smc100::timing::*;

    fn axis(address: u8) -> AxisConfig {
        AxisConfig {
            name: "a".into(),
            address,
            units: "deg".into(),
            min: -170.0,
            max: 170.0,
            velocity: Some(20.0),
            acceleration: None,
            tolerance: 0.01,
            home_timeout_s: 120.0,
        }
    }

    #[test]
    fn each_exchange_is_its_bytes_and_the_latency() {
        let x = move_exchanges(&axis(1), 0, 57_600, Duration::from_millis(50));
        // `1TP\r\n` out, `1TP-37.5\r\n` back: 15 bytes, 2.6 ms, and the 10 ms.
        assert!((x.before_s - (0.010 + 150.0 / 57_600.0)).abs() < 1e-12);
        // `1PA-37.5\r\n` goes out unanswered.
        assert!((x.command_s - 100.0 / 57_600.0).abs() < 1e-12);
        // `1TE\r\n`, `1TE@\r\n`; `1TS\r\n`, `1TS000028\r\n`.
        assert!((x.check_s - (0.010 + 110.0 / 57_600.0)).abs() < 1e-12);
        assert!((x.status_s - (0.010 + 160.0 / 57_600.0)).abs() < 1e-12);
        assert_eq!(x.poll_s, 0.05);
        // Homing sets the configured velocity (`1VA20`) and checks it; no acceleration.
        let h = home_exchanges(&axis(1), 0, 57_600, Duration::from_millis(50));
        assert!((h.after_s - (70.0 / 57_600.0 + x.check_s)).abs() < 1e-12);
    }

    #[test]
    fn a_search_is_a_trapezoid_at_the_home_velocity() {
        // 40° at 10 °/s with 80 °/s²: 4 s and an eighth of a second of ramps.
        assert!((home_search_s(-40.0, 0.0, 10.0, 80.0) - 4.125).abs() < 1e-12);
        assert_eq!(home_search_s(0.0, 0.0, 10.0, 80.0), 0.0);
    }
}
