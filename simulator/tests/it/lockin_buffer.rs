//! Readings through the SR830's data buffer (issue 40) against the twin, in memory on
//! virtual time: the buffered targeted reading agrees with the snapshot one, and with
//! the twin's signal, within the σ each claims.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use gonio_driver::sr830::{ReadTarget, Sr830, Sr830Config};
use gonio_driver::{Clock, ManualClock, Transport, TransportError};
use gonio_proto::Framer;
use gonio_proto::sr830::target::NoiseDensity;
use gonio_proto::sr830::{FilterSlope, Sensitivity, Sr830Framer, TimeConstant};
use gonio_sim::lockin::{LockIn, LockInConfig};

/// The driver's `Transport` on the twin, with the SR830's framer; each byte takes
/// 10 bits at 9600 baud.
struct FramedPort {
    lockin: Arc<Mutex<LockIn>>,
    clock: ManualClock,
    framer: Sr830Framer,
    in_flight: VecDeque<(Duration, Vec<u8>)>,
}

const BAUD: f64 = 9600.0;

fn wire(n: usize) -> Duration {
    Duration::from_secs_f64(n as f64 * 10.0 / BAUD)
}

impl Transport for FramedPort {
    fn send(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        self.clock.advance(wire(bytes.len()));
        let now = self.clock.now();
        self.framer.sent(bytes);
        let line = bytes.strip_suffix(b"\n").unwrap_or(bytes);
        let mut out = Vec::new();
        self.lockin
            .lock()
            .expect("twin")
            .handle_line(now.as_secs_f64(), line, &mut out);
        if !out.is_empty() {
            let at = now + Duration::from_millis(5) + wire(out.len());
            self.in_flight.push_back((at, out));
        }
        Ok(())
    }

    fn receive_line(&mut self, timeout: Duration) -> Result<Vec<u8>, TransportError> {
        let deadline = self.clock.now() + timeout;
        loop {
            if let Some(f) = self.framer.next_frame() {
                return f.map_err(TransportError::from);
            }
            match self.in_flight.pop_front() {
                Some((at, bytes)) if at <= deadline => {
                    let now = self.clock.now();
                    self.clock.advance(at.saturating_sub(now));
                    self.framer.push(&bytes);
                }
                other => {
                    if let Some(o) = other {
                        self.in_flight.push_front(o);
                    }
                    let now = self.clock.now();
                    self.clock.advance(deadline.saturating_sub(now));
                    return Err(TransportError::Timeout(timeout));
                }
            }
        }
    }

    fn clear_input(&mut self) -> Result<(), TransportError> {
        self.framer.clear();
        self.in_flight.clear();
        Ok(())
    }

    fn reconnect(&mut self) -> Result<(), TransportError> {
        Ok(())
    }

    fn name(&self) -> String {
        "twin".into()
    }
}

/// A targeted reading of a settled signal of `r` V (lock-in R) with `buffer` on or
/// off, the twin seeded with `seed`.
fn read(r: f64, sens: u8, buffer: bool, seed: u64) -> gonio_driver::sr830::Reading {
    let twin = LockInConfig::default();
    let noise = NoiseDensity {
        floor: twin.amplifier_noise,
        shot: twin.shot_noise,
    };
    let mut lockin = LockIn::new(twin.clone(), seed);
    lockin.set_input(0.0, r / twin.chop_gain);
    let lockin = Arc::new(Mutex::new(lockin));
    let clock = ManualClock::new();
    clock.advance(Duration::from_secs(100));
    let port = FramedPort {
        lockin: lockin.clone(),
        clock: clock.clone(),
        framer: Sr830Framer::new(256),
        in_flight: VecDeque::new(),
    };
    let config = Sr830Config {
        sensitivity: Sensitivity::new(sens).expect("SENS"),
        time_constant: TimeConstant::new(7).expect("30 ms"),
        slope: FilterSlope::Db24,
        noise: Some(noise),
        // 30 ms alone: snapshots 42.5 ms apart sample its noise sparsely, so a long
        // reading gains from the buffer's 64 Hz (the 300 ms snapshots would not).
        time_constant_range: Some([
            TimeConstant::new(7).expect("valid"),
            TimeConstant::new(7).expect("valid"),
        ]),
        buffer,
        settle_residual: 1e-4,
        ..Sr830Config::default()
    }
    .with_baud(9600);
    let mut d = Sr830::new(port, clock.clone(), config).expect("valid");
    d.setup().expect("set-up");
    let now = clock.now().as_secs_f64();
    lockin.lock().expect("valid").restart(now, seed);
    d.input_changed();
    let target = ReadTarget {
        sigma_relative: SIGMA,
        sigma_absolute: 0.0,
        max_s: 30.0,
        min_samples: 1,
    };
    d.read_targeted(&target, Some(r)).expect("reading")
}

