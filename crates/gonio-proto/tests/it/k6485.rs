//! The Keithley 6485 codec and session against the manual, byte for byte: every
//! command, every reply kind, the range, accuracy and NPLC tables, and the session's
//! set-up, read and autorange transcripts on virtual time. Property tests: every
//! command survives encode → parse, and no input makes a parser panic.

use std::collections::VecDeque;
use std::time::Duration;

use gonio_proto::TransportError;
use gonio_proto::k6485::{
    self, Command, CommandError, Current, EventStatus, FilterType, Identity, K6485Config,
    K6485Error, K6485Session, LineFrequency, MAX_AUTORANGE_STEPS, Model, Range, Reply, ReplyError,
    Sample, ScpiError, StatusWord, accuracy_a, fuzz,
};
use gonio_proto::link::{Deadline, Io, Operation};
use proptest::prelude::*;

const IDN: &str = "KEITHLEY INSTRUMENTS INC.,MODEL 6485,1234567,B03   Sep 25 2002 10:53:29/A02  /E";

fn range(i: u8) -> Range {
    Range::new(i).expect("range index")
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * b.abs().max(1e-300)
}

fn ms(v: u64) -> Duration {
    Duration::from_millis(v)
}

// ---------------------------------------------------------------------------------
// Codec.

/// Every command the driver sends, byte for byte, and back.
#[test]
fn every_command_is_byte_exact() {
    let table: Vec<(Command, &str)> = vec![
        (Command::Reset, "*RST"),
        (Command::Clear, "*CLS"),
        (Command::Identify, "*IDN?"),
        (Command::EventStatus, "*ESR?"),
        (Command::NextError, "SYST:ERR?"),
        (Command::ZeroCheck(true), "SYST:ZCH ON"),
        (Command::ZeroCheck(false), "SYST:ZCH OFF"),
        (Command::ZeroCorrectAcquire, "SYST:ZCOR:ACQ"),
        (Command::ZeroCorrect(true), "SYST:ZCOR ON"),
        (Command::ZeroCorrect(false), "SYST:ZCOR OFF"),
        (Command::SetRange(range(0)), "CURR:RANG 2E-9"),
        (Command::SetRange(range(3)), "CURR:RANG 2E-6"),
        (Command::SetRange(range(7)), "CURR:RANG 2E-2"),
        (Command::QueryRange, "CURR:RANG?"),
        (Command::AutoRange(true), "CURR:RANG:AUTO ON"),
        (Command::AutoRange(false), "CURR:RANG:AUTO OFF"),
        (Command::SetNplc(1.0), "CURR:NPLC 1"),
        (Command::SetNplc(0.01), "CURR:NPLC 0.01"),
        (Command::SetNplc(60.0), "CURR:NPLC 60"),
        (Command::FilterType(FilterType::Repeat), "AVER:TCON REP"),
        (Command::FilterType(FilterType::Moving), "AVER:TCON MOV"),
        (Command::FilterCount(10), "AVER:COUN 10"),
        (Command::Filter(true), "AVER ON"),
        (Command::Filter(false), "AVER OFF"),
        (Command::FormatElements, "FORM:ELEM READ,TIME,STAT"),
        (Command::TriggerCount(1), "TRIG:COUN 1"),
        (Command::Initiate, "INIT"),
        (Command::Read, "READ?"),
        (Command::Fetch, "FETC?"),
        (Command::LineFrequency, "SYST:LFR?"),
    ];
    for (command, text) in table {
        assert_eq!(
            command.to_bytes(),
            format!("{text}\r").as_bytes(),
            "{command:?}"
        );
        assert_eq!(
            Command::parse(text.as_bytes()),
            Ok(command.clone()),
            "{text}"
        );
        assert_eq!(command.is_query(), text.ends_with('?'), "{text}");
    }
    assert_eq!(k6485::TERMINATOR, b"\r");
    assert_eq!(k6485::REPLY_TERMINATOR, b'\r');
}

/// SCPI long forms, lower case, the optional `SENS` root, `STAT` leaf and leading
/// colon, numbers in any form, and several commands on one line.
#[test]
fn scpi_forms_parse_like_the_instrument() {
    for (text, command) in [
        (":SYSTem:ZCHeck ON", Command::ZeroCheck(true)),
        ("syst:zch:stat off", Command::ZeroCheck(false)),
        ("SYSTEM:ZCORRECT:ACQUIRE", Command::ZeroCorrectAcquire),
        ("SENS:CURR:RANG 2e-9", Command::SetRange(range(0))),
        (":sense:current:range 0.000002", Command::SetRange(range(3))),
        // The range for an expected current: 1.5 µA needs the 2 µA range.
        ("CURR:RANG 1.5E-6", Command::SetRange(range(3))),
        ("CURR:RANG 21E-3", Command::SetRange(range(7))),
        ("CURRent:NPLCycles 6", Command::SetNplc(6.0)),
        (
            "SENS:AVERage:TCONtrol MOVing",
            Command::FilterType(FilterType::Moving),
        ),
        ("AVER:COUNT 100", Command::FilterCount(100)),
        // The low end of p. 4-8's "one to 100".
        ("AVER:COUN 1", Command::FilterCount(1)),
        ("AVER:STAT 1", Command::Filter(true)),
        (
            "FORMat:ELEMents READing,TIME,STATus",
            Command::FormatElements,
        ),
        ("FORM:ELEM STAT,READ,TIME", Command::FormatElements),
        ("SYST:ERR:NEXT?", Command::NextError),
        ("trig:coun 2048", Command::TriggerCount(2048)),
        ("initiate", Command::Initiate),
        ("SYST:LFRequency?", Command::LineFrequency),
    ] {
        assert_eq!(Command::parse(text.as_bytes()), Ok(command), "{text}");
    }
    assert_eq!(
        k6485::parse_line(b"*RST;*CLS;;READ?\r"),
        vec![Ok(Command::Reset), Ok(Command::Clear), Ok(Command::Read)]
    );
}

