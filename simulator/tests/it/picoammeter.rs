//! The real `K6485Session` driving the simulated picoammeter, in memory, on virtual
//! time: a tiny pump hands the session's bytes to [`Picoammeter::handle_line`] and its
//! replies back at [`Picoammeter::busy_until`]. Set-up, the noise model against its
//! analytic prediction (mean and variance, with chi-square bounds), autoranging both
//! ways, zero correction, the front end's settling, timing, and reproducibility.

use std::collections::VecDeque;
use std::time::Duration;

use gonio_proto::k6485::{
    Command, FilterType, K6485Config, K6485Session, PicoReading, Range, Reply, ScpiError,
};
use gonio_proto::link::{Deadline, Io, Operation};
use gonio_sim::picoammeter::{BOLTZMANN, ELEMENTARY_CHARGE, Picoammeter, PicoammeterConfig};

/// The twin, the time, and a record of the wire.
struct Rig {
    pico: Picoammeter,
    now: Duration,
    /// Replies on their way: (time due, line without terminator).
    inbox: VecDeque<(Duration, Vec<u8>)>,
    /// Every line sent, with its time.
    sent: Vec<(Duration, Vec<u8>)>,
    /// Every byte received, terminators included.
    received: Vec<u8>,
}

impl Rig {
    fn new(config: &PicoammeterConfig, seed: u64) -> Self {
        Rig {
            pico: Picoammeter::new(config, seed),
            now: Duration::ZERO,
            inbox: VecDeque::new(),
            sent: Vec::new(),
            received: Vec::new(),
        }
    }

    fn secs(&self) -> f64 {
        self.now.as_secs_f64()
    }

    /// Pumps `op` to its end: lines to the twin at the time they are sent, replies
    /// handed back when the twin has them ready, the clock moved to each deadline.
    fn run<O: Operation>(&mut self, mut op: O) -> O::Output {
        loop {
            while let Some(io) = op.poll_io() {
                match io {
                    Io::Transmit(bytes) => {
                        let bytes = bytes.to_vec();
                        self.sent.push((self.now, bytes.clone()));
                        let line = bytes.strip_suffix(b"\r").unwrap_or(&bytes);
                        let mut out = Vec::new();
                        self.pico
                            .handle_line(self.now.as_secs_f64(), line, &mut out);
                        let due = Duration::from_secs_f64(self.pico.busy_until()).max(self.now);
                        for reply in out.split(|b| *b == b'\r').filter(|l| !l.is_empty()) {
                            self.inbox.push_back((due, reply.to_vec()));
                        }
                        op.handle_sent(self.now, Ok(()));
                    }
                    Io::ClearInput => self.inbox.clear(),
                    Io::Reconnect => op.handle_reconnected(self.now, Ok(())),
                }
            }
            if let Some(out) = op.poll_output() {
                return out;
            }
            match op.poll_timeout().expect("a deadline") {
                Deadline::Reply(at) => match self.inbox.front() {
                    Some((due, _)) if *due <= at => {
                        let (due, line) = self.inbox.pop_front().expect("front");
                        self.now = self.now.max(due);
                        self.received.extend_from_slice(&line);
                        self.received.push(b'\r');
                        op.handle_line(self.now, &line);
                    }
                    _ => {
                        self.now = self.now.max(at);
                        op.handle_timeout(self.now);
                    }
                },
                Deadline::Poll(at) | Deadline::Sleep(at) => {
                    self.now = self.now.max(at);
                    op.handle_timeout(self.now);
                }
            }
        }
    }

    /// A session set up on the twin with `config`.
    fn session(&mut self, config: K6485Config) -> K6485Session {
        let mut s = K6485Session::new(config, "twin", self.now).expect("valid config");
        let now = self.now;
        let id = self.run(s.start_setup(now)).expect("set up");
        assert_eq!(id.model, "MODEL 6485");
        s
    }

    fn read(&mut self, s: &mut K6485Session) -> PicoReading {
        let now = self.now;
        self.run(s.start_read(now)).expect("reading")
    }

    /// The light changes now (the session is told, as after a move).
    fn light(&mut self, s: &mut K6485Session, watts: f64) {
        let t = self.secs();
        self.pico.set_input(t, watts);
        s.input_changed(self.now);
    }
}

/// A fixed range, 1 PLC at 50 Hz, filter off, `samples` samples, zero correction.
fn fixed(range: Range, samples: usize) -> K6485Config {
    K6485Config {
        range,
        autorange: false,
        nplc: 1.0,
        line_frequency_hz: 50,
        filter_count: 1,
        samples,
        zero_correct: true,
        ..K6485Config::default()
    }
}

