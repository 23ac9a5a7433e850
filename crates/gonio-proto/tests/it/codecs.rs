//! Codec unit tests of the line families that need only the public API (moved out of
//! `src/` so that the source holds the codecs): statements and answers byte for byte,
//! refusals with the manuals' codes, the timing arithmetic.

mod cs130_command {
    use gonio_proto::cs130::{Command, Units};

    #[test]
    fn statements_encode_as_the_manual_writes_them() {
        assert_eq!(Command::GoWave(500.0).to_bytes(), b"GOWAVE 500\r\n");
        assert_eq!(Command::GoWave(587.1).to_bytes(), b"GOWAVE 587.1\r\n");
        assert_eq!(Command::GoWave(587.12349).to_bytes(), b"GOWAVE 587.123\r\n");
        assert_eq!(Command::Wave.to_bytes(), b"WAVE?\r\n");
        assert_eq!(Command::Shutter(true).to_bytes(), b"SHUTTER O\r\n");
        assert_eq!(Command::Shutter(false).to_bytes(), b"SHUTTER C\r\n");
        assert_eq!(Command::Grat(2).to_bytes(), b"GRAT 2\r\n");
        assert_eq!(Command::Filter(3).to_bytes(), b"FILTER 3\r\n");
        assert_eq!(Command::Units(Units::Nm).to_bytes(), b"UNITS NM\r\n");
        assert_eq!(Command::Wai.to_bytes(), b"*WAI\r\n");
    }

    #[test]
    fn parsing_ignores_case_and_extra_spaces_and_refuses_with_the_manual_codes() {
        assert_eq!(
            Command::parse(b"gowave   587.1 "),
            Ok(Command::GoWave(587.1))
        );
        assert_eq!(Command::parse(b"shutter o"), Ok(Command::Shutter(true)));
        assert_eq!(Command::parse(b"*wai"), Ok(Command::Wai));
        assert_eq!(Command::parse(b"Filter 4"), Ok(Command::Filter(4)));
        let e = Command::parse(b"GOWAVE").unwrap_err();
        assert_eq!(e.code(), 2);
        assert_eq!(Command::parse(b"GOWAVE nan").unwrap_err().code(), 2);
        assert_eq!(Command::parse(b"GRAT -1").unwrap_err().code(), 2);
        assert_eq!(Command::parse(b"WAVE? 3").unwrap_err().code(), 2);
        assert_eq!(Command::parse(b"GOWAV 500").unwrap_err().code(), 1);
    }

    #[test]
    fn units_convert_both_ways() {
        assert_eq!(Units::Um.to_nm(0.5), 500.0);
        assert_eq!(Units::Wn.to_nm(20_000.0), 500.0);
        assert_eq!(Units::Wn.from_nm(500.0), 20_000.0);
        assert_eq!(Units::Nm.from_nm(500.0), 500.0);
    }
}

mod cs130_reply {
    use gonio_proto::cs130::{Command, ErrorCode, Reply, ReplyError, StatusByte, is_echo};

    #[test]
    fn answers_parse_by_query() {
        assert_eq!(
            Reply::parse(&Command::Wave, b"500.01"),
            Ok(Reply::Wavelength(500.01))
        );
        assert_eq!(
            Reply::parse(&Command::Stb, b"00"),
            Ok(Reply::Status(StatusByte(0)))
        );
        // Decimal (§15.9, Model 74000 table): `32` after an error, `00` or `0` without.
        assert_eq!(
            Reply::parse(&Command::Stb, b"32"),
            Ok(Reply::Status(StatusByte(32)))
        );
        assert_eq!(
            Reply::parse(&Command::Stb, b"0"),
            Ok(Reply::Status(StatusByte(0)))
        );
        // The CS260's hexadecimal `20` is nonzero, so still an error.
        let Ok(Reply::Status(s)) = Reply::parse(&Command::Stb, b"20") else {
            panic!()
        };
        assert!(s.error());
        for not_a_byte in [&b"2A"[..], b"256", b"-1", b"3.2", b"", b"0032"] {
            assert_eq!(
                Reply::parse(&Command::Stb, not_a_byte),
                Err(ReplyError::BadValue),
                "{not_a_byte:?}"
            );
        }
        assert_eq!(
            Reply::parse(&Command::Error, b"3"),
            Ok(Reply::Error(ErrorCode::DESTINATION))
        );
        assert_eq!(
            Reply::parse(&Command::ShutterQuery, b"C"),
            Ok(Reply::Shutter(false))
        );
        assert_eq!(
            Reply::parse(&Command::GratQuery, b"2,600,IR"),
            Ok(Reply::Grating {
                number: 2,
                lines_per_mm: Some(600),
                label: Some("IR".into())
            })
        );
        assert_eq!(
            Reply::parse(&Command::GratQuery, b"1"),
            Ok(Reply::Grating {
                number: 1,
                lines_per_mm: None,
                label: None
            })
        );
        assert_eq!(
            Reply::parse(&Command::Wave, b"abc"),
            Err(ReplyError::BadValue)
        );
        assert_eq!(
            Reply::parse(&Command::Wave, b"inf"),
            Err(ReplyError::BadValue)
        );
        assert_eq!(
            Reply::parse(&Command::GoWave(1.0), b"1"),
            Err(ReplyError::NotAQuery)
        );
    }

