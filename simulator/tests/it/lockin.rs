//! The simulated SR830: the driver's byte transcripts, the filter and noise physics,
//! overload and status latching, determinism, and the real driver against the model.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use gonio_driver::sr830::{ReadingFlags, Sr830, Sr830Config};
use gonio_driver::{Clock, ManualClock, Transport, TransportError};
use gonio_proto::sr830::{Command, FilterSlope, Reply, Sensitivity, SnapParams, TimeConstant};
use gonio_sim::lockin::{LockIn, LockInConfig, OVERLOAD_FACTOR, PointStart, advance_cascade};
use gonio_sim::{SimClock, SimConfig, SimInstrument};

/// A lock-in without noise.
fn quiet() -> LockInConfig {
    LockInConfig {
        amplifier_noise: 0.0,
        shot_noise: 0.0,
        ..LockInConfig::default()
    }
}

/// Sends one line at `t` and returns the reply bytes as text.
fn send(l: &mut LockIn, t: f64, line: &str) -> String {
    let mut out = Vec::new();
    l.handle_line(t, line.as_bytes(), &mut out);
    String::from_utf8(out).expect("ASCII reply")
}

/// A lock-in talking on RS-232 with its status bytes cleared, at t = 0.
fn on_rs232(config: LockInConfig, seed: u64) -> LockIn {
    let mut l = LockIn::new(config, seed);
    assert_eq!(send(&mut l, 0.0, "OUTX 0"), "");
    assert_eq!(send(&mut l, 0.0, "*CLS"), "");
    l
}

/// `SNAP? 1,2` at `t`, parsed as the driver parses it.
fn snap_xy(l: &mut LockIn, t: f64) -> (f64, f64) {
    let c = Command::Snap(SnapParams::XY);
    let text = send(l, t, "SNAP? 1,2");
    let body = text.strip_suffix('\r').expect("CR-terminated");
    match Reply::parse(&c, body.as_bytes()) {
        Ok(Reply::Snap(v)) => (v[0], v[1]),
        other => panic!("{other:?}"),
    }
}

/// `OUTP? 1` at `t`, parsed.
fn read_x(l: &mut LockIn, t: f64) -> f64 {
    let text = send(l, t, "OUTP? 1");
    text.trim_end().parse().expect("a number")
}

const IDN: &str = "Stanford_Research_Systems,SR830,s/n00111,ver1.07\r";

// ---------------------------------------------------------------------------------
// Protocol: what the driver sends, byte for byte.

#[test]
fn silent_on_rs232_until_outx_0() {
    let mut l = LockIn::new(LockInConfig::default(), 1);
    // Replies go to GPIB at power-up: the queries run, nothing comes back.
    assert_eq!(send(&mut l, 0.0, "*IDN?"), "");
    assert_eq!(send(&mut l, 0.0, "OUTX?"), "");
    assert_eq!(send(&mut l, 0.0, "SENS?;OFLT?;OFSL?"), "");
    assert_eq!(send(&mut l, 0.0, "OUTX 0"), "");
    assert_eq!(send(&mut l, 0.0, "*IDN?"), IDN);
    assert_eq!(send(&mut l, 0.0, "OUTX?"), "0\r");
    // Power-on sets PON (bit 7) until read.
    assert_eq!(send(&mut l, 0.0, "*ESR?"), "128\r");
    assert_eq!(send(&mut l, 0.0, "*ESR?"), "0\r");
    // The *RST state: 1 V, 100 ms, 12 dB/oct; one reply line per query.
    assert_eq!(send(&mut l, 0.0, "SENS?;OFLT?;OFSL?"), "26\r8\r1\r");
    assert_eq!(send(&mut l, 0.0, "FMOD?;FREQ?;SLVL?"), "1\r1000\r1\r");
    // Back to GPIB: silent again, and OUTX itself never answers.
    assert_eq!(send(&mut l, 0.0, "OUTX 1;SENS?"), "");
    assert_eq!(send(&mut l, 0.0, "outx0 ; sens ?"), "26\r");
}

#[test]
fn driver_setup_transcript() {
    let mut l = LockIn::new(LockInConfig::default(), 1);
    // Exactly the lines `Sr830::setup` sends for 10 mV, 100 ms, 24 dB/oct.
    let transcript = [
        ("OUTX 0", ""),
        ("*IDN?", IDN),
        ("*CLS", ""),
        ("SENS 20", ""),
        ("OFLT 8", ""),
        ("OFSL 3", ""),
        ("*ESR?", "0\r"),
        // `refresh_settings` after AGAN, and a read cycle's status queries.
        ("SENS?", "20\r"),
        ("OFLT?", "8\r"),
        ("OFSL?", "3\r"),
        ("LIAS?", "0\r"),
        ("SNAP? 1,2", "0,0\r"),
        ("LIAS?", "0\r"),
        ("FREQ?", "1000\r"),
    ];
    let mut silent = LockIn::new(quiet(), 1);
    for (line, reply) in transcript {
        if line != "SNAP? 1,2" {
            assert_eq!(send(&mut l, 0.0, line), reply, "{line}");
        }
        assert_eq!(send(&mut silent, 0.0, line), reply, "{line} (no noise)");
    }
    // The manual's start-up example (instruments.md §2.7).
    assert_eq!(
        send(
            &mut l,
            0.0,
            "FMOD 1;FREQ 1000;SLVL 0.5;SENS 20;OFLT 9;OFSL 3"
        ),
        ""
    );
    assert_eq!(send(&mut l, 0.0, "*ESR?"), "0\r");
    assert_eq!(
        send(&mut l, 0.0, "SLVL?;OFLT?;FREQ?;SENS?"),
        "0.5\r9\r1000\r20\r"
    );
    assert_eq!(
        (l.sensitivity().index(), l.time_constant().index()),
        (20, 9)
    );
    assert_eq!(l.slope(), FilterSlope::Db24);
}

