//! The Cornerstone 130: the twin against the manual's wire format (echo, status byte,
//! error codes, `*WAI`), and the real driver (`gonio_driver::cs130::Cs130`) talking to
//! the twin over an in-memory transport on virtual time: wavelengths, the automatic
//! grating and order-filter changes at the documented crossovers, the shutter, the
//! actual wavelength read back, move times, refusals before any byte, and a unit with
//! and without a filter wheel.

use std::time::Duration;

use gonio_driver::cs130::{Cs130, Cs130Config, Cs130Error, ErrorCode, MonoState};
use gonio_driver::{Clock, ManualClock, Transport, TransportError};
use gonio_proto::LineFramer;
use gonio_sim::monochromator::{Cs130Twin, MonoOptical, MonochromatorSim};
use gonio_sim::twin::TimedLine;

/// The twin behind the driver's `Transport`: bytes to it at the clock's time, its
/// output delivered when due, the clock moved to each delivery or deadline.
struct TwinLink {
    twin: Cs130Twin,
    clock: ManualClock,
    framer: LineFramer,
    /// Every byte the driver wrote.
    wire: Vec<u8>,
}

impl TwinLink {
    fn new(config: &MonochromatorSim, clock: ManualClock) -> Self {
        config.validate().expect("valid twin config");
        TwinLink {
            twin: Cs130Twin::new(config),
            clock,
            framer: LineFramer::new(b'\n', 256),
            wire: Vec::new(),
        }
    }

    fn secs(&self) -> f64 {
        self.clock.now().as_secs_f64()
    }
}

impl Transport for TwinLink {
    fn send(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        self.wire.extend_from_slice(bytes);
        let now = self.secs();
        self.twin.push(now, bytes);
        Ok(())
    }

    fn receive_line(&mut self, timeout: Duration) -> Result<Vec<u8>, TransportError> {
        let deadline = self.clock.now() + timeout;
        loop {
            if let Some(frame) = self.framer.next_line() {
                return frame.map_err(TransportError::from);
            }
            match self.twin.next_event() {
                Some(t) if t <= deadline.as_secs_f64() => {
                    let at = Duration::from_secs_f64(t);
                    if at > self.clock.now() {
                        self.clock.advance(at - self.clock.now());
                    }
                    let mut out = Vec::new();
                    self.twin.poll(t, &mut out);
                    self.framer.push(&out);
                }
                _ => {
                    self.clock
                        .advance(deadline.saturating_sub(self.clock.now()));
                    return Err(TransportError::Timeout(timeout));
                }
            }
        }
    }

    fn clear_input(&mut self) -> Result<(), TransportError> {
        let mut stale = Vec::new();
        let now = self.secs();
        self.twin.poll(now, &mut stale);
        self.framer.clear();
        Ok(())
    }

    fn reconnect(&mut self) -> Result<(), TransportError> {
        Ok(())
    }

    fn name(&self) -> String {
        "twin".into()
    }
}

type Driver = Cs130<TwinLink, ManualClock>;

fn rig(sim: &MonochromatorSim) -> (Driver, ManualClock) {
    rig_with(sim, Cs130Config::default())
}

fn rig_with(sim: &MonochromatorSim, config: Cs130Config) -> (Driver, ManualClock) {
    let clock = ManualClock::new();
    let link = TwinLink::new(sim, clock.clone());
    let driver = Cs130::new(link, clock.clone(), config).expect("valid config");
    (driver, clock)
}

fn state(nm: f64, grating: u8, filter: u8, shutter_open: bool) -> MonoState {
    MonoState {
        wavelength_nm: nm,
        grating,
        filter,
        shutter_open,
    }
}

/// The twin's optics at the clock's time, after handing the driver back.
fn optics(driver: Driver) -> (MonoOptical, Vec<u8>) {
    let (link, clock) = driver.into_inner();
    (link.twin.optical(clock.now().as_secs_f64()), link.wire)
}