/// The averaging filter count: "Both are a simple average of one to 100 reading
/// conversions" (Model 6485 Instruction Manual, p. 4-8): `AVER:COUN 1` and
/// `AVER:COUN 100` are accepted and sent as written, 0 and 101 refused with −222.
#[test]
fn the_filter_count_is_one_to_100_as_page_4_8_says() {
    assert_eq!(k6485::FILTER_COUNT, 1..=100);
    for n in [1, 2, 100] {
        let line = format!("AVER:COUN {n}");
        assert_eq!(Command::parse(line.as_bytes()), Ok(Command::FilterCount(n)));
        assert_eq!(
            Command::FilterCount(n).to_bytes(),
            format!("{line}\r").into_bytes()
        );
    }
    for text in ["AVER:COUN 0", "AVER:COUN 101", "AVER:COUN 1.5"] {
        let e = Command::parse(text.as_bytes()).expect_err(text);
        assert_eq!(e.code(), -222, "{text}");
    }
    // Gonio's own count 1 still means "filter off", and validates.
    let off = K6485Config {
        filter_count: 1,
        ..K6485Config::default()
    };
    off.validate().unwrap();
    assert!(!off.filter_on());
    assert_eq!(off.conversions_per_reading(), 1);
}

/// Refused commands name the SCPI error and the `*ESR?` bit.
#[test]
fn refused_commands_name_their_error() {
    let cases: [(&str, i32, u8); 12] = [
        ("FOO", -113, EventStatus::CME),
        ("SYST:ZCHX ON", -113, EventStatus::CME),
        ("SYST:ZCH MAYBE", -102, EventStatus::CME),
        ("SYST:ZCH", -102, EventStatus::CME),
        ("READ", -102, EventStatus::CME),
        ("*RST 1", -102, EventStatus::CME),
        ("CURR:RANG 0.03", -222, EventStatus::EXE),
        ("CURR:NPLC 0.001", -222, EventStatus::EXE),
        ("CURR:NPLC 61", -222, EventStatus::EXE),
        // p. 4-8: "a simple average of one to 100 reading conversions".
        ("AVER:COUN 0", -222, EventStatus::EXE),
        ("AVER:COUN 101", -222, EventStatus::EXE),
        ("TRIG:COUN 2049", -222, EventStatus::EXE),
    ];
    for (text, code, bit) in cases {
        let e = Command::parse(text.as_bytes()).expect_err(text);
        assert_eq!(e.code(), code, "{text}: {e}");
        assert_eq!(e.event_status(), EventStatus(bit), "{text}");
    }
    assert_eq!(
        CommandError::OutOfRange("CURR:NPLC").message(),
        "Parameter data out of range"
    );
    assert_eq!(
        CommandError::Unknown("FOO".into()).message(),
        "Undefined header"
    );
}

fn sample(text: &str) -> Sample {
    match Reply::parse(&Command::Read, text.as_bytes()) {
        Ok(Reply::Sample(s)) => s,
        other => panic!("{text:?}: {other:?}"),
    }
}

/// Readings as `FORM:ELEM READ,TIME,STAT` sends them; overflow and NAN typed.
#[test]
fn readings_parse_with_overflow_typed() {
    let s = sample("+1.234567E-09A,+2.236299E+02,+0.000000E+00");
    assert_eq!(s.current, Current::Amps(1.234567e-9));
    assert_eq!(s.time_s, 223.6299);
    assert_eq!(s.status, StatusWord(0));
    assert_eq!(
        Reply::Sample(s).to_bytes(),
        b"+1.234567E-09A,+2.236299E+02,+0.000000E+00\r"
    );
    // Without the unit suffix, negative, status as an integer.
    let s = sample("-5.000000E-12,+1.0E+00,1536");
    assert_eq!(s.current, Current::Amps(-5e-12));
    assert!(s.status.zero_check() && s.status.zero_correct());
    // Overflow: the value is never a current.
    let s = sample("+9.900000E+37A,+1.000000E+01,+1.000000E+00");
    assert_eq!(s.current, Current::Overflow);
    assert_eq!(s.current.amps(), None);
    assert!(s.status.overflow());
    assert_eq!(sample("+9.9E37A,+1,+1").current, Current::Overflow);
    assert_eq!(sample("-9.9E37A,+1,+1").current, Current::Overflow);
    assert_eq!(sample("+9.91E37A,+1,+0").current, Current::Invalid);
    // The manual's example status 138 = bits 1, 3, 7: filter, null, overvoltage.
    let s = sample("+1.040560E-06A,+2.236299E+02,+1.380000E+02");
    assert_eq!(s.status, StatusWord(138));
    assert!(s.status.has(StatusWord::FILTER) && s.status.has(StatusWord::NULL));
    assert!(s.status.overvoltage() && !s.status.overflow());
    assert_eq!(s.status.to_string(), "FILT|NULL|OVV");
    assert_eq!(StatusWord(0).to_string(), "none");
    assert_eq!(StatusWord(0x0101).to_string(), "OFLO|0x0100");
}

