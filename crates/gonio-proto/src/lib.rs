//! The instruments of a Gonio goniometer, sans-IO: the Newport SMC100 motion
//! controller ([`smc100`]), the Thorlabs APT controllers KDC101 and K10CR1 ([`apt`],
//! binary messages), the Stanford Research SR830 lock-in amplifier ([`sr830`]),
//! the Keithley 6485 picoammeter ([`k6485`], a DC detector), the Newport
//! Cornerstone 130 monochromator ([`cs130`], with its echo) and the Thorlabs FW102C
//! filter wheel ([`fw102c`], filter-based spectral bands), byte-exactly as their
//! manuals define them, and the policy that drives them, as state machines.
//!
//! Deterministic: no I/O, no clocks, no threads. Two layers:
//!
//! - **Codecs.** Commands and replies are formatted into caller-owned buffers and
//!   parsed from byte slices; [`LineFramer`] cuts a byte stream into lines. The driver
//!   (`gonio-driver`) and the simulated instrument (`gonio-sim`) both build on these
//!   types, so the bytes a test sends to the simulator are the bytes the lab sends to
//!   hardware.
//! - **Sessions.** [`smc100::Smc100Session`] and [`sr830::Sr830Session`] hold each
//!   instrument's policy: limits checked before any byte, `TE` after every set command,
//!   re-sends only of what may be repeated, lost acknowledgements, power loss, reconnects,
//!   stops; set-up, settling waits, the read cycle, averaging, autoranging, flags. Each
//!   `start_*` call returns a running [`Task`], a [`link::Operation`] in the shape of quinn-proto's
//!   connection: its caller (a *pump*) polls out the bytes to send, input to clear, a
//!   reconnection to attempt or a [`link::Deadline`] to wait for, hands in what happened
//!   (`handle_sent`, `handle_line`, `handle_link_error`, `handle_timeout`, ...) with the
//!   time it happened, and finally polls out the typed result. Time is a `Duration` since
//!   the caller's origin. `gonio-driver` pumps operations over serial ports; the
//!   simulator's tests pump them straight into the device models on virtual time.
//!   Inside, every operation is an `async fn` over the one engine (`engine`), which
//!   also holds the link policy every family shares.
//!
//! ```
//! use gonio_proto::smc100::{Command, Frame, Reply, ReplyBody};
//!
//! let mut out = Vec::new();
//! Frame::addressed(1, Command::TellPosition).encode(&mut out);
//! assert_eq!(out, b"1TP\r\n");
//!
//! let reply = Reply::parse(b"1TP12.5").unwrap();
//! assert_eq!(reply.body, ReplyBody::Position(12.5));
//! ```
//!
//! Parsers never panic on any input: every function that reads bytes returns a typed
//! error instead, and the `fuzz/` targets exercise that.
//!
//! The sessions record what they decide with `tracing` (state changes at `debug`,
//! faults, retries, reconnections and stops at `warn`); the bytes themselves are logged
//! by the pump that moves them.

pub mod apt;
mod codec;
mod config;
pub mod cs130;
mod engine;
mod facts;
mod framing;
pub mod fw102c;
mod idn;
pub mod k6485;
pub mod link;
pub mod motion;
mod number;
pub mod smc100;
pub mod sr830;
pub mod timing;

pub use engine::{SessionCore, Task};
pub use facts::Unconfirmed;
pub use framing::{FrameError, Framer, LineFramer};
pub use link::TransportError;
