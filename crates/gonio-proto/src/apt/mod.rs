//! The Thorlabs APT (Kinesis) binary protocol, for single-channel controllers on a
//! USB virtual serial port: the KDC101 K-Cube DC servo controller (driving a PRM1-Z8
//! rotation stage) and the K10CR1 rotation mount with its built-in stepper controller.
//!
//! Source: *Thorlabs APT Controllers Host-Controller Communications Protocol*
//! (Issue 25, 25 August 2020; "the manual" below; page numbers are that issue's, from
//! its contents list, and are given where they could be checked). Message layouts
//! were cross-checked against the parser of the public `thorlabs-apt-device` Python
//! package (facts only; no code taken). Every message starts with a 6-byte
//! header (the manual's introduction, "Message Header"): the message id (u16 little
//! endian), then either two parameter bytes (a *short* message, header only) or, when
//! the destination byte has bit 7 set, a u16 little-endian length of the data packet
//! that follows (a *long* message); then the destination and source addresses. All
//! multi-byte fields are little endian; positions are signed 32-bit counts.
//!
//! - [`Header`], the address constants and [`AptFramer`] cut a byte stream into
//!   messages (a [`Framer`](crate::Framer), so the same transport carries every
//!   protocol);
//! - [`Message`] and [`Packet`] encode and parse every message the sessions and the
//!   simulator use, in both directions, and pass through the ones they do not know;
//! - [`status`] names the status bits; [`StageKind`] converts counts and APT velocity
//!   and acceleration units to degrees;
//! - [`AptSession`] is the policy that drives one controller, sans-IO like
//!   [`Smc100Session`](crate::smc100::Smc100Session).

mod framer;
mod message;
mod session;
mod stage;
pub mod status;

pub mod fuzz;
pub mod timing;

pub use framer::AptFramer;
pub use message::{
    AptError, AptInfo, DcStatus, Direction, GenMoveParams, Header, HomeParams, JogParams,
    LimSwitchParams, Message, Packet, STEPPER_STATUS_EXTRA, StepperStatus, StopMode, VelParams,
};
pub use session::{AptAxisConfig, AptSession, AptStatus, KEEPALIVE_EVERY};
pub use stage::StageKind;

/// The host (the PC), as source and destination.
pub const HOST: u8 = 0x01;
/// A rack controller, the motherboard of a card-slot system, or a comms router board.
pub const RACK: u8 = 0x11;
/// Bay 0 of a card-slot system; bays 1–9 follow (`0x22`–`0x2A`).
pub const BAY0: u8 = 0x21;
/// The last bay address, bay 9.
pub const BAY9: u8 = 0x2A;
/// A generic USB hardware unit: every single-channel K-Cube and the K10CR1.
pub const USB_UNIT: u8 = 0x50;
/// The destination byte's flag for a long message (a data packet follows).
pub const LONG_FLAG: u8 = 0x80;
/// The header's length, bytes.
pub const HEADER_LEN: usize = 6;
/// The largest data packet accepted. The manual states that no data packet exceeds
/// 255 bytes; the largest this crate knows, `HW_GET_INFO`, is 84.
pub const MAX_DATA_LEN: usize = 255;
/// The channel of a single-channel controller.
pub const CHANNEL: u16 = 1;

/// What Gonio relies on about the APT controllers that no manual page confirms, with
/// how to check it on the unit: `docs/instruments/apt.md` lists the same.
pub const UNCONFIRMED: &[crate::Unconfirmed] = crate::facts::unconfirmed! {
    "Which status messages a controller counts towards the server-alive limit"
        => "`gonio instrument selftest` with `keepalive = false` on one axis: note the move at which completions stop (manual p. 130)",
    "The length of the stepper status `0x0481` on the unit in hand"
        => "`gonio instrument selftest` records the data length of every status message it receives",
    "The scale of the DC status velocity word"
        => "log a `MOT_GET_DCSTATUSUPDATE` during a move at a known velocity (Gonio ignores the word)",
    "Stage maxima (25 °/s for the PRM1-Z8, 10 °/s for the K10CR1) and the acceleration bounds"
        => "compare with the stage's Thorlabs specification sheet",
    "The PRM1-Z8's home velocity and offset (10 °/s, 4°)"
        => "read `MOT_REQ_HOMEPARAMS` on a KDC101 set up by Kinesis",
};

/// True for an address the manual defines (host, rack, bays 0–9, USB unit), or 0,
/// which some controllers put as the source of unsolicited messages.
pub fn is_address(a: u8) -> bool {
    matches!(a, 0x00 | HOST | RACK | USB_UNIT) || (BAY0..=BAY9).contains(&a)
}