#[test]
fn other_replies_parse() {
    let Ok(Reply::Identity(id)) = Reply::parse(&Command::Identify, IDN.as_bytes()) else {
        panic!("*IDN?");
    };
    assert_eq!(id.model, "MODEL 6485");
    assert_eq!(id.serial, "1234567");
    assert_eq!(id.picoammeter(), Some(Model::K6485));
    let other = Identity::parse(b"KEITHLEY INSTRUMENTS INC.,MODEL 6487,4,A").expect("4 fields");
    assert_eq!(other.picoammeter(), Some(Model::K6487));
    let dmm = Identity::parse(b"KEITHLEY INSTRUMENTS INC.,MODEL 2000,4,A").expect("4 fields");
    assert_eq!(dmm.picoammeter(), None);
    assert_eq!(
        Reply::parse(&Command::NextError, b"0,\"No error\""),
        Ok(Reply::Error(ScpiError::none()))
    );
    assert_eq!(
        Reply::parse(&Command::NextError, b"-222,\"Parameter data out of range\""),
        Ok(Reply::Error(ScpiError {
            code: -222,
            message: "Parameter data out of range".into()
        }))
    );
    assert_eq!(
        Reply::parse(&Command::QueryRange, b"2.000000E-09"),
        Ok(Reply::Range(range(0)))
    );
    assert_eq!(
        Reply::Range(range(5)).to_bytes(),
        b"+2.000000E-04\r".to_vec()
    );
    assert_eq!(
        Reply::parse(&Command::LineFrequency, b"60"),
        Ok(Reply::LineFrequency(LineFrequency::Hz60))
    );
    assert_eq!(
        Reply::parse(&Command::EventStatus, b"32"),
        Ok(Reply::EventStatus(EventStatus(32)))
    );
}

#[test]
fn malformed_replies_are_typed_errors() {
    let cases: [(Command, &[u8], ReplyError); 9] = [
        (Command::Read, b"", ReplyError::Empty),
        (Command::Read, b"+1E-9A,+1", ReplyError::WrongCount(2)),
        (Command::Read, b"+1E-9A,+1,+0,+0", ReplyError::WrongCount(4)),
        (Command::Read, b"abcA,+1,+0", ReplyError::BadValue),
        (Command::Read, b"+1E-9A,+1,+0.5", ReplyError::BadValue),
        (
            Command::Read,
            b"+1E-9A,+1,70000",
            ReplyError::OutOfRange(70000.0),
        ),
        (Command::QueryRange, b"3E-9", ReplyError::OutOfRange(3e-9)),
        (Command::LineFrequency, b"55", ReplyError::OutOfRange(55.0)),
        (Command::Reset, b"0", ReplyError::NotAQuery("*RST")),
    ];
    for (command, line, e) in cases {
        assert_eq!(Reply::parse(&command, line), Err(e), "{line:?}");
    }
    assert_eq!(
        Reply::parse(&Command::NextError, b"-113,Undefined header"),
        Err(ReplyError::BadValue)
    );
}

// ---------------------------------------------------------------------------------
// Tables.

#[test]
fn range_table() {
    let amps: Vec<f64> = Range::all().map(Range::amps).collect();
    assert_eq!(amps, [2e-9, 2e-8, 2e-7, 2e-6, 2e-5, 2e-4, 2e-3, 2e-2]);
    let labels: Vec<String> = Range::all().map(|r| r.to_string()).collect();
    assert_eq!(
        labels,
        [
            "2 nA", "20 nA", "200 nA", "2 µA", "20 µA", "200 µA", "2 mA", "20 mA"
        ]
    );
    assert_eq!("20uA".parse::<Range>(), Ok(range(4)));
    assert_eq!("2 μA".parse::<Range>(), Ok(range(3)));
    assert!("3 nA".parse::<Range>().is_err());
    assert_eq!(Range::MOST.down(), None);
    assert_eq!(Range::LEAST.up(), None);
    assert_eq!(range(3).up(), Some(range(4)));
    assert_eq!(range(3).down(), Some(range(2)));
    assert_eq!(Range::default(), Range::LEAST);
    // 5 % over range (p. 4-2): 21 µA on the 20 µA range.
    assert!(close(range(4).overflow_amps(), 21e-6));
    assert_eq!(Range::for_current(2.1e-9), Some(range(1)));
    assert_eq!(Range::for_current(-2e-3), Some(range(6)));
    assert_eq!(Range::for_current(0.022), None);
    assert_eq!(Range::for_current(f64::NAN), None);
    // Rise times: 8 ms on the nA ranges, 500 µs above; a single pole settles to 1e-4
    // in ln(1e4)/ln(9) rise times.
    assert_eq!(range(0).rise_time_s(), 8e-3);
    assert_eq!(range(2).rise_time_s(), 500e-6);
    assert!(close(
        range(0).settle_s(1e-4),
        8e-3 * 1e4f64.ln() / 9f64.ln()
    ));
}