#[test]
fn refused_commands_set_cmd_or_exe_silently() {
    let mut l = on_rs232(quiet(), 1);
    // Illegal: CMD, 32.
    assert_eq!(send(&mut l, 0.0, "FOO 1"), "");
    assert_eq!(send(&mut l, 0.0, "*ESR?"), "32\r");
    assert_eq!(send(&mut l, 0.0, "*ESR?"), "0\r");
    // Out of range: EXE, 16.
    assert_eq!(send(&mut l, 0.0, "SENS 27"), "");
    assert_eq!(send(&mut l, 0.0, "*ESR?"), "16\r");
    // A query form that does not exist, a set form of a query, a non-number: CMD.
    for line in ["AGAN?", "OUTP 1", "SENS x", "SNAP? 1"] {
        assert_eq!(send(&mut l, 0.0, line), "", "{line}");
        assert_eq!(send(&mut l, 0.0, "*ESR?"), "32\r", "{line}");
    }
    // A non-integer index: EXE. The setting is unchanged.
    assert_eq!(send(&mut l, 0.0, "SENS 2.5"), "");
    assert_eq!(send(&mut l, 0.0, "*ESR?;SENS?"), "16\r26\r");
    // The rest of a line runs after a refused command; single bits read and clear.
    assert_eq!(send(&mut l, 0.0, "SENS 99;FOO;SENS 3;SENS?"), "3\r");
    assert_eq!(send(&mut l, 0.0, "*ESR? 5"), "1\r");
    assert_eq!(send(&mut l, 0.0, "*ESR? 5;*ESR? 4"), "0\r1\r");
    assert_eq!(send(&mut l, 0.0, "*ESR?"), "0\r");
    // FREQ cannot set an external reference; FREQ? then reads the chopper.
    assert_eq!(
        send(&mut l, 0.0, "FMOD 0;FREQ 500;*ESR?;FREQ?"),
        "16\r1000\r"
    );
    assert_eq!(send(&mut l, 0.0, "FMOD 1;FREQ 137.5;FREQ?"), "137.5\r");
    // A line overflowing the 256-character input buffer: INP (bit 0), nothing runs.
    let long = format!("SENS 20;{}", " ".repeat(300));
    assert_eq!(send(&mut l, 0.0, &long), "");
    assert_eq!(send(&mut l, 0.0, "*ESR?;SENS?"), "1\r3\r");
    // ERRS? is always clear.
    assert_eq!(send(&mut l, 0.0, "ERRS?;ERRS? 1"), "0\r0\r");
}

#[test]
fn time_constants_over_30_s_need_the_low_frequency_range() {
    let mut l = on_rs232(quiet(), 1);
    // 100 s at 1 kHz: refused.
    assert_eq!(send(&mut l, 0.0, "OFLT 14;*ESR?;OFLT?"), "16\r8\r");
    // At 100 Hz it is allowed; crossing 200 Hz latches RANGE (16).
    assert_eq!(send(&mut l, 0.0, "FREQ 100;OFLT 14;*ESR?;OFLT?"), "0\r14\r");
    // Back above 200 Hz: RANGE again, and T drops to 30 s (TC, 32).
    assert_eq!(send(&mut l, 0.0, "FREQ 1000;OFLT?;LIAS?"), "13\r48\r");
}

#[test]
fn reset_restores_defaults_but_not_the_interface_or_status() {
    let mut l = on_rs232(quiet(), 1);
    send(
        &mut l,
        0.0,
        "SENS 20;OFLT 6;OFSL 3;FREQ 500;SLVL 0.1;SENS 99",
    );
    assert_eq!(
        send(
            &mut l,
            0.0,
            "*RST;SENS?;OFLT?;OFSL?;FREQ?;SLVL?;OUTX?;*ESR?"
        ),
        "26\r8\r1\r1000\r1\r0\r16\r"
    );
}

// ---------------------------------------------------------------------------------
// Status latching and overload.

#[test]
fn lias_latches_and_reading_clears_it() {
    let mut l = on_rs232(quiet(), 1);
    // 10 mV full scale, R = 0.45 × 0.03 V = 13.5 mV > 1.09 × 10 mV.
    send(&mut l, 0.0, "SENS 20");
    l.set_input(0.0, 0.03);
    assert_eq!(send(&mut l, 1.0, "LIAS?"), "4\r");
    // Clipped at 1.09 × full scale = 10.9 mV (the manual leaves it open).
    assert_eq!(
        send(&mut l, 1.0, "OUTP? 1;OUTP? 2;OUTP? 3"),
        "0.0109\r0\r0.0109\r"
    );
    assert_eq!(OVERLOAD_FACTOR, 1.09);
    // The overload persists: read again at once, it is set again.
    assert_eq!(send(&mut l, 1.0, "LIAS?"), "4\r");
    // The signal goes: the bit stays latched until read, then clears.
    l.set_input(1.0, 0.0);
    assert_eq!(send(&mut l, 3.0, "LIAS?"), "4\r");
    assert_eq!(send(&mut l, 3.0, "LIAS?"), "0\r");
    // Faults latch while on, even when over before a read.
    l.set_unlocked(true);
    l.set_unlocked(false);
    l.force_overload(true);
    l.force_overload(false);
    assert_eq!(send(&mut l, 3.1, "LIAS? 3"), "1\r");
    assert_eq!(send(&mut l, 3.1, "LIAS? 3"), "0\r");
    assert_eq!(send(&mut l, 3.1, "LIAS?"), "1\r");
    assert_eq!(send(&mut l, 3.1, "LIAS?"), "0\r");
    // The input limit is 1.4 V: 1.39 V is fine (R = 0.6255 V on 1 V), 1.5 V overloads.
    send(&mut l, 3.1, "SENS 26");
    l.set_input(3.1, 1.39);
    assert_eq!(send(&mut l, 6.0, "LIAS?"), "0\r");
    l.set_input(6.0, 1.5);
    assert_eq!(send(&mut l, 6.0, "LIAS?"), "1\r");
    // *CLS clears everything latched.
    l.set_input(6.0, 0.0);
    l.set_unlocked(true);
    l.set_unlocked(false);
    assert_eq!(send(&mut l, 6.0, "*CLS;LIAS?"), "0\r");
}

#[test]
fn output_overload_counts_x_y_and_r_and_clips_each() {
    let mut l = on_rs232(
        LockInConfig {
            phase_deg: 45.0,
            ..quiet()
        },
        1,
    );
    // R = 10 mV at 45°: X = Y = 7.07 mV, under 10.9 mV; R overloads 5 mV full scale.
    send(&mut l, 0.0, "SENS 19");
    l.set_input(0.0, 0.01 / 0.45);
    assert_eq!(send(&mut l, 50.0, "LIAS?"), "4\r");
    assert_eq!(
        send(&mut l, 50.0, "SNAP? 1,2,3,4"),
        "0.00545,0.00545,0.00545,45\r"
    );
    // At 10 mV: X, Y, R all under 10.9 mV, no overload.
    assert_eq!(send(&mut l, 50.0, "SENS 20;*CLS;LIAS?"), "0\r");
    assert_eq!(
        send(&mut l, 50.0, "SNAP? 1,2,3"),
        "0.00707107,0.00707107,0.01\r"
    );
}

