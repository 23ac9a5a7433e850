//! The simulated goniometer: a chain of SMC100 controllers and an SR830 lock-in that
//! speak their protocols byte for byte (through `gonio-proto`), drive simulated stages
//! along trapezoidal profiles, and measure a sample's BRDF through simulated optics,
//! detector noise, drift and faults.
//!
//! - [`SimInstrument`] is the whole instrument: bytes in, bytes out, at the time of a
//!   shared [`SimClock`].
//! - [`SimTransport`] puts it behind the driver's `Transport` trait in memory;
//!   [`PtySim`] behind pseudo-terminals, for drivers in this or another process
//!   (`gonio-sim --config FILE`).
//! - [`connect`] builds a `gonio_driver::Goniometer` on an in-process simulator: what
//!   tests use, and what an instrument config whose ports are `"sim"` gets.
//!
//! Deterministic: the config's seed fixes every noise sample and every random fault,
//! so the same seed and the same commands give the same bytes.

pub mod apt;
pub mod bench;
pub mod clock;
pub mod config;
pub mod controller;
pub mod faults;
pub mod filterwheel;
pub mod instrument;
pub mod lockin;
pub mod monochromator;
pub mod motion;
pub mod optics;
pub mod picoammeter;
pub mod pty;
pub mod serve;
pub mod spectral;
pub mod transport;
pub mod twin;

pub use bench::SimBench;
pub use clock::SimClock;
pub use config::{SampleKind, SimConfig, SimConfigError};
pub use faults::{FaultConfig, Port};
pub use instrument::{SimInstrument, SimStats};
pub use optics::LightPath;
pub use pty::PtySim;
pub use transport::{SharedSim, SimTransport, lock};

use std::sync::{Arc, Mutex};

use gonio_driver::config::{DetectorKind, LineKind};
use gonio_driver::{Goniometer, GoniometerError, InstrumentConfig, PortUse};

/// Why a simulated instrument could not be built.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The sim config is not usable.
    #[error("{0}")]
    Config(#[from] SimConfigError),
    /// The instrument config names axes the simulator does not have.
    #[error("instrument config: {0}")]
    Mismatch(String),
    /// The goniometer could not be built.
    #[error("{0}")]
    Goniometer(#[from] GoniometerError),
}

/// A simulator on a new driven clock.
pub fn instrument(sim: &SimConfig) -> Result<SharedSim, SimError> {
    let clock = SimClock::driven(sim.time_scale);
    Ok(Arc::new(Mutex::new(SimInstrument::new(sim, clock)?)))
}

/// The simulated line an instrument config's port stands for.
fn sim_port(
    instrument: &InstrumentConfig,
    sim: &SimConfig,
    use_: PortUse<'_>,
) -> Result<Port, SimError> {
    let line = match use_ {
        PortUse::Detector(_) => return Ok(Port::Detector),
        PortUse::Monochromator(_) => return Ok(Port::Monochromator),
        PortUse::FilterWheel(_) => return Ok(Port::FilterWheel),
        PortUse::Motion(line) => line,
    };
    let LineKind::Apt(axis, _) = &line.kind else {
        return Ok(Port::Motion);
    };
    let role = instrument
        .kinematics
        .as_ref()
        .and_then(|k| {
            k.layout
                .roles()
                .iter()
                .zip(k.role_axes())
                .find(|(_, a)| *a == axis.name)
                .map(|(r, _)| *r)
        })
        .ok_or_else(|| {
            SimError::Mismatch(format!(
                "APT axis {:?} plays no role of the [kinematics] section, so no simulated stage stands for it",
                axis.name
            ))
        })?;
    let n = sim
        .apt_roles()
        .iter()
        .position(|r| *r == role)
        .and_then(|n| u8::try_from(n).ok())
        .ok_or_else(|| {
            SimError::Mismatch(format!(
                "axis {:?} ({role}) is an APT controller, but the simulator has no [apt.{role}]",
                axis.name
            ))
        })?;
    if let Some(twin) = sim.apt.get(role)
        && twin.model.stage() != axis.stage
    {
        return Err(SimError::Mismatch(format!(
            "axis {:?} is a {:?}, but the simulator's [apt.{role}] is a {:?}",
            axis.name,
            axis.stage,
            twin.model.stage()
        )));
    }
    Ok(Port::Apt(n))
}

/// Checks that every axis of `instrument` is a simulated controller of its family, and
/// the detector the simulated one.
pub fn check_compatible(instrument: &InstrumentConfig, sim: &SimConfig) -> Result<(), SimError> {
    let addrs = sim
        .role_addresses()
        .map_err(|(f, m)| SimError::Mismatch(format!("{f}: {m}")))?;
    for line in instrument.motion.lines() {
        if let LineKind::Smc100(axes) = &line.kind {
            for a in axes {
                if !addrs.contains(&a.address) {
                    return Err(SimError::Mismatch(format!(
                        "axis {:?} is at address {}, but the simulator's controllers are at {addrs:?}",
                        a.name, a.address
                    )));
                }
            }
        }
        sim_port(instrument, sim, PortUse::Motion(&line))?;
    }
    let selectors = [
        (
            "monochromator",
            instrument.monochromator.is_some(),
            sim.monochromator.is_some(),
        ),
        (
            "filter_wheel",
            instrument.filter_wheel.is_some(),
            sim.filter_wheel.is_some(),
        ),
    ];
    if let Some((name, ..)) = selectors.iter().find(|(_, wanted, has)| *wanted && !has) {
        return Err(SimError::Mismatch(format!(
            "the instrument has a [{name}], but the simulator has none"
        )));
    }
    match (instrument.detector.kind, sim.picoammeter.is_some()) {
        (DetectorKind::Sr830, true) => Err(SimError::Mismatch(
            "the detector is an SR830, but the simulator's is a picoammeter ([picoammeter])".into(),
        )),
        (DetectorKind::K6485, false) => Err(SimError::Mismatch(
            "the detector is a K6485, but the simulator has no [picoammeter]".into(),
        )),
        _ => Ok(()),
    }
}

/// A goniometer driving an in-process simulator over in-memory lines, on the
/// simulator's clock; and the handle to the simulator (faults, stats, clock).
pub type SimGoniometer = Goniometer<SimClock>;

/// Builds a simulator from `sim` and a goniometer from `instrument` that drives it:
/// each line of the instrument config on the simulated line of its family.
pub fn connect(
    instrument_cfg: &InstrumentConfig,
    sim: &SimConfig,
) -> Result<(SimGoniometer, SharedSim), SimError> {
    check_compatible(instrument_cfg, sim)?;
    let shared = instrument(sim)?;
    let clock = lock(&shared).clock().clone();
    let mut mismatch = None;
    let g = Goniometer::from_ports(
        instrument_cfg,
        |use_, _| match sim_port(instrument_cfg, sim, use_) {
            Ok(port) => Ok(Box::new(SimTransport::new(shared.clone(), port))),
            Err(e) => {
                let m = e.to_string();
                mismatch = Some(e);
                Err(gonio_driver::TransportError::Script(m))
            }
        },
        clock,
    );
    if let Some(e) = mismatch {
        return Err(e);
    }
    Ok((g?, shared))
}
