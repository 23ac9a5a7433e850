//! The SR830 driver against scripted transcripts, byte for byte, on virtual time:
//! set-up, averaging, settling waits, autoranging, flags, and every fault.

use std::time::Duration;

use gonio_driver::script::ScriptHandle;
use gonio_driver::sr830::{
    ConfigError, MAX_AUTORANGE_STEPS, Reading, ReadingFlags, Sr830, Sr830Config, Sr830Error,
};
use gonio_driver::{Clock, ManualClock, ScriptedTransport, Transport, TransportError};
use gonio_proto::sr830::{
    Command, EventStatus, FilterSlope, LiaStatus, Reply, ReplyError, Sensitivity, TimeConstant,
};

const IDN: &str = "Stanford_Research_Systems,SR830,s/n00111,ver1.000\r";

fn sens(i: u8) -> Sensitivity {
    Sensitivity::new(i).expect("SENS index")
}

fn tc(i: u8) -> TimeConstant {
    TimeConstant::new(i).expect("OFLT index")
}

/// 10 mV, 100 ms, 24 dB/oct (settling 1.0 s), 4 samples, autorange at 0.1 of full scale,
/// 500 ms timeout, 3 reconnections 200 ms apart.
fn config() -> Sr830Config {
    Sr830Config {
        sensitivity: sens(20),
        time_constant: tc(8),
        slope: FilterSlope::Db24,
        samples: 4,
        autorange: true,
        min_fraction: 0.1,
        timeout_ms: 500,
        reconnect_attempts: 3,
        reconnect_delay_ms: 200,
        retries: 0,
        settle_residual: 0.01,
        ..Sr830Config::default()
    }
}

type Driver = Sr830<ScriptedTransport, ManualClock>;

fn rig(config: Sr830Config) -> (Driver, ScriptHandle, ManualClock) {
    let clock = ManualClock::new();
    let (t, h) = ScriptedTransport::new(b'\r', 256, clock.clone());
    let driver = Sr830::new(t, clock.clone(), config).expect("valid config");
    (driver, h, clock)
}

/// The set-up exchanges for `config()`.
fn script_setup(h: &ScriptHandle) {
    h.send("OUTX 0\n")
        .exchange("*IDN?\n", IDN)
        .send("*CLS\n")
        .send("SENS 20\n")
        .send("OFLT 8\n")
        .send("OFSL 3\n")
        .exchange("*ESR?\n", "0\r");
}

/// A driver already set up with `config`, the clock still at zero.
fn ready(config: Sr830Config) -> (Driver, ScriptHandle, ManualClock) {
    let (mut d, h, clock) = rig(config.clone());
    h.send("OUTX 0\n")
        .exchange("*IDN?\n", IDN)
        .send("*CLS\n")
        .send(format!("SENS {}\n", config.sensitivity.index()))
        .send(format!("OFLT {}\n", config.time_constant.index()))
        .send(format!("OFSL {}\n", config.slope.index()))
        .exchange("*ESR?\n", "0\r");
    d.setup().expect("scripted set-up");
    assert_eq!(clock.now(), Duration::ZERO);
    (d, h, clock)
}

/// One read cycle: clear `LIAS?`, the `SNAP? 1,2` replies, then `LIAS?` → `status`.
fn script_cycle(h: &ScriptHandle, samples: &[&str], status: u8) {
    h.exchange("LIAS?\n", "0\r");
    for s in samples {
        h.exchange("SNAP? 1,2\n", format!("{s}\r"));
    }
    h.exchange("LIAS?\n", format!("{status}\r"));
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * b.abs().max(1e-300)
}

/// X, Y samples in volts whose R are 5, 6, 7, 8 mV.
const FOUR: [&str; 4] = ["0.003,0.004", "0.006,0", "0,-0.007", "-0.008,0"];

fn assert_four(r: &Reading) {
    assert_eq!(r.n, 4);
    assert!(close(r.r_mean, 0.0065), "{}", r.r_mean);
    // Deviations ±1.5, ±0.5 mV: sample variance (2·2.25 + 2·0.25)/3 mV² = 5/3 mV².
    assert!(close(r.r_std, (5.0f64 / 3.0).sqrt() * 1e-3), "{}", r.r_std);
    assert!(close(r.x_mean, 0.00025), "{}", r.x_mean);
    assert!(close(r.y_mean, -0.00075), "{}", r.y_mean);
}