// ---------------------------------------------------------------------------------
// Outputs.

#[test]
fn steady_state_without_noise_is_exactly_chop_gain_times_input() {
    let mut l = on_rs232(quiet(), 1);
    l.set_input(0.0, 0.02);
    assert_eq!(l.settled_r(1000.0), 0.45 * 0.02);
    assert_eq!(
        send(&mut l, 1000.0, "OUTP? 3;SNAP? 1,2"),
        "0.009\r0.009,0\r"
    );

    let mut l = on_rs232(
        LockInConfig {
            phase_deg: 30.0,
            ..quiet()
        },
        1,
    );
    l.set_input(0.0, 0.02);
    // X = 9 mV cos 30°, Y = 9 mV sin 30°, R, θ, frequency, Aux In 1.
    assert_eq!(
        send(&mut l, 1000.0, "SNAP? 1,2,3,4,9,5"),
        "0.00779423,0.0045,0.009,30,1000,0\r"
    );
    // The displays show X and Y.
    assert_eq!(send(&mut l, 1000.0, "SNAP? 10,11"), "0.00779423,0.0045\r");
    assert_eq!(send(&mut l, 1000.0, "OUTP? 4"), "30\r");
    // The reply format is what the codec writes: 6 significant digits, exponent for
    // small values.
    l.set_input(1000.0, 1e-6 / 0.45);
    assert_eq!(send(&mut l, 2000.0, "OUTP? 3"), "1e-6\r");
}

#[test]
fn unlock_stops_demodulating() {
    let mut l = on_rs232(quiet(), 1);
    l.set_input(0.0, 0.02);
    let full = 0.45 * 0.02;
    assert_eq!(l.settled_r(10.0), full);
    l.set_unlocked(true);
    // The filters decay from 9 mV: after 2 T at 12 dB/oct, 9 mV × 3e^-2.
    let r = l.settled_r(10.2);
    assert!((r - full * 3.0 * (-2.0f64).exp()).abs() < 1e-15, "{r}");
    assert_eq!(send(&mut l, 100.0, "OUTP? 3;LIAS?"), "0\r8\r");
}

// ---------------------------------------------------------------------------------
// The time-constant filter.

/// The cascade integrated by Euler steps of dt/steps.
fn euler(mut y: [f64; 4], u: f64, dt: f64, tc: f64, steps: usize) -> [f64; 4] {
    let h = dt / steps as f64;
    for _ in 0..steps {
        let prev = y;
        y[0] += h * (u - prev[0]) / tc;
        for k in 1..4 {
            y[k] += h * (prev[k - 1] - prev[k]) / tc;
        }
    }
    y
}

#[test]
fn exact_cascade_matches_fine_euler_integration() {
    let cases = [
        ([0.3, -0.2, 0.7, 0.1], 1.0, 0.3, 1.0),
        ([0.0, 0.0, 0.0, 0.0], -0.8, 2.5, 1.0),
        ([1.0, 0.5, -0.5, 2.0], 0.25, 7.0e-3, 1.0e-3),
    ];
    for (start, u, dt, tc) in cases {
        let mut exact = start;
        advance_cascade(&mut exact, u, dt, tc);
        // Euler's global error is c₁h + c₂h² + …: with 10⁶ steps it is ~1e-6, and the
        // Richardson combination 2·E(h/2) − E(h) cancels c₁h, leaving ~1e-11.
        let n = 1_000_000;
        let coarse = euler(start, u, dt, tc, n);
        let fine = euler(start, u, dt, tc, 2 * n);
        for k in 0..4 {
            let extrapolated = 2.0 * fine[k] - coarse[k];
            assert!(
                (exact[k] - extrapolated).abs() < 1e-9,
                "stage {k}: exact {} vs Euler {extrapolated}",
                exact[k]
            );
            assert!((exact[k] - fine[k]).abs() < 1e-5, "plain Euler, stage {k}");
        }
        // Many small exact steps are the same as one big one.
        let mut chunked = start;
        for _ in 0..1000 {
            advance_cascade(&mut chunked, u, dt / 1000.0, tc);
        }
        for k in 0..4 {
            assert!((chunked[k] - exact[k]).abs() < 1e-12, "chunked stage {k}");
        }
    }
}

#[test]
fn settling_follows_the_manuals_table() {
    // Residual of a unit step after a time constants for N stages: e^-a Σ_{j<N} a^j/j!.
    let residual = |n: usize, a: f64| {
        let (mut sum, mut term) = (0.0, 1.0);
        for j in 0..n {
            sum += term;
            term *= a / (j + 1) as f64;
        }
        (-a).exp() * sum
    };
    for slope in FilterSlope::ALL {
        let n = usize::from(slope.index()) + 1;
        let factor = slope.settle_factor();
        let mut l = on_rs232(quiet(), 1);
        send(&mut l, 0.0, &format!("OFSL {}", slope.index()));
        let tc = l.time_constant().seconds();
        l.set_input(0.0, 1.0);
        let at = |l: &mut LockIn, a: f64| 1.0 - l.settled_r(a * tc) / 0.45;
        // One time constant early, more than 1 % is left: the table is tight.
        let early = at(&mut l, factor - 1.0);
        assert!(early > 0.01, "{slope}: {early}");
        let left = at(&mut l, factor);
        assert!(
            (left - residual(n, factor)).abs() < 1e-12,
            "{slope}: {left}"
        );
        if slope == FilterSlope::Db24 {
            // Four equal poles leave 1.034 % at 10 T and reach 99 % at 10.05 T:
            // the manual rounds.
            assert!((0.0103..0.0104).contains(&left), "{left}");
            assert!(at(&mut l, 10.05) < 0.01);
        } else {
            // 0.674 %, 0.730 %, 0.623 % at 5, 7, 9 T.
            assert!(left < 0.01, "{slope}: {left}");
        }
    }
}

