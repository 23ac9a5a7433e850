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

/// `STB?` as both manuals give it, in decimal: CS130B §15.9 "Whenever any error is
/// encountered it is set to the value 32"; Model 74000 table "STB? … The response will
/// be 32 when an error occurred or 00 when no error is present. Reading this code
/// clears the status byte."
#[test]
fn the_status_byte_is_read_in_decimal_and_any_nonzero_value_is_an_error() {
    assert_eq!(Command::Stb.to_bytes(), b"STB?\r\n");
    for (line, value, error) in [
        (&b"32"[..], 32, true),
        (b"00", 0, false),
        (b"0", 0, false),
        (b" 32 ", 32, true),
        // Never printed per the manuals, but safe: nonzero is an error in any base,
        // so the CS260's hexadecimal `20` (= 32) is still seen as one.
        (b"20", 20, true),
        (b"1", 1, true),
        (b"255", 255, true),
    ] {
        let Ok(Reply::Status(sb)) = Reply::parse(&Command::Stb, line) else {
            panic!("{line:?}")
        };
        assert_eq!(sb, StatusByte(value), "{line:?}");
        assert_eq!(sb.error(), error, "{line:?}");
    }
    // What the twin sends back: the manual's two answers, CR LF (§15.3).
    assert_eq!(Reply::Status(StatusByte(32)).to_bytes(), b"32\r\n");
    assert_eq!(Reply::Status(StatusByte(0)).to_bytes(), b"00\r\n");
}

/// `FILTER` per the Model 74000 table: "Acceptable values range from 1 through 6. The
/// response to FILTER? is the integer value describing the current filter position; if
/// there is no filter wheel connected, or if the wheel is out of position, 0 is
/// returned and an error is set in the status byte".
#[test]
fn the_filter_statements_and_the_no_wheel_answer() {
    assert_eq!(Command::Filter(1).to_bytes(), b"FILTER 1\r\n");
    assert_eq!(Command::Filter(6).to_bytes(), b"FILTER 6\r\n");
    assert_eq!(Command::FilterQuery.to_bytes(), b"FILTER?\r\n");
    assert_eq!(
        Reply::parse(&Command::FilterQuery, b"6"),
        Ok(Reply::Filter(6))
    );
    assert_eq!(
        Reply::parse(&Command::FilterQuery, b"0"),
        Ok(Reply::Filter(0))
    );
    assert_eq!(Reply::Filter(0).to_bytes(), b"0\r\n");
    assert_eq!(gonio_proto::cs130::MAX_FILTER_POSITION, 6);
    assert_eq!(gonio_proto::cs130::NO_FILTER_WHEEL, 0);
}

/// The other Model 74000 table entries Gonio relies on, byte for byte.
#[test]
fn the_model_74000_table_entries() {
    // "UNITS tt … NM for nanometers, UM for micrometers, WN for wavenumbers (cm-1)".
    assert_eq!(Command::parse(b"UNITS NM"), Ok(Command::Units(Units::Nm)));
    assert_eq!(Command::parse(b"UNITS UM"), Ok(Command::Units(Units::Um)));
    assert_eq!(Command::parse(b"UNITS WN"), Ok(Command::Units(Units::Wn)));
    // "The response to GRAT? contains three parameters separated by commas without
    // spaces. The first parameter is the grating number, then the lines/mm, then the
    // label for that grating".
    assert_eq!(
        Reply::parse(&Command::GratQuery, b"2,600,IR"),
        Ok(Reply::Grating {
            number: 2,
            lines_per_mm: Some(600),
            label: Some("IR".into())
        })
    );
    // "Closing the shutter requires "C", whereas opening it requires "O". The response
    // to SHUTTER? is simply the one character parameter".
    assert_eq!(Command::Shutter(false).to_bytes(), b"SHUTTER C\r\n");
    assert_eq!(
        Reply::parse(&Command::ShutterQuery, b"O"),
        Ok(Reply::Shutter(true))
    );
    // INFO? "Oriel, Model 74000 Cornerstone 130,SNXXX,VYY.YY.YY".
    let info = "Oriel, Model 74000 Cornerstone 130,SN123,V1.02.03";
    assert_eq!(
        Reply::parse(&Command::Info, info.as_bytes()),
        Ok(Reply::Info(info.into()))
    );
    // "ABORT Stops any wavelength motion immediately".
    assert_eq!(Command::Abort.to_bytes(), b"ABORT\r\n");
    assert_eq!(Command::parse(b"abort"), Ok(Command::Abort));
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
    assert_eq!(StatusByte::ERROR, 32);
    // Printed in decimal, as the Model 74000 table writes both answers.
    assert_eq!(StatusByte(32).to_string(), "32");
    assert_eq!(StatusByte(0).to_string(), "00");
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
        Reply::parse(&Command::Stb, b"256"),
        Err(ReplyError::BadValue)
    );
    assert_eq!(
        Reply::parse(&Command::Stb, b"2A"),
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