fn range(i: u8) -> Range {
    Range::new(i).expect("range index")
}

/// The variance of one conversion, from the physics alone (not the twin's code): shot
/// 2qIB, Johnson 4kTB/R, B = 1/(2T), and the meter's noise at 1 PLC scaled by 1/NPLC.
fn predicted_variance(pc: &PicoammeterConfig, r: Range, i: f64, nplc: f64) -> [f64; 3] {
    let t = nplc / f64::from(pc.line_frequency_hz);
    let b = 1.0 / (2.0 * t);
    let shot = 2.0 * ELEMENTARY_CHARGE * i.abs() * b;
    let johnson = 4.0 * BOLTZMANN * pc.temperature_k * b / pc.shunt_resistance_ohm;
    let meter = pc.meter_noise_a[usize::from(r.index())].powi(2) / nplc;
    [shot, johnson, meter]
}

/// The chi-square quantile for `k` degrees of freedom at `z` standard normal
/// deviations, by Wilson and Hilferty's cube-root approximation (accurate to a few
/// parts in 1e3 for k in the hundreds).
fn chi2_quantile(k: f64, z: f64) -> f64 {
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}

/// Asserts that the sample variance of `n` values is consistent with `var` at ±5
/// standard normal deviations (false-alarm rate about 6e-7).
fn assert_variance(r: &PicoReading, var: f64, what: &str) {
    let k = (r.n - 1) as f64;
    let lo = chi2_quantile(k, -5.0) / k * var;
    let hi = chi2_quantile(k, 5.0) / k * var;
    let s2 = r.std_a * r.std_a;
    assert!(
        (lo..=hi).contains(&s2),
        "{what}: sample variance {s2:e} outside [{lo:e}, {hi:e}] (predicted {var:e})"
    );
}

#[test]
fn setup_over_the_twin_leaves_it_zero_corrected() {
    let pc = PicoammeterConfig {
        input_offset_a: 30e-12,
        ..PicoammeterConfig::default()
    };
    let mut rig = Rig::new(&pc, 1);
    assert!(rig.pico.zero_check(), "powers up zero-checked");
    let s = rig.session(fixed(range(1), 10));
    assert!(!rig.pico.zero_check() && rig.pico.zero_correct());
    assert_eq!(rig.pico.range(), range(1));
    assert_eq!(s.range(), range(1));
    // The zero is one conversion of offset + meter noise (100 fA at 1 PLC on 20 nA).
    assert!(
        (rig.pico.zero_value() - 30e-12).abs() < 5.0 * 100e-15,
        "{}",
        rig.pico.zero_value()
    );
    // The session's idea of the instrument's busy time matches the twin's.
    assert!((s.busy_until().as_secs_f64() - rig.pico.busy_until()).abs() < 1e-9);
}

/// Mean and scatter of many readings against responsivity × power + dark and the
/// analytic noise, in three regimes: shot-, meter- and Johnson-dominated.
#[test]
fn readings_follow_the_photocurrent_and_the_noise_model() {
    let n = 2000;
    let cases = [
        // 1 nA on 2 nA: shot noise 89 fA against the meter's 20 fA.
        (
            "shot",
            PicoammeterConfig::default(),
            range(0),
            1e-9 / 0.3,
            0,
        ),
        // 0.3 µA on 2 µA: the meter's 10 pA dominates.
        ("meter", PicoammeterConfig::default(), range(3), 1e-6, 2),
        // A 10 kΩ shunt: 0.2 nA/√(T) of Johnson noise current dominates.
        (
            "johnson",
            PicoammeterConfig {
                shunt_resistance_ohm: 1e4,
                ..PicoammeterConfig::default()
            },
            range(1),
            1e-9,
            1,
        ),
    ];
    for (what, pc, r, watts, dominant) in cases {
        let mut rig = Rig::new(&pc, 7);
        let mut s = rig.session(fixed(r, n));
        rig.light(&mut s, watts);
        let reading = rig.read(&mut s);
        assert!(reading.is_valid(), "{what}: {reading:?}");
        assert_eq!((reading.n, reading.range), (n, r));
        let i = pc.responsivity_a_per_w * watts + pc.dark_current_a;
        let parts = predicted_variance(&pc, r, i, 1.0);
        let var: f64 = parts.iter().sum();
        assert!(parts[dominant] > 0.6 * var, "{what}: {parts:?}");
        // The zero was one conversion on this range with the source disconnected: its
        // error (the meter's noise alone) stays in every corrected reading.
        let zero_var = parts[2];
        let tol = 5.0 * (var / n as f64 + zero_var).sqrt();
        assert!(
            (reading.mean_a - i).abs() < tol,
            "{what}: mean {:e} vs {i:e} (±{tol:e})",
            reading.mean_a
        );
        assert_variance(&reading, var, what);
    }
}

