//! The 6485 driver against scripted transcripts, byte for byte, on virtual time:
//! set-up with zero correction, averaging, autoranging, flags, and faults.

use std::time::Duration;

use gonio_driver::k6485::{
    ConfigError, K6485, K6485Config, K6485Error, MAX_AUTORANGE_STEPS, accuracy_a,
};
use gonio_driver::script::ScriptHandle;
use gonio_driver::{Clock, ManualClock, ScriptedTransport};
use gonio_proto::k6485::{Command, FilterType, Range, Reply, ScpiError};

const IDN: &str =
    "KEITHLEY INSTRUMENTS INC.,MODEL 6485,1234567,B03   Sep 25 2002 10:53:29/A02  /E\r";

fn range(i: u8) -> Range {
    Range::new(i).expect("range index")
}

fn ms(v: u64) -> Duration {
    Duration::from_millis(v)
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * b.abs().max(1e-300)
}

/// 2 µA, autorange at 0.05, 1 PLC at 50 Hz, repeat filter of 5 (100 ms per READ?),
/// 3 samples, zero correction, 100 ms after a range change, 500 ms timeout, one
/// re-ask, 2 reconnections 200 ms apart.
fn config() -> K6485Config {
    K6485Config {
        range: range(3),
        autorange: true,
        min_fraction: 0.05,
        nplc: 1.0,
        line_frequency_hz: 50,
        filter_count: 5,
        filter_type: FilterType::Repeat,
        samples: 3,
        zero_correct: true,
        range_settle_ms: 100,
        settle_residual: 1e-4,
        timeout_ms: 500,
        retries: 1,
        reconnect_attempts: 2,
        reconnect_delay_ms: 200,
    }
}

type Driver = K6485<ScriptedTransport, ManualClock>;

fn rig(config: K6485Config) -> (Driver, ScriptHandle, ManualClock) {
    let clock = ManualClock::new();
    let (t, h) = ScriptedTransport::new(b'\r', 256, clock.clone());
    let driver = K6485::new(t, clock.clone(), config).expect("valid config");
    (driver, h, clock)
}

fn script_setup(h: &ScriptHandle, c: &K6485Config) {
    script_setup_ending(h, c, "0,\"No error\"\r");
}

/// The set-up exchanges for `config()`, `SYST:ERR?` answering `last`.
fn script_setup_ending(h: &ScriptHandle, c: &K6485Config, last: &str) {
    let rang = |r: Range| format!("CURR:RANG 2E{}\r", i32::from(r.index()) - 9);
    // With autoranging the zero is taken on 2 nA, then the starting range is set.
    let zero = if c.autorange { Range::MOST } else { c.range };
    h.exchange("*IDN?\r", IDN)
        .send("*RST\r")
        .send("*CLS\r")
        .exchange("SYST:LFR?\r", "50\r")
        .send("FORM:ELEM READ,TIME,STAT\r")
        .send("TRIG:COUN 1\r")
        .send("CURR:NPLC 1\r")
        .send("AVER:TCON REP\r")
        .send("AVER:COUN 5\r")
        .send("AVER ON\r")
        .send("CURR:RANG:AUTO OFF\r")
        .send("SYST:ZCH ON\r")
        .send(rang(zero))
        .send("INIT\r")
        .send("SYST:ZCOR:ACQ\r")
        .send("SYST:ZCOR ON\r");
    if zero != c.range {
        h.send(rang(c.range));
    }
    h.send("SYST:ZCH OFF\r").exchange("SYST:ERR?\r", last);
}

fn ready(config: K6485Config) -> (Driver, ScriptHandle, ManualClock) {
    let (mut d, h, clock) = rig(config.clone());
    script_setup(&h, &config);
    d.setup().expect("scripted set-up");
    h.finish().expect("set-up transcript");
    (d, h, clock)
}

fn sample(v: f64, status: u16) -> String {
    if v > 1e37 {
        format!("+9.900000E+37A,+1.000000E+01,+{status}\r")
    } else {
        format!("{v:+e}A,+1.000000E+01,+{status}\r")
    }
}

