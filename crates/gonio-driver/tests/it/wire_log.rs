//! Observability: the pump logs every line sent and received at `trace` under the
//! target `gonio_driver::wire`, operations run in spans, state changes are `debug`
//! events and faults `warn` events.

use std::io::Write;
use std::sync::{Arc, Mutex};

use gonio_driver::smc100::{AxisConfig, ChainPolicy, Smc100Chain};
use gonio_driver::sr830::{Sr830, Sr830Config};
use gonio_driver::{ManualClock, ScriptedTransport};
use gonio_proto::sr830::{FilterSlope, Sensitivity, TimeConstant};

/// A log sink shared with the subscriber.
#[derive(Clone, Default)]
struct Sink(Arc<Mutex<Vec<u8>>>);

impl Write for Sink {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().expect("sink").extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl<'a> tracing_subscriber::fmt::MakeWriter<'a> for Sink {
    type Writer = Sink;
    fn make_writer(&'a self) -> Sink {
        self.clone()
    }
}

/// Runs `f` with every event at `trace` and above written to a string.
fn logged(f: impl FnOnce()) -> String {
    let sink = Sink::default();
    let subscriber = tracing_subscriber::fmt()
        .with_writer(sink.clone())
        .with_max_level(tracing::Level::TRACE)
        .with_ansi(false)
        .finish();
    tracing::subscriber::with_default(subscriber, f);
    let bytes = sink.0.lock().expect("sink").clone();
    String::from_utf8(bytes).expect("UTF-8 log")
}

fn axis() -> AxisConfig {
    AxisConfig {
        name: "source".into(),
        address: 1,
        units: "deg".into(),
        min: -170.0,
        max: 170.0,
        velocity: None,
        acceleration: None,
        tolerance: 0.01,
        home_timeout_s: 60.0,
    }
}

#[test]
fn a_move_logs_its_lines_its_span_and_its_states() {
    let log = logged(|| {
        let clock = ManualClock::new();
        let (t, h) = ScriptedTransport::new(b'\n', 128, clock.clone());
        let mut c =
            Smc100Chain::new(t, clock, vec![axis()], ChainPolicy::default()).expect("valid axes");
        h.exchange("1TP\r\n", "1TP0\r\n")
            .exchange("1PT12.5\r\n", "1PT1\r\n")
            .send("1PA12.5\r\n")
            // A lost acknowledgement: PA is re-sent, which is a retry.
            .send("1TE\r\n")
            .send("1PA12.5\r\n")
            .exchange("1TE\r\n", "1TE@\r\n")
            .exchange("1TS\r\n", "1TS000033\r\n")
            .exchange("1TP\r\n", "1TP12.5\r\n")
            .send("ST\r\n");
        assert_eq!(c.move_to(&[("source", 12.5)]).expect("moves"), vec![12.5]);
        drop(c);
        h.finish().expect("transcript");
    });
    let lines: Vec<&str> = log.lines().collect();
    let has = |parts: &[&str]| lines.iter().any(|l| parts.iter().all(|p| l.contains(p)));
    // Every line out and in, escaped, with its port and direction.
    assert!(
        has(&[
            "TRACE",
            "gonio_driver::wire",
            "port=\"script\"",
            "dir=\"tx\"",
            r"line=1PA12.5\r\n"
        ]),
        "{log}"
    );
    assert!(
        has(&["TRACE", "gonio_driver::wire", "dir=\"rx\"", "line=1TE@"]),
        "{log}"
    );
    assert!(has(&["dir=\"rx\"", "no reply within"]), "{log}");
    // The operation's span and its state changes.
    assert!(has(&["DEBUG", "smc100.move", "operation started"]), "{log}");
    assert!(has(&["DEBUG", "smc100.move", "stage READY"]), "{log}");
    assert!(
        has(&["DEBUG", "smc100.move", "operation finished"]),
        "{log}"
    );
    // The retry is a warning.
    assert!(has(&["WARN", "acknowledgement lost"]), "{log}");
}

#[test]
fn a_reading_logs_its_lines_and_its_settling_wait() {
    let log = logged(|| {
        let clock = ManualClock::new();
        let (t, h) = ScriptedTransport::new(b'\r', 256, clock.clone());
        let config = Sr830Config {
            sensitivity: Sensitivity::new(20).expect("SENS index"),
            time_constant: TimeConstant::new(8).expect("OFLT index"),
            slope: FilterSlope::Db24,
            samples: 1,
            autorange: false,
            ..Sr830Config::default()
        };
        let mut d = Sr830::new(t, clock, config).expect("valid config");
        h.send("OUTX 0\n")
            .exchange(
                "*IDN?\n",
                "Stanford_Research_Systems,SR830,s/n00111,ver1.000\r",
            )
            .send("*CLS\n")
            .send("SENS 20\n")
            .send("OFLT 8\n")
            .send("OFSL 3\n")
            .exchange("*ESR?\n", "0\r")
            .exchange("LIAS?\n", "0\r")
            .exchange("SNAP? 1,2\n", "0.003,0.004\r")
            .exchange("LIAS?\n", "0\r");
        d.setup().expect("set-up");
        assert!(d.read().expect("reading").is_valid());
        h.finish().expect("transcript");
    });
    let has = |parts: &[&str]| log.lines().any(|l| parts.iter().all(|p| l.contains(p)));
    assert!(
        has(&[
            "TRACE",
            "gonio_driver::wire",
            "dir=\"tx\"",
            r"line=SNAP? 1,2\n"
        ]),
        "{log}"
    );
    assert!(has(&["TRACE", "dir=\"rx\"", "line=0.003,0.004"]), "{log}");
    assert!(
        has(&["DEBUG", "sr830.read", "waiting for the filters to settle"]),
        "{log}"
    );
    assert!(
        has(&["DEBUG", "sr830.setup", "settling wait restarts"]),
        "{log}"
    );
}
