//! Sans-IO codecs for the instruments of a Gonio goniometer: the Newport SMC100 motion
//! controller ([`smc100`]) and the Stanford Research SR830 lock-in amplifier
//! ([`sr830`]), byte-exactly as their manuals define them.
//!
//! Deterministic: no I/O, no clocks, no threads. Commands and replies are formatted
//! into caller-owned buffers and parsed from byte slices; [`LineFramer`] cuts a byte
//! stream into lines. The driver (`gonio-driver`) and the simulated instrument
//! (`gonio-sim`) both build on these types, so the bytes a test sends to the simulator
//! are the bytes the lab sends to hardware.
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

mod framing;
pub mod link;
mod machine;
mod number;
pub mod smc100;
pub mod sr830;

pub use framing::{FrameError, LineFramer};
pub use link::TransportError;
