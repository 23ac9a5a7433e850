//! The SR830 codec against the manual's exchanges (instruments.md §2.4, §2.5, §2.7)
//! byte for byte, the full SENS and OFLT tables, and property tests: every command and
//! reply survives encode → parse, and no input makes a parser panic.

use gonio_proto::sr830::{
    self, BitIndex, Command, CommandError, ErrorStatus, EventStatus, FilterSlope, Identity,
    Interface, LiaStatus, Output, ReferenceSource, Reply, ReplyError, Sensitivity, SnapParam,
    SnapParams, TimeConstant, fuzz,
};
use proptest::prelude::*;

fn snap(p: &[u8]) -> Command {
    let params: Vec<SnapParam> = p
        .iter()
        .map(|c| SnapParam::from_code(*c).expect("SNAP? code"))
        .collect();
    Command::Snap(SnapParams::new(&params).expect("2 to 6 codes"))
}

fn sens(i: u8) -> Sensitivity {
    Sensitivity::new(i).expect("SENS index")
}

fn tc(i: u8) -> TimeConstant {
    TimeConstant::new(i).expect("OFLT index")
}

/// One host line: the parser reads it as `commands`, and `encode_line` writes exactly
/// `line` + `\n` back from them.
pub(crate) fn host_line(line: &str, commands: &[Command]) {
    let parsed: Vec<Command> = sr830::parse_line(line.as_bytes())
        .into_iter()
        .collect::<Result<_, _>>()
        .unwrap_or_else(|e| panic!("{line:?}: {e}"));
    assert_eq!(parsed, commands, "{line:?}");
    let mut out = Vec::new();
    sr830::encode_line(commands, &mut out);
    assert_eq!(out, format!("{line}\n").as_bytes());
}

/// One reply: `text` parses as `reply` to `command`, and encodes back to `text` + `\r`.
fn reply_line(command: &Command, text: &str, reply: Reply) {
    assert_eq!(
        Reply::parse(command, text.as_bytes()),
        Ok(reply.clone()),
        "{text:?}"
    );
    assert_eq!(reply.to_bytes(), format!("{text}\r").as_bytes());
}

#[test]
fn constants() {
    assert_eq!(sr830::TERMINATOR, b"\n");
    assert_eq!(sr830::REPLY_TERMINATOR, b'\r');
    assert_eq!(sr830::MAX_LINE, 256);
}

#[test]
fn start_up_transcript() {
    // → OUTX 0 (no reply; must come first)
    host_line("OUTX 0", &[Command::SetInterface(Interface::Rs232)]);
    assert!(!Command::SetInterface(Interface::Rs232).expects_reply());
    assert_eq!(
        Command::SetInterface(Interface::Rs232).to_bytes(),
        b"OUTX 0\n"
    );

    // → *IDN?  ← Stanford_Research_Systems,SR830,s/n00111,ver1.000
    host_line("*IDN?", &[Command::Identify]);
    assert!(Command::Identify.expects_reply());
    let id = Identity {
        manufacturer: "Stanford_Research_Systems".into(),
        model: "SR830".into(),
        serial: "s/n00111".into(),
        firmware: "ver1.000".into(),
    };
    assert!(id.is_sr830());
    reply_line(
        &Command::Identify,
        "Stanford_Research_Systems,SR830,s/n00111,ver1.000",
        Reply::Identity(id),
    );

    // → *CLS (no reply)
    host_line("*CLS", &[Command::Clear]);
    assert!(!Command::Clear.expects_reply());

    // → SENS?;OFLT?;OFSL?  ← 26 ← 8 ← 1: the *RST defaults 1 V, 100 ms, 12 dB/oct.
    let queries = [
        Command::QuerySensitivity,
        Command::QueryTimeConstant,
        Command::QuerySlope,
    ];
    host_line("SENS?;OFLT?;OFSL?", &queries);
    reply_line(&queries[0], "26", Reply::Sensitivity(Sensitivity::LEAST));
    reply_line(&queries[1], "8", Reply::TimeConstant(tc(8)));
    reply_line(&queries[2], "1", Reply::Slope(FilterSlope::Db12));
    assert_eq!(Sensitivity::LEAST.volts(), 1.0);
    assert_eq!(tc(8).seconds(), 0.1);

    // → FMOD 1;FREQ 1000;SLVL 0.5;SENS 20;OFLT 9;OFSL 3 (no reply)
    let setup = [
        Command::SetReferenceSource(ReferenceSource::Internal),
        Command::SetFrequency(1000.0),
        Command::SetAmplitude(0.5),
        Command::SetSensitivity(sens(20)),
        Command::SetTimeConstant(tc(9)),
        Command::SetSlope(FilterSlope::Db24),
    ];
    host_line("FMOD 1;FREQ 1000;SLVL 0.5;SENS 20;OFLT 9;OFSL 3", &setup);
    assert!(setup.iter().all(|c| !c.expects_reply()));

    // → *ESR?  ← 0
    host_line("*ESR?", &[Command::EventStatus(None)]);
    reply_line(
        &Command::EventStatus(None),
        "0",
        Reply::EventStatus(EventStatus(0)),
    );
}

