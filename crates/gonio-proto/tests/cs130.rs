//! The Cornerstone 130 codec against the CS130B manual (90088262, Appendix I): the
//! statements and answers the session uses, byte for byte; the status byte and error
//! table of §15.9; round trips under proptest; the fuzz bodies on arbitrary bytes.

use gonio_proto::cs130::{Command, ErrorCode, Reply, ReplyError, StatusByte, Units, fuzz, is_echo};
use proptest::prelude::*;

#[test]
fn the_manuals_examples_byte_for_byte() {
    // §15.4: "Send: GOWAVE 500[cr][lf] Response: GOWAVE 500[cr][lf]".
    let sent = Command::GoWave(500.0).to_bytes();
    assert_eq!(sent, b"GOWAVE 500\r\n");
    assert!(is_echo(&Command::GoWave(500.0), &sent[..sent.len() - 2]));
    // §15.5's query example, echo on: "WAVE?[cr][lf]500.01[cr][lf]".
    assert_eq!(Command::Wave.to_bytes(), b"WAVE?\r\n");
    assert_eq!(
        Reply::parse(&Command::Wave, b"500.01"),
        Ok(Reply::Wavelength(500.01))
    );
    assert_eq!(Reply::Wavelength(500.01).to_bytes(), b"500.01\r\n");
    // §15.8's sequence: "gowave 587.1", "*wai", "shutter o", as the instrument parses it.
    assert_eq!(Command::parse(b"gowave 587.1"), Ok(Command::GoWave(587.1)));
    assert_eq!(Command::parse(b"*wai"), Ok(Command::Wai));
    assert_eq!(Command::parse(b"shutter o"), Ok(Command::Shutter(true)));
}

#[test]
fn every_statement_the_session_sends() {
    let cases: [(Command, &[u8]); 12] = [
        (Command::Info, b"INFO?\r\n"),
        (Command::Units(Units::Nm), b"UNITS NM\r\n"),
        (Command::GratQuery, b"GRAT?\r\n"),
        (Command::FilterQuery, b"FILTER?\r\n"),
        (Command::ShutterQuery, b"SHUTTER?\r\n"),
        (Command::Wave, b"WAVE?\r\n"),
        (Command::Stb, b"STB?\r\n"),
        (Command::Error, b"ERROR?\r\n"),
        (Command::Grat(2), b"GRAT 2\r\n"),
        (Command::Filter(4), b"FILTER 4\r\n"),
        (Command::GoWave(1200.5), b"GOWAVE 1200.5\r\n"),
        (Command::Shutter(false), b"SHUTTER C\r\n"),
    ];
    for (c, bytes) in cases {
        assert_eq!(c.to_bytes(), bytes, "{c:?}");
        assert_eq!(Command::parse(&bytes[..bytes.len() - 2]), Ok(c));
    }
}

#[test]
fn the_status_byte_and_error_table() {
    // §15.9: 0 at power-up, 32 after any error.
    assert!(!StatusByte(0).error());
    assert!(StatusByte(32).error());
    assert_eq!(StatusByte(32).to_string(), "20");
    let table = [
        (0, "no error"),
        (1, "command not understood"),
        (2, "bad parameter used in command"),
        (3, "destination position for wavelength motion not allowed"),
        (6, "accessory not present (usually filter wheel)"),
        (8, "could not home wavelength drive"),
        (9, "label too long"),
        (10, "system error"),
    ];
    for (code, cause) in table {
        assert_eq!(ErrorCode(code).cause(), Some(cause));
        assert_eq!(
            Reply::parse(&Command::Error, code.to_string().as_bytes()),
            Ok(Reply::Error(ErrorCode(code)))
        );
    }
    for code in [4, 5, 7, 11, 255] {
        assert_eq!(ErrorCode(code).cause(), None);
    }
    assert_eq!(Command::parse(b"FOO").unwrap_err().code(), 1);
    assert_eq!(Command::parse(b"GRAT x").unwrap_err().code(), 2);
}

#[test]
fn lenient_where_the_instrument_is_and_strict_where_it_matters() {
    assert_eq!(
        Reply::parse(&Command::Wave, b" 500.01 "),
        Ok(Reply::Wavelength(500.01))
    );
    assert_eq!(
        Reply::parse(&Command::ShutterQuery, b"o"),
        Ok(Reply::Shutter(true))
    );
    assert_eq!(
        Reply::parse(&Command::FilterQuery, b"7x"),
        Err(ReplyError::BadValue)
    );
    assert_eq!(
        Reply::parse(&Command::Stb, b"100"),
        Err(ReplyError::BadValue)
    );
    assert_eq!(
        Reply::parse(&Command::Wave, b"WAVE?"),
        Err(ReplyError::BadValue)
    );
    assert!(!is_echo(&Command::Wave, b"WAVE"));
}

fn any_command() -> impl Strategy<Value = Command> {
    prop_oneof![
        (0u32..3_000_000).prop_map(|m| Command::GoWave(f64::from(m) / 1000.0)),
        Just(Command::Wave),
        any::<u8>().prop_map(Command::Grat),
        Just(Command::GratQuery),
        any::<u8>().prop_map(Command::Filter),
        Just(Command::FilterQuery),
        any::<bool>().prop_map(Command::Shutter),
        Just(Command::ShutterQuery),
        prop_oneof![Just(Units::Nm), Just(Units::Um), Just(Units::Wn)].prop_map(Command::Units),
        Just(Command::Stb),
        Just(Command::Error),
        Just(Command::Info),
        Just(Command::Abort),
        Just(Command::Wai),
    ]
}

proptest! {
    #[test]
    fn statements_round_trip_in_any_case(c in any_command(), lower in any::<bool>()) {
        let mut body = Vec::new();
        c.encode_body(&mut body);
        if lower {
            body.make_ascii_lowercase();
        }
        prop_assert!(is_echo(&c, &body));
        prop_assert_eq!(Command::parse(&body), Ok(c));
    }

    #[test]
    fn wavelengths_round_trip(cents in 0u32..10_000_000) {
        let v = f64::from(cents) / 100.0;
        let bytes = Reply::Wavelength(v).to_bytes();
        prop_assert_eq!(Reply::parse(&Command::Wave, &bytes[..bytes.len() - 2]), Ok(Reply::Wavelength(v)));
    }

    #[test]
    fn the_fuzz_bodies_never_panic(data in proptest::collection::vec(any::<u8>(), 0..64)) {
        fuzz::fuzz_parse_line(&data);
        fuzz::fuzz_parse_reply(&data);
    }

    #[test]
    fn the_fuzz_bodies_never_panic_on_near_statements(
        k in 0usize..6, tail in "[ 0-9.eE+-]{0,12}", sel in any::<u8>()
    ) {
        let head = ["GOWAVE ", "GRAT ", "FILTER ", "SHUTTER ", "UNITS ", "wave?"][k];
        let line = format!("{head}{tail}");
        fuzz::fuzz_parse_line(line.as_bytes());
        let mut reply = vec![sel];
        reply.extend_from_slice(tail.as_bytes());
        fuzz::fuzz_parse_reply(&reply);
    }
}