#[test]
fn the_driver_walks_the_crossovers_and_reads_back_set_plus_accuracy() {
    let sim = MonochromatorSim::default();
    let acc = sim.accuracy_nm;
    let (mut d, _) = rig(&sim);
    assert_eq!(d.init().unwrap(), state(400.0, 1, 1, false));
    assert_eq!(d.info(), Some("CORNERSTONE 130 TWIN"));
    // Every move approaches from below: actual = asked + accuracy. The filter and
    // grating change at the crossovers of Cs130Config::order_filter_for / grating_for.
    for (nm, grating, filter) in [
        (480.0, 1, 1),
        (499.5, 1, 1),
        (500.0, 1, 2),
        (599.0, 1, 2),
        (600.0, 1, 3),
        (900.0, 1, 3),
        (950.0, 2, 3),
        (1009.0, 2, 3),
        (1010.0, 2, 4),
        (1600.0, 2, 5),
    ] {
        let got = d.go_to(nm).unwrap();
        assert_eq!(got, state(nm + acc, grating, filter, false), "at {nm} nm");
    }
    let (optical, wire) = optics(d);
    assert_eq!(optical.actual_nm, 1600.0 + acc);
    assert_eq!((optical.grating, optical.filter), (2, 5));
    // 2 nm FWHM at 1200 l/mm: 4 nm with 600 l/mm.
    assert_eq!(optical.bandwidth_nm, 4.0);
    let wire = String::from_utf8(wire).unwrap();
    assert_eq!(wire.matches("GRAT 2\r\n").count(), 1);
    assert_eq!(wire.matches("FILTER ").count(), 4, "{wire}");
    assert!(wire.contains("FILTER 2\r\nGOWAVE 500\r\n*WAI\r\nWAVE?\r\nSTB?\r\n"));
    assert!(wire.contains("GRAT 2\r\nGOWAVE 950\r\n"));
}

#[test]
fn approaching_from_above_leaves_the_drive_backlash_short_unless_the_session_comes_up() {
    let sim = MonochromatorSim::default();
    // Straight down (approach_nm = 0): the drive stops backlash short.
    let (mut d, _) = rig_with(
        &sim,
        Cs130Config {
            approach_nm: 0.0,
            ..Cs130Config::default()
        },
    );
    d.init().unwrap();
    d.go_to(650.0).unwrap();
    let got = d.go_to(620.0).unwrap();
    assert_eq!(got.wavelength_nm, 620.0 + sim.accuracy_nm + sim.backlash_nm);
    // The session's default goes 5 nm below first and comes up: no backlash.
    let (mut d, _) = rig(&sim);
    d.init().unwrap();
    d.go_to(650.0).unwrap();
    let got = d.go_to(620.0).unwrap();
    assert_eq!(got.wavelength_nm, 620.0 + sim.accuracy_nm);
    let (_, wire) = optics(d);
    let wire = String::from_utf8(wire).unwrap();
    assert!(wire.contains("GOWAVE 615\r\nGOWAVE 620\r\n"), "{wire}");
}

#[test]
fn a_move_takes_grating_filter_and_slew_times() {
    let sim = MonochromatorSim::default();
    let (mut d, clock) = rig(&sim);
    d.init().unwrap();
    d.go_to(480.0).unwrap();
    let t0 = clock.now().as_secs_f64();
    d.go_to(1100.0).unwrap();
    let elapsed = clock.now().as_secs_f64() - t0;
    // GRAT 2, FILTER 4, then 480.25 → 1100.25 nm at 200 nm/s, one after the other.
    let expected = sim.grating_change_s + sim.filter_change_s + 620.0 / 200.0;
    assert!(
        (elapsed - expected).abs() < 1e-6,
        "{elapsed} s, expected {expected} s"
    );
}

#[test]
fn the_shutter_closes_and_opens() {
    let (mut d, _) = rig(&MonochromatorSim::default());
    d.init().unwrap();
    assert!(d.shutter(true).unwrap().shutter_open);
    assert!(!d.shutter(false).unwrap().shutter_open);
    assert_eq!(d.state().unwrap(), state(400.0, 1, 1, false));
    let (optical, _) = optics(d);
    assert!(!optical.shutter_open);
}

#[test]
fn an_out_of_range_wavelength_writes_nothing() {
    let (mut d, _) = rig(&MonochromatorSim::default());
    for nm in [2500.0, 100.0, f64::NAN] {
        let e = d.go_to(nm).unwrap_err();
        assert!(matches!(e, Cs130Error::Select(_)), "{e}");
    }
    let (_, wire) = optics(d);
    assert!(wire.is_empty(), "{:?}", String::from_utf8_lossy(&wire));
}