#[test]
fn read_cycle_transcript() {
    // → LIAS?  ← 0
    host_line("LIAS?", &[Command::LiaStatus(None)]);
    reply_line(
        &Command::LiaStatus(None),
        "0",
        Reply::LiaStatus(LiaStatus(0)),
    );

    // → SNAP? 1,2  ← 0.951359,0.0253297
    let xy = snap(&[1, 2]);
    host_line("SNAP? 1,2", std::slice::from_ref(&xy));
    assert_eq!(xy.to_bytes(), b"SNAP? 1,2\n");
    reply_line(
        &xy,
        "0.951359,0.0253297",
        Reply::Snap(vec![0.951359, 0.0253297]),
    );

    // → OUTP? 3  ← 0.951696
    host_line("OUTP? 3", &[Command::ReadOutput(Output::R)]);
    reply_line(
        &Command::ReadOutput(Output::R),
        "0.951696",
        Reply::Output(0.951696),
    );

    // → LIAS?  ← 4: bit 2, output overload.
    let Ok(Reply::LiaStatus(s)) = Reply::parse(&Command::LiaStatus(None), b"4") else {
        panic!("LIAS? reply");
    };
    assert!(s.output_overload());
    assert!(!s.input_overload() && !s.filter_overload() && !s.unlocked());
    assert_eq!(s.to_string(), "OUTPT");
}

#[test]
fn command_reference_examples() {
    // SNAP?1,2,9,5 ← 0.951359,0.0253297,1000.00,1.234 (X, Y, frequency, Aux In 1).
    let cmd = sr830::parse_line(b"SNAP?1,2,9,5");
    let four = snap(&[1, 2, 9, 5]);
    assert_eq!(cmd, vec![Ok(four.clone())]);
    assert_eq!(four.to_bytes(), b"SNAP? 1,2,9,5\n");
    assert_eq!(
        Reply::parse(&four, b"0.951359,0.0253297,1000.00,1.234"),
        Ok(Reply::Snap(vec![0.951359, 0.0253297, 1000.0, 1.234]))
    );
    // PyMeasure's fixture: exponent with three digits.
    assert_eq!(
        Reply::parse(&snap(&[1, 2]), b"-4.17234e-007,-5.9605e-007"),
        Ok(Reply::Snap(vec![-4.17234e-7, -5.9605e-7]))
    );
    // OUTP? example, and the TRCA exponent form.
    assert_eq!(
        Reply::parse(&Command::ReadOutput(Output::X), b"-1.01026"),
        Ok(Reply::Output(-1.01026))
    );
    assert_eq!(
        Reply::parse(&Command::ReadOutput(Output::Y), b"-1.234567e-009"),
        Ok(Reply::Output(-1.234567e-9))
    );
    // A real unit's *IDN?.
    let Ok(Reply::Identity(id)) = Reply::parse(
        &Command::Identify,
        b"Stanford_Research_Systems,SR830,s/n55581,ver1.07",
    ) else {
        panic!("*IDN?");
    };
    assert_eq!(
        (id.serial.as_str(), id.firmware.as_str()),
        ("s/n55581", "ver1.07")
    );
    // Status and enumerated replies are bare integers.
    let Ok(Reply::LiaStatus(s)) = Reply::parse(&Command::LiaStatus(None), b"3") else {
        panic!("LIAS?");
    };
    assert!(s.input_overload() && s.filter_overload() && !s.output_overload());
    assert_eq!(
        Reply::parse(&Command::QuerySensitivity, b"19"),
        Ok(Reply::Sensitivity(sens(19)))
    );
    assert_eq!(
        Reply::parse(&Command::QueryTimeConstant, b"10"),
        Ok(Reply::TimeConstant(tc(10)))
    );
    // Canonical forms of the remaining commands.
    for (c, bytes) in [
        (Command::QueryInterface, "OUTX?\n"),
        (Command::SetInterface(Interface::Gpib), "OUTX 1\n"),
        (Command::SetSensitivity(sens(20)), "SENS 20\n"),
        (Command::QuerySensitivity, "SENS?\n"),
        (Command::SetTimeConstant(tc(19)), "OFLT 19\n"),
        (Command::SetSlope(FilterSlope::Db6), "OFSL 0\n"),
        (Command::AutoGain, "AGAN\n"),
        (Command::LiaStatus(BitIndex::new(2)), "LIAS? 2\n"),
        (Command::ErrorStatus(None), "ERRS?\n"),
        (Command::EventStatus(BitIndex::new(5)), "*ESR? 5\n"),
        (Command::Reset, "*RST\n"),
        (Command::QueryFrequency, "FREQ?\n"),
        (snap(&[1, 2, 3, 4, 10, 11]), "SNAP? 1,2,3,4,10,11\n"),
    ] {
        assert_eq!(String::from_utf8(c.to_bytes()).unwrap(), bytes);
        assert_eq!(Command::parse(bytes.trim_end().as_bytes()), Ok(c));
    }
}

