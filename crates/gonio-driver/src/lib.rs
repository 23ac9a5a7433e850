//! Gonio's instrument drivers: the thin I/O layer around `gonio-proto`'s codecs.
//!
//! - [`Transport`] moves bytes and lines: [`SerialTransport`] over a real port path
//!   (`/dev/ttyUSB0`, or a pseudo-terminal `/dev/pts/N`), [`ScriptedTransport`] for
//!   tests that replay expected command → reply transcripts.
//! - [`Clock`] is where drivers wait: [`SystemClock`] in the lab, [`ManualClock`] in
//!   tests, so polling loops run on virtual time.
//! - [`smc100::Smc100Chain`] drives a chain of SMC100 controllers: homing, moves with
//!   soft limits enforced before any byte goes out, completion by status polling,
//!   error checks, stops.
//! - [`sr830::Sr830`] reads the lock-in with settling waits, autoranging and averaging.
//! - [`Goniometer`] is the named axes and the detector, built from an instrument
//!   config file.

pub mod clock;
pub mod config;
mod goniometer;
mod pump;
pub mod script;
pub mod smc100;
pub mod sr830;
mod transport;

pub use clock::{Clock, ManualClock, SystemClock};
pub use config::{ConfigFileError, InstrumentConfig};
pub use goniometer::{Goniometer, GoniometerError, StartupReport};
pub use script::ScriptedTransport;
pub use transport::{FlowControl, SerialSettings, SerialTransport, Transport, TransportError};