/// The accuracy table of Appendix A, ±(% rdg + offset), at a reading of half scale
/// and at zero.
#[test]
fn accuracy_matches_the_specification() {
    let expected = [
        (0.4e-2, 400e-15),
        (0.4e-2, 1e-12),
        (0.2e-2, 10e-12),
        (0.15e-2, 100e-12),
        (0.1e-2, 1e-9),
        (0.1e-2, 10e-9),
        (0.1e-2, 100e-9),
        (0.1e-2, 1e-6),
    ];
    for (r, (gain, offset)) in Range::all().zip(expected) {
        let half = r.amps() / 2.0;
        assert!(close(accuracy_a(r, half), gain * half + offset), "{r}");
        assert!(close(accuracy_a(r, -half), gain * half + offset), "{r}");
        assert_eq!(accuracy_a(r, 0.0), offset, "{r}");
    }
    // Spot values: 1 nA on 2 nA is ±4.4 pA; 10 mA on 20 mA is ±11 µA.
    assert!(close(accuracy_a(range(0), 1e-9), 4.4e-12));
    assert!(close(accuracy_a(range(3), 1e-6), 1.6e-9));
    assert!(close(accuracy_a(range(7), 1e-2), 1.1e-5));
}

#[test]
fn line_frequency_and_nplc_limits() {
    assert_eq!(LineFrequency::Hz50.plc_s(), 0.02);
    assert!(close(LineFrequency::Hz60.plc_s(), 1.0 / 60.0));
    assert_eq!(LineFrequency::Hz50.max_nplc(), 50.0);
    assert_eq!(LineFrequency::Hz60.max_nplc(), 60.0);
    assert_eq!(k6485::MIN_NPLC, 0.01);
    let bad = |c: K6485Config| c.validate().expect_err("refused").field;
    let ok = K6485Config::default();
    assert_eq!(ok.validate(), Ok(()));
    assert_eq!(
        bad(K6485Config {
            nplc: 55.0,
            ..ok.clone()
        }),
        "nplc"
    );
    assert_eq!(
        K6485Config {
            nplc: 55.0,
            line_frequency_hz: 60,
            ..ok.clone()
        }
        .validate(),
        Ok(())
    );
    assert_eq!(
        bad(K6485Config {
            nplc: 0.005,
            ..ok.clone()
        }),
        "nplc"
    );
    assert_eq!(
        bad(K6485Config {
            line_frequency_hz: 400,
            ..ok.clone()
        }),
        "line_frequency_hz"
    );
    assert_eq!(
        bad(K6485Config {
            filter_count: 101,
            ..ok.clone()
        }),
        "filter_count"
    );
    assert_eq!(
        bad(K6485Config {
            filter_count: 0,
            ..ok.clone()
        }),
        "filter_count"
    );
    assert_eq!(
        bad(K6485Config {
            samples: 0,
            ..ok.clone()
        }),
        "samples"
    );
    assert_eq!(
        bad(K6485Config {
            min_fraction: 0.1,
            ..ok.clone()
        }),
        "min_fraction"
    );
    assert_eq!(
        bad(K6485Config {
            settle_residual: 0.0,
            ..ok.clone()
        }),
        "settle_residual"
    );
    assert_eq!(
        bad(K6485Config {
            timeout_ms: 0,
            ..ok.clone()
        }),
        "timeout_ms"
    );
    assert_eq!(
        bad(K6485Config {
            retries: 11,
            ..ok.clone()
        }),
        "retries"
    );
    assert_eq!(
        bad(K6485Config {
            reconnect_attempts: 101,
            ..ok.clone()
        }),
        "reconnect_attempts"
    );
    assert_eq!(
        bad(K6485Config {
            range_settle_ms: 60_001,
            ..ok.clone()
        }),
        "range_settle_ms"
    );
    // Measuring time: 10 PLC at 60 Hz × a repeat filter of 5 = 0.8333 s per READ?.
    let c = K6485Config {
        nplc: 10.0,
        line_frequency_hz: 60,
        filter_count: 5,
        samples: 3,
        ..ok.clone()
    };
    assert!(close(c.read_s(), 10.0 / 60.0 * 5.0));
    assert!(close(c.reading_seconds(), 3.0 * 10.0 / 60.0 * 5.0));
    let moving = K6485Config {
        filter_type: FilterType::Moving,
        ..c
    };
    assert!(close(moving.read_s(), 10.0 / 60.0));
}

// ---------------------------------------------------------------------------------
// Session transcripts on virtual time.

