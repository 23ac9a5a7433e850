//! Gonio's instrument drivers: the thin I/O layer around `gonio-proto`'s codecs and
//! sessions. Every policy decision (what to send, what a reply means, when to retry,
//! reconnect, stop or give up) is made by a `gonio-proto` session; this crate moves its
//! bytes over a port and waits on a clock.
//!
//! - [`Transport`] moves bytes and lines: [`SerialTransport`] over a real port path
//!   (`/dev/ttyUSB0`, or a pseudo-terminal `/dev/pts/N`), [`ScriptedTransport`] for
//!   tests that replay expected command → reply transcripts.
//! - [`Clock`] is where drivers wait: [`SystemClock`] in the lab, [`ManualClock`] in
//!   tests, so polling loops run on virtual time.
//! - The pump (one loop, `pump.rs`) runs a session's operation over a transport: sends
//!   what it asks, reads a line until its deadline or sleeps until it, reads the abort
//!   flag at its abort points, and hands back what happened. It logs every line sent and
//!   received at `trace` under the target `gonio_driver::wire`.
//! - The [`Heartbeat`] sends the keep-alives sessions declare (the APT controllers'
//!   server-alive) on time through every wait of every line, and through the
//!   instrument's idle time ([`Goniometer::idle_until`]).
//! - [`smc100::Smc100Chain`] drives a chain of SMC100 controllers (the pump around
//!   [`gonio_proto::smc100::Smc100Session`]): homing, moves with soft limits enforced
//!   before any byte goes out, completion by status polling, error checks, stops.
//! - [`sr830::Sr830`] reads the lock-in (the pump around
//!   [`gonio_proto::sr830::Sr830Session`]) with settling waits, autoranging and
//!   averaging.
//! - [`Goniometer`] is the named axes and the detector, built from an instrument
//!   config file.

pub mod apt;
pub mod bench;
pub mod clock;
pub mod config;
pub mod cs130;
pub mod detector;
pub mod fw102c;
mod goniometer;
pub mod heartbeat;
pub mod k6485;
pub mod motion;
pub mod ports;
mod pump;
pub mod script;
pub mod selftest;
pub mod smc100;
pub mod spectral;
pub mod sr830;
mod transport;

pub use bench::{Bench, BenchError, OperatorBench, Setup};
pub use clock::{Clock, ManualClock, SystemClock};
pub use config::{ConfigFileError, InstrumentConfig};
pub use detector::{DetectorDevice, DetectorError};
pub use goniometer::{Goniometer, GoniometerError, PortUse, StartupReport};
pub use heartbeat::Heartbeat;
pub use motion::{Motion, MotionDevice};
pub use script::ScriptedTransport;
pub use spectral::{BandSelector, SpectralError};
pub use transport::{
    FlowControl, Framing, SerialSettings, SerialTransport, Transport, TransportError,
};

/// The instruments Gonio drives, by family (the name [`selftest::unconfirmed`] and
/// the devices report) and what the family is: what the demo and docs list.
pub const DRIVERS: [(&str, &str); 7] = [
    ("smc100", "Newport SMC100 stage controllers"),
    ("kdc101", "Thorlabs KDC101 K-Cube (APT)"),
    ("k10cr1", "Thorlabs K10CR1 rotation stage (APT)"),
    ("sr830", "SRS SR830 lock-in amplifier"),
    ("k6485", "Keithley 6485 picoammeter"),
    ("cs130", "Newport Cornerstone 130 monochromator"),
    ("fw102c", "Thorlabs FW102C filter wheel"),
];

#[cfg(test)]
mod tests {
    /// Every family listed has its unconfirmed facts on record (the self-test
    /// names them), so the list cannot name a family the drivers do not know.
    #[test]
    fn every_driver_listed_is_a_family_the_self_test_knows() {
        for (family, _) in super::DRIVERS {
            assert!(super::selftest::unconfirmed(family).is_some(), "{family}");
        }
    }
}