#[test]
fn a_destination_the_twin_refuses_is_reported_with_error_3() {
    // The session allows 250 nm; this twin's grating 1 starts at 300 nm.
    let mut sim = MonochromatorSim::default();
    sim.gratings[0].min_nm = 300.0;
    let (mut d, _) = rig(&sim);
    d.init().unwrap();
    let e = d.go_to(260.0).unwrap_err();
    assert_eq!(e, Cs130Error::Rejected(ErrorCode::DESTINATION));
}

/// The twin's bytes at the time they leave.
fn exchange(twin: &mut Cs130Twin, t: f64, bytes: &[u8]) -> Vec<u8> {
    twin.push(t, bytes);
    let mut out = Vec::new();
    twin.poll(t, &mut out);
    out
}

#[test]
fn the_twin_echoes_answers_and_reports_errors_as_the_manual_says() {
    let mut twin = Cs130Twin::new(&MonochromatorSim::default());
    // §15.4: the echo, then the answer.
    assert_eq!(
        exchange(&mut twin, 0.0, b"WAVE?\r\n"),
        b"WAVE?\r\n400.00\r\n"
    );
    assert_eq!(
        exchange(&mut twin, 0.0, b"GOWAVE 500\r\n"),
        b"GOWAVE 500\r\n"
    );
    // Echoed byte by byte, whatever the chunks.
    assert_eq!(exchange(&mut twin, 0.1, b"wa"), b"wa");
    assert_eq!(exchange(&mut twin, 0.1, b"ve?\r\n"), b"ve?\r\n410.00\r\n");
    // §15.8: after *WAI the query waits for the move (100.25 nm at 100 nm/s).
    assert_eq!(
        exchange(&mut twin, 0.2, b"*WAI\r\nWAVE?\r\n"),
        b"*WAI\r\nWAVE?\r\n"
    );
    assert_eq!(twin.next_event(), Some(1.0025));
    let mut out = Vec::new();
    twin.poll(1.0025, &mut out);
    assert_eq!(out, b"500.25\r\n");
    // §15.9: errors set the status byte until STB?, the code until ERROR?.
    assert_eq!(
        exchange(&mut twin, 2.0, b"GOWAVE 5000\r\n"),
        b"GOWAVE 5000\r\n"
    );
    // Decimal, as the Model 74000 table gives it: "32 when an error occurred or 00".
    assert_eq!(exchange(&mut twin, 2.0, b"STB?\r\n"), b"STB?\r\n32\r\n");
    assert_eq!(exchange(&mut twin, 2.0, b"STB?\r\n"), b"STB?\r\n00\r\n");
    assert_eq!(exchange(&mut twin, 2.0, b"ERROR?\r\n"), b"ERROR?\r\n3\r\n");
    assert_eq!(exchange(&mut twin, 2.0, b"ERROR?\r\n"), b"ERROR?\r\n0\r\n");
    exchange(&mut twin, 2.0, b"GOWAV 5\r\n");
    assert_eq!(exchange(&mut twin, 2.0, b"ERROR?\r\n"), b"ERROR?\r\n1\r\n");
    exchange(&mut twin, 2.0, b"FILTER 9\r\n");
    assert_eq!(exchange(&mut twin, 2.0, b"ERROR?\r\n"), b"ERROR?\r\n2\r\n");
    assert_eq!(
        exchange(&mut twin, 2.0, b"SHUTTER O\r\nSHUTTER?\r\n"),
        b"SHUTTER O\r\nSHUTTER?\r\nO\r\n"
    );
    assert_eq!(
        exchange(&mut twin, 2.0, b"GRAT?\r\n"),
        b"GRAT?\r\n1,1200,BLAZE350\r\n"
    );
    assert_eq!(
        exchange(&mut twin, 2.0, b"UNITS UM\r\nWAVE?\r\n"),
        b"UNITS UM\r\nWAVE?\r\n0.50\r\n"
    );
}

#[test]
fn the_picoammeter_shaped_hooks_put_held_answers_at_busy_until() {
    let mut twin = Cs130Twin::new(&MonochromatorSim::default());
    let mut out = Vec::new();
    twin.handle_line(0.0, b"GOWAVE 600", &mut out);
    assert_eq!(out, b"GOWAVE 600\r\n");
    // Not held: due at once, while the drive moves until 2.0025 s.
    assert_eq!(twin.busy_until(), 0.0);
    assert_eq!(twin.motion_until(), 2.0025);
    out.clear();
    twin.handle_line(0.5, b"*WAI", &mut out);
    twin.handle_line(0.5, b"WAVE?", &mut out);
    assert_eq!(out, b"*WAI\r\nWAVE?\r\n600.25\r\n");
    assert_eq!(twin.busy_until(), 2.0025);
    assert_eq!(twin.optical(1.0).actual_nm, 400.0 + 200.25 / 2.0025);
}