#[test]
fn syntax_is_case_and_space_insensitive_and_numbers_take_any_form() {
    let s20 = Ok(Command::SetSensitivity(sens(20)));
    for line in [
        "SENS 20",
        "sens 20",
        "SeNs20",
        " S E N S 2 0 ",
        "SENS 20.0",
        "SENS .2E2",
        "SENS 2e1",
        "SENS\t+20",
    ] {
        assert_eq!(Command::parse(line.as_bytes()), s20, "{line:?}");
    }
    assert_eq!(
        Command::parse(b"OFSL .3E1"),
        Ok(Command::SetSlope(FilterSlope::Db24))
    );
    assert_eq!(
        Command::parse(b"outp?3"),
        Ok(Command::ReadOutput(Output::R))
    );
    assert_eq!(Command::parse(b"*idn?"), Ok(Command::Identify));
    assert_eq!(
        Command::parse(b"lias ? 2"),
        Ok(Command::LiaStatus(BitIndex::new(2)))
    );
    // Empty commands between separators are skipped; \r inside a line also ends a command.
    assert_eq!(
        sr830::parse_line(b";SENS?;;OFLT?\rOFSL?;"),
        vec![
            Ok(Command::QuerySensitivity),
            Ok(Command::QueryTimeConstant),
            Ok(Command::QuerySlope)
        ]
    );
    assert!(sr830::parse_line(b"").is_empty());
    assert!(sr830::parse_line(b"  ;  ").is_empty());
}