#[test]
fn sens_keeps_the_filter_and_oflt_changes_t_from_then_on() {
    let mut l = on_rs232(quiet(), 1);
    l.set_input(0.0, 1.0);
    let before = l.settled_r(0.05);
    send(&mut l, 0.05, "SENS 25");
    assert_eq!(l.settled_r(0.05), before);
    // 100 ms until 0.05 s, then 10 ms.
    send(&mut l, 0.05, "OFLT 6");
    let mut stages = [0.0; 4];
    advance_cascade(&mut stages, 0.45, 0.05, 0.1);
    assert!((stages[1] - before).abs() < 1e-15);
    advance_cascade(&mut stages, 0.45, 0.02, 0.01);
    assert!((l.settled_r(0.07) - stages[1]).abs() < 1e-15);
    // A steeper slope reads a later stage of the same cascade.
    send(&mut l, 0.07, "OFSL 3");
    assert!((l.settled_r(0.07) - stages[3]).abs() < 1e-15);
}

// ---------------------------------------------------------------------------------
// Noise.

/// Sample mean and standard deviation (n − 1).
fn mean_std(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let ss: f64 = v.iter().map(|x| (x - m).powi(2)).sum();
    (m, (ss / (n - 1.0)).sqrt())
}

/// Lag-1 autocorrelation.
fn lag1(v: &[f64]) -> f64 {
    let (m, _) = mean_std(v);
    let num: f64 = v.windows(2).map(|w| (w[0] - m) * (w[1] - m)).sum();
    let den: f64 = v.iter().map(|x| (x - m).powi(2)).sum();
    num / den
}

// Tolerances. For n independent normal readings, (n − 1)s²/σ² is χ² with n − 1 degrees
// of freedom, so s/σ has standard error 1/√(2(n − 1)): 0.50 % for n = 20 000. Readings
// 10 T apart correlate by e^-10 = 4.5e-5, which changes nothing measurable. The
// tolerance of 2.5 % is 5 standard errors. For an AR(1) series the lag-1 estimate has
// standard error √((1 − ρ²)/n): 0.098 % for ρ = e^-0.05 and n = 100 000; the tolerance
// 0.5 % is again 5 of them.

#[test]
fn noise_standard_deviation_is_density_times_root_enbw() {
    // Shot-noise dominated: R = 10 mV, density = √((20 nV)² + (1e-4)²·0.01) ≈ 10 µV/√Hz.
    let config = LockInConfig {
        phase_deg: 30.0,
        shot_noise: 1e-4,
        ..LockInConfig::default()
    };
    let density = (20e-9f64.powi(2) + 1e-4f64.powi(2) * 0.01).sqrt();
    // 100 ms at 12 dB/oct: ENBW = 1/(8T) = 1.25 Hz, σ = 11.2 µV.
    let sigma = density * (1.25f64).sqrt();
    let mut l = on_rs232(config, 42);
    l.set_input(0.0, 0.01 / 0.45);
    let n = 20_000;
    let (mut xs, mut ys) = (Vec::new(), Vec::new());
    for k in 0..n {
        let (x, y) = snap_xy(&mut l, 100.0 + k as f64);
        xs.push(x);
        ys.push(y);
    }
    let ((mx, sx), (my, sy)) = (mean_std(&xs), mean_std(&ys));
    for (name, s) in [("X", sx), ("Y", sy)] {
        assert!((s / sigma - 1.0).abs() < 0.025, "{name}: {s} vs {sigma}");
    }
    // The means are the signal, to a few σ/√n.
    let se = 5.0 * sigma / (n as f64).sqrt();
    assert!((mx - 0.01 * 30f64.to_radians().cos()).abs() < se, "{mx}");
    assert!((my - 0.005).abs() < se, "{my}");
    assert!(lag1(&xs).abs() < 5.0 / (n as f64).sqrt());

    // Amplifier noise only, no signal, 10 ms at 24 dB/oct: ENBW = 5/(64T) = 7.8 Hz,
    // σ = 20 nV/√Hz × 2.80 √Hz = 55.9 nV.
    let mut l = on_rs232(LockInConfig::default(), 43);
    send(&mut l, 0.0, "OFLT 6;OFSL 3");
    let sigma = 20e-9 * (5.0f64 / 64.0 / 0.01).sqrt();
    let (mut xs, mut ys) = (Vec::new(), Vec::new());
    for k in 0..n {
        let (x, y) = snap_xy(&mut l, 1.0 + 0.1 * k as f64);
        xs.push(x);
        ys.push(y);
    }
    for (name, v) in [("X", &xs), ("Y", &ys)] {
        let s = mean_std(v).1;
        assert!((s / sigma - 1.0).abs() < 0.025, "{name}: {s} vs {sigma}");
    }
}

#[test]
fn readings_closer_than_t_are_correlated() {
    let mut l = on_rs232(LockInConfig::default(), 7);
    // T = 100 ms, readings 5 ms apart: ρ = e^-0.05 = 0.9512.
    let n = 100_000;
    let xs: Vec<f64> = (0..n)
        .map(|k| read_x(&mut l, 1.0 + 0.005 * k as f64))
        .collect();
    let rho = lag1(&xs);
    assert!((rho - (-0.05f64).exp()).abs() < 0.005, "{rho}");
}

// ---------------------------------------------------------------------------------
// Determinism.

/// A session with signal changes and readings; all the bytes it got back.
fn session(seed: u64) -> Vec<u8> {
    let mut l = LockIn::new(LockInConfig::default(), seed);
    let mut out = Vec::new();
    l.handle_line(0.0, b"OUTX 0;*IDN?;SENS 22", &mut out);
    for k in 0..200 {
        let t = 0.037 * k as f64;
        l.set_input(t, 0.01 * (1.0 + (k % 7) as f64));
        l.handle_line(t + 0.01, b"SNAP? 1,2,3,4;LIAS?;OUTP? 3", &mut out);
    }
    out
}

#[test]
fn same_seed_same_bytes_other_seed_other_bytes() {
    let a = session(11);
    assert_eq!(a, session(11));
    assert_ne!(a, session(12));
    assert!(a.starts_with(IDN.as_bytes()));
}

// ---------------------------------------------------------------------------------
// Auto gain.