#[test]
fn abort_stops_the_drive_where_it_is() {
    let mut twin = Cs130Twin::new(&MonochromatorSim::default());
    exchange(&mut twin, 0.0, b"GOWAVE 600\r\n");
    exchange(&mut twin, 1.0, b"ABORT\r\n");
    assert_eq!(twin.optical(5.0).actual_nm, 500.0);
    assert_eq!(
        exchange(&mut twin, 5.0, b"WAVE?\r\n"),
        b"WAVE?\r\n500.00\r\n"
    );
}

#[test]
fn the_sim_config_refuses_bad_fields_by_name() {
    let parsed: MonochromatorSim = toml::from_str("accuracy_nm = 0.1\nbacklash_nm = 0.2").unwrap();
    assert_eq!(parsed.accuracy_nm, 0.1);
    parsed.validate().unwrap();
    assert!(parsed.filter_wheel, "a wheel unless said otherwise");
    let no_wheel: MonochromatorSim = toml::from_str("filter_wheel = false").unwrap();
    no_wheel.validate().unwrap();
    assert!(!no_wheel.filter_wheel);
    assert!(toml::from_str::<MonochromatorSim>("speed = 3").is_err());
    let mut bad = MonochromatorSim::default();
    bad.gratings[1].slew_nm_per_s = 0.0;
    assert_eq!(
        bad.validate().unwrap_err().field,
        "gratings[1].slew_nm_per_s"
    );
    let bad = MonochromatorSim {
        backlash_nm: -1.0,
        ..MonochromatorSim::default()
    };
    assert_eq!(bad.validate().unwrap_err().field, "backlash_nm");
}

/// A twin without a filter wheel.
fn wheel_less_twin() -> MonochromatorSim {
    MonochromatorSim {
        filter_wheel: false,
        ..MonochromatorSim::default()
    }
}

/// A session config for a unit without a filter wheel.
fn wheel_less_session() -> Cs130Config {
    Cs130Config {
        filter_wheel: false,
        auto_order_filter: false,
        ..Cs130Config::default()
    }
}

#[test]
fn the_twin_answers_filter_as_the_model_74000_table_says_with_and_without_a_wheel() {
    // With a wheel: "The response to FILTER? is the integer value describing the
    // current filter position"; "Acceptable values range from 1 through 6".
    let mut twin = Cs130Twin::new(&MonochromatorSim::default());
    assert_eq!(
        exchange(&mut twin, 0.0, b"FILTER?\r\n"),
        b"FILTER?\r\n1\r\n"
    );
    assert_eq!(exchange(&mut twin, 0.0, b"STB?\r\n"), b"STB?\r\n00\r\n");
    exchange(&mut twin, 0.0, b"FILTER 6\r\n");
    assert_eq!(
        exchange(&mut twin, 9.0, b"FILTER?\r\n"),
        b"FILTER?\r\n6\r\n"
    );
    exchange(&mut twin, 9.0, b"FILTER 7\r\n");
    assert_eq!(exchange(&mut twin, 9.0, b"STB?\r\n"), b"STB?\r\n32\r\n");
    assert_eq!(exchange(&mut twin, 9.0, b"ERROR?\r\n"), b"ERROR?\r\n2\r\n");
    // Without: "if there is no filter wheel connected … 0 is returned and an error is
    // set in the status byte"; the code is §15.9's 6, "accessory not present (usually
    // filter wheel)".
    let mut twin = Cs130Twin::new(&wheel_less_twin());
    assert_eq!(
        exchange(&mut twin, 0.0, b"FILTER?\r\n"),
        b"FILTER?\r\n0\r\n"
    );
    assert_eq!(exchange(&mut twin, 0.0, b"STB?\r\n"), b"STB?\r\n32\r\n");
    assert_eq!(exchange(&mut twin, 0.0, b"STB?\r\n"), b"STB?\r\n00\r\n");
    assert_eq!(exchange(&mut twin, 0.0, b"ERROR?\r\n"), b"ERROR?\r\n6\r\n");
    assert_eq!(exchange(&mut twin, 0.0, b"FILTER 2\r\n"), b"FILTER 2\r\n");
    assert_eq!(exchange(&mut twin, 0.0, b"STB?\r\n"), b"STB?\r\n32\r\n");
    assert_eq!(exchange(&mut twin, 0.0, b"ERROR?\r\n"), b"ERROR?\r\n6\r\n");
    // Nothing moved: no wheel, no filter in the beam.
    assert_eq!(twin.optical(5.0).filter, 0);
}