const SIGMA: f64 = 3e-5;

#[test]
fn a_buffered_reading_agrees_with_the_signal_within_its_target() {
    let r = 1e-4;
    let mut z2 = 0.0;
    let n = 8;
    for seed in 0..n {
        let b = read(r, 15, true, seed);
        assert!(b.sample_rate.is_some(), "{b:?}");
        let z = (b.r_mean - r) / (SIGMA * r);
        z2 += z * z;
        eprintln!("seed {seed}: buffered {} n {} ({z:+.2} σ)", b.r_mean, b.n);
    }
    assert!(z2 / (n as f64) < 3.0, "mean z² {}", z2 / n as f64);
}

/// A signal the present range does not fit is read by snapshots: a range change
/// costs a whole buffered look where a snapshot shows it at once.
#[test]
fn a_signal_outside_the_present_range_is_read_by_snapshots() {
    let b = read(1e-4, 26, true, 1);
    assert_eq!(b.sample_rate, None, "{b:?}");
    assert!(b.autorange_steps > 0);
}

/// The same through the simulator's instrument and its in-memory transport (its
/// wire times, latency and framer), against the optics' signal.
#[test]
fn a_buffered_reading_through_the_simulated_instrument_reads_its_signal() {
    use gonio_sim::transport::{SimTransport, lock};
    use gonio_sim::{Port, SimConfig};
    for buffer in [false, true] {
        let mut cfg = SimConfig::default_config().expect("sim");
        cfg.seed = 5;
        let sim = gonio_sim::instrument(&cfg).expect("sim");
        let clock = lock(&sim).clock().clone();
        let port = SimTransport::new(sim.clone(), Port::Detector);
        let twin = lock(&sim).lockin_mut().config().clone();
        let config = Sr830Config {
            noise: Some(NoiseDensity {
                floor: twin.amplifier_noise,
                shot: twin.shot_noise,
            }),
            time_constant_range: Some([
                TimeConstant::new(7).expect("valid"),
                TimeConstant::new(7).expect("valid"),
            ]),
            buffer,
            // 1 mV: the signal, about 0.39 mV, fits it.
            sensitivity: Sensitivity::new(17).expect("1 mV"),
            slope: FilterSlope::Db24,
            settle_residual: 1e-4,
            ..Sr830Config::default()
        }
        .with_baud(9600);
        let mut d = Sr830::new(port, clock.clone(), config).expect("valid");
        d.setup().expect("set-up");
        lock(&sim).begin_point(1, None);
        d.input_changed();
        let t = clock.now().as_secs_f64();
        let r = twin.chop_gain * lock(&sim).signal(t);
        let target = ReadTarget {
            sigma_relative: 1e-5,
            sigma_absolute: 0.0,
            max_s: 120.0,
            min_samples: 1,
        };
        let started = clock.now();
        let got = d.read_targeted(&target, Some(r)).expect("reading");
        let took = (clock.now() - started).as_secs_f64();
        let z = (got.r_mean - r) / (1e-5 * r);
        eprintln!(
            "buffer {buffer}: {} vs {r} ({z:+.2} σ), n {}, rate {:?}, {took:.2} s",
            got.r_mean, got.n, got.sample_rate
        );
        assert!(z.abs() < 4.0, "buffer {buffer}: {got:?} vs {r}");
        assert_eq!(got.sample_rate.is_some(), buffer, "{got:?}");
    }
}
