//! The sessions of `gonio-proto` against the simulator's device models, in memory, on
//! virtual time: no driver, no transport, no pty, no sleep. A tiny pump ([`Rig::run`])
//! hands a session's bytes to [`SimInstrument`], its replies back (after the link's
//! latency), and moves the simulated clock to the deadlines the session asks for. That
//! is all a session needs: bytes and time.
//!
//! Every fault class the simulator produces is covered, each asserting the typed
//! outcome, the exact lines on the wire where they are deterministic, the stops, and the
//! times on the virtual clock.

//!
//! This file: the SR830 session — readings, settling, autoranging, flags and faults.

use crate::session_rig;

use session_rig::*;

// ---------------------------------------------------------------------------------
// Detection.

/// A settled reading after a move agrees with the simulator's optics (R = chop gain ×
/// detector signal) within its noise model.
#[test]
fn reading_matches_the_optics_within_the_noise() {
    let (mut rig, mut chain, mut lockin) = ready(15, |_| {});
    rig.run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect("moved");
    lockin.input_changed(rig.now);
    let r: Reading = rig
        .run(Port::Detector, lockin.start_read(rig.now))
        .expect("reading");
    let t = rig.secs();
    let chop = rig.sim.lockin_mut().config().chop_gain;
    let expected = chop * rig.sim.signal(t);
    assert!(expected > 1e-4, "a real signal: {expected}");
    let sigma = noise_sigma(&mut rig.sim, expected, r.slope, r.time_constant);
    assert!(r.is_valid(), "{r:?}");
    assert!(
        (r.r_mean - expected).abs() < 6.0 * sigma + 2e-4 * expected,
        "R {} vs {expected} (σ {sigma})",
        r.r_mean
    );
    assert!(
        r.r_std > 0.0 && r.r_std < 6.0 * sigma,
        "{} vs σ {sigma}",
        r.r_std
    );
    assert_eq!(r.n, 10);
    // Autoranging from 1 V stopped at a range where R is 10 % to 100 % of full scale.
    let fs = r.sensitivity.volts();
    assert!(
        r.r_mean >= 0.1 * fs && r.r_mean <= fs,
        "{} on {fs}",
        r.r_mean
    );
    assert_eq!(usize::from(26 - r.sensitivity.index()), r.autorange_steps);
    assert_eq!(lockin.sensitivity(), r.sensitivity);
}

/// The settling wait, measured on the virtual clock: the first `LIAS?` of a reading
/// goes out exactly the filter's settling time after the input changed, and the
/// snapshots one time constant apart. The settling time is checked against the
/// manual's table at 1 % and against the step response of the RC cascade otherwise.
#[test]
fn settling_wait_follows_the_filter_formula() {
    let mut rig = Rig::new(16, |_| {});
    for (slope, residual, factor) in [
        (FilterSlope::Db6, 0.01, 5.0),
        (FilterSlope::Db12, 0.01, 7.0),
        (FilterSlope::Db18, 0.01, 9.0),
        (FilterSlope::Db24, 0.01, 10.0),
        (FilterSlope::Db24, 1e-4, cascade_time(4, 1e-4)),
        (FilterSlope::Db12, 1e-3, cascade_time(2, 1e-3)),
    ] {
        let tc = TimeConstant::new(9).expect("300 ms");
        let config = Sr830Config {
            slope,
            time_constant: tc,
            settle_residual: residual,
            samples: 3,
            autorange: false,
            ..lockin_config()
        };
        let mut lockin = Sr830Session::new(config, "sim", rig.now).expect("valid");
        rig.run(Port::Detector, lockin.start_setup(rig.now))
            .expect("set up");
        let changed = rig.now;
        lockin.input_changed(changed);
        let from = rig.sent.len();
        rig.run(Port::Detector, lockin.start_read(rig.now))
            .expect("reading");
        let times: Vec<(String, Duration)> = rig.sent[from..]
            .iter()
            .map(|(_, t, b)| (String::from_utf8_lossy(b).into_owned(), *t))
            .collect();
        assert_eq!(times[0].0, "LIAS?\n");
        let wait = (times[0].1 - changed).as_secs_f64();
        assert!(
            (wait - factor * 0.3).abs() < 2e-9,
            "{slope} to {residual}: waited {wait} s, expected {factor} T"
        );
        let snaps: Vec<Duration> = times
            .iter()
            .filter(|(l, _)| l == "SNAP? 1,2\n")
            .map(|(_, t)| *t)
            .collect();
        assert_eq!(snaps.len(), 3);
        for w in snaps.windows(2) {
            // One time constant, after the 5 ms reply latency of the snapshot before.
            assert_eq!(w[1] - w[0], Duration::from_millis(305));
        }
    }
}