#[test]
fn refused_commands_name_the_status_bit() {
    let bit = |line: &str| Command::parse(line.as_bytes()).unwrap_err().bit();
    // Illegal: CMD, bit 5.
    for line in [
        "FOO?",
        "SEN",
        "",
        "SENS",
        "SENS? 3",
        "SENS x",
        "SENS 1,2",
        "AGAN?",
        "OUTP 1",
        "OUTP?",
        "SNAP? 1",
        "SNAP? 1,2,3,4,5,6,7",
        "SNAP 1,2",
        "*IDN",
        "*RST?",
        "LIAS",
        "SENS 1,",
    ] {
        assert_eq!(bit(line), 5, "{line:?}");
    }
    assert_eq!(
        Command::parse(b"foo?"),
        Err(CommandError::Unknown("FOO?".into()))
    );
    // Out of range or not executable: EXE, bit 4.
    for line in [
        "SENS 27",
        "SENS -1",
        "SENS 2.5",
        "OFLT 20",
        "OFSL 4",
        "OUTX 2",
        "OUTP? 0",
        "OUTP? 5",
        "SNAP? 1,12",
        "SNAP? 0,1",
        "LIAS? 8",
        "FREQ 0.0001",
        "FREQ 102001",
        "SLVL 0.003",
        "SLVL 5.001",
        "FMOD 2",
        "SENS 1e9",
    ] {
        assert_eq!(bit(line), 4, "{line:?}");
    }
    assert_eq!(
        Command::parse(b"SENS 27").unwrap_err().event_status(),
        EventStatus(EventStatus::EXE)
    );
    // A bad command in a line fails alone; the others still parse.
    assert_eq!(
        sr830::parse_line(b"SENS 20;BOGUS;OFLT 30"),
        vec![
            Ok(Command::SetSensitivity(sens(20))),
            Err(CommandError::Unknown("BOGUS".into())),
            Err(CommandError::OutOfRange("OFLT")),
        ]
    );
}

#[test]
fn sensitivity_table() {
    let table: [(f64, &str); 27] = [
        (2e-9, "2 nV"),
        (5e-9, "5 nV"),
        (10e-9, "10 nV"),
        (20e-9, "20 nV"),
        (50e-9, "50 nV"),
        (100e-9, "100 nV"),
        (200e-9, "200 nV"),
        (500e-9, "500 nV"),
        (1e-6, "1 µV"),
        (2e-6, "2 µV"),
        (5e-6, "5 µV"),
        (10e-6, "10 µV"),
        (20e-6, "20 µV"),
        (50e-6, "50 µV"),
        (100e-6, "100 µV"),
        (200e-6, "200 µV"),
        (500e-6, "500 µV"),
        (1e-3, "1 mV"),
        (2e-3, "2 mV"),
        (5e-3, "5 mV"),
        (10e-3, "10 mV"),
        (20e-3, "20 mV"),
        (50e-3, "50 mV"),
        (100e-3, "100 mV"),
        (200e-3, "200 mV"),
        (500e-3, "500 mV"),
        (1.0, "1 V"),
    ];
    assert_eq!(Sensitivity::all().count(), 27);
    for (s, (volts, label)) in Sensitivity::all().zip(table) {
        let i = s.index();
        assert_eq!(s.volts(), volts, "SENS {i}");
        assert_eq!(s.to_string(), label, "SENS {i}");
        assert_eq!(label.parse::<Sensitivity>(), Ok(s));
        assert_eq!(
            s.less_sensitive().map(Sensitivity::index),
            (i < 26).then_some(i + 1)
        );
        assert_eq!(s.more_sensitive().map(Sensitivity::index), i.checked_sub(1));
    }
    assert_eq!(sens(0).volts(), 2e-9);
    assert_eq!(sens(26).volts(), 1.0);
    assert_eq!(Sensitivity::new(27), None);
    assert_eq!(Sensitivity::MOST, sens(0));
    assert_eq!("10mV".parse::<Sensitivity>(), Ok(sens(20)));
    assert_eq!("5 uV".parse::<Sensitivity>(), Ok(sens(10)));
    assert!("11 mV".parse::<Sensitivity>().is_err());
    assert!("10 MV".parse::<Sensitivity>().is_err());
}

#[test]
fn time_constant_table() {
    let table: [(f64, &str); 20] = [
        (10e-6, "10 µs"),
        (30e-6, "30 µs"),
        (100e-6, "100 µs"),
        (300e-6, "300 µs"),
        (1e-3, "1 ms"),
        (3e-3, "3 ms"),
        (10e-3, "10 ms"),
        (30e-3, "30 ms"),
        (100e-3, "100 ms"),
        (300e-3, "300 ms"),
        (1.0, "1 s"),
        (3.0, "3 s"),
        (10.0, "10 s"),
        (30.0, "30 s"),
        (100.0, "100 s"),
        (300.0, "300 s"),
        (1e3, "1 ks"),
        (3e3, "3 ks"),
        (10e3, "10 ks"),
        (30e3, "30 ks"),
    ];
    assert_eq!(TimeConstant::all().count(), 20);
    for (t, (seconds, label)) in TimeConstant::all().zip(table) {
        assert_eq!(t.seconds(), seconds, "OFLT {}", t.index());
        assert_eq!(t.to_string(), label);
        assert_eq!(label.parse::<TimeConstant>(), Ok(t));
    }
    assert_eq!(tc(8).seconds(), 0.1);
    assert_eq!(tc(19).seconds(), 30_000.0);
    assert_eq!(TimeConstant::new(20), None);
}