#[test]
fn autorange_steps_up_on_overflow_and_down_on_a_small_signal() {
    let pc = PicoammeterConfig::default();
    let mut rig = Rig::new(&pc, 3);
    let config = K6485Config {
        autorange: true,
        min_fraction: 0.05,
        samples: 5,
        range: Range::MOST,
        ..fixed(Range::MOST, 5)
    };
    let mut s = rig.session(config);
    // 0.3 µA overflows 2 nA, 20 nA and 200 nA (1.05 × 200 nA = 210 nA): 2 µA.
    rig.light(&mut s, 1e-6);
    let r = rig.read(&mut s);
    assert!(r.is_valid(), "{r:?}");
    assert_eq!((r.range, r.autorange_steps), (range(3), 3));
    let i = 0.3e-6 + pc.dark_current_a;
    assert!(
        (r.mean_a - i).abs() < 5.0 * 10e-12 + 0.0,
        "{} vs {i}",
        r.mean_a
    );
    assert_eq!(rig.pico.range(), range(3));
    let overflowed = rig.received.windows(6).filter(|w| *w == b"+9.900").count();
    assert_eq!(overflowed, 3, "one overflowed sample per range crossed");

    // 0.31 nA is under 0.05 of 2 µA, 200 nA and 20 nA: down to 2 nA.
    rig.light(&mut s, 1e-9);
    let r = rig.read(&mut s);
    assert!(r.is_valid(), "{r:?}");
    assert_eq!((r.range, r.autorange_steps), (range(0), 3));
    let i = 0.3e-9 + pc.dark_current_a;
    // The zero was taken on 2 nA: its error and the noise, within 5 σ.
    let var: f64 = predicted_variance(&pc, range(0), i, 1.0).iter().sum();
    let tol = 5.0 * (var / 5.0 + 20e-15f64.powi(2)).sqrt();
    assert!((r.mean_a - i).abs() < tol, "{} vs {i} (±{tol})", r.mean_a);
}

#[test]
fn an_overflow_on_20_ma_is_flagged() {
    let pc = PicoammeterConfig::default();
    let mut rig = Rig::new(&pc, 4);
    let mut s = rig.session(K6485Config {
        autorange: true,
        ..fixed(Range::LEAST, 3)
    });
    // 0.3 A/W × 0.1 W = 30 mA: over 21 mA.
    rig.light(&mut s, 0.1);
    let r = rig.read(&mut s);
    assert!(r.flags.overflow && !r.is_valid());
    assert_eq!((r.range, r.n, r.current()), (Range::LEAST, 0, None));
}

/// The offset the meter adds is read as is without zero correction and removed with
/// it; zero check reads it alone.
#[test]
fn zero_correction_removes_the_offset() {
    let pc = PicoammeterConfig {
        input_offset_a: 50e-12,
        ..PicoammeterConfig::default()
    };
    let watts = 0.5e-9 / 0.3;
    let i = 0.5e-9 + pc.dark_current_a;
    let n = 400;
    let mut means = Vec::new();
    for zero_correct in [false, true] {
        let mut rig = Rig::new(&pc, 11);
        let mut s = rig.session(K6485Config {
            zero_correct,
            ..fixed(Range::MOST, n)
        });
        rig.light(&mut s, watts);
        let r = rig.read(&mut s);
        assert!(r.is_valid());
        means.push(r.mean_a);

        // Zero check on: the reading is the offset alone, flagged.
        let now = rig.now;
        rig.run(s.start_execute(&Command::ZeroCheck(true), now))
            .expect("zero check");
        let z = rig.read(&mut s);
        assert!(z.flags.zero_check && !z.is_valid());
        let expected = if zero_correct { 0.0 } else { 50e-12 };
        // Meter noise only: 20 fA per conversion, and the zero's own conversion.
        let tol = 5.0 * (20e-15f64.powi(2) / n as f64 + 20e-15f64.powi(2)).sqrt();
        assert!(
            (z.mean_a - expected).abs() < tol,
            "{} vs {expected}",
            z.mean_a
        );
    }
    let var: f64 = predicted_variance(&pc, Range::MOST, i, 1.0).iter().sum();
    let tol = 5.0 * (var / n as f64 + 20e-15f64.powi(2)).sqrt();
    assert!(
        (means[0] - (i + 50e-12)).abs() < tol,
        "{} uncorrected",
        means[0]
    );
    assert!((means[1] - i).abs() < tol, "{} corrected", means[1]);
}