#[test]
fn setup_transcript() {
    let (d, _h, clock) = ready(config());
    let id = d.identity().expect("identified");
    assert_eq!(
        (id.model.as_str(), id.serial.as_str()),
        ("MODEL 6485", "1234567")
    );
    assert_eq!(d.range(), range(3));
    // The only wait: the range's 100 ms before the zero is measured.
    assert_eq!(clock.now(), ms(100));
    assert_eq!(d.reconnects(), 0);
    assert_eq!(d.retried(), 0);
    assert_eq!(d.config().samples, 3);
}

#[test]
fn setup_refuses_another_instrument_and_reports_a_refused_command() {
    let (mut d, h, _) = rig(config());
    h.exchange("*IDN?\r", "KEITHLEY INSTRUMENTS INC.,MODEL 6517B,1,A\r");
    match d.setup() {
        Err(K6485Error::WrongInstrument(id)) => assert_eq!(id.model, "MODEL 6517B"),
        other => panic!("{other:?}"),
    }
    h.finish().expect("transcript");

    let (mut d, h, _) = rig(config());
    script_setup_ending(&h, &config(), "-221,\"Settings conflict\"\r");
    match d.setup() {
        Err(K6485Error::Rejected(ScpiError {
            code: -221,
            message,
        })) => {
            assert_eq!(message, "Settings conflict");
        }
        other => panic!("{other:?}"),
    }
    h.finish().expect("transcript");
}

#[test]
fn reading_averages_and_reports_its_accuracy() {
    let (mut d, h, clock) = ready(config());
    for v in [1.0e-6, 1.1e-6, 0.9e-6] {
        h.exchange("READ?\r", sample(v, 2));
    }
    let r = d.read().expect("reading");
    h.finish().expect("transcript");
    assert!(close(r.mean_a, 1e-6), "{}", r.mean_a);
    assert!(close(r.std_a, 1e-7), "{}", r.std_a);
    assert_eq!(
        (r.n, r.range, r.nplc, r.filter_count),
        (3, range(3), 1.0, 5)
    );
    assert!(r.is_valid());
    // Status 2: the filter bit, not a flag.
    assert_eq!(r.status.0, 2);
    assert!(close(r.accuracy_a(), accuracy_a(range(3), 1e-6)));
    assert!(close(r.accuracy_a(), 1.6e-9));
    // The 2 µA range set after the zero settles at 200 ms; the scripted replies come
    // at once.
    assert_eq!(clock.now(), ms(200));
}

#[test]
fn autorange_up_and_down_wait_each_range_change() {
    let (mut d, h, clock) = ready(config());
    // Overflow on 2 µA: up to 20 µA at once.
    h.exchange("READ?\r", sample(9.9e37, 1))
        .send("CURR:RANG 2E-5\r");
    for _ in 0..3 {
        h.exchange("READ?\r", sample(5e-6, 0));
    }
    let r = d.read().expect("reading");
    assert_eq!((r.range, r.autorange_steps), (range(4), 1));
    assert!(r.is_valid());
    assert_eq!(clock.now(), ms(300));
    // 0.5 µA is 0.025 of 20 µA: down to 2 µA.
    for _ in 0..3 {
        h.exchange("READ?\r", sample(5e-7, 0));
    }
    h.send("CURR:RANG 2E-6\r");
    for _ in 0..3 {
        h.exchange("READ?\r", sample(5e-7, 0));
    }
    let r = d.read().expect("reading");
    assert_eq!((r.range, r.autorange_steps), (range(3), 1));
    assert_eq!(d.range(), range(3));
    assert_eq!(clock.now(), ms(400));
    h.finish().expect("transcript");
}