/// A scripted instrument for one operation at a time: each line the session must send,
/// and the reply (if any). A reply arrives when the session's deadline minus the reply
/// timeout falls: the moment the instrument has finished measuring.
struct Wire {
    steps: VecDeque<(String, Option<String>)>,
    now: Duration,
    timeout: Duration,
    /// Every line sent, with its time.
    sent: Vec<(Duration, String)>,
    /// Every reply deadline polled.
    deadlines: Vec<Duration>,
}

impl Wire {
    fn new(timeout_ms: u64) -> Self {
        Wire {
            steps: VecDeque::new(),
            now: Duration::ZERO,
            timeout: ms(timeout_ms),
            sent: Vec::new(),
            deadlines: Vec::new(),
        }
    }

    fn send(&mut self, line: &str) -> &mut Self {
        self.steps.push_back((format!("{line}\r"), None));
        self
    }

    fn ask(&mut self, line: &str, reply: &str) -> &mut Self {
        self.steps
            .push_back((format!("{line}\r"), Some(reply.to_string())));
        self
    }

    fn run<O: Operation>(&mut self, mut op: O) -> O::Output {
        let mut reply: Option<String> = None;
        loop {
            while let Some(io) = op.poll_io() {
                match io {
                    Io::Transmit(bytes) => {
                        let line = String::from_utf8_lossy(bytes).into_owned();
                        let (want, answer) = self
                            .steps
                            .pop_front()
                            .unwrap_or_else(|| panic!("unexpected {line:?}"));
                        assert_eq!(line, want, "at {:?}", self.now);
                        self.sent.push((self.now, line));
                        reply = answer;
                        op.handle_sent(self.now, Ok(()));
                    }
                    Io::ClearInput => reply = None,
                    Io::Reconnect => op.handle_reconnected(self.now, Ok(())),
                }
            }
            if let Some(out) = op.poll_output() {
                return out;
            }
            match op.poll_timeout().expect("a deadline") {
                Deadline::Reply(at) => {
                    self.deadlines.push(at);
                    match reply.take() {
                        Some(line) => {
                            self.now = self.now.max(at - self.timeout);
                            op.handle_line(self.now, line.as_bytes());
                        }
                        None => {
                            self.now = at;
                            op.handle_timeout(self.now);
                        }
                    }
                }
                Deadline::Poll(at) | Deadline::Sleep(at) => {
                    self.now = self.now.max(at);
                    op.handle_timeout(self.now);
                }
            }
        }
    }

    fn done(&self) {
        assert!(self.steps.is_empty(), "unsent: {:?}", self.steps);
    }

    fn lines_since(&self, k: usize) -> Vec<(Duration, &str)> {
        self.sent[k..]
            .iter()
            .map(|(t, l)| (*t, l.as_str()))
            .collect()
    }
}

/// 2 µA, autorange at 0.05, 1 PLC at 50 Hz (20 ms), filter off, 4 samples, zero
/// correction, 100 ms after a range change, 500 ms timeout, one re-ask.
fn config() -> K6485Config {
    K6485Config {
        range: range(3),
        autorange: true,
        min_fraction: 0.05,
        nplc: 1.0,
        line_frequency_hz: 50,
        filter_count: 1,
        filter_type: FilterType::Repeat,
        samples: 4,
        zero_correct: true,
        range_settle_ms: 100,
        settle_residual: 1e-4,
        timeout_ms: 500,
        retries: 1,
        reconnect_attempts: 2,
        reconnect_delay_ms: 200,
    }
}

fn script_setup(w: &mut Wire, c: &K6485Config) {
    w.ask("*IDN?", IDN)
        .send("*RST")
        .send("*CLS")
        .ask("SYST:LFR?", &c.line_frequency_hz.to_string())
        .send("FORM:ELEM READ,TIME,STAT")
        .send("TRIG:COUN 1");
    let mut nplc = Vec::new();
    Command::SetNplc(c.nplc).encode_body(&mut nplc);
    w.send(&String::from_utf8_lossy(&nplc));
    if c.filter_count >= 2 {
        w.send(&format!("AVER:TCON {}", c.filter_type.mnemonic()))
            .send(&format!("AVER:COUN {}", c.filter_count))
            .send("AVER ON");
    } else {
        w.send("AVER OFF");
    }
    let rang = |r: Range| format!("CURR:RANG 2E{}", i32::from(r.index()) - 9);
    w.send("CURR:RANG:AUTO OFF").send("SYST:ZCH ON");
    if c.zero_correct {
        // With autorange the zero is taken on 2 nA, then the starting range is set.
        let zero = if c.autorange { Range::MOST } else { c.range };
        w.send(&rang(zero))
            .send("INIT")
            .send("SYST:ZCOR:ACQ")
            .send("SYST:ZCOR ON");
        if zero != c.range {
            w.send(&rang(c.range));
        }
    } else {
        w.send(&rang(c.range)).send("SYST:ZCOR OFF");
    }
    w.send("SYST:ZCH OFF").ask("SYST:ERR?", "0,\"No error\"");
}

fn ready(c: K6485Config) -> (K6485Session, Wire) {
    let mut w = Wire::new(c.timeout_ms);
    let mut s = K6485Session::new(c.clone(), "wire", Duration::ZERO).expect("valid");
    script_setup(&mut w, &c);
    let now = w.now;
    w.run(s.start_setup(now)).expect("set up");
    w.done();
    (s, w)
}