#[test]
fn auto_gain_puts_r_between_30_and_100_percent_of_full_scale() {
    let mut l = on_rs232(quiet(), 1);
    // 3 mV: 5 mV full scale (60 %).
    l.set_input(0.0, 0.003 / 0.45);
    assert_eq!(send(&mut l, 10.0, "AGAN;SENS?"), "19\r");
    // Over R from 1 nV to 0.8 V.
    let mut t = 10.0;
    for k in 0..90 {
        let r = 1e-9 * 10f64.powf(k as f64 / 10.0);
        l.set_input(t, r / 0.45);
        t += 100.0;
        send(&mut l, t, "AGAN");
        let fraction = r / l.sensitivity().volts();
        let floor = if l.sensitivity() == Sensitivity::MOST {
            0.0
        } else {
            0.3
        };
        assert!(
            (floor..=1.0).contains(&fraction),
            "R {r}: {} ({fraction})",
            l.sensitivity()
        );
    }
    // Nothing happens with T over 1 s (3 s here); at 1 s it works.
    l.set_input(t, 0.003 / 0.45);
    assert_eq!(
        send(&mut l, t + 100.0, "SENS 26;OFLT 11;AGAN;SENS?"),
        "26\r"
    );
    assert_eq!(send(&mut l, t + 200.0, "OFLT 10;AGAN;SENS?"), "19\r");
}

// ---------------------------------------------------------------------------------
// The real driver against the model.

/// The model and the signal, shared between the test and the transport.
struct Bench {
    lockin: LockIn,
    input_v: f64,
}

/// The driver's `Transport` on the model: each line runs at the clock's time, after
/// the signal is brought up to date; replies are queued by line.
struct ModelPort {
    bench: Arc<Mutex<Bench>>,
    clock: ManualClock,
    replies: VecDeque<Vec<u8>>,
}

impl Transport for ModelPort {
    fn send(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        let now = self.clock.now().as_secs_f64();
        let mut b = self.bench.lock().expect("bench");
        let v = b.input_v;
        b.lockin.set_input(now, v);
        let line = bytes.strip_suffix(b"\n").unwrap_or(bytes);
        let mut out = Vec::new();
        b.lockin.handle_line(now, line, &mut out);
        for reply in out.split_inclusive(|c| *c == b'\r') {
            let body = reply.strip_suffix(b"\r").expect("CR-terminated");
            self.replies.push_back(body.to_vec());
        }
        Ok(())
    }

    fn receive_line(&mut self, timeout: Duration) -> Result<Vec<u8>, TransportError> {
        self.replies.pop_front().ok_or_else(|| {
            self.clock.advance(timeout);
            TransportError::Timeout(timeout)
        })
    }

    fn clear_input(&mut self) -> Result<(), TransportError> {
        self.replies.clear();
        Ok(())
    }

    fn reconnect(&mut self) -> Result<(), TransportError> {
        Ok(())
    }

    fn name(&self) -> String {
        "model".into()
    }
}

type Driver = Sr830<ModelPort, ManualClock>;

/// A model with detector signal `input_v` since t = 0 and a driver on it, the clock
/// at 100 s (the signal has long settled: the lock-in was on before the program).
fn bench(config: Sr830Config, input_v: f64) -> (Driver, Arc<Mutex<Bench>>, ManualClock) {
    let mut lockin = LockIn::new(LockInConfig::default(), 2024);
    lockin.set_input(0.0, input_v);
    let shared = Arc::new(Mutex::new(Bench { lockin, input_v }));
    let clock = ManualClock::new();
    clock.advance(Duration::from_secs(100));
    let port = ModelPort {
        bench: shared.clone(),
        clock: clock.clone(),
        replies: VecDeque::new(),
    };
    let driver = Sr830::new(port, clock.clone(), config).expect("valid config");
    (driver, shared, clock)
}

fn sens(i: u8) -> Sensitivity {
    Sensitivity::new(i).expect("SENS index")
}

fn tc(i: u8) -> TimeConstant {
    TimeConstant::new(i).expect("OFLT index")
}

#[test]
fn driver_sets_up_and_reads_the_model() {
    let config = Sr830Config {
        sensitivity: sens(20),
        time_constant: tc(8),
        slope: FilterSlope::Db24,
        autorange: false,
        ..Sr830Config::default()
    };
    // R = 5 mV on 10 mV full scale.
    let (mut d, shared, clock) = bench(config, 0.005 / 0.45);
    let id = d.setup().expect("set-up");
    assert_eq!(
        (id.model.as_str(), id.serial.as_str(), id.firmware.as_str()),
        ("SR830", "s/n00111", "ver1.07")
    );
    {
        let b = shared.lock().expect("bench");
        assert_eq!(b.lockin.sensitivity(), sens(20));
        assert_eq!(b.lockin.slope(), FilterSlope::Db24);
    }
    let r = d.read().expect("reading");
    // Noise: density √((20 nV)² + (2 µV)²·5 mV) = 143 nV/√Hz, ENBW 5/(64·0.1 s):
    // σ = 126 nV per sample; the mean of 10 is good to well under 1 µV.
    assert!((r.r_mean - 0.005).abs() < 1e-6, "{}", r.r_mean);
    assert!((r.x_mean - 0.005).abs() < 1e-6 && r.y_mean.abs() < 1e-6);
    assert!(r.r_std > 0.0 && r.r_std < 1e-6, "{}", r.r_std);
    assert_eq!(r.flags, ReadingFlags::default());
    assert!(r.is_valid());
    assert_eq!((r.n, r.sensitivity, r.autorange_steps), (10, sens(20), 0));
    // Settle 10 T = 1 s, then 9 gaps of T.
    assert_eq!(clock.now(), Duration::from_millis(101_900));
}

#[test]
fn driver_autoranges_a_3_mv_signal_down_from_1_v() {
    // Default config: 1 V, 100 ms, 12 dB/oct, autorange below 0.1 of full scale.
    let (mut d, shared, _) = bench(Sr830Config::default(), 0.003 / 0.45);
    d.setup().expect("set-up");
    let r = d.read().expect("reading");
    // 1 V → 500, 200, 100, 50 mV (3 mV is under 10 % of each) → 20 mV (15 %).
    assert_eq!((r.sensitivity, r.autorange_steps), (sens(21), 5));
    assert!(r.is_valid());
    assert!((r.r_mean - 0.003).abs() < 1e-6, "{}", r.r_mean);
    assert_eq!(shared.lock().expect("bench").lockin.sensitivity(), sens(21));
}

#[test]
fn driver_steps_out_of_an_output_overload() {
    let config = Sr830Config {
        sensitivity: sens(18),
        slope: FilterSlope::Db24,
        ..Sr830Config::default()
    };
    // 3 mV on 2 mV full scale overloads; 5 mV is fine.
    let (mut d, _, _) = bench(config, 0.003 / 0.45);
    d.setup().expect("set-up");
    let r = d.read().expect("reading");
    assert_eq!((r.sensitivity, r.autorange_steps), (sens(19), 1));
    assert!(r.is_valid());
    assert!((r.r_mean - 0.003).abs() < 1e-6, "{}", r.r_mean);
}

