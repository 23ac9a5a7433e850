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
pub mod instrument;
pub mod lockin;
pub mod optics;
pub mod picoammeter;
pub mod pty;
pub mod serve;
pub mod transport;

pub use bench::SimBench;
pub use clock::SimClock;
pub use config::{SampleKind, SimConfig, SimConfigError};
pub use faults::{FaultConfig, Port};
pub use instrument::{SimInstrument, SimStats};
pub use optics::LightPath;
pub use pty::PtySim;
pub use transport::{SharedSim, SimTransport, lock};

use std::sync::{Arc, Mutex};

use gonio_driver::{Goniometer, GoniometerError, InstrumentConfig};

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

/// Checks that every axis of `instrument` is a simulated controller.
pub fn check_compatible(instrument: &InstrumentConfig, sim: &SimConfig) -> Result<(), SimError> {
    let addrs = sim
        .role_addresses()
        .map_err(|(f, m)| SimError::Mismatch(format!("{f}: {m}")))?;
    for a in &instrument.motion.axes {
        if !addrs.contains(&a.address) {
            return Err(SimError::Mismatch(format!(
                "axis {:?} is at address {}, but the simulator's controllers are at {addrs:?}",
                a.name, a.address
            )));
        }
    }
    Ok(())
}

/// A goniometer driving an in-process simulator over in-memory lines, on the
/// simulator's clock; and the handle to the simulator (faults, stats, clock).
pub type SimGoniometer = Goniometer<SimClock>;

/// Builds a simulator from `sim` and a goniometer from `instrument` that drives it.
pub fn connect(
    instrument_cfg: &InstrumentConfig,
    sim: &SimConfig,
) -> Result<(SimGoniometer, SharedSim), SimError> {
    check_compatible(instrument_cfg, sim)?;
    let shared = instrument(sim)?;
    let clock = lock(&shared).clock().clone();
    let g = Goniometer::from_transports(
        instrument_cfg,
        SimTransport::new(shared.clone(), Port::Motion),
        SimTransport::new(shared.clone(), Port::Detector),
        clock.clone(),
        clock,
    )?;
    Ok((g, shared))
}