fn reading(v: f64, status: u16) -> String {
    let mut out = Vec::new();
    Reply::Sample(Sample {
        current: if v > 1e37 {
            Current::Overflow
        } else {
            Current::Amps(v)
        },
        time_s: 1.0,
        status: StatusWord(status),
    })
    .encode(&mut out);
    out.pop();
    String::from_utf8(out).expect("ASCII")
}

const OFLO: f64 = 9.9e37;

#[test]
fn setup_transcript_acquires_the_zero_after_the_range_settles() {
    let (s, w) = ready(config());
    let lines = w.lines_since(0);
    let t = |l: &str| {
        lines
            .iter()
            .find(|(_, x)| *x == l)
            .map(|(t, _)| *t)
            .expect(l)
    };
    // Everything up to the zero's range (2 nA, autorange being on) at t = 0; INIT
    // waits its 100 ms range settling; the zero is measured for 20 ms (1 PLC at
    // 50 Hz) while the starting range 2 µA is set; SYST:ERR? answers after it.
    assert_eq!(t("CURR:RANG 2E-9\r"), Duration::ZERO);
    assert_eq!(t("INIT\r"), ms(100));
    assert_eq!(t("SYST:ZCOR:ACQ\r"), ms(100));
    assert_eq!(t("CURR:RANG 2E-6\r"), ms(100));
    assert_eq!(*w.deadlines.last().expect("SYST:ERR?"), ms(120 + 500));
    assert_eq!(w.now, ms(120));
    assert_eq!(s.range(), range(3));
    assert_eq!(s.identity().map(|i| i.serial.as_str()), Some("1234567"));
    assert_eq!(s.busy_until(), ms(120));
    // Readings wait for the 2 µA range until 200 ms.
    assert_eq!(s.settled_at(), ms(200));

    // Without autorange the zero is taken on the configured range itself.
    let (s, w) = ready(K6485Config {
        autorange: false,
        ..config()
    });
    let ranges: Vec<&str> = w
        .sent
        .iter()
        .map(|(_, l)| l.as_str())
        .filter(|l| l.starts_with("CURR:RANG 2"))
        .collect();
    assert_eq!(ranges, ["CURR:RANG 2E-6\r"]);
    assert_eq!(s.settled_at(), ms(100));
}

#[test]
fn setup_with_filter_and_without_zero_correction() {
    let c = K6485Config {
        filter_count: 10,
        filter_type: FilterType::Moving,
        zero_correct: false,
        nplc: 0.1,
        ..config()
    };
    let (_, w) = ready(c);
    let sent: Vec<&str> = w.sent.iter().map(|(_, l)| l.as_str()).collect();
    assert!(sent.contains(&"AVER:TCON MOV\r") && sent.contains(&"AVER:COUN 10\r"));
    assert!(sent.contains(&"CURR:NPLC 0.1\r") && sent.contains(&"SYST:ZCOR OFF\r"));
    assert!(!sent.contains(&"INIT\r"));
    // No zero to measure: no settling wait in set-up.
    assert_eq!(w.now, Duration::ZERO);
}

#[test]
fn setup_refuses_another_instrument_a_rejected_command_and_a_wrong_mains() {
    let c = config();
    let mut s = K6485Session::new(c.clone(), "wire", Duration::ZERO).expect("valid");
    let mut w = Wire::new(c.timeout_ms);
    w.ask("*IDN?", "KEITHLEY INSTRUMENTS INC.,MODEL 2000,1,A");
    match w.run(s.start_setup(Duration::ZERO)) {
        Err(K6485Error::WrongInstrument(id)) => assert_eq!(id.model, "MODEL 2000"),
        other => panic!("{other:?}"),
    }
    w.done();

    let mut w = Wire::new(c.timeout_ms);
    w.ask("*IDN?", IDN)
        .send("*RST")
        .send("*CLS")
        .ask("SYST:LFR?", "60");
    match w.run(s.start_setup(Duration::ZERO)) {
        Err(K6485Error::LineFrequency {
            configured: 50,
            instrument: 60,
        }) => {}
        other => panic!("{other:?}"),
    }
    w.done();

    let mut w = Wire::new(c.timeout_ms);
    script_setup(&mut w, &c);
    w.steps.pop_back();
    w.ask("SYST:ERR?", "-222,\"Parameter data out of range\"");
    match w.run(s.start_setup(Duration::ZERO)) {
        Err(K6485Error::Rejected(e)) => assert_eq!(e.code, -222),
        other => panic!("{other:?}"),
    }
    w.done();
}