#[test]
fn an_uncurable_overflow_is_flagged() {
    let (mut d, h, _) = ready(config());
    h.send("CURR:RANG 2E-2\r");
    d.set_range(Range::LEAST).expect("range");
    for _ in 0..3 {
        h.exchange("READ?\r", sample(9.9e37, 1));
    }
    let r = d.read().expect("flagged reading");
    assert!(r.flags.overflow && !r.is_valid());
    assert_eq!(r.current(), None);
    h.finish().expect("transcript");
    assert_eq!(r.autorange_steps, 0);
    assert_eq!(MAX_AUTORANGE_STEPS, 8);
}

#[test]
fn a_lost_reply_is_asked_again_after_the_timeout() {
    let (mut d, h, clock) = ready(K6485Config {
        samples: 1,
        autorange: false,
        ..config()
    });
    h.send("READ?\r").exchange("READ?\r", sample(1e-6, 0));
    let r = d.read().expect("reading");
    assert_eq!(r.current(), Some(1e-6));
    assert_eq!(d.retried(), 1);
    // The wait for the lost one: the zero's INIT measures until 200 ms (the scripted
    // replies do not wait for it), the READ? 100 ms more, then the 500 ms timeout.
    assert_eq!(clock.now(), ms(200 + 100 + 500));
    h.finish().expect("transcript");
}

#[test]
fn a_vanished_port_is_reopened_and_the_reading_restarted() {
    let (mut d, h, clock) = ready(K6485Config {
        samples: 2,
        autorange: false,
        ..config()
    });
    h.exchange("READ?\r", sample(1e-6, 0))
        .vanish(1)
        .exchange("READ?\r", sample(2e-6, 0));
    // The cycle starts again after the reopening and the range wait.
    h.exchange("READ?\r", sample(1e-6, 0))
        .exchange("READ?\r", sample(1e-6, 0));
    let r = d.read().expect("reading");
    assert!(close(r.mean_a, 1e-6));
    assert_eq!(d.reconnects(), 1);
    assert_eq!(d.retried(), 1);
    // Two 200 ms pauses before the reopenings, then 100 ms for the instrument.
    assert_eq!(clock.now(), ms(100 + 400 + 100));
    h.finish().expect("transcript");
}

#[test]
fn execute_and_input_changed() {
    let (mut d, h, clock) = ready(K6485Config {
        range: Range::MOST,
        ..config()
    });
    h.exchange("CURR:RANG?\r", "+2.000000E-09\r");
    assert_eq!(
        d.execute(&Command::QueryRange).expect("range"),
        Some(Reply::Range(Range::MOST))
    );
    let t0 = clock.now();
    d.input_changed();
    let wait = d.input_settle_time();
    assert!((wait.as_secs_f64() - 8e-3 * 1e4f64.ln() / 9f64.ln()).abs() < 1e-9);
    for _ in 0..3 {
        h.exchange("READ?\r", sample(1e-9, 0));
    }
    d.read().expect("reading");
    assert_eq!(clock.now(), t0 + wait);
    let (_transport, _clock) = d.into_inner();
    h.finish().expect("transcript");
}

#[test]
fn config_from_toml_and_refusals() {
    let c: K6485Config = toml::from_str(
        "range = \"20 uA\"\nautorange = false\nnplc = 10\nline_frequency_hz = 60\n\
         filter_count = 10\nfilter_type = \"moving\"",
    )
    .expect("config");
    assert_eq!(c.range, range(4));
    assert_eq!(c.filter_type, FilterType::Moving);
    assert!(!c.autorange);
    let c: K6485Config = toml::from_str("range = 2e-9").expect("amps");
    assert_eq!(c.range, Range::MOST);
    for text in [
        "range = 3e-9",
        "range = \"3 nA\"",
        "ranges = 1",
        "filter_type = \"median\"",
    ] {
        assert!(toml::from_str::<K6485Config>(text).is_err(), "{text}");
    }
    let clock = ManualClock::new();
    let (t, _h) = ScriptedTransport::new(b'\r', 256, clock.clone());
    match K6485::new(
        t,
        clock,
        K6485Config {
            nplc: 100.0,
            ..config()
        },
    ) {
        Err(K6485Error::Config(ConfigError { field, .. })) => assert_eq!(field, "nplc"),
        other => panic!("{other:?}"),
    }
}