/// The time, in time constants, for `n` cascaded RC stages to come within `residual`
/// of a step: the root of e^-a Σ_{j<n} a^j/j! = residual, by Newton's method (the
/// derivative of the left side is -e^-a a^(n-1)/(n-1)!).
fn cascade_time(n: u32, residual: f64) -> f64 {
    let left = |a: f64| {
        let (mut term, mut sum) = (1.0, 1.0);
        for j in 1..n {
            term *= a / f64::from(j);
            sum += term;
        }
        (-a).exp() * sum
    };
    let fact: f64 = (1..n).map(f64::from).product();
    let mut a: f64 = 10.0;
    for _ in 0..50 {
        let d = -(-a).exp() * a.powi(i32::try_from(n).expect("small") - 1) / fact;
        a -= (left(a) - residual) / d;
    }
    a
}

/// An overloaded output steps one range less sensitive and reads again, until the
/// reading is clean: every range change is one `SENS` line, upward only.
#[test]
fn output_overload_autoranges_up() {
    let (mut rig, mut chain, mut lockin) = ready(17, |_| {});
    rig.run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect("moved");
    let t = rig.secs();
    let r_true = rig.sim.lockin_mut().config().chop_gain * rig.sim.signal(t);
    // Start three ranges too sensitive: full scale about R / 10.
    let start = Sensitivity::all()
        .filter(|s| s.volts() < r_true / 5.0)
        .last()
        .expect("a range below R");
    rig.run(Port::Detector, lockin.start_set_sensitivity(start, rig.now))
        .expect("SENS");
    let from = rig.sent.len();
    let r = rig
        .run(Port::Detector, lockin.start_read(rig.now))
        .expect("reading");
    assert!(r.is_valid(), "{r:?}");
    assert!(r.sensitivity > start);
    let sens: Vec<String> = rig
        .lines_since(from, Port::Detector)
        .into_iter()
        .filter(|l| l.starts_with("SENS"))
        .collect();
    let expected: Vec<String> = (start.index() + 1..=r.sensitivity.index())
        .map(|i| format!("SENS {i}\n"))
        .collect();
    assert_eq!(sens, expected);
    assert_eq!(r.autorange_steps, sens.len());
    assert!(r.r_mean < 1.09 * r.sensitivity.volts() && r.r_mean >= 0.1 * r.sensitivity.volts());
}

/// An input overload that no range cures (forced by the simulator) climbs to 1 V and
/// is returned flagged, never valid.
#[test]
fn input_overload_is_flagged_at_the_least_sensitive_range() {
    let (mut rig, _, mut lockin) = ready(18, |_| {});
    let t = rig.secs();
    rig.sim.faults_mut().overload.push(Window {
        from_s: t,
        to_s: t + 1e6,
    });
    rig.run(
        Port::Detector,
        lockin.start_set_sensitivity(Sensitivity::new(20).expect("10 mV"), rig.now),
    )
    .expect("SENS");
    let r = rig
        .run(Port::Detector, lockin.start_read(rig.now))
        .expect("a reading, flagged");
    assert!(r.flags.input_overload && !r.is_valid());
    assert_eq!(r.r(), None);
    assert_eq!(r.sensitivity, Sensitivity::LEAST);
    assert_eq!(r.autorange_steps, 6);
}

/// A reference unlock flags the reading: not valid, and not ranged on (its small R is
/// not a measurement).
#[test]
fn unlock_flags_the_reading() {
    let (mut rig, mut chain, mut lockin) = ready(19, |_| {});
    rig.run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect("moved");
    let t = rig.secs();
    rig.sim.faults_mut().unlock.push(Window {
        from_s: t,
        to_s: t + 1e6,
    });
    let before = lockin.sensitivity();
    let from = rig.sent.len();
    let r = rig
        .run(Port::Detector, lockin.start_read(rig.now))
        .expect("a reading, flagged");
    assert!(r.flags.unlock && !r.is_valid());
    assert!(r.status.has(LiaStatus::UNLOCK));
    assert_eq!(r.r(), None);
    assert_eq!((r.sensitivity, r.autorange_steps), (before, 0));
    assert!(
        !rig.lines_since(from, Port::Detector)
            .iter()
            .any(|l| l.starts_with("SENS"))
    );
}

/// Lost and garbled lock-in replies: snapshots are asked again, a lost flags answer
/// restarts the cycle (its bits were cleared by the read), and the reading is still
/// clean; each lost or garbled line is one retry.
#[test]
fn lockin_faults_on_the_line_are_retried() {
    let (mut rig, mut chain, mut lockin) = ready(20, |_| {});
    rig.run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect("moved");
    rig.sim.faults_mut().drop_reply = 0.05;
    rig.sim.faults_mut().corrupt_reply = 0.05;
    lockin.input_changed(rig.now);
    let r = rig
        .run(Port::Detector, lockin.start_read(rig.now))
        .expect("retries get through");
    assert!(r.is_valid(), "{r:?}");
    let s = rig.sim.stats();
    assert!(s.dropped + s.corrupted > 0, "the faults fired");
    assert_eq!(lockin.retried(), s.dropped + s.corrupted);
}