#[test]
fn read_averages_samples_spaced_by_the_integration() {
    let (mut s, mut w) = ready(config());
    let k = w.sent.len();
    for v in [1.0e-7, 1.2e-7, 0.8e-7, 1.0e-7] {
        w.ask("READ?", &reading(v, 0));
    }
    let r = w.run(s.start_read(w.now)).expect("reading");
    w.done();
    assert!(close(r.mean_a, 1e-7), "{}", r.mean_a);
    assert!(close(r.std_a, (0.08f64 / 3.0).sqrt() * 1e-7), "{}", r.std_a);
    assert_eq!(
        (r.n, r.samples, r.range, r.autorange_steps),
        (4, 4, range(3), 0)
    );
    assert_eq!(r.current(), Some(r.mean_a));
    assert!(close(r.fraction_of_full_scale(), 0.05));
    assert!(close(r.accuracy_a(), 0.0015 * 1e-7 + 100e-12));
    // From the 2 µA range's settling at 200 ms, one READ? every 20 ms (1 PLC at
    // 50 Hz): each answers when its conversion ends.
    let times: Vec<Duration> = w.lines_since(k).iter().map(|(t, _)| *t).collect();
    assert_eq!(times, [ms(200), ms(220), ms(240), ms(260)]);
    assert_eq!(w.now, ms(280));
    assert_eq!(
        w.deadlines[w.deadlines.len() - 4..],
        [ms(720), ms(740), ms(760), ms(780)]
    );
}

#[test]
fn autorange_steps_up_on_overflow_and_down_on_a_small_signal() {
    // Up: the first sample overflows on 2 µA; 20 µA after its 100 ms settling.
    let (mut s, mut w) = ready(config());
    let k = w.sent.len();
    w.ask("READ?", &reading(OFLO, 1)).send("CURR:RANG 2E-5");
    for _ in 0..4 {
        w.ask("READ?", &reading(3e-6, 0));
    }
    let r = w.run(s.start_read(w.now)).expect("reading");
    w.done();
    assert!(r.is_valid());
    assert_eq!((r.range, r.autorange_steps), (range(4), 1));
    assert!(close(r.mean_a, 3e-6));
    let lines = w.lines_since(k);
    assert_eq!(lines[1], (ms(220), "CURR:RANG 2E-5\r"));
    assert_eq!(lines[2], (ms(320), "READ?\r"));

    // Down: 50 nA is 0.025 of 2 µA, under 0.05: 200 nA, where it is 0.25.
    let (mut s, mut w) = ready(config());
    for _ in 0..4 {
        w.ask("READ?", &reading(5e-8, 0));
    }
    w.send("CURR:RANG 2E-7");
    for _ in 0..4 {
        w.ask("READ?", &reading(5e-8, 0));
    }
    let r = w.run(s.start_read(w.now)).expect("reading");
    w.done();
    assert_eq!((r.range, r.autorange_steps, r.n), (range(2), 1, 4));
    assert_eq!(s.range(), range(2));
}

#[test]
fn an_overflow_on_the_top_range_is_returned_flagged_never_valid() {
    let (mut s, mut w) = ready(K6485Config {
        range: Range::LEAST,
        ..config()
    });
    for _ in 0..4 {
        w.ask("READ?", &reading(OFLO, 1));
    }
    let r = w.run(s.start_read(w.now)).expect("a flagged reading");
    w.done();
    assert!(r.flags.overflow && !r.is_valid());
    assert_eq!(r.current(), None);
    assert_eq!((r.n, r.range), (0, Range::LEAST));
    assert!(r.mean_a.is_nan());
}

#[test]
fn autorange_gives_up_on_an_oscillating_signal() {
    let (mut s, mut w) = ready(config());
    for _ in 0..MAX_AUTORANGE_STEPS / 2 {
        w.ask("READ?", &reading(OFLO, 1)).send("CURR:RANG 2E-5");
        for _ in 0..4 {
            w.ask("READ?", &reading(1e-7, 0));
        }
        w.send("CURR:RANG 2E-6");
    }
    w.ask("READ?", &reading(OFLO, 1));
    match w.run(s.start_read(w.now)) {
        Err(K6485Error::Autorange { steps, last }) => {
            assert_eq!(steps, MAX_AUTORANGE_STEPS);
            assert!(last.flags.overflow);
        }
        other => panic!("{other:?}"),
    }
    w.done();
}

#[test]
fn zero_checked_and_overvoltage_readings_are_flagged() {
    let (mut s, mut w) = ready(K6485Config {
        autorange: false,
        samples: 2,
        ..config()
    });
    w.ask("READ?", &reading(1e-7, StatusWord::ZERO_CHECK))
        .ask("READ?", &reading(1e-7, StatusWord::OVERVOLTAGE));
    let r = w.run(s.start_read(w.now)).expect("flagged");
    assert!(r.flags.zero_check && r.flags.overvoltage && !r.is_valid());
    assert_eq!(
        r.status,
        StatusWord(StatusWord::ZERO_CHECK | StatusWord::OVERVOLTAGE)
    );
}

#[test]
fn a_lost_reading_is_asked_again_and_a_lost_error_query_is_not() {
    let (mut s, mut w) = ready(K6485Config {
        samples: 1,
        autorange: false,
        ..config()
    });
    w.send("READ?").ask("READ?", &reading(1e-7, 0));
    let r = w.run(s.start_read(w.now)).expect("reading");
    assert_eq!(r.current(), Some(1e-7));
    assert_eq!(s.retried(), 1);
    // Lost at 120 + 20 + 500 ms; asked again, answered 20 ms later.
    assert_eq!(w.now, ms(660));

    // A garbled reading is asked again too.
    w.ask("READ?", "+1.0E-07A,+1.0E+00")
        .ask("READ?", &reading(2e-7, 0));
    let r = w.run(s.start_read(w.now)).expect("reading");
    assert_eq!(r.current(), Some(2e-7));
    assert_eq!(s.retried(), 2);

    w.send("SYST:ERR?");
    match w.run(s.start_execute(&Command::NextError, w.now)) {
        Err(K6485Error::Transport {
            source: TransportError::Timeout(_),
            command,
        }) => assert_eq!(command, "SYST:ERR?"),
        other => panic!("{other:?}"),
    }
    w.done();
}