    #[test]
    fn the_echo_is_the_statement_as_sent() {
        assert!(is_echo(&Command::GoWave(500.0), b"GOWAVE 500"));
        assert!(is_echo(&Command::GoWave(500.0), b"gowave 500 "));
        assert!(!is_echo(&Command::GoWave(500.0), b"GOWAVE 501"));
        assert!(!is_echo(&Command::Wave, b"500.01"));
    }

    #[test]
    fn answers_encode_as_parsed() {
        for (q, r) in [
            (Command::Wave, Reply::Wavelength(500.25)),
            (Command::FilterQuery, Reply::Filter(3)),
            (Command::Stb, Reply::Status(StatusByte(32))),
            (Command::Stb, Reply::Status(StatusByte(0))),
            (Command::Error, Reply::Error(ErrorCode(6))),
            (Command::Info, Reply::Info("CORNERSTONE 130 TWIN".into())),
        ] {
            let bytes = r.to_bytes();
            assert!(bytes.ends_with(b"\r\n"));
            assert_eq!(Reply::parse(&q, &bytes[..bytes.len() - 2]), Ok(r));
        }
        assert_eq!(Reply::Status(StatusByte(32)).to_bytes(), b"32\r\n");
        assert_eq!(Reply::Status(StatusByte(0)).to_bytes(), b"00\r\n");
        assert_eq!(Reply::Wavelength(500.0).to_bytes(), b"500.00\r\n");
    }
}

mod fw102c_command {
    use gonio_proto::fw102c::{Command, CommandError, SensorMode, Speed, TriggerMode};

    #[test]
    fn every_command_encodes_byte_exactly_and_parses_back() {
        let table: [(Command, &[u8]); 14] = [
            (Command::Identify, b"*idn?\r"),
            (Command::SetPosition(1), b"pos=1\r"),
            (Command::SetPosition(12), b"pos=12\r"),
            (Command::QueryPosition, b"pos?\r"),
            (Command::SetPositionCount(6), b"pcount=6\r"),
            (Command::QueryPositionCount, b"pcount?\r"),
            (Command::SetSpeed(Speed::Low), b"speed=0\r"),
            (Command::SetSpeed(Speed::High), b"speed=1\r"),
            (Command::QuerySpeed, b"speed?\r"),
            (Command::SetTrigger(TriggerMode::Output), b"trig=1\r"),
            (Command::QueryTrigger, b"trig?\r"),
            (Command::SetSensors(SensorMode::OffWhenIdle), b"sensors=0\r"),
            (Command::QuerySensors, b"sensors?\r"),
            (Command::Save, b"save\r"),
        ];
        for (c, bytes) in table {
            assert_eq!(c.to_bytes(), bytes, "{c:?}");
            assert_eq!(Command::parse(&bytes[..bytes.len() - 1]), Ok(c));
        }
    }

    #[test]
    fn the_wheel_refuses_what_it_does_not_know() {
        use CommandError::*;
        for (line, e) in [
            (&b""[..], NotDefined),
            (b"move=3", NotDefined),
            (b"pos", NotDefined),
            (b"pos=0", ArgInvalid),
            (b"pos=", ArgInvalid),
            (b"pos=-1", ArgInvalid),
            (b"pos=x", ArgInvalid),
            (b"pos=999", ArgInvalid),
            (b"pcount=7", ArgInvalid),
            (b"speed=2", ArgInvalid),
            (b"sensors=1.0", ArgInvalid),
            (b"\xff", NotDefined),
        ] {
            assert_eq!(Command::parse(line), Err(e), "{line:?}");
        }
        assert_eq!(Command::parse(b" POS=4 "), Ok(Command::SetPosition(4)));
    }
}

mod sr830_command {
    use gonio_proto::sr830::{CommandError, EventStatus};

    #[test]
    fn command_errors_name_their_status_bit() {
        assert_eq!(
            CommandError::Unknown("X".into()).event_status(),
            EventStatus(32)
        );
        assert_eq!(CommandError::Syntax("SENS").bit(), 5);
        assert_eq!(
            CommandError::OutOfRange("SENS").event_status(),
            EventStatus(16)
        );
    }
}

mod sr830_timing {
    use gonio_proto::sr830::Sr830Config;
    use gonio_proto::sr830::timing::{lia_status_s, snapshot_s};

    #[test]
    fn a_cycle_is_its_settling_its_snapshots_and_their_exchanges() {
        let c = Sr830Config {
            samples: 10,
            ..Sr830Config::default()
        }
        .with_baud(9600);
        // `LIAS?\n` and `0\r`: 8 bytes and the 5 ms; `SNAP? 1,2\n` and
        // `0.00123456,-2.34567e-5\r`: 33 bytes and the 5 ms.
        assert!((lia_status_s(9600) - (0.005 + 80.0 / 9600.0)).abs() < 1e-12);
        assert!((snapshot_s(9600) - (0.005 + 330.0 / 9600.0)).abs() < 1e-12);
        let tc = c.time_constant;
        let expected = 7.0 * 0.1 + 2.0 * lia_status_s(9600) + 10.0 * snapshot_s(9600) + 0.9;
        assert!(
            (c.cycle_s(tc) - expected).abs() < 1e-12,
            "{}",
            c.cycle_s(tc)
        );
    }
}

