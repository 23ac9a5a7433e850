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
    ]
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
        v.prop_map(|x| ReplyBody::Value(Param::Velocity, x)),
    ]
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