#[test]
fn input_changed_waits_the_ranges_analog_settling() {
    let (mut s, mut w) = ready(K6485Config {
        range: Range::MOST,
        samples: 1,
        autorange: false,
        ..config()
    });
    let t0 = w.now;
    s.input_changed(t0);
    // 2 nA: 8 ms rise (10–90 %), a single pole: to 1e-4 in 8 ms × ln(1e4)/ln(9).
    let wait = s.input_settle_time().as_secs_f64();
    assert!(
        (wait - 8e-3 * 1e4f64.ln() / 9f64.ln()).abs() < 1e-9,
        "{wait}"
    );
    let k = w.sent.len();
    w.ask("READ?", &reading(1e-9, 0));
    w.run(s.start_read(w.now)).expect("reading");
    assert_eq!(w.lines_since(k)[0].0, t0 + s.input_settle_time());
    // Setting a range waits the longer of 100 ms and the analog settling.
    w.send("CURR:RANG 2E-8");
    w.run(s.start_set_range(range(1), w.now)).expect("range");
    assert_eq!(s.settled_at(), w.now + ms(100));
}

// ---------------------------------------------------------------------------------
// Properties.

fn any_command() -> impl Strategy<Value = Command> {
    prop_oneof![
        Just(Command::Reset),
        Just(Command::Clear),
        Just(Command::Identify),
        Just(Command::EventStatus),
        Just(Command::NextError),
        any::<bool>().prop_map(Command::ZeroCheck),
        Just(Command::ZeroCorrectAcquire),
        any::<bool>().prop_map(Command::ZeroCorrect),
        (0..8u8).prop_map(|i| Command::SetRange(range(i))),
        Just(Command::QueryRange),
        any::<bool>().prop_map(Command::AutoRange),
        (0.01..=60.0f64).prop_map(Command::SetNplc),
        prop_oneof![Just(FilterType::Repeat), Just(FilterType::Moving)]
            .prop_map(Command::FilterType),
        (1..=100u32).prop_map(Command::FilterCount),
        any::<bool>().prop_map(Command::Filter),
        Just(Command::FormatElements),
        (1..=2048u32).prop_map(Command::TriggerCount),
        Just(Command::Initiate),
        Just(Command::Read),
        Just(Command::Fetch),
        Just(Command::LineFrequency),
    ]
}

proptest! {
    #[test]
    fn commands_round_trip(c in any_command(), lower in any::<bool>()) {
        let mut body = Vec::new();
        c.encode_body(&mut body);
        if lower {
            body.make_ascii_lowercase();
        }
        prop_assert_eq!(Command::parse(&body), Ok(c));
    }

    #[test]
    fn samples_round_trip(v in -2.1e-2..2.1e-2f64, t in 0.0..99_999.99f64, st in any::<u16>()) {
        let s = Sample { current: Current::Amps(v), time_s: t, status: StatusWord(st) };
        let bytes = Reply::Sample(s).to_bytes();
        let body = &bytes[..bytes.len() - 1];
        let Ok(Reply::Sample(back)) = Reply::parse(&Command::Read, body) else {
            panic!("{bytes:?}");
        };
        prop_assert_eq!(back.status, StatusWord(st));
        let a = back.current.amps().expect("a value");
        // Seven significant digits.
        prop_assert!((a - v).abs() <= 5e-7 * v.abs() + 1e-300);
        prop_assert_eq!(Reply::Sample(back).to_bytes(), bytes);
    }

    #[test]
    fn parsers_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..200)) {
        let _ = k6485::parse_line(&bytes);
        for c in [Command::Identify, Command::EventStatus, Command::NextError,
                  Command::QueryRange, Command::LineFrequency, Command::Read] {
            let _ = Reply::parse(&c, &bytes);
        }
        fuzz::fuzz_parse_line(&bytes);
        fuzz::fuzz_parse_reply(&bytes);
    }

    #[test]
    fn fuzz_bodies_survive_near_valid_input(
        pick in 0..4usize,
        v in any::<f64>(),
        st in any::<u16>(),
        sel in any::<u8>(),
    ) {
        let line = match pick {
            0 => format!("{v:e}A,{v},{st}"),
            1 => format!("{v}A,+1.0E+00,+{st}.0E+00"),
            2 => format!("CURR:RANG {v}"),
            _ => format!("CURR:NPLC {v};AVER:COUN {st}"),
        };
        let mut data = vec![sel];
        data.extend_from_slice(line.as_bytes());
        fuzz::fuzz_parse_reply(&data);
        fuzz::fuzz_parse_line(line.as_bytes());
    }
}