/// The detector line vanishes mid-reading: the session pauses, reopens it, re-sends
/// `OUTX 0` (replies would go to GPIB otherwise), and starts the cycle again after a
/// new settling wait.
#[test]
fn detector_port_outage_restarts_the_reading() {
    let (mut rig, mut chain, mut lockin) = ready(21, |_| {});
    rig.run(Port::Motion, chain.start_move(&POINT, rig.now))
        .expect("moved");
    // A first reading settles and ranges; the faulted one starts settled.
    rig.run(Port::Detector, lockin.start_read(rig.now))
        .expect("reading");
    let t = rig.secs();
    rig.sim.faults_mut().outage.push(PortOutage {
        port: Port::Detector,
        window: Window {
            from_s: t + 0.2,
            to_s: t + 0.9,
        },
    });
    let from = rig.sent.len();
    let r = rig
        .run(Port::Detector, lockin.start_read(rig.now))
        .expect("reconnects");
    assert!(r.is_valid(), "{r:?}");
    assert_eq!(lockin.reconnects(), 1);
    assert_eq!(rig.reopened, [(Port::Detector, true)]);
    let lines = rig.lines_since(from, Port::Detector);
    let outx = lines
        .iter()
        .position(|l| l == "OUTX 0\n")
        .expect("OUTX 0 re-sent");
    // Cleared twice: the interrupted cycle and the one after the reconnection.
    assert_eq!(lines.iter().filter(|l| *l == "LIAS?\n").count(), 3);
    assert_eq!(lines[outx + 1], "SNAP? 1,2\n");
}

// ---------------------------------------------------------------------------------
// The manual's hazards.

/// Runs `op` on the detector line as [`Rig::run`] does, but writes `noise` (bytes
/// without a terminator) to the lock-in just before the first line that starts with
/// `before`.
fn run_with_noise<O: Operation>(
    rig: &mut Rig,
    mut op: O,
    before: &[u8],
    noise: &[u8],
) -> O::Output {
    let port = Port::Detector;
    let mut pending = Some(noise.to_vec());
    loop {
        while let Some(io) = op.poll_io() {
            match io {
                Io::Transmit(bytes) => {
                    if bytes.starts_with(before)
                        && let Some(n) = pending.take()
                    {
                        assert_eq!(rig.sim.lockin_bytes(&n), b"", "noise has no answer");
                    }
                    let r = rig.transmit(port, bytes);
                    op.handle_sent(rig.now, r);
                }
                Io::ClearInput => rig.clear(port),
                Io::Reconnect => panic!("no reconnection expected"),
            }
        }
        if let Some(out) = op.poll_output() {
            return out;
        }
        match op.poll_timeout().expect("waits for something") {
            Deadline::Reply(at) => match rig.receive(port, at) {
                Some(Ok(line)) => op.handle_line(rig.now, &line),
                Some(Err(e)) => op.handle_link_error(rig.now, e),
                None => op.handle_timeout(rig.now),
            },
            Deadline::Poll(at) | Deadline::Sleep(at) => {
                rig.advance_to(at);
                op.handle_timeout(rig.now);
            }
        }
    }
}

/// The 256-character input buffer: "If either buffer overflows, both buffers are
/// cleared and an error reported" (manual p. 5-2, quoted second-hand), INP in `*ESR?`
/// (bit 0). Line noise without a terminator (249 bytes: a cable plugged in, a
/// crashed program's half line) fills the buffer so that the terminator of the
/// set-up's `SENS 20` overflows it: that command is lost, and INP is the only sign. The
/// set-up must fail on it; a session checking only CMD and EXE would report the
/// lock-in set up while it still stands at 1 V full scale.
#[test]
fn setup_reports_a_command_lost_to_an_input_buffer_overflow() {
    use gonio_proto::sr830::{EventStatus, MAX_LINE, Sr830Error};
    let mut rig = Rig::new(31, |_| {});
    let config = Sr830Config {
        sensitivity: Sensitivity::new(20).expect("10 mV"),
        ..lockin_config()
    };
    let mut lockin = Sr830Session::new(config, "sim:detector", rig.now).expect("valid config");
    let noise = vec![b'#'; MAX_LINE - "SENS 20".len()];
    let from = rig.sent.len();
    let op = lockin.start_setup(rig.now);
    match run_with_noise(&mut rig, op, b"SENS", &noise) {
        Err(Sr830Error::Rejected(esr)) => assert_eq!(esr, EventStatus(EventStatus::INP)),
        other => panic!("{other:?}"),
    }
    assert_eq!(
        rig.lines_since(from, Port::Detector),
        [
            "OUTX 0\n",
            "*IDN?\n",
            "*CLS\n",
            "SENS 20\n",
            "OFLT 8\n",
            "OFSL 3\n",
            "*ESR?\n"
        ]
    );
    assert_eq!(
        rig.sim.lockin_mut().sensitivity(),
        Sensitivity::LEAST,
        "SENS 20 never ran"
    );
    // On a clean line the set-up runs whole (reading *ESR? cleared INP).
    rig.run(Port::Detector, lockin.start_setup(rig.now))
        .expect("set up");
    assert_eq!(rig.sim.lockin_mut().sensitivity().index(), 20);
}