#[test]
fn defaults_are_the_reset_state() {
    // *RST: SENS 26, OFLT 8, OFSL 1 (p. 4-4).
    assert_eq!(Sensitivity::default(), sens(26));
    assert_eq!(TimeConstant::default(), tc(8));
    assert_eq!(FilterSlope::default(), FilterSlope::Db12);
    assert_eq!(
        SnapParams::XY,
        SnapParams::new(&[SnapParam::X, SnapParam::Y]).unwrap()
    );
    assert_eq!(SnapParams::XY.as_slice(), &[SnapParam::X, SnapParam::Y]);
    assert_eq!(SnapParams::new(&[SnapParam::X]), None);
    assert_eq!(SnapParams::new(&[SnapParam::X; 7]), None);
}

#[test]
fn slopes_settle_and_bandwidth() {
    let t = tc(8); // 100 ms
    let table = [
        (FilterSlope::Db6, 0, 6, 5.0, 1.0 / (4.0 * 0.1)),
        (FilterSlope::Db12, 1, 12, 7.0, 1.0 / (8.0 * 0.1)),
        (FilterSlope::Db18, 2, 18, 9.0, 3.0 / (32.0 * 0.1)),
        (FilterSlope::Db24, 3, 24, 10.0, 5.0 / (64.0 * 0.1)),
    ];
    for (s, index, db, factor, enbw) in table {
        assert_eq!(s.index(), index);
        assert_eq!(FilterSlope::from_index(index), Some(s));
        assert_eq!(s.db_per_octave(), db);
        assert_eq!(FilterSlope::from_db(db), Some(s));
        assert_eq!(s.settle_factor(), factor);
        assert!((s.settle_seconds(t) - factor * 0.1).abs() < 1e-15);
        assert!((s.enbw_hz(t) - enbw).abs() < 1e-12, "{s}");
    }
    assert_eq!(FilterSlope::Db24.settle_seconds(t), 1.0);
    assert_eq!(FilterSlope::Db6.enbw_hz(t), 2.5);
    assert_eq!(FilterSlope::from_index(4), None);
    assert_eq!(FilterSlope::from_db(30), None);
    assert_eq!(FilterSlope::Db18.to_string(), "18 dB/oct");
}

#[test]
fn status_bytes_name_their_bits() {
    let masks = [
        (LiaStatus::INPUT_OVERLOAD, 1),
        (LiaStatus::FILTER_OVERLOAD, 2),
        (LiaStatus::OUTPUT_OVERLOAD, 4),
        (LiaStatus::UNLOCK, 8),
        (LiaStatus::RANGE, 16),
        (LiaStatus::TIME_CONSTANT_CHANGED, 32),
        (LiaStatus::TRIGGERED, 64),
    ];
    for (m, v) in masks {
        assert_eq!(m, v);
    }
    assert_eq!(LiaStatus(13).to_string(), "INPUT/RESRV|OUTPT|UNLK");
    assert_eq!(LiaStatus(0).to_string(), "none");
    assert_eq!(LiaStatus(128).to_string(), "0x80");
    assert!(LiaStatus(8).unlocked() && LiaStatus(0).is_empty());

    let esr = [
        (EventStatus::INP, 1),
        (EventStatus::QRY, 4),
        (EventStatus::EXE, 16),
        (EventStatus::CMD, 32),
        (EventStatus::URQ, 64),
        (EventStatus::PON, 128),
    ];
    for (m, v) in esr {
        assert_eq!(m, v);
    }
    assert!(EventStatus(16).has_command_error());
    assert!(EventStatus(32).has_command_error());
    assert!(!EventStatus(64 | 128 | 1).has_command_error());
    assert_eq!(EventStatus(48).to_string(), "EXE|CMD");

    let errs = [
        (ErrorStatus::BACKUP, 2),
        (ErrorStatus::RAM, 4),
        (ErrorStatus::ROM, 16),
        (ErrorStatus::GPIB, 32),
        (ErrorStatus::DSP, 64),
        (ErrorStatus::MATH, 128),
    ];
    for (m, v) in errs {
        assert_eq!(m, v);
    }
    assert_eq!(
        Reply::parse(&Command::ErrorStatus(None), b"6"),
        Ok(Reply::ErrorStatus(ErrorStatus(6)))
    );
    assert_eq!(
        Reply::parse(&Command::LiaStatus(BitIndex::new(3)), b"1"),
        Ok(Reply::Bit(true))
    );
}