#[test]
fn setup_transcript() {
    let (mut d, h, clock) = rig(config());
    script_setup(&h);
    let id = d.setup().unwrap();
    assert_eq!(id.model, "SR830");
    assert_eq!(id.serial, "s/n00111");
    assert_eq!(d.identity(), Some(&id));
    assert_eq!(h.sent()[0], b"OUTX 0\n");
    assert_eq!(
        (d.sensitivity(), d.time_constant(), d.slope()),
        (sens(20), tc(8), FilterSlope::Db24)
    );
    assert_eq!(d.settle_time(), Duration::from_secs(1));
    // Set-up sends and waits for nothing: the settling wait comes before a reading.
    assert_eq!(clock.now(), Duration::ZERO);
    h.finish().unwrap();
}

#[test]
fn setup_refuses_another_instrument() {
    let (mut d, h, _) = rig(config());
    h.send("OUTX 0\n").exchange(
        "*IDN?\n",
        "Stanford_Research_Systems,SR810,s/n00042,ver1.000\r",
    );
    match d.setup() {
        Err(Sr830Error::WrongInstrument(id)) => assert_eq!(id.model, "SR810"),
        other => panic!("{other:?}"),
    }
    h.finish().unwrap();
}

#[test]
fn setup_reports_refused_commands() {
    let (mut d, h, _) = rig(config());
    h.send("OUTX 0\n")
        .exchange("*IDN?\n", IDN)
        .send("*CLS\n")
        .send("SENS 20\n")
        .send("OFLT 8\n")
        .send("OFSL 3\n")
        .exchange("*ESR?\n", "16\r");
    match d.setup() {
        Err(Sr830Error::Rejected(s)) => {
            assert_eq!(s, EventStatus(EventStatus::EXE));
            assert!(s.has_command_error());
        }
        other => panic!("{other:?}"),
    }
    h.finish().unwrap();
}

#[test]
fn reading_averages_samples_after_settling() {
    let (mut d, h, clock) = ready(config());
    script_cycle(&h, &FOUR, 0);
    let r = d.read().unwrap();
    assert_four(&r);
    assert!(r.is_valid());
    assert_eq!(r.r(), Some(r.r_mean));
    assert_eq!(r.flags, ReadingFlags::default());
    assert_eq!(r.status, LiaStatus(0));
    assert_eq!(
        (r.sensitivity, r.time_constant, r.slope, r.autorange_steps),
        (sens(20), tc(8), FilterSlope::Db24, 0)
    );
    assert!(close(r.fraction_of_full_scale(), 0.65));
    // 24 dB/oct at 100 ms: settle 10 T = 1.0 s, then 3 gaps of T between 4 samples.
    assert_eq!(clock.now(), Duration::from_millis(1300));

    // Settled already: the next reading waits only between its samples.
    script_cycle(&h, &FOUR, 0);
    d.read().unwrap();
    assert_eq!(clock.now(), Duration::from_millis(1600));
    h.finish().unwrap();
}

#[test]
fn every_filter_change_restarts_the_settling_wait() {
    let mut c = config();
    c.samples = 1;
    let (mut d, h, clock) = ready(c);
    // 1 s at 12 dB/oct: 7 s.
    h.send("OFLT 10\n").send("OFSL 1\n");
    d.set_time_constant(tc(10)).unwrap();
    d.set_slope(FilterSlope::Db12).unwrap();
    assert_eq!(d.settle_time(), Duration::from_secs(7));
    script_cycle(&h, &["0.005,0"], 0);
    let r = d.read().unwrap();
    assert_eq!((r.time_constant, r.slope), (tc(10), FilterSlope::Db12));
    assert_eq!(clock.now(), Duration::from_secs(7));
    // A sensitivity change also waits the full settling time.
    h.send("SENS 21\n");
    d.set_sensitivity(sens(21)).unwrap();
    script_cycle(&h, &["0.005,0"], 0);
    assert_eq!(d.read().unwrap().sensitivity, sens(21));
    assert_eq!(clock.now(), Duration::from_secs(14));
    // The latest change counts: 30 ks set by mistake and undone does not cost days.
    h.send("OFLT 19\n").send("OFLT 8\n");
    d.set_time_constant(tc(19)).unwrap();
    d.set_time_constant(tc(8)).unwrap();
    script_cycle(&h, &["0.005,0"], 0);
    d.read().unwrap();
    assert_eq!(clock.now(), Duration::from_millis(14_700));
    h.finish().unwrap();
}