/// Without `input_changed`, the first conversion after a step of light averages the
/// front end's rise (8 ms on 2 nA: τ = 3.64 ms against 20 ms of integration, 18 %
/// short); with it, the session waits for the settling and reads the new value.
#[test]
fn readings_after_a_step_wait_for_the_front_end() {
    let pc = PicoammeterConfig::default();
    let new_i = 1e-9 + pc.dark_current_a;
    let tau = 8e-3 / 9f64.ln();
    let t = 0.02;
    let deficit = tau / t * (1.0 - (-t / tau).exp());
    let mut got = Vec::new();
    for tell in [false, true] {
        let mut rig = Rig::new(&pc, 5);
        let mut s = rig.session(fixed(Range::MOST, 1));
        let now = rig.secs();
        rig.pico.set_input(now, 1e-9 / 0.3);
        if tell {
            s.input_changed(rig.now);
        }
        got.push(rig.read(&mut s).mean_a);
    }
    let step = 1e-9;
    let sigma = 5.0 * 120e-15;
    assert!(
        (got[0] - (new_i - deficit * step)).abs() < sigma,
        "unsettled {} vs {}",
        got[0],
        new_i - deficit * step
    );
    assert!(
        (got[1] - new_i).abs() < sigma,
        "settled {} vs {new_i}",
        got[1]
    );
}

/// `READ?` answers when its conversions are done: 4 × 2 PLC at 60 Hz with the repeat
/// filter is 133.3 ms, and the session's timing agrees with the twin's.
#[test]
fn reads_are_paced_by_the_integration() {
    let pc = PicoammeterConfig {
        line_frequency_hz: 60,
        ..PicoammeterConfig::default()
    };
    let mut rig = Rig::new(&pc, 6);
    let mut s = rig.session(K6485Config {
        line_frequency_hz: 60,
        nplc: 2.0,
        filter_count: 4,
        filter_type: FilterType::Repeat,
        ..fixed(range(2), 5)
    });
    rig.light(&mut s, 1e-7);
    let from = rig.sent.len();
    let r = rig.read(&mut s);
    assert_eq!(r.filter_count, 4);
    assert!(r.status.has(gonio_proto::k6485::StatusWord::FILTER));
    let times: Vec<f64> = rig.sent[from..]
        .iter()
        .map(|(t, _)| t.as_secs_f64())
        .collect();
    assert_eq!(times.len(), 5);
    for w in times.windows(2) {
        assert!((w[1] - w[0] - 4.0 * 2.0 / 60.0).abs() < 1e-6, "{w:?}");
    }
    assert!((rig.pico.busy_until() - (times[4] + 4.0 * 2.0 / 60.0)).abs() < 1e-6);
}

/// The same seed and commands give the same bytes; another seed, other bytes; and a
/// restart makes a point read the same whatever came before it.
#[test]
fn same_seed_same_bytes_and_restart_forgets_the_history() {
    let pc = PicoammeterConfig::default();
    let scenario = |seed: u64, extra: usize| {
        let mut rig = Rig::new(&pc, seed);
        let mut s = rig.session(K6485Config {
            autorange: true,
            ..fixed(Range::LEAST, 4)
        });
        rig.light(&mut s, 2e-7);
        rig.read(&mut s);
        for _ in 0..extra {
            rig.read(&mut s);
        }
        (rig, s)
    };
    let (a, _) = scenario(42, 0);
    let (b, _) = scenario(42, 0);
    let (c, _) = scenario(43, 0);
    assert_eq!(a.received, b.received);
    assert_ne!(a.received, c.received);

    // Two histories (one read more), then a restart at the same time and seed.
    let (mut a, mut sa) = scenario(42, 0);
    let (mut b, mut sb) = scenario(42, 2);
    let t = a.now.max(b.now) + Duration::from_secs(1);
    let mut reads = Vec::new();
    for (rig, s) in [(&mut a, &mut sa), (&mut b, &mut sb)] {
        rig.now = t;
        rig.pico.restart(t.as_secs_f64(), 99);
        let from = rig.received.len();
        let r = rig.read(s);
        reads.push((r, rig.received[from..].to_vec()));
    }
    assert_eq!(reads[0].0, reads[1].0);
    assert_eq!(reads[0].1, reads[1].1);
}