#[test]
fn malformed_replies_are_typed_errors() {
    let xy = snap(&[1, 2]);
    assert_eq!(Reply::parse(&xy, b""), Err(ReplyError::Empty));
    assert_eq!(
        Reply::parse(&xy, b"0.951359"),
        Err(ReplyError::WrongCount {
            expected: 2,
            got: 1
        })
    );
    assert_eq!(Reply::parse(&xy, b"0.951359,"), Err(ReplyError::BadValue));
    assert_eq!(Reply::parse(&xy, b"0.95#359,1"), Err(ReplyError::BadValue));
    assert_eq!(
        Reply::parse(&Command::QuerySensitivity, b"27"),
        Err(ReplyError::OutOfRange(27.0))
    );
    assert_eq!(
        Reply::parse(&Command::QuerySensitivity, b"2.5"),
        Err(ReplyError::BadValue)
    );
    assert_eq!(
        Reply::parse(&Command::LiaStatus(None), b"256"),
        Err(ReplyError::OutOfRange(256.0))
    );
    assert_eq!(
        Reply::parse(&Command::Identify, b"Stanford_Research_Systems,SR830"),
        Err(ReplyError::BadValue)
    );
    assert_eq!(
        Reply::parse(&Command::ReadOutput(Output::R), b"inf"),
        Err(ReplyError::BadValue)
    );
    assert_eq!(
        Reply::parse(&Command::SetSensitivity(sens(3)), b"3"),
        Err(ReplyError::NotAQuery("SENS"))
    );
    // Whitespace around a reply is tolerated.
    assert_eq!(
        Reply::parse(&Command::QuerySlope, b" 3 "),
        Ok(Reply::Slope(FilterSlope::Db24))
    );
}

fn any_bit() -> impl Strategy<Value = Option<BitIndex>> {
    prop::option::of((0u8..8).prop_map(|b| BitIndex::new(b).expect("bit 0..8")))
}

fn any_snap_params() -> impl Strategy<Value = SnapParams> {
    prop::collection::vec(prop::sample::select(SnapParam::ALL.to_vec()), 2..=6)
        .prop_map(|v| SnapParams::new(&v).expect("2..=6 entries"))
}

fn any_command() -> impl Strategy<Value = Command> {
    prop_oneof![
        prop::bool::ANY.prop_map(|g| Command::SetInterface(if g {
            Interface::Gpib
        } else {
            Interface::Rs232
        })),
        Just(Command::QueryInterface),
        prop::bool::ANY.prop_map(|i| Command::SetReferenceSource(if i {
            ReferenceSource::Internal
        } else {
            ReferenceSource::External
        })),
        Just(Command::QueryReferenceSource),
        (0.001..=102_000.0f64).prop_map(Command::SetFrequency),
        Just(Command::QueryFrequency),
        (0.004..=5.0f64).prop_map(Command::SetAmplitude),
        Just(Command::QueryAmplitude),
        (0u8..27).prop_map(|i| Command::SetSensitivity(sens(i))),
        Just(Command::QuerySensitivity),
        (0u8..20).prop_map(|i| Command::SetTimeConstant(tc(i))),
        Just(Command::QueryTimeConstant),
        prop::sample::select(FilterSlope::ALL.to_vec()).prop_map(Command::SetSlope),
        Just(Command::QuerySlope),
        Just(Command::AutoGain),
        prop::sample::select(Output::ALL.to_vec()).prop_map(Command::ReadOutput),
        any_snap_params().prop_map(Command::Snap),
        any_bit().prop_map(Command::LiaStatus),
        any_bit().prop_map(Command::ErrorStatus),
        any_bit().prop_map(Command::EventStatus),
        Just(Command::Identify),
        Just(Command::Reset),
        Just(Command::Clear),
    ]
}