mod timing {
    use gonio_proto::timing::{exchange_s, wire_s};

    #[test]
    fn bytes_take_ten_bits_each() {
        // `1TP\r\n` at 57 600 baud: 50 bits.
        assert!((wire_s(5, 57_600) - 50.0 / 57_600.0).abs() < 1e-15);
        // A query: both ways and the latency; a command: its bytes alone.
        assert!((exchange_s(6, 2, 9600, 0.005) - (0.005 + 80.0 / 9600.0)).abs() < 1e-15);
        assert_eq!(exchange_s(6, 0, 9600, 0.005), wire_s(6, 9600));
    }
}

mod fw102c_fuzz {
    use gonio_proto::fw102c::{Command, fuzz};
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn parsers_never_panic(data in proptest::collection::vec(any::<u8>(), 0..64)) {
            fuzz::fuzz_parse_line(&data);
            fuzz::fuzz_parse_reply(&data);
        }

        #[test]
        fn positions_round_trip(n in 1u8..=255) {
            let c = Command::SetPosition(n);
            let bytes = c.to_bytes();
            prop_assert_eq!(Command::parse(&bytes[..bytes.len() - 1]), Ok(c));
        }
    }
}

mod fw102c_reply {
    use gonio_proto::fw102c::{
        Command, DeviceError, ErrorCode, Line, Reply, ReplyError, SensorMode, Speed, strip_prompt,
    };

    #[test]
    fn the_prompt_is_stripped_from_the_next_line() {
        assert_eq!(strip_prompt(b"> pos?"), b"pos?");
        assert_eq!(strip_prompt(b">> > 3\n"), b"3");
        assert_eq!(strip_prompt(b">"), b"");
        assert_eq!(Line::classify(b"> "), Line::Blank);
        assert_eq!(Line::classify(b"> pos=2"), Line::Text(b"pos=2"));
        assert_eq!(
            Line::classify(b"Command error CMD_ARG_INVALID"),
            Line::Error(DeviceError {
                code: ErrorCode::ArgInvalid
            })
        );
        assert_eq!(
            Line::classify(b"> Command error CMD_NOT_DEFINED"),
            Line::Error(DeviceError {
                code: ErrorCode::NotDefined
            })
        );
        assert_eq!(
            Line::classify(b"Command error CMD_BUSY"),
            Line::Error(DeviceError {
                code: ErrorCode::Other("CMD_BUSY".into())
            })
        );
    }

    #[test]
    fn error_lines_encode_as_parsed() {
        for code in [ErrorCode::NotDefined, ErrorCode::ArgInvalid] {
            let mut out = Vec::new();
            DeviceError { code: code.clone() }.encode(&mut out);
            let line = out.strip_suffix(b"\r").unwrap();
            assert_eq!(DeviceError::parse(line), Some(DeviceError { code }));
        }
        let mut out = Vec::new();
        DeviceError {
            code: ErrorCode::ArgInvalid,
        }
        .encode(&mut out);
        assert_eq!(out, b"Command error CMD_ARG_INVALID\r");
    }

    #[test]
    fn values_parse_by_query() {
        let idn = b"THORLABS FW102C/FW212C Filter Wheel version 1.04";
        assert_eq!(
            Reply::parse(&Command::Identify, idn),
            Ok(Reply::Identity(String::from_utf8_lossy(idn).into()))
        );
        assert_eq!(
            Reply::parse(&Command::QueryPosition, b"12"),
            Ok(Reply::Position(12))
        );
        assert_eq!(
            Reply::parse(&Command::QueryPosition, b"0"),
            Err(ReplyError::BadValue)
        );
        assert_eq!(
            Reply::parse(&Command::QueryPosition, b"2.0"),
            Err(ReplyError::BadValue)
        );
        assert_eq!(
            Reply::parse(&Command::QueryPositionCount, b"6"),
            Ok(Reply::PositionCount(6))
        );
        assert_eq!(
            Reply::parse(&Command::QuerySpeed, b"0"),
            Ok(Reply::Speed(Speed::Low))
        );
        assert_eq!(
            Reply::parse(&Command::QuerySpeed, b"2"),
            Err(ReplyError::BadValue)
        );
        assert_eq!(
            Reply::parse(&Command::QuerySensors, b"0"),
            Ok(Reply::Sensors(SensorMode::OffWhenIdle))
        );
        assert_eq!(
            Reply::parse(&Command::SetPosition(2), b"2"),
            Err(ReplyError::NotAQuery)
        );
        assert_eq!(Reply::Position(7).to_bytes(), b"7\r");
    }
}