#[test]
fn protocol_errors_and_queries() {
    let pc = PicoammeterConfig::default();
    let mut p = Picoammeter::new(&pc, 0);
    let mut out = Vec::new();
    p.handle_line(0.0, b"*IDN?", &mut out);
    assert_eq!(
        out,
        b"KEITHLEY INSTRUMENTS INC.,MODEL 6485,1234567,B03   Sep 25 2002 10:53:29/A02  /E\r"
    );
    out.clear();
    p.handle_line(0.0, b"SYST:LFR?;*ESR?", &mut out);
    assert_eq!(out, b"50\r128\r");
    out.clear();
    // 55 PLC is over the 50 allowed at 50 Hz; FOO is no command.
    p.handle_line(
        0.0,
        b"CURR:NPLC 55;FOO;SYST:ERR?;SYST:ERR?;SYST:ERR?;*ESR?",
        &mut out,
    );
    let lines: Vec<&[u8]> = out
        .split(|b| *b == b'\r')
        .filter(|l| !l.is_empty())
        .collect();
    let err = |l: &[u8]| match Reply::parse(&Command::NextError, l) {
        Ok(Reply::Error(e)) => e,
        other => panic!("{other:?}"),
    };
    assert_eq!(err(lines[0]).code, -222);
    assert_eq!(err(lines[1]).code, -113);
    assert_eq!(err(lines[2]), ScpiError::none());
    assert_eq!(lines[3], b"48");
    // A READ? at 1 s on the power-up settings (5 PLC at 50 Hz, zero check on) is due
    // 100 ms later, flagged zero-checked.
    out.clear();
    p.handle_line(1.0, b"READ?", &mut out);
    assert!((p.busy_until() - 1.1).abs() < 1e-12);
    let body = out.strip_suffix(b"\r").expect("CR");
    let Ok(Reply::Sample(sample)) = Reply::parse(&Command::Read, body) else {
        panic!("{out:?}");
    };
    assert!(sample.status.zero_check());
    assert!((sample.time_s - 1.1).abs() < 1e-6);
    // FETC? sends the same reading again, at once; two triggers send two triples.
    let first = out.clone();
    out.clear();
    p.handle_line(1.1, b"FETC?", &mut out);
    assert_eq!(out, first);
    assert!((p.busy_until() - 1.1).abs() < 1e-12);
    out.clear();
    p.handle_line(1.1, b"TRIG:COUN 2;READ?", &mut out);
    assert_eq!(out.iter().filter(|b| **b == b',').count(), 5);
    assert!((p.busy_until() - 1.3).abs() < 1e-12);
    // Acquiring a zero with zero check off is refused.
    out.clear();
    p.handle_line(2.0, b"SYST:ZCH OFF;SYST:ZCOR:ACQ;SYST:ERR?", &mut out);
    assert_eq!(out, b"-221,\"Settings conflict\"\r");
}

/// The averaging filter count per p. 4-8, "Both are a simple average of one to 100
/// reading conversions": the twin takes `AVER:COUN 1` without an error, and a repeat
/// filter of one conversion takes one conversion per `READ?`; 0 and 101 are refused
/// with −222.
#[test]
fn the_filter_count_runs_from_one_to_100() {
    let pc = PicoammeterConfig::default();
    let mut p = Picoammeter::new(&pc, 0);
    let mut out = Vec::new();
    let no_error = |out: &[u8]| {
        let body = out.strip_suffix(b"\r").expect("CR");
        assert_eq!(
            Reply::parse(&Command::NextError, body),
            Ok(Reply::Error(ScpiError::none())),
            "{:?}",
            String::from_utf8_lossy(out)
        );
    };
    p.handle_line(
        0.0,
        b"AVER:TCON REP;AVER:COUN 1;AVER ON;SYST:ERR?",
        &mut out,
    );
    no_error(&out);
    // Power-up NPLC 5 at 50 Hz (SLOW, p. 4-6): one conversion is 100 ms.
    out.clear();
    p.handle_line(1.0, b"READ?", &mut out);
    assert!((p.busy_until() - 1.1).abs() < 1e-12, "{}", p.busy_until());
    let body = out.strip_suffix(b"\r").expect("CR");
    let Ok(Reply::Sample(sample)) = Reply::parse(&Command::Read, body) else {
        panic!("{out:?}");
    };
    assert!(sample.status.has(gonio_proto::k6485::StatusWord::FILTER));
    out.clear();
    p.handle_line(2.0, b"AVER:COUN 100;SYST:ERR?", &mut out);
    no_error(&out);
    for bad in [&b"AVER:COUN 0;SYST:ERR?"[..], b"AVER:COUN 101;SYST:ERR?"] {
        out.clear();
        p.handle_line(3.0, bad, &mut out);
        assert_eq!(out, b"-222,\"Parameter data out of range\"\r");
    }
}