/// Gonio's start-up before the `filter_wheel` field: `FILTER?` always, then a clean
/// `STB?` demanded. On a unit without a wheel the status byte is 32 by then, so that
/// start-up could never succeed; on a unit with one it was clean.
#[test]
fn the_old_start_up_fails_on_a_wheel_less_unit() {
    let old_init: &[&[u8]] = &[
        b"INFO?\r\n",
        b"UNITS NM\r\n",
        b"GRAT?\r\n",
        b"FILTER?\r\n",
        b"SHUTTER?\r\n",
        b"WAVE?\r\n",
    ];
    for (sim, status) in [
        (MonochromatorSim::default(), &b"STB?\r\n00\r\n"[..]),
        (wheel_less_twin(), b"STB?\r\n32\r\n"),
    ] {
        let mut twin = Cs130Twin::new(&sim);
        for statement in old_init {
            exchange(&mut twin, 0.0, statement);
        }
        assert_eq!(exchange(&mut twin, 0.0, b"STB?\r\n"), status);
    }
    // And the same through the session: a wheel configured on a wheel-less unit.
    let (mut d, _) = rig(&wheel_less_twin());
    let e = d.init().unwrap_err();
    assert_eq!(
        e,
        Cs130Error::NoFilterWheel {
            code: Some(ErrorCode::NO_ACCESSORY)
        }
    );
}

#[test]
fn without_a_wheel_the_driver_starts_moves_and_never_sends_filter() {
    let sim = wheel_less_twin();
    let acc = sim.accuracy_nm;
    let (mut d, _) = rig_with(&sim, wheel_less_session());
    assert_eq!(d.init().unwrap(), state(400.0, 1, 0, false));
    for (nm, grating) in [(480.0, 1), (650.0, 1), (1100.0, 2), (1600.0, 2)] {
        assert_eq!(d.go_to(nm).unwrap(), state(nm + acc, grating, 0, false));
    }
    assert!(d.shutter(true).unwrap().shutter_open);
    let (optical, wire) = optics(d);
    assert_eq!(optical.filter, 0);
    let wire = String::from_utf8(wire).unwrap();
    assert!(!wire.contains("FILTER"), "{wire}");
    assert!(wire.starts_with("INFO?\r\nUNITS NM\r\nGRAT?\r\nSHUTTER?\r\nWAVE?\r\nSTB?\r\n"));
}

#[test]
fn a_wheel_configured_on_a_wheel_less_unit_fails_start_up_and_leaves_it_clean() {
    let (mut d, _) = rig(&wheel_less_twin());
    let e = d.init().unwrap_err();
    let text = e.to_string();
    assert!(text.contains("no filter wheel answered"), "{text}");
    assert!(text.contains("filter_wheel = false"), "{text}");
    let (link, clock) = d.into_inner();
    let wire = String::from_utf8(link.wire.clone()).unwrap();
    assert!(
        wire.ends_with("GRAT?\r\nFILTER?\r\nSTB?\r\nERROR?\r\n"),
        "{wire}"
    );
    // The error was read back: the next start-up (config fixed) finds a clean unit.
    let mut twin = link.twin;
    let t = clock.now().as_secs_f64();
    assert_eq!(exchange(&mut twin, t, b"STB?\r\n"), b"STB?\r\n00\r\n");
}

#[test]
fn a_session_without_a_wheel_works_on_a_unit_with_one_and_leaves_it_alone() {
    let (mut d, _) = rig_with(&MonochromatorSim::default(), wheel_less_session());
    assert_eq!(d.init().unwrap().filter, 0);
    d.go_to(1100.0).unwrap();
    let (optical, wire) = optics(d);
    assert_eq!(optical.filter, 1);
    assert!(!String::from_utf8(wire).unwrap().contains("FILTER"));
}