#[test]
fn auto_gain_reads_back_the_settings_it_chose() {
    let mut c = config();
    c.samples = 1;
    let (mut d, h, clock) = ready(c);
    h.send("AGAN\n")
        .exchange("SENS?\n", "17\r")
        .exchange("OFLT?\n", "8\r")
        .exchange("OFSL?\n", "3\r");
    assert_eq!(d.execute(&Command::AutoGain).unwrap(), None);
    assert_eq!(d.sensitivity(), sens(17));
    script_cycle(&h, &["0.0005,0"], 0);
    let r = d.read().unwrap();
    assert_eq!((r.sensitivity, r.r()), (sens(17), Some(0.0005)));
    assert_eq!(clock.now(), Duration::from_secs(1));
    // Any query goes through `execute` too.
    h.exchange("FREQ?\n", "1000.00\r");
    assert_eq!(
        d.execute(&Command::QueryFrequency).unwrap(),
        Some(Reply::Frequency(1000.0))
    );
    h.finish().unwrap();
}

#[test]
fn output_overload_steps_less_sensitive_and_reads_again() {
    let (mut d, h, clock) = ready(config());
    script_cycle(&h, &["0.0108,0.001"; 4], 4);
    h.send("SENS 21\n");
    script_cycle(&h, &FOUR, 0);
    let r = d.read().unwrap();
    assert_four(&r);
    assert!(r.is_valid());
    assert_eq!(r.sensitivity, sens(21));
    assert_eq!(r.autorange_steps, 1);
    assert_eq!(d.sensitivity(), sens(21));
    // Two settling waits and two sets of sample gaps.
    assert_eq!(clock.now(), Duration::from_millis(2600));
    h.finish().unwrap();
}

#[test]
fn input_overload_steps_less_sensitive_too() {
    let mut c = config();
    c.samples = 1;
    let (mut d, h, _) = ready(c);
    script_cycle(&h, &["0.002,0"], 1);
    h.send("SENS 21\n");
    script_cycle(&h, &["0.002,0"], 0);
    let r = d.read().unwrap();
    assert_eq!(
        (r.sensitivity, r.autorange_steps, r.r()),
        (sens(21), 1, Some(0.002))
    );
    h.finish().unwrap();
}

#[test]
fn small_signal_steps_more_sensitive_and_reads_again() {
    let mut c = config();
    c.samples = 2;
    let (mut d, h, _) = ready(c);
    // 0.5 mV on 10 mV is under 0.1 of full scale.
    script_cycle(&h, &["0.0005,0", "0,0.0005"], 0);
    h.send("SENS 19\n");
    // 0.6 mV on 5 mV is 0.12 of full scale: stays.
    script_cycle(&h, &["0.0006,0", "0,-0.0006"], 0);
    let r = d.read().unwrap();
    assert_eq!(r.sensitivity, sens(19));
    assert_eq!(r.autorange_steps, 1);
    assert!(close(r.r_mean, 0.0006));
    assert_eq!(r.r_std, 0.0);
    assert!(r.is_valid());
    h.finish().unwrap();
}

#[test]
fn overload_at_the_least_sensitive_range_is_returned_flagged() {
    let mut c = config();
    c.sensitivity = Sensitivity::LEAST;
    c.samples = 1;
    let (mut d, h, _) = ready(c);
    script_cycle(&h, &["1.2,0"], 1);
    let r = d.read().unwrap();
    assert!(r.flags.input_overload);
    assert!(!r.is_valid());
    assert_eq!(r.r(), None);
    assert_eq!(r.sensitivity, Sensitivity::LEAST);
    h.finish().unwrap();
}

#[test]
fn without_autorange_an_overload_is_only_flagged() {
    let mut c = config();
    c.autorange = false;
    c.samples = 1;
    let (mut d, h, _) = ready(c);
    script_cycle(&h, &["0.011,0"], 4);
    let r = d.read().unwrap();
    assert!(r.flags.output_overload && !r.is_valid());
    assert_eq!((r.sensitivity, r.autorange_steps), (sens(20), 0));
    // A tiny signal is not ranged either.
    script_cycle(&h, &["0.00001,0"], 0);
    let r = d.read().unwrap();
    assert!(r.is_valid());
    assert_eq!(r.sensitivity, sens(20));
    h.finish().unwrap();
}