/// A float as the instrument might return it: any magnitude, sign, or zero.
fn any_value() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1e3..1e3f64,
        prop::num::f64::NORMAL | prop::num::f64::SUBNORMAL | prop::num::f64::ZERO,
    ]
}

fn field() -> impl Strategy<Value = String> {
    "[!-+\\--~]([ !-+\\--~]{0,20}[!-+\\--~])?"
}

/// A query and a reply it can get.
fn any_query_reply() -> impl Strategy<Value = (Command, Reply)> {
    prop_oneof![
        prop::bool::ANY.prop_map(|g| (
            Command::QueryInterface,
            Reply::Interface(if g { Interface::Gpib } else { Interface::Rs232 })
        )),
        prop::bool::ANY.prop_map(|i| (
            Command::QueryReferenceSource,
            Reply::ReferenceSource(if i {
                ReferenceSource::Internal
            } else {
                ReferenceSource::External
            })
        )),
        any_value().prop_map(|v| (Command::QueryFrequency, Reply::Frequency(v))),
        any_value().prop_map(|v| (Command::QueryAmplitude, Reply::Amplitude(v))),
        (0u8..27).prop_map(|i| (Command::QuerySensitivity, Reply::Sensitivity(sens(i)))),
        (0u8..20).prop_map(|i| (Command::QueryTimeConstant, Reply::TimeConstant(tc(i)))),
        prop::sample::select(FilterSlope::ALL.to_vec())
            .prop_map(|s| (Command::QuerySlope, Reply::Slope(s))),
        (prop::sample::select(Output::ALL.to_vec()), any_value())
            .prop_map(|(o, v)| (Command::ReadOutput(o), Reply::Output(v))),
        any_snap_params().prop_flat_map(|p| {
            prop::collection::vec(any_value(), p.as_slice().len())
                .prop_map(move |v| (Command::Snap(p), Reply::Snap(v)))
        }),
        any::<u8>().prop_map(|b| (Command::LiaStatus(None), Reply::LiaStatus(LiaStatus(b)))),
        any::<u8>().prop_map(|b| (
            Command::ErrorStatus(None),
            Reply::ErrorStatus(ErrorStatus(b))
        )),
        any::<u8>().prop_map(|b| (
            Command::EventStatus(None),
            Reply::EventStatus(EventStatus(b))
        )),
        (0u8..8, any::<bool>())
            .prop_map(|(i, b)| (Command::EventStatus(BitIndex::new(i)), Reply::Bit(b))),
        (field(), field(), field(), field()).prop_map(|(a, b, c, d)| (
            Command::Identify,
            Reply::Identity(Identity {
                manufacturer: a,
                model: b,
                serial: c,
                firmware: d
            })
        )),
    ]
}

