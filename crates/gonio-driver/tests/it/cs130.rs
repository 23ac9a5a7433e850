//! The Cornerstone 130 driver against scripted transcripts, byte for byte, on virtual
//! time: init, a move with the grating and order filter, the wait for the move, a
//! refusal before any byte, a refused destination, a vanished port.

use std::time::Duration;

use gonio_driver::cs130::{Cs130, Cs130Config, Cs130Error, ErrorCode, MonoState};
use gonio_driver::script::ScriptHandle;
use gonio_driver::{Clock, ManualClock, ScriptedTransport};

type Driver = Cs130<ScriptedTransport, ManualClock>;

fn rig(config: Cs130Config) -> (Driver, ScriptHandle, ManualClock) {
    let clock = ManualClock::new();
    let (t, h) = ScriptedTransport::new(b'\n', 256, clock.clone());
    let driver = Cs130::new(t, clock.clone(), config).expect("valid config");
    (driver, h, clock)
}

/// The statement and, echo first, what the instrument sends back.
fn echo(h: &ScriptHandle, statement: &str, answer: Option<&str>) {
    let mut reply = format!("{statement}\r\n");
    if let Some(a) = answer {
        reply.push_str(&format!("{a}\r\n"));
    }
    h.exchange(format!("{statement}\r\n"), reply);
}

fn script_init(h: &ScriptHandle) {
    echo(h, "INFO?", Some("CS130B VER 1.2"));
    echo(h, "UNITS NM", None);
    echo(h, "GRAT?", Some("1,1200,UV"));
    echo(h, "FILTER?", Some("1"));
    echo(h, "SHUTTER?", Some("C"));
    echo(h, "WAVE?", Some("400.00"));
    echo(h, "STB?", Some("00"));
}

fn ready() -> (Driver, ScriptHandle, ManualClock) {
    let (mut d, h, clock) = rig(Cs130Config::default());
    script_init(&h);
    let state = d.init().expect("scripted init");
    assert_eq!(
        state,
        MonoState {
            wavelength_nm: 400.0,
            grating: 1,
            filter: 1,
            shutter_open: false
        }
    );
    h.finish().expect("init transcript");
    (d, h, clock)
}

#[test]
fn init_and_a_move_across_the_grating_crossover() {
    let (mut d, h, _) = ready();
    assert_eq!(d.info(), Some("CS130B VER 1.2"));
    echo(&h, "GRAT 2", None);
    echo(&h, "FILTER 3", None);
    echo(&h, "GOWAVE 950", None);
    echo(&h, "*WAI", None);
    echo(&h, "WAVE?", Some("950.25"));
    echo(&h, "STB?", Some("00"));
    let state = d.go_to(950.0).unwrap();
    assert_eq!(
        state,
        MonoState {
            wavelength_nm: 950.25,
            grating: 2,
            filter: 3,
            shutter_open: false
        }
    );
    h.finish().expect("move transcript");
    assert_eq!(d.known_state(), Some(state));
}

#[test]
fn a_refused_wavelength_sends_nothing() {
    let (mut d, h, _) = rig(Cs130Config::default());
    let e = d.go_to(3000.0).unwrap_err();
    assert!(matches!(e, Cs130Error::Select(_)), "{e}");
    assert!(h.sent().is_empty());
    h.finish().expect("nothing scripted, nothing sent");
}

#[test]
fn a_refused_destination_is_reported_with_its_code() {
    let (mut d, h, _) = ready();
    // Down from 400 nm: the drive first goes 5 nm below, to come up onto 260 nm.
    echo(&h, "GOWAVE 255", None);
    echo(&h, "GOWAVE 260", None);
    echo(&h, "*WAI", None);
    echo(&h, "WAVE?", Some("400.00"));
    // Decimal: "32 when an error occurred" (Model 74000 table; CS130B §15.9).
    echo(&h, "STB?", Some("32"));
    echo(&h, "ERROR?", Some("3"));
    assert_eq!(
        d.go_to(260.0),
        Err(Cs130Error::Rejected(ErrorCode::DESTINATION))
    );
    h.finish().expect("transcript");
    assert_eq!(d.known_state(), None);
}

#[test]
fn a_lost_answer_after_wai_waits_the_move_timeout_then_asks_again() {
    let config = Cs130Config {
        move_timeout_ms: 20_000,
        ..Cs130Config::default()
    };
    let (mut d, h, clock) = rig(config);
    script_init(&h);
    d.init().unwrap();
    let t0 = clock.now();
    echo(&h, "GOWAVE 450", None);
    echo(&h, "*WAI", None);
    // The echo comes, the answer is lost.
    echo(&h, "WAVE?", None);
    echo(&h, "WAVE?", Some("450.25"));
    echo(&h, "STB?", Some("00"));
    assert_eq!(d.go_to(450.0).unwrap().wavelength_nm, 450.25);
    h.finish().expect("transcript");
    assert_eq!(clock.now() - t0, Duration::from_secs(20));
    assert_eq!(d.retried(), 1);
}

#[test]
fn a_vanished_port_is_reopened_and_the_statement_sent_again() {
    let (mut d, h, _) = ready();
    h.vanish(0);
    echo(&h, "SHUTTER O", None);
    echo(&h, "STB?", Some("00"));
    assert!(d.shutter(true).unwrap().shutter_open);
    h.finish().expect("transcript");
    assert_eq!(d.reconnects(), 1);
}