#[test]
fn unlock_and_filter_overload_are_flagged_and_invalid() {
    let mut c = config();
    c.samples = 2;
    let (mut d, h, _) = ready(c);
    // Unlocked, with a signal small enough to range down: no range change on a
    // flagged reading.
    script_cycle(&h, &["0.0001,0", "0.0001,0"], 8);
    let r = d.read().unwrap();
    assert_eq!(
        r.flags,
        ReadingFlags {
            unlock: true,
            ..ReadingFlags::default()
        }
    );
    assert!(!r.is_valid());
    assert_eq!(r.r(), None);
    assert_eq!(r.status, LiaStatus(LiaStatus::UNLOCK));
    assert_eq!(r.sensitivity, sens(20));

    script_cycle(&h, &["0.005,0", "0.005,0"], 2);
    let r = d.read().unwrap();
    assert!(r.flags.filter_overload && !r.flags.unlock);
    assert!(!r.is_valid());
    // Bits that do not spoil a reading (TC changed, range) do not flag it.
    script_cycle(&h, &["0.005,0", "0.005,0"], 32 | 16);
    assert!(d.read().unwrap().is_valid());
    h.finish().unwrap();
}

#[test]
fn autorange_gives_up_on_an_oscillating_signal() {
    let mut c = config();
    c.samples = 1;
    let (mut d, h, _) = ready(c);
    // Overload at 10 mV, too small at 20 mV, and so on.
    for step in 0..MAX_AUTORANGE_STEPS {
        if step % 2 == 0 {
            script_cycle(&h, &["0.011,0"], 4);
            h.send("SENS 21\n");
        } else {
            script_cycle(&h, &["0.0001,0"], 0);
            h.send("SENS 20\n");
        }
    }
    script_cycle(&h, &["0.011,0"], 4);
    match d.read() {
        Err(Sr830Error::Autorange { steps, last }) => {
            assert_eq!(steps, MAX_AUTORANGE_STEPS);
            assert!(last.flags.output_overload && !last.is_valid());
        }
        other => panic!("{other:?}"),
    }
    h.finish().unwrap();
}

#[test]
fn no_reply_is_a_timeout() {
    let (mut d, h, clock) = ready(config());
    h.exchange("LIAS?\n", "0\r").send("SNAP? 1,2\n");
    match d.read() {
        Err(Sr830Error::Transport { command, source }) => {
            assert_eq!(command, "SNAP? 1,2");
            assert_eq!(source, TransportError::Timeout(Duration::from_millis(500)));
        }
        other => panic!("{other:?}"),
    }
    // Settling 1.0 s, then the 0.5 s timeout.
    assert_eq!(clock.now(), Duration::from_millis(1500));
    // The driver is usable afterwards.
    script_cycle(&h, &FOUR, 0);
    assert!(d.read().unwrap().is_valid());
    h.finish().unwrap();
}

#[test]
fn a_reply_without_terminator_is_a_timeout() {
    let (mut d, h, _) = ready(config());
    h.exchange("LIAS?\n", "0\r")
        .exchange("SNAP? 1,2\n", "0.9513");
    assert!(matches!(
        d.read(),
        Err(Sr830Error::Transport {
            source: TransportError::Timeout(_),
            ..
        })
    ));
    h.finish().unwrap();
}

#[test]
fn garbage_and_truncated_replies_are_protocol_errors_with_the_bytes() {
    let (mut d, h, _) = ready(config());
    let cases: [(&str, &[u8], ReplyError); 3] = [
        ("0.95#1,xyz\r", b"0.95#1,xyz", ReplyError::BadValue),
        ("0.951359,\r", b"0.951359,", ReplyError::BadValue),
        (
            "0.951359\r",
            b"0.951359",
            ReplyError::WrongCount {
                expected: 2,
                got: 1,
            },
        ),
    ];
    for (reply, bytes, error) in cases {
        h.exchange("LIAS?\n", "0\r").exchange("SNAP? 1,2\n", reply);
        match d.read() {
            Err(Sr830Error::Protocol {
                command,
                reply,
                source,
            }) => {
                assert_eq!(command, "SNAP? 1,2");
                assert_eq!(reply, bytes);
                assert_eq!(source, error);
            }
            other => panic!("{other:?}"),
        }
    }
    // A status byte out of range is refused too.
    h.exchange("LIAS?\n", "300\r");
    assert!(matches!(
        d.read(),
        Err(Sr830Error::Protocol {
            source: ReplyError::OutOfRange(_),
            ..
        })
    ));
    h.finish().unwrap();
}