#[test]
fn driver_flags_input_overload_and_unlock() {
    let config = Sr830Config {
        samples: 2,
        ..Sr830Config::default()
    };
    // 1.6 V of detector signal: R = 0.72 V fits 1 V, but the input overloads.
    let (mut d, shared, clock) = bench(config, 1.6);
    d.setup().expect("set-up");
    let r = d.read().expect("reading");
    assert!(r.flags.input_overload && !r.flags.output_overload);
    assert!(!r.is_valid());
    assert_eq!(r.sensitivity, Sensitivity::LEAST);

    // 0.5 V (R = 0.225 V) but the reference is lost.
    clock.advance(Duration::from_secs(10));
    {
        let mut b = shared.lock().expect("bench");
        b.input_v = 0.5;
        b.lockin.set_input(clock.now().as_secs_f64(), 0.5);
        b.lockin.set_unlocked(true);
    }
    let r = d.read().expect("reading");
    assert!(r.flags.unlock && !r.flags.input_overload);
    assert_eq!(r.r(), None);

    // Locked again and settled: a valid reading of 0.225 V.
    shared.lock().expect("bench").lockin.set_unlocked(false);
    clock.advance(Duration::from_secs(10));
    let r = d.read().expect("reading");
    assert_eq!(r.flags, ReadingFlags::default());
    assert!((r.r().expect("valid") - 0.225).abs() < 1e-5);
}

#[test]
fn driver_auto_gain_reads_back_the_models_choice() {
    let (mut d, _, _) = bench(Sr830Config::default(), 0.003 / 0.45);
    d.setup().expect("set-up");
    assert_eq!(d.execute(&Command::AutoGain).expect("AGAN"), None);
    // 3 mV: 5 mV full scale, 60 %.
    assert_eq!(d.sensitivity(), sens(19));
    let r = d.read().expect("reading");
    assert_eq!((r.sensitivity, r.autorange_steps), (sens(19), 0));
    assert!((r.fraction_of_full_scale() - 0.6).abs() < 1e-3);
}

#[test]
fn config_file_fields_and_validation() {
    let c: LockInConfig = toml::from_str("chop_gain = 0.5\nserial = \"s/n55581\"").expect("toml");
    assert_eq!((c.chop_gain, c.serial.as_str()), (0.5, "s/n55581"));
    assert_eq!(c.firmware, "ver1.07");
    assert_eq!(c.input_overload_v, 1.4);
    c.validate().expect("valid");
    assert!(toml::from_str::<LockInConfig>("gain = 1").is_err());
    let bad = |c: LockInConfig| c.validate().expect_err("invalid").field;
    let d = LockInConfig::default;
    assert_eq!(
        bad(LockInConfig {
            chop_gain: 0.0,
            ..d()
        }),
        "chop_gain"
    );
    assert_eq!(
        bad(LockInConfig {
            shot_noise: -1.0,
            ..d()
        }),
        "shot_noise"
    );
    assert_eq!(
        bad(LockInConfig {
            phase_deg: f64::NAN,
            ..d()
        }),
        "phase_deg"
    );
    assert_eq!(
        bad(LockInConfig {
            chopper_hz: 0.0,
            ..d()
        }),
        "chopper_hz"
    );
    assert_eq!(
        bad(LockInConfig {
            serial: "a,b".into(),
            ..d()
        }),
        "serial"
    );
}

/// After `restart` with the same seed at the same input, two lock-ins with different
/// histories read the same bytes: what makes resumed runs reproduce uninterrupted ones.
#[test]
fn restart_forgets_history() {
    let cfg = LockInConfig::default();
    let mut a = on_rs232(cfg.clone(), 1);
    let mut b = on_rs232(cfg, 2);
    a.set_input(0.0, 0.5);
    b.set_input(0.0, 0.01);
    b.set_input(0.7, 0.2);
    a.set_input(3.0, 0.2);
    b.set_input(3.0, 0.2);
    a.restart(3.0, 99);
    b.restart(3.0, 99);
    for k in 1..20 {
        let t = 3.0 + 0.1 * f64::from(k);
        assert_eq!(send(&mut a, t, "SNAP? 1,2"), send(&mut b, t, "SNAP? 1,2"));
    }
    // Another seed, other noise.
    b.restart(5.0, 100);
    a.restart(5.0, 99);
    assert_ne!(
        send(&mut a, 5.1, "SNAP? 1,2"),
        send(&mut b, 5.1, "SNAP? 1,2")
    );
}

// ---------------------------------------------------------------------------------
// Where a point starts: settled, or at the previous reading (the step response).

/// The step response of `n` identical RC stages all starting at `y0`, with input `u`,
/// after `a` time constants: u + (y0 − u)·e^(−a)·Σ_{j<n} a^j/j!.
fn step_response(y0: f64, u: f64, a: f64, n: usize) -> f64 {
    let (mut sum, mut term) = (0.0, 1.0);
    for j in 0..n {
        sum += term;
        term *= a / (j + 1) as f64;
    }
    u + (y0 - u) * (-a).exp() * sum
}

/// `reply` is `exact` to a reply's 6 significant digits: within half a unit of the
/// sixth digit (and a hair for the arithmetic on either side).
fn assert_six_digits(reply: f64, exact: f64, what: &str) {
    let unit = 10f64.powf(exact.abs().log10().floor() - 5.0);
    assert!(
        (reply - exact).abs() <= 0.5 * unit * (1.0 + 1e-9),
        "{what}: replied {reply}, exact {exact}"
    );
}

/// X and Y a 0.02 V signal at 30° makes: 0.45 × 0.02 V × (cos 30°, sin 30°).
const U30: (f64, f64) = (0.007_794_228_634_059_948, 0.0045);

/// A noise-free lock-in at 30°, on `OFSL slope` and 100 ms, fed 0.02 V since t = 0.
fn at_30_degrees(slope: u8) -> LockIn {
    let mut l = on_rs232(
        LockInConfig {
            phase_deg: 30.0,
            ..quiet()
        },
        1,
    );
    assert_eq!(send(&mut l, 0.0, &format!("OFSL {slope};OFLT 8")), "");
    l.set_input(0.0, 0.02);
    l
}

