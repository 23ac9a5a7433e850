//! The FW102C driver against scripted transcripts, byte for byte, on virtual time:
//! set-up, moves polled to their end, a lost echo, a refusal, a vanished port.

use std::time::Duration;

use gonio_driver::fw102c::{Filter, Fw102c, Fw102cConfig, Fw102cError};
use gonio_driver::script::ScriptHandle;
use gonio_driver::{Clock, ManualClock, ScriptedTransport};
use gonio_proto::fw102c::{ErrorCode, MAX_LINE, TERMINATOR};

const IDN: &str = "THORLABS FW102C/FW212C Filter Wheel version 1.04";

fn ms(v: u64) -> Duration {
    Duration::from_millis(v)
}

fn config() -> Fw102cConfig {
    Fw102cConfig {
        filters: vec![
            Filter::Bandpass {
                position: 3,
                centre_nm: 550.0,
                fwhm_nm: 10.0,
                peak_transmittance: 1.0,
            },
            Filter::Dark { position: 6 },
        ],
        timeout_ms: 1000,
        move_timeout_ms: 5000,
        poll_interval_ms: 100,
        retries: 1,
        reconnect_attempts: 1,
        reconnect_delay_ms: 200,
        ..Fw102cConfig::default()
    }
}

type Driver = Fw102c<ScriptedTransport, ManualClock>;

fn rig() -> (Driver, ScriptHandle, ManualClock) {
    let clock = ManualClock::new();
    let (t, h) = ScriptedTransport::new(TERMINATOR, MAX_LINE, clock.clone());
    let d = Fw102c::new(t, clock.clone(), config()).expect("valid config");
    (d, h, clock)
}

/// What the wheel sends for a query: echo, value, prompt.
fn query(cmd: &str, value: &str) -> String {
    format!("{cmd}\r{value}\r> ")
}

fn script_init(h: &ScriptHandle, position: u8) {
    h.exchange("*idn?\r", query("*idn?", IDN))
        .exchange("pcount?\r", query("pcount?", "6"))
        .exchange("speed=1\r", "speed=1\r> ")
        .exchange("speed?\r", query("speed?", "1"))
        .exchange("sensors=0\r", "sensors=0\r> ")
        .exchange("sensors?\r", query("sensors?", "0"))
        .exchange("pos?\r", query("pos?", &position.to_string()));
}

#[test]
fn init_transcript() {
    let (mut d, h, clock) = rig();
    script_init(&h, 2);
    assert_eq!(d.init().expect("init"), IDN);
    h.finish().expect("transcript");
    assert_eq!(d.identity(), Some(IDN));
    assert_eq!(d.last_position(), Some(2));
    assert_eq!(clock.now(), Duration::ZERO);
}

#[test]
fn select_band_polls_until_the_wheel_reads_the_filter() {
    let (mut d, h, clock) = rig();
    script_init(&h, 1);
    d.init().expect("init");
    // The echo at once; a pos? answered while turning reads the old position; the
    // prompt of pos=3 comes only when the wheel stops.
    h.exchange("pos=3\r", "pos=3\r")
        .exchange("pos?\r", "pos?\r1\r")
        .exchange("pos?\r", "> pos?\r3\r> ");
    assert_eq!(d.select_band(550.0).expect("select"), 3);
    h.finish().expect("transcript");
    assert_eq!(clock.now(), ms(100), "one poll interval");
    assert_eq!(d.last_position(), Some(3));
}

#[test]
fn a_lost_echo_is_sent_again_and_a_refusal_is_typed() {
    let (mut d, h, clock) = rig();
    h.send("pos?\r").exchange("pos?\r", query("pos?", "4"));
    assert_eq!(d.position().expect("position"), 4);
    assert_eq!(clock.now(), ms(1000), "one reply timeout");
    assert_eq!(d.retried(), 1);
    h.exchange("pos=6\r", "pos=6\r")
        .exchange("pos?\r", "Command error CMD_ARG_INVALID\r> pos?\r4\r> ");
    assert_eq!(
        d.select_dark(),
        Err(Fw102cError::Refused {
            command: "pos=6".into(),
            code: ErrorCode::ArgInvalid
        })
    );
    h.finish().expect("transcript");
    assert_eq!(d.last_position(), None, "unknown after a failed move");
}

#[test]
fn a_vanished_port_is_reopened_once() {
    let (mut d, h, clock) = rig();
    h.vanish(0).exchange("pos?\r", query("pos?", "5"));
    assert_eq!(d.position().expect("position"), 5);
    h.finish().expect("transcript");
    assert_eq!(d.reconnects(), 1);
    assert_eq!(clock.now(), ms(200), "the reconnection delay");
}

#[test]
fn positions_beyond_the_wheel_send_nothing() {
    let (mut d, h, _) = rig();
    assert_eq!(
        d.select(0),
        Err(Fw102cError::PositionOutOfRange {
            position: 0,
            positions: 6
        })
    );
    assert!(matches!(
        d.select_band(600.0),
        Err(Fw102cError::NoFilterForBand { nm, .. }) if nm == 600.0
    ));
    assert!(h.sent().is_empty());
    h.finish().expect("nothing scripted, nothing sent");
}