#[test]
fn nul_byte_is_a_typed_error() {
    let (mut d, h, _) = ready(config());
    h.exchange("LIAS?\n", "0\r")
        .exchange("SNAP? 1,2\n", "0.95\x001,0.1\r");
    match d.read() {
        Err(Sr830Error::Transport { command, source }) => {
            assert_eq!(command, "SNAP? 1,2");
            assert_eq!(source, TransportError::Nul);
        }
        other => panic!("{other:?}"),
    }
    h.finish().unwrap();
}

#[test]
fn vanished_port_is_reopened_and_the_reading_restarted() {
    let (mut d, h, clock) = ready(config());
    h.exchange("LIAS?\n", "0\r")
        .exchange("SNAP? 1,2\n", "0.1,0.1\r")
        // The port vanishes; one reopening fails, the second works.
        .vanish(1)
        .send("OUTX 0\n")
        // The query is retried...
        .exchange("SNAP? 1,2\n", "0.1,0.1\r");
    // ...then the whole cycle starts over, after settling again.
    script_cycle(&h, &FOUR, 0);
    let r = d.read().unwrap();
    assert_four(&r);
    assert!(r.is_valid());
    assert_eq!(h.reconnects(), 1);
    assert_eq!(d.reconnects(), 1);
    // Settle 1.0 s, one gap 0.1 s, two reconnection delays 0.2 s, settle 1.0 s,
    // three gaps 0.3 s.
    assert_eq!(clock.now(), Duration::from_millis(2800));
    h.finish().unwrap();
}

#[test]
fn vanished_port_during_a_set_command_is_recovered() {
    let (mut d, h, _) = ready(config());
    h.vanish(0).send("OUTX 0\n").send("SENS 22\n");
    d.set_sensitivity(sens(22)).unwrap();
    assert_eq!(d.sensitivity(), sens(22));
    assert_eq!(h.reconnects(), 1);
    h.finish().unwrap();
}