#[test]
fn a_point_from_the_previous_reading_follows_the_cascade_step_response() {
    let (t0, tc) = (2.0, 0.1);
    let (x0, y0) = (-0.004, 0.012);
    for (slope, n) in [(1u8, 2usize), (3, 4)] {
        let mut l = at_30_degrees(slope);
        l.restart_from(t0, 5, Some([x0, y0]));
        // At the start the outputs read the previous reading exactly.
        assert_eq!(send(&mut l, t0, "SNAP? 1,2"), "-0.004,0.012\r");
        for a in [0.05, 0.3, 0.5, 1.0, 1.7, 2.5, 4.0, 6.3, 9.0, 15.0] {
            let (x, y) = snap_xy(&mut l, t0 + a * tc);
            let what = format!("{}dB/oct at {a} T", 6 * n);
            assert_six_digits(x, step_response(x0, U30.0, a, n), &format!("X {what}"));
            assert_six_digits(y, step_response(y0, U30.1, a, n), &format!("Y {what}"));
        }
        // Long after, the new value, exactly as a settled start reads it.
        assert_eq!(send(&mut l, t0 + 100.0, "SNAP? 1,2"), "0.00779423,0.0045\r");
    }
    // One value worked by hand: 24 dB/oct, X after 2 T: e^-2 (1 + 2 + 2 + 4/3) =
    // 0.8571235 of the step left, X = 0.007794229 − 0.011794229 × 0.8571235 =
    // −0.002314881.
    let mut l = at_30_degrees(3);
    l.restart_from(t0, 5, Some([x0, y0]));
    assert_eq!(send(&mut l, t0 + 2.0 * tc, "OUTP? 1"), "-0.00231488\r");
}

#[test]
fn the_first_point_of_a_run_starts_from_a_dark_output() {
    let (t0, tc) = (1.0, 0.1);
    let mut l = at_30_degrees(1);
    l.restart_from(t0, 5, None);
    assert_eq!(send(&mut l, t0, "SNAP? 1,2"), "0,0\r");
    for a in [0.2, 1.0, 3.0, 7.0] {
        let (x, y) = snap_xy(&mut l, t0 + a * tc);
        // From zero: u (1 − e^-a (1 + a)) at 12 dB/oct.
        let left = (-a).exp() * (1.0 + a);
        assert_six_digits(x, U30.0 * (1.0 - left), &format!("X at {a} T"));
        assert_six_digits(y, U30.1 * (1.0 - left), &format!("Y at {a} T"));
    }
}

#[test]
fn a_settled_point_is_flat_at_the_new_value_from_the_start() {
    let t0 = 2.0;
    for slope in [1u8, 3] {
        let mut l = at_30_degrees(slope);
        // A history far from the present input: a step to 0.5 V just before.
        l.set_input(1.9, 0.5);
        l.set_input(t0, 0.02);
        l.restart(t0, 5);
        for t in [t0, t0 + 0.005, t0 + 0.1, t0 + 0.37, t0 + 2.0] {
            assert_eq!(
                send(&mut l, t, "SNAP? 1,2"),
                "0.00779423,0.0045\r",
                "OFSL {slope} at {t} s"
            );
        }
    }
}

#[test]
fn a_point_from_the_previous_reading_is_deterministic() {
    // Noise on: the same seed, key and previous reading give the same bytes whatever
    // came before; another previous reading, other bytes.
    let run = |history: f64, from: Option<[f64; 2]>, seed: u64| {
        let mut l = on_rs232(LockInConfig::default(), 7);
        l.set_input(0.0, history);
        l.set_input(0.4, 0.02);
        l.restart_from(0.5, seed, from);
        (1..30)
            .map(|k| send(&mut l, 0.5 + 0.01 * f64::from(k), "SNAP? 1,2"))
            .collect::<String>()
    };
    let a = run(0.9, Some([0.001, -0.002]), 42);
    assert_eq!(a, run(0.001, Some([0.001, -0.002]), 42));
    assert_ne!(a, run(0.9, Some([0.002, -0.002]), 42));
    assert_ne!(a, run(0.9, Some([0.001, -0.002]), 43));
    assert_eq!(run(0.9, None, 42), run(0.3, Some([0.0, 0.0]), 42));
}

#[test]
fn a_previous_reading_out_of_any_range_starts_at_the_largest_output() {
    // ±1.09 × 1 V, the most any output reads; a non-finite value is taken as zero.
    let mut l = at_30_degrees(1);
    assert_eq!(send(&mut l, 0.0, "SENS 26"), "");
    l.restart_from(1.0, 5, Some([1e300, f64::NAN]));
    assert_eq!(send(&mut l, 1.0, "SNAP? 1,2;LIAS? 2"), "1.09,0\r0\r");
    l.restart_from(1.0, 5, Some([f64::NEG_INFINITY, -5.0]));
    assert_eq!(send(&mut l, 1.0, "SNAP? 1,2"), "0,-1.09\r");
}

// ---------------------------------------------------------------------------------
// The point start through the whole simulated instrument and its config.

fn config_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../config")
}

/// The simulator of `config/sim-transient.toml` without noise, replying on RS-232 at
/// 24 dB/oct and 100 ms, its input settled; the lock-in's X and Y of the signal.
fn transient_sim(point_start: PointStart) -> (SimInstrument, f64, f64) {
    let mut cfg = SimConfig::load(&config_dir().join("sim-transient.toml")).expect("sim config");
    cfg.lockin.amplifier_noise = 0.0;
    cfg.lockin.shot_noise = 0.0;
    cfg.lockin.point_start = point_start;
    let mut sim = SimInstrument::new(&cfg, SimClock::driven(0.0)).expect("simulator");
    assert_eq!(sim.lockin_bytes(b"OUTX 0\nOFSL 3\nOFLT 8\n"), b"");
    sim.clock().advance(Duration::from_secs(50));
    let v = sim.signal(sim.clock().seconds());
    // The arms at their power-up angles see the paint: a signal to step to.
    assert!(v > 1e-4, "{v}");
    let r = cfg.lockin.chop_gain * v;
    let phase = cfg.lockin.phase_deg.to_radians();
    (sim, r * phase.cos(), r * phase.sin())
}

/// `SNAP? 1,2` through the instrument, `after_s` seconds later.
fn sim_snap(sim: &mut SimInstrument, after_s: f64) -> (f64, f64) {
    sim.clock().advance(Duration::from_secs_f64(after_s));
    let text = String::from_utf8(sim.lockin_bytes(b"SNAP? 1,2\n")).expect("ASCII");
    let (x, y) = text.trim_end().split_once(',').expect("two values");
    (x.parse().expect("X"), y.parse().expect("Y"))
}