/// Inserts spaces at random positions and randomises letter case, as a sloppy host might.
fn mangle(bytes: &[u8], spaces: &[bool], upper: &[bool]) -> Vec<u8> {
    let mut out = Vec::new();
    for (k, b) in bytes.iter().enumerate() {
        if spaces.get(k).copied().unwrap_or(false) {
            out.push(b' ');
        }
        let up = upper.get(k).copied().unwrap_or(true);
        out.push(if up {
            b.to_ascii_uppercase()
        } else {
            b.to_ascii_lowercase()
        });
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn commands_round_trip(c in any_command()) {
        let bytes = c.to_bytes();
        prop_assert!(bytes.ends_with(b"\n"));
        prop_assert!(bytes.len() <= sr830::MAX_LINE);
        let body = &bytes[..bytes.len() - 1];
        prop_assert_eq!(Command::parse(body), Ok(c.clone()));
        prop_assert_eq!(sr830::parse_line(body), vec![Ok(c.clone())]);
        prop_assert_eq!(c.expects_reply(), body.contains(&b'?'));
    }

    #[test]
    fn lines_of_commands_round_trip(cs in prop::collection::vec(any_command(), 1..6)) {
        let mut line = Vec::new();
        sr830::encode_line(&cs, &mut line);
        let parsed: Vec<_> = sr830::parse_line(&line).into_iter().collect::<Result<_, _>>().unwrap();
        prop_assert_eq!(parsed, cs);
    }

    #[test]
    fn case_and_spaces_do_not_matter(
        c in any_command(),
        spaces in prop::collection::vec(any::<bool>(), 40),
        upper in prop::collection::vec(any::<bool>(), 40),
    ) {
        let mut body = Vec::new();
        c.encode_body(&mut body);
        prop_assert_eq!(Command::parse(&mangle(&body, &spaces, &upper)), Ok(c));
    }

    #[test]
    fn replies_round_trip((c, r) in any_query_reply()) {
        let bytes = r.to_bytes();
        prop_assert!(bytes.ends_with(b"\r"));
        prop_assert!(bytes.len() <= sr830::MAX_LINE, "{} bytes", bytes.len());
        prop_assert_eq!(Reply::parse(&c, &bytes[..bytes.len() - 1]), Ok(r));
    }

    #[test]
    fn parsers_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        let _ = sr830::parse_line(&bytes);
        let _ = Command::parse(&bytes);
        for c in [Command::Identify, Command::LiaStatus(None), snap(&[1, 2, 3]), Command::QuerySensitivity] {
            let _ = Reply::parse(&c, &bytes);
        }
        fuzz::fuzz_parse_line(&bytes);
        fuzz::fuzz_parse_reply(&bytes);
    }

    #[test]
    fn fuzz_bodies_survive_near_valid_input(
        c in any_command(),
        (q, r) in any_query_reply(),
        cut in 0usize..64,
        selector in any::<u8>(),
        noise in prop::collection::vec(prop::sample::select(b"0123456789.,;?-+eE *SENAP\r\n".to_vec()), 0..24),
    ) {
        let mut line = c.to_bytes();
        line.truncate(cut.min(line.len()));
        line.extend_from_slice(&noise);
        fuzz::fuzz_parse_line(&line);
        let mut reply = vec![selector];
        reply.extend_from_slice(&r.to_bytes());
        reply.truncate(cut.max(1).min(reply.len()));
        reply.extend_from_slice(&noise);
        fuzz::fuzz_parse_reply(&reply);
        let _ = Reply::parse(&q, &reply);
    }
}

/// The exact settling of the N-stage cascade against the manual's rounded table
/// (p. 3-21): to 1 % it takes ln 100 = 4.61 T at 6 dB/oct (manual: 5), 6.64 (7),
/// 8.41 (9) and 10.05 T (10) — the table rounds up, except at 24 dB/oct.
#[test]
fn exact_settling_against_the_manual_table() {
    use gonio_proto::sr830::FilterSlope;
    let want = [
        (FilterSlope::Db6, 4.6052),
        (FilterSlope::Db12, 6.6384),
        (FilterSlope::Db18, 8.4059),
        (FilterSlope::Db24, 10.0451),
    ];
    for (s, a) in want {
        let got = s.settle_factor_for(0.01);
        assert!((got - a).abs() < 1e-3, "{s:?}: {got}");
        assert!((s.settle_factor() - got).abs() < 0.7);
    }
    assert!((FilterSlope::Db6.settle_factor_for(1e-4) - 1e4f64.ln()).abs() < 1e-9);
}

/// Every line Gonio's session sends fits the instrument's 256-character input buffer
/// with room to spare (manual p. 5-2): the longest command it encodes, a six-value
/// `SNAP?`, is far shorter.
#[test]
fn every_command_fits_the_input_buffer() {
    let six = SnapParams::new(&[
        SnapParam::X,
        SnapParam::Y,
        SnapParam::R,
        SnapParam::Theta,
        SnapParam::Frequency,
        SnapParam::AuxIn1,
    ])
    .expect("six values");
    let bytes = Command::Snap(six).to_bytes();
    assert!(bytes.len() < gonio_proto::sr830::MAX_LINE / 4, "{bytes:?}");
}