#[test]
fn port_that_stays_away_is_an_error_after_the_configured_attempts() {
    let (mut d, h, clock) = ready(config());
    h.exchange("LIAS?\n", "0\r").vanish(3);
    match d.read() {
        Err(Sr830Error::Disconnected {
            attempts, source, ..
        }) => {
            assert_eq!(attempts, 3);
            assert!(matches!(source, TransportError::Disconnected { .. }));
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(h.reconnects(), 0);
    // Settle 1.0 s, then three delays of 0.2 s.
    assert_eq!(clock.now(), Duration::from_millis(1600));
    // The port comes back later: the script's vanish step is then used up.
    let (mut t, _) = d.into_inner();
    t.reconnect().unwrap();
    assert_eq!(h.reconnects(), 1);
    h.finish().unwrap();
}

#[test]
fn config_file_fields() {
    #[derive(serde::Deserialize)]
    struct File {
        detector: Sr830Config,
    }
    let f: File = toml::from_str(
        r#"
        [detector]
        sensitivity = "10 mV"
        time_constant = "300 ms"
        slope_db = 18
        samples = 5
        autorange = false
        min_fraction = 0.2
        timeout_ms = 2000
        reconnect_attempts = 1
        reconnect_delay_ms = 50
        "#,
    )
    .unwrap();
    let c = f.detector;
    assert_eq!(c.sensitivity, sens(20));
    assert_eq!(c.time_constant, tc(9));
    assert_eq!(c.slope, FilterSlope::Db18);
    assert_eq!((c.samples, c.autorange, c.min_fraction), (5, false, 0.2));
    assert_eq!(c.timeout(), Duration::from_secs(2));
    assert_eq!(c.reconnect_delay(), Duration::from_millis(50));
    c.validate().unwrap();

    // Indices work too; omitted fields take the defaults.
    let c: Sr830Config = toml::from_str("sensitivity = 20\ntime_constant = 19").unwrap();
    assert_eq!((c.sensitivity, c.time_constant), (sens(20), tc(19)));
    assert_eq!(c.slope, FilterSlope::Db12);
    assert_eq!(Sr830Config::default().sensitivity, Sensitivity::LEAST);

    for (text, needle) in [
        ("sensitivity = \"11 mV\"", "11 mV"),
        ("sensitivity = 27", "27"),
        ("time_constant = \"2 s\"", "2 s"),
        ("slope_db = 3", "3 dB/oct"),
        ("gain = 3", "gain"),
    ] {
        let e = toml::from_str::<Sr830Config>(text).unwrap_err().to_string();
        assert!(e.contains(needle), "{text}: {e}");
    }
}

#[test]
fn validation_names_the_field() {
    let bad = |f: fn(&mut Sr830Config)| {
        let mut c = config();
        f(&mut c);
        c.validate().unwrap_err().field
    };
    assert_eq!(bad(|c| c.samples = 0), "samples");
    assert_eq!(bad(|c| c.min_fraction = 0.4), "min_fraction");
    assert_eq!(bad(|c| c.min_fraction = -0.1), "min_fraction");
    assert_eq!(bad(|c| c.min_fraction = f64::NAN), "min_fraction");
    assert_eq!(bad(|c| c.timeout_ms = 0), "timeout_ms");
    assert_eq!(bad(|c| c.reconnect_attempts = 1000), "reconnect_attempts");
    assert_eq!(
        bad(|c| c.reconnect_delay_ms = 600_000),
        "reconnect_delay_ms"
    );
    config().validate().unwrap();

    let clock = ManualClock::new();
    let (t, h) = ScriptedTransport::new(b'\r', 256, clock.clone());
    let mut c = config();
    c.samples = 0;
    match Sr830::new(t, clock, c) {
        Err(Sr830Error::Config(ConfigError { field, .. })) => assert_eq!(field, "samples"),
        other => panic!("{:?}", other.map(|_| ())),
    }
    h.finish().unwrap();
}

/// With `retries`, a lost or garbled answer to a read-only query is asked again, and
/// the reading is the same as without the fault; a lost `LIAS?` is never re-asked
/// (reading it clears the latched flags).
#[test]
fn read_only_queries_are_retried_status_bytes_are_not() {
    let cfg = Sr830Config {
        retries: 2,
        ..config()
    };
    let (mut d, h, _) = ready(cfg.clone());
    h.exchange("LIAS?\n", "0\r")
        .exchange("SNAP? 1,2\n", "0.00#3,0.004\r")
        .send("SNAP? 1,2\n")
        .exchange("SNAP? 1,2\n", "0.003,0.004\r");
    for s in &FOUR[1..] {
        h.exchange("SNAP? 1,2\n", format!("{s}\r"));
    }
    h.exchange("LIAS?\n", "0\r");
    let r = d.read().unwrap();
    assert_four(&r);
    assert_eq!(d.retried(), 2);
    h.finish().unwrap();

    // The flags' answer is lost: the cycle starts again, and the flag it then reports
    // is not lost.
    let (mut d, h, _) = ready(cfg);
    script_cycle_without_flags(&h, &FOUR);
    h.send("LIAS?\n");
    script_cycle(&h, &FOUR, 8);
    let r = d.read().unwrap();
    assert!(r.flags.unlock && !r.is_valid());
    assert_eq!(d.retried(), 1);
    h.finish().unwrap();
}

/// A read cycle whose final `LIAS?` is left to the caller.
fn script_cycle_without_flags(h: &ScriptHandle, samples: &[&str]) {
    h.exchange("LIAS?\n", "0\r");
    for s in samples {
        h.exchange("SNAP? 1,2\n", format!("{s}\r"));
    }
}

/// After the light changes (a move), the next reading waits a full settling time even
/// though no setting changed: 24 dB/oct at 100 ms is 1 s.
#[test]
fn a_changed_input_waits_for_settling() {
    let (mut d, h, clock) = ready(config());
    script_cycle(&h, &FOUR, 0);
    d.read().unwrap();
    let before = clock.now();
    d.input_changed();
    script_cycle(&h, &FOUR, 0);
    d.read().unwrap();
    // The settling second, then three sample spacings of 100 ms.
    assert_eq!(clock.now() - before, Duration::from_millis(1300));
    h.finish().unwrap();
}

/// A tighter settling target waits longer: 1e-4 of the step at 24 dB/oct is the root
/// of e^-a (1 + a + a²/2 + a³/6) = 1e-4, 15.9 time constants.
#[test]
fn settle_residual_sets_the_wait() {
    let d = rig(Sr830Config {
        settle_residual: 1e-4,
        ..config()
    })
    .0;
    let t = d.settle_time().as_secs_f64();
    assert!((t - 1.5914).abs() < 1e-3, "{t}");
    let a = t / 0.1;
    let resid = (-a).exp() * (1.0 + a + a * a / 2.0 + a * a * a / 6.0);
    assert!((resid - 1e-4).abs() < 1e-9, "{resid}");
    assert!(
        Sr830Config {
            settle_residual: 0.0,
            ..config()
        }
        .validate()
        .is_err()
    );
}