#[test]
fn the_instrument_starts_a_point_as_its_config_says() {
    let tc = 0.1;
    let previous = [0.0125, -0.003];
    let (mut sim, ux, uy) = transient_sim(PointStart::Previous);
    sim.begin_point(17, Some(previous));
    let mut elapsed = 0.0;
    for a in [0.0, 0.4, 1.5, 3.0, 6.0, 12.0] {
        let (x, y) = sim_snap(&mut sim, a * tc - elapsed);
        elapsed = a * tc;
        assert_six_digits(x, step_response(previous[0], ux, a, 4), &format!("X {a} T"));
        if a > 0.0 {
            assert_six_digits(y, step_response(previous[1], uy, a, 4), &format!("Y {a} T"));
        } else {
            assert_eq!((x, y), (0.0125, -0.003));
        }
    }
    // Settled: the previous reading is ignored, the outputs read the signal at once.
    let (mut sim, ux, _) = transient_sim(PointStart::Settled);
    sim.begin_point(17, Some(previous));
    for dt in [0.0, 0.04, 0.3] {
        let (x, y) = sim_snap(&mut sim, dt);
        assert_six_digits(x, ux, &format!("settled X after {dt} s"));
        assert_eq!(y, 0.0);
    }
}

#[test]
fn instruments_with_the_same_seed_key_and_previous_read_the_same_bytes() {
    let root = config_dir();
    let cfg = SimConfig::load(&root.join("sim-transient.toml")).expect("sim config");
    let session = |previous: Option<[f64; 2]>, key: u64| {
        let mut sim = SimInstrument::new(&cfg, SimClock::driven(0.0)).expect("simulator");
        let mut out = sim.lockin_bytes(b"OUTX 0\n");
        sim.clock().advance(Duration::from_secs(3));
        sim.begin_point(key, previous);
        for _ in 0..20 {
            sim.clock().advance(Duration::from_millis(30));
            out.extend(sim.lockin_bytes(b"SNAP? 1,2\n"));
        }
        out
    };
    let a = session(Some([0.01, 0.002]), 5);
    assert_eq!(a, session(Some([0.01, 0.002]), 5));
    assert_ne!(a, session(Some([0.011, 0.002]), 5));
    assert_ne!(a, session(Some([0.01, 0.002]), 6));
    assert_ne!(a, session(None, 5));
}

#[test]
fn sim_transient_is_the_default_with_point_start_previous() {
    let root = config_dir();
    let mut transient = SimConfig::load(&root.join("sim-transient.toml")).expect("transient");
    let mut example = SimConfig::load(&root.join("sim-example.toml")).expect("example");
    assert_eq!(transient.lockin.point_start, PointStart::Previous);
    assert_eq!(example.lockin.point_start, PointStart::Settled);
    assert_eq!(
        SimConfig::default_config()
            .expect("default")
            .lockin
            .point_start,
        PointStart::Settled
    );
    transient.lockin.point_start = PointStart::Settled;
    (transient.source, example.source) = (None, None);
    assert_eq!(transient, example);
}

#[test]
fn point_start_accepts_settled_or_previous_only() {
    let parse = |v: &str| toml::from_str::<LockInConfig>(&format!("point_start = \"{v}\""));
    assert_eq!(
        parse("previous").expect("previous").point_start,
        PointStart::Previous
    );
    assert_eq!(
        parse("settled").expect("settled").point_start,
        PointStart::Settled
    );
    let text = gonio_sim::config::DEFAULT_SIM.replacen(
        "shot_noise = 2e-6",
        "shot_noise = 2e-6\npoint_start = \"at-once\"",
        1,
    );
    let e = SimConfig::from_toml(&text, None).expect_err("an unknown start");
    assert_eq!(e.field.as_deref(), Some("lockin.point_start"), "{e}");
    let line = text[..text.find("point_start").expect("in text")]
        .matches('\n')
        .count()
        + 1;
    assert_eq!(e.line, Some(line), "{e}");
    assert_eq!(
        e.message,
        "unknown variant `at-once`, expected `settled` or `previous`"
    );
}

/// The input buffer over the wire (`SimInstrument::lockin_bytes`), as the manual's
/// p. 5-2 describes it: 256 characters, terminator included; an overflow clears it and
/// sets INP, and what arrives after it fills it afresh (the twin's reading).
#[test]
fn an_over_long_line_overflows_the_input_buffer_over_the_wire() {
    let cfg = SimConfig::load(&config_dir().join("sim-example.toml")).expect("sim config");
    let mut sim = SimInstrument::new(&cfg, SimClock::driven(0.0)).expect("simulator");
    let mut say = |line: &[u8]| String::from_utf8(sim.lockin_bytes(line)).expect("ASCII");
    assert_eq!(say(b"OUTX 0\n*CLS\n"), "");
    // 255 characters and the terminator fit: the line runs.
    let mut fits = format!("SENS 3;{}", " ".repeat(248)).into_bytes();
    assert_eq!(fits.len(), 255);
    fits.push(b'\r');
    assert_eq!(say(&fits), "");
    assert_eq!(say(b"*ESR?;SENS?\n"), "0\r3\r");
    // 256 characters: the terminator overflows the buffer; the line is lost.
    let mut full = format!("SENS 5;{}", "#".repeat(249)).into_bytes();
    full.push(b'\n');
    assert_eq!(say(&full), "");
    assert_eq!(say(b"*ESR?;SENS?\n"), "1\r3\r");
    // 300 characters: the 257th overflows it; the 43 after it run as a line of their
    // own, an illegal command (CMD as well as INP).
    let mut long = format!("SENS 7;{}", "#".repeat(293)).into_bytes();
    long.push(b'\n');
    assert_eq!(say(&long), "");
    assert_eq!(say(b"*ESR?;SENS?\n"), "33\r3\r");
    // A tail that is a command runs: 256 characters, one lost, then `SENS?`.
    let mut tail = vec![b'#'; 257];
    tail.extend_from_slice(b"SENS?\n");
    assert_eq!(say(&tail), "3\r");
    assert_eq!(say(b"*ESR?\n"), "1\r");
    // Far longer than the wire's framer keeps (16 buffers' worth): INP all the same.
    let mut huge = vec![b'#'; 10_000];
    huge.push(b'\n');
    assert_eq!(say(&huge), "");
    assert_eq!(say(b"*ESR?;SENS?\n"), "1\r3\r");
}
