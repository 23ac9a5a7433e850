//! The CS130 session driven by hand, byte for byte: each statement sent, the lines
//! the instrument answers, and the deadlines.

use std::collections::VecDeque;
use std::time::Duration;

use gonio_proto::TransportError;
use gonio_proto::cs130::{
    Cs130Config, Cs130Error, Cs130Session, ErrorCode, MonoState, NO_FILTER_WHEEL,
};
use gonio_proto::link::{Deadline, Io, Operation};

/// One statement expected on the wire and the lines that answer it (`None`: the
/// instrument stays silent, so the deadline passes).
type Turn = (&'static [u8], &'static [&'static [u8]]);

/// Drives `op` through `script`; returns the output, what was sent, and each reply
/// deadline seen (relative to the time its statement was sent).
fn drive<O: Operation>(mut op: O, script: &[Turn]) -> (O::Output, Vec<Vec<u8>>, Vec<Duration>) {
    let mut now = Duration::ZERO;
    let mut sent = Vec::new();
    let mut deadlines = Vec::new();
    let mut inbox: VecDeque<&[u8]> = VecDeque::new();
    let mut sent_at = now;
    loop {
        while let Some(io) = op.poll_io() {
            match io {
                Io::Transmit(bytes) => {
                    let turn = script
                        .get(sent.len())
                        .unwrap_or_else(|| panic!("unscripted {bytes:?}"));
                    assert_eq!(bytes, turn.0, "statement {}", sent.len());
                    sent.push(bytes.to_vec());
                    inbox.extend(turn.1.iter().copied());
                    sent_at = now;
                    op.handle_sent(now, Ok(()));
                }
                Io::ClearInput => inbox.clear(),
                Io::Reconnect => op.handle_reconnected(now, Ok(())),
            }
        }
        if let Some(out) = op.poll_output() {
            assert_eq!(sent.len(), script.len(), "script not finished");
            return (out, sent, deadlines);
        }
        match op.poll_timeout().expect("a deadline") {
            Deadline::Reply(at) => {
                deadlines.push(at - sent_at);
                match inbox.pop_front() {
                    Some(line) => {
                        now += Duration::from_millis(1);
                        op.handle_line(now, line);
                    }
                    None => {
                        now = at;
                        op.handle_timeout(now);
                    }
                }
            }
            Deadline::Poll(at) | Deadline::Sleep(at) => {
                now = at;
                op.handle_timeout(now);
            }
        }
    }
}

const INIT: &[Turn] = &[
    (b"INFO?\r\n", &[b"INFO?", b"CS130B VER 1.2"]),
    (b"UNITS NM\r\n", &[b"UNITS NM"]),
    (b"GRAT?\r\n", &[b"GRAT?", b"1,1200,UV"]),
    (b"FILTER?\r\n", &[b"FILTER?", b"1"]),
    (b"SHUTTER?\r\n", &[b"SHUTTER?", b"C"]),
    (b"WAVE?\r\n", &[b"WAVE?", b"400.00"]),
    (b"STB?\r\n", &[b"STB?", b"00"]),
];

fn ready() -> Cs130Session {
    let mut s = Cs130Session::new(Cs130Config::default(), "test").expect("a valid config");
    let (out, _, _) = drive(s.start_init(Duration::ZERO), INIT);
    assert_eq!(
        out.expect("the set-up succeeds"),
        MonoState {
            wavelength_nm: 400.0,
            grating: 1,
            filter: 1,
            shutter_open: false
        }
    );
    assert_eq!(s.info(), Some("CS130B VER 1.2"));
    s
}

#[test]
fn init_reads_every_setting_with_echoes() {
    ready();
}

#[test]
fn go_sets_the_order_filter_waits_for_the_move_and_reads_back() {
    let mut s = ready();
    let (out, _, deadlines) = drive(
        s.start_go(650.0, Duration::ZERO),
        &[
            (b"FILTER 3\r\n", &[b"FILTER 3"]),
            (b"GOWAVE 650\r\n", &[b"GOWAVE 650"]),
            (b"*WAI\r\n", &[b"*WAI"]),
            (b"WAVE?\r\n", &[b"WAVE?", b"650.25"]),
            (b"STB?\r\n", &[b"STB?", b"00"]),
        ],
    );
    assert_eq!(
        out.unwrap(),
        MonoState {
            wavelength_nm: 650.25,
            grating: 1,
            filter: 3,
            shutter_open: false
        }
    );
    // After a statement that moves, until a query is answered, echoes and answers may
    // wait for the move (60 s); the rest 1 s.
    let second = Duration::from_secs(1);
    let minute = Duration::from_secs(60);
    assert_eq!(
        deadlines,
        [second, minute, minute, minute, minute, second, second]
    );
}

#[test]
fn go_changes_grating_then_filter_and_nothing_already_set() {
    let mut s = ready();
    let (out, _, _) = drive(
        s.start_go(1100.0, Duration::ZERO),
        &[
            (b"GRAT 2\r\n", &[b"GRAT 2"]),
            (b"FILTER 4\r\n", &[b"FILTER 4"]),
            (b"GOWAVE 1100\r\n", &[b"GOWAVE 1100"]),
            (b"*WAI\r\n", &[b"*WAI"]),
            (b"WAVE?\r\n", &[b"WAVE?", b"1100.00"]),
            (b"STB?\r\n", &[b"STB?", b"00"]),
        ],
    );
    assert_eq!(out.unwrap().grating, 2);
    let (out, _, _) = drive(
        s.start_go(1200.5, Duration::ZERO),
        &[
            (b"GOWAVE 1200.5\r\n", &[b"GOWAVE 1200.5"]),
            (b"*WAI\r\n", &[b"*WAI"]),
            (b"WAVE?\r\n", &[b"WAVE?", b"1200.50"]),
            (b"STB?\r\n", &[b"STB?", b"00"]),
        ],
    );
    assert_eq!(out.unwrap().wavelength_nm, 1200.5);
}

#[test]
fn a_wavelength_out_of_range_sends_nothing() {
    let mut s = ready();
    let (out, sent, _) = drive(s.start_go(2100.0, Duration::ZERO), &[]);
    assert!(matches!(out, Err(Cs130Error::Select(_))), "{out:?}");
    assert!(sent.is_empty());
    let (out, sent, _) = drive(s.start_go(-5.0, Duration::ZERO), &[]);
    assert!(matches!(out, Err(Cs130Error::Select(_))), "{out:?}");
    assert!(sent.is_empty());
}

#[test]
fn an_error_bit_is_reported_with_its_code_and_forgets_the_settings() {
    let mut s = ready();
    let (out, _, _) = drive(
        s.start_go(450.0, Duration::ZERO),
        &[
            (b"GOWAVE 450\r\n", &[b"GOWAVE 450"]),
            (b"*WAI\r\n", &[b"*WAI"]),
            (b"WAVE?\r\n", &[b"WAVE?", b"400.00"]),
            // §15.9 / Model 74000 table: "32 when an error occurred".
            (b"STB?\r\n", &[b"STB?", b"32"]),
            (b"ERROR?\r\n", &[b"ERROR?", b"3"]),
        ],
    );
    assert_eq!(out, Err(Cs130Error::Rejected(ErrorCode::DESTINATION)));
    assert_eq!(s.state(), None);
}

#[test]
fn a_wavelength_read_back_too_far_is_an_error() {
    let mut s = ready();
    let (out, _, _) = drive(
        s.start_go(450.0, Duration::ZERO),
        &[
            (b"GOWAVE 450\r\n", &[b"GOWAVE 450"]),
            (b"*WAI\r\n", &[b"*WAI"]),
            (b"WAVE?\r\n", &[b"WAVE?", b"447.00"]),
            (b"STB?\r\n", &[b"STB?", b"00"]),
        ],
    );
    assert!(matches!(out, Err(Cs130Error::NotReached { read_nm, .. }) if read_nm == 447.0));
}

#[test]
fn a_lost_or_wrong_echo_sends_the_statement_again() {
    let mut s = ready();
    let (out, _, _) = drive(
        s.start_shutter(true, Duration::ZERO),
        &[
            (b"SHUTTER O\r\n", &[]),
            (b"SHUTTER O\r\n", &[b"SHUTTER C"]),
            (b"SHUTTER O\r\n", &[b"SHUTTER O"]),
            (b"STB?\r\n", &[b"STB?", b"00"]),
        ],
    );
    assert!(out.unwrap().shutter_open);
    assert_eq!(s.retried(), 2);
}

#[test]
fn the_status_byte_is_never_asked_twice() {
    let mut s = ready();
    let (out, _, _) = drive(
        s.start_shutter(false, Duration::ZERO),
        &[
            (b"SHUTTER C\r\n", &[b"SHUTTER C"]),
            (b"STB?\r\n", &[b"STB?"]),
        ],
    );
    assert!(
        matches!(&out, Err(Cs130Error::Transport { command, source: TransportError::Timeout(_) }) if command == "STB?"),
        "{out:?}"
    );
}

#[test]
fn without_echo_only_answers_are_read() {
    let config = Cs130Config {
        echo: false,
        ..Cs130Config::default()
    };
    let mut s = Cs130Session::new(config, "test").unwrap();
    let (out, _, _) = drive(
        s.start_read_state(Duration::ZERO),
        &[
            (b"GRAT?\r\n", &[b"2"]),
            (b"FILTER?\r\n", &[b"4"]),
            (b"SHUTTER?\r\n", &[b"O"]),
            (b"WAVE?\r\n", &[b"1500.00"]),
        ],
    );
    assert_eq!(
        out.unwrap(),
        MonoState {
            wavelength_nm: 1500.0,
            grating: 2,
            filter: 4,
            shutter_open: true
        }
    );
}

#[test]
fn a_go_from_an_unknown_state_sets_everything_and_reads_the_shutter() {
    let mut s = Cs130Session::new(Cs130Config::default(), "test").unwrap();
    let (out, _, _) = drive(
        s.start_go(300.0, Duration::ZERO),
        &[
            (b"GRAT 1\r\n", &[b"GRAT 1"]),
            (b"FILTER 1\r\n", &[b"FILTER 1"]),
            // From an unknown position the last approach starts 5 nm below.
            (b"GOWAVE 295\r\n", &[b"GOWAVE 295"]),
            (b"GOWAVE 300\r\n", &[b"GOWAVE 300"]),
            (b"*WAI\r\n", &[b"*WAI"]),
            (b"WAVE?\r\n", &[b"WAVE?", b"300.00"]),
            (b"SHUTTER?\r\n", &[b"SHUTTER?", b"O"]),
            (b"STB?\r\n", &[b"STB?", b"00"]),
        ],
    );
    assert_eq!(
        out.unwrap(),
        MonoState {
            wavelength_nm: 300.0,
            grating: 1,
            filter: 1,
            shutter_open: true
        }
    );
}

#[test]
fn every_wavelength_is_approached_from_below() {
    let mut s = Cs130Session::new(Cs130Config::default(), "test").unwrap();
    fn step(s: &mut Cs130Session, nm: f64, script: &[Turn]) -> MonoState {
        let (out, _, _) = drive(s.start_go(nm, Duration::ZERO), script);
        out.unwrap()
    }
    step(
        &mut s,
        450.0,
        &[
            (b"GRAT 1\r\n", &[b"GRAT 1"]),
            (b"FILTER 1\r\n", &[b"FILTER 1"]),
            (b"GOWAVE 445\r\n", &[b"GOWAVE 445"]),
            (b"GOWAVE 450\r\n", &[b"GOWAVE 450"]),
            (b"*WAI\r\n", &[b"*WAI"]),
            (b"WAVE?\r\n", &[b"WAVE?", b"450.00"]),
            (b"SHUTTER?\r\n", &[b"SHUTTER?", b"C"]),
            (b"STB?\r\n", &[b"STB?", b"00"]),
        ],
    );
    // Up: straight there.
    step(
        &mut s,
        460.0,
        &[
            (b"GOWAVE 460\r\n", &[b"GOWAVE 460"]),
            (b"*WAI\r\n", &[b"*WAI"]),
            (b"WAVE?\r\n", &[b"WAVE?", b"460.00"]),
            (b"STB?\r\n", &[b"STB?", b"00"]),
        ],
    );
    // Down: below first, then up onto it.
    let st = step(
        &mut s,
        420.0,
        &[
            (b"GOWAVE 415\r\n", &[b"GOWAVE 415"]),
            (b"GOWAVE 420\r\n", &[b"GOWAVE 420"]),
            (b"*WAI\r\n", &[b"*WAI"]),
            (b"WAVE?\r\n", &[b"WAVE?", b"420.00"]),
            (b"STB?\r\n", &[b"STB?", b"00"]),
        ],
    );
    assert_eq!(st.wavelength_nm, 420.0);
    // Turned off, down goes straight.
    let mut off = Cs130Session::new(
        Cs130Config {
            approach_nm: 0.0,
            ..Cs130Config::default()
        },
        "test",
    )
    .unwrap();
    step(
        &mut off,
        450.0,
        &[
            (b"GRAT 1\r\n", &[b"GRAT 1"]),
            (b"FILTER 1\r\n", &[b"FILTER 1"]),
            (b"GOWAVE 450\r\n", &[b"GOWAVE 450"]),
            (b"*WAI\r\n", &[b"*WAI"]),
            (b"WAVE?\r\n", &[b"WAVE?", b"450.00"]),
            (b"SHUTTER?\r\n", &[b"SHUTTER?", b"C"]),
            (b"STB?\r\n", &[b"STB?", b"00"]),
        ],
    );
}

#[test]
fn a_vanished_port_is_reopened_a_bounded_number_of_times() {
    let config = Cs130Config {
        reconnect_attempts: 1,
        ..Cs130Config::default()
    };
    let mut s = Cs130Session::new(config, "test").unwrap();
    let mut op = s.start_shutter(true, Duration::ZERO);
    let lost = || TransportError::Disconnected {
        port: "test".into(),
        reason: "gone".into(),
    };
    assert_eq!(op.poll_io(), Some(Io::Transmit(b"SHUTTER O\r\n")));
    op.handle_sent(Duration::ZERO, Err(lost()));
    assert_eq!(
        op.poll_timeout(),
        Some(Deadline::Sleep(Duration::from_secs(1)))
    );
    op.handle_timeout(Duration::from_secs(1));
    assert_eq!(op.poll_io(), Some(Io::Reconnect));
    op.handle_reconnected(Duration::from_secs(1), Ok(()));
    assert_eq!(op.poll_io(), Some(Io::Transmit(b"SHUTTER O\r\n")));
    op.handle_sent(Duration::from_secs(1), Err(lost()));
    assert!(matches!(
        op.poll_output(),
        Some(Err(Cs130Error::Disconnected { attempts: 1, .. }))
    ));
}

/// A config for a unit without a filter wheel.
fn wheel_less() -> Cs130Config {
    Cs130Config {
        filter_wheel: false,
        auto_order_filter: false,
        ..Cs130Config::default()
    }
}

#[test]
fn without_a_wheel_init_go_and_read_state_never_send_filter() {
    let mut s = Cs130Session::new(wheel_less(), "test").unwrap();
    let (out, _, _) = drive(
        s.start_init(Duration::ZERO),
        &[
            (
                b"INFO?\r\n",
                &[
                    b"INFO?",
                    b"Oriel, Model 74000 Cornerstone 130,SN123,V1.02.03",
                ],
            ),
            (b"UNITS NM\r\n", &[b"UNITS NM"]),
            (b"GRAT?\r\n", &[b"GRAT?", b"1,1200,UV"]),
            // No FILTER?: a unit without a wheel would answer 0 and flag an error.
            (b"SHUTTER?\r\n", &[b"SHUTTER?", b"C"]),
            (b"WAVE?\r\n", &[b"WAVE?", b"400.00"]),
            (b"STB?\r\n", &[b"STB?", b"00"]),
        ],
    );
    let ready = MonoState {
        wavelength_nm: 400.0,
        grating: 1,
        filter: NO_FILTER_WHEEL,
        shutter_open: false,
    };
    assert_eq!(out.unwrap(), ready);
    // 1100 nm: with a wheel this would be FILTER 4; without, only the grating.
    let (out, _, _) = drive(
        s.start_go(1100.0, Duration::ZERO),
        &[
            (b"GRAT 2\r\n", &[b"GRAT 2"]),
            (b"GOWAVE 1100\r\n", &[b"GOWAVE 1100"]),
            (b"*WAI\r\n", &[b"*WAI"]),
            (b"WAVE?\r\n", &[b"WAVE?", b"1100.25"]),
            (b"STB?\r\n", &[b"STB?", b"00"]),
        ],
    );
    assert_eq!(out.unwrap().filter, 0);
    // After an error every setting is forgotten, the (absent) filter excepted: the
    // next go asks for what it does not know, and still not for the filter.
    let (out, _, _) = drive(
        s.start_go(1200.0, Duration::ZERO),
        &[
            (b"GOWAVE 1200\r\n", &[b"GOWAVE 1200"]),
            (b"*WAI\r\n", &[b"*WAI"]),
            (b"WAVE?\r\n", &[b"WAVE?", b"1100.25"]),
            (b"STB?\r\n", &[b"STB?", b"32"]),
            (b"ERROR?\r\n", &[b"ERROR?", b"3"]),
        ],
    );
    assert_eq!(out, Err(Cs130Error::Rejected(ErrorCode::DESTINATION)));
    let (out, _, _) = drive(
        s.start_shutter(true, Duration::ZERO),
        &[
            (b"SHUTTER O\r\n", &[b"SHUTTER O"]),
            (b"GRAT?\r\n", &[b"GRAT?", b"2,600,IR"]),
            (b"WAVE?\r\n", &[b"WAVE?", b"1100.25"]),
            (b"STB?\r\n", &[b"STB?", b"00"]),
        ],
    );
    assert_eq!(out.unwrap().filter, NO_FILTER_WHEEL);
    let (out, _, _) = drive(
        s.start_read_state(Duration::ZERO),
        &[
            (b"GRAT?\r\n", &[b"GRAT?", b"2,600,IR"]),
            (b"SHUTTER?\r\n", &[b"SHUTTER?", b"O"]),
            (b"WAVE?\r\n", &[b"WAVE?", b"1100.25"]),
        ],
    );
    assert_eq!(out.unwrap().filter, NO_FILTER_WHEEL);
}

#[test]
fn a_wheel_configured_but_not_answering_fails_init_naming_the_field() {
    let mut s = Cs130Session::new(Cs130Config::default(), "test").unwrap();
    let (out, _, _) = drive(
        s.start_init(Duration::ZERO),
        &[
            (b"INFO?\r\n", &[b"INFO?", b"CS130B VER 1.2"]),
            (b"UNITS NM\r\n", &[b"UNITS NM"]),
            (b"GRAT?\r\n", &[b"GRAT?", b"1,1200,UV"]),
            // Model 74000 table: no wheel (or out of position) → 0, error set.
            (b"FILTER?\r\n", &[b"FILTER?", b"0"]),
            // Read back at once, so the unit is left with a clean status byte.
            (b"STB?\r\n", &[b"STB?", b"32"]),
            (b"ERROR?\r\n", &[b"ERROR?", b"6"]),
        ],
    );
    let e = out.unwrap_err();
    assert_eq!(
        e,
        Cs130Error::NoFilterWheel {
            code: Some(ErrorCode::NO_ACCESSORY)
        }
    );
    let text = e.to_string();
    assert!(text.contains("no filter wheel answered"), "{text}");
    assert!(text.contains("filter_wheel = false"), "{text}");
    assert!(text.contains("error 6 (accessory not present"), "{text}");
    assert_eq!(s.state(), None);
}

#[test]
fn a_filter_answer_of_0_without_an_error_flag_is_still_no_wheel() {
    let mut s = Cs130Session::new(Cs130Config::default(), "test").unwrap();
    let (out, _, _) = drive(
        s.start_read_state(Duration::ZERO),
        &[
            (b"GRAT?\r\n", &[b"GRAT?", b"1"]),
            (b"FILTER?\r\n", &[b"FILTER?", b"0"]),
            (b"STB?\r\n", &[b"STB?", b"00"]),
        ],
    );
    assert_eq!(out, Err(Cs130Error::NoFilterWheel { code: None }));
}
