//! The Newport (Oriel) Cornerstone 130 monochromator over RS-232 (Cornerstone 130B
//! manual, 90088262 "MCS130B", Appendix I "Remote commands and queries", §15).
//!
//! A statement is a keyword and, for some, a parameter after at least one space, in
//! any case (§15.3): `GOWAVE 500`, `WAVE?`. The host ends each with CR LF; every
//! response ends with CR LF (§15.3; the CS260B manual's §15.1 "requires all Statements
//! to be terminated by a carriage return followed by a linefeed"). In standard mode
//! with echo on (the factory setting per the CS260B manual §15.1; **UNCONFIRMED** for
//! the CS130B), the instrument echoes every character it receives, so each statement
//! comes back as a line, and a query's answer follows its echo (§15.4):
//!
//! ```text
//! GOWAVE 500\r\n      →  GOWAVE 500\r\n
//! WAVE?\r\n           →  WAVE?\r\n500.01\r\n
//! ```
//!
//! Errors set the status byte to 32 until `STB?` reads it, and `ERROR?` tells which
//! (§15.9); `STB?` prints it in decimal, `32` or `00` (§15.9; the Model 74000 command
//! table), and any nonzero answer counts as an error ([`StatusByte`]). `*WAI` holds
//! every later statement until pending operations (a move) are done (§15.8), which
//! is how the session knows that a move has ended.
//!
//! ```
//! use gonio_proto::cs130::{Command, Reply, is_echo};
//!
//! assert_eq!(Command::GoWave(587.1).to_bytes(), b"GOWAVE 587.1\r\n");
//! assert!(is_echo(&Command::Wave, b"WAVE?"));
//! assert_eq!(Reply::parse(&Command::Wave, b"500.01"), Ok(Reply::Wavelength(500.01)));
//! ```

mod command;
mod config;
mod reply;
mod session;
mod status;

pub mod fuzz;
pub mod timing;

pub use command::{Command, CommandError, Units};
pub use config::{
    BANDWIDTH_NM, ConfigError, Cs130Config, GratingSpec, MAX_FILTER_POSITION, MAX_GRATINGS,
    NO_FILTER_WHEEL, OrderFilterSpec, SelectError, WAVELENGTH_UNCERTAINTY_NM,
};
pub use reply::{Reply, ReplyError, is_echo};
pub use session::Cs130Session;
pub use status::{ErrorCode, StatusByte};

use crate::TransportError;

/// The host's line terminator: CR LF (§15.3, §15.4's examples).
pub const TERMINATOR: &[u8] = b"\r\n";

/// The byte that ends every line from the instrument (its lines end CR LF, §15.3; a
/// line framer on LF drops the CR).
pub const REPLY_TERMINATOR: u8 = b'\n';

/// The longest line a framer should accept. The manual gives no limit; answers are
/// short and `INFO?` is one line, so this is a bound for framing, not the
/// instrument's.
pub const MAX_LINE: usize = 256;

/// The instrument's input buffer, statements: "This buffer can store up to about 20
/// commands" (§15.8). The session never has more than one outstanding.
pub const INPUT_BUFFER_STATEMENTS: usize = 20;

/// What the monochromator is set to, read back or set with its status checked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MonoState {
    /// The wavelength `WAVE?` reads back, nm.
    pub wavelength_nm: f64,
    /// The grating in use.
    pub grating: u8,
    /// The filter wheel position, 1..=6; [`NO_FILTER_WHEEL`] (0) when the config says
    /// the unit has no wheel.
    pub filter: u8,
    /// True when the shutter is open.
    pub shutter_open: bool,
}

/// Why a CS130 operation failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Cs130Error {
    /// The configuration is out of range.
    #[error("CS130 config: {0}")]
    Config(#[from] ConfigError),
    /// The wavelength cannot be delivered: refused before any byte was sent.
    #[error("CS130: {0}")]
    Select(#[from] SelectError),
    /// No echo or answer in time, a NUL byte, an overlong line, or a transport fault
    /// other than a vanished port.
    #[error("CS130 {command}: {source}")]
    Transport {
        /// The statement, as sent (without terminator).
        command: String,
        /// The transport's error.
        source: TransportError,
    },
    /// A line that is not the echo or the answer expected.
    #[error("CS130 {command}: unreadable line {:?}: {source}", String::from_utf8_lossy(.reply))]
    Protocol {
        /// The statement, as sent.
        command: String,
        /// The line, terminator removed.
        reply: Vec<u8>,
        /// Why it does not fit.
        source: ReplyError,
    },
    /// The port vanished and every reconnection attempt failed.
    #[error("CS130 port {port} lost; {attempts} reconnection attempts failed: {source}")]
    Disconnected {
        /// The port's name.
        port: String,
        /// Attempts made.
        attempts: u32,
        /// The last failure.
        source: TransportError,
    },
    /// The status byte reported an error, and `ERROR?` this code (§15.9).
    #[error("the CS130 refused a statement: error {0}")]
    Rejected(ErrorCode),
    /// `filter_wheel = true` but `FILTER?` answered `0` (no wheel connected, or out of
    /// position); the error it set is read back, leaving the status byte clear.
    #[error(
        "CS130: no filter wheel answered (FILTER? gave 0{}: no wheel connected, or the \
         wheel out of position); fit or seat the wheel, or, if this unit has none, set \
         filter_wheel = false and auto_order_filter = false in [monochromator.cs130]",
        no_wheel_code(.code)
    )]
    NoFilterWheel {
        /// What `ERROR?` answered after it (6, "accessory not present (usually filter
        /// wheel)", §15.9), when the status byte flagged an error and `ERROR?` was
        /// read.
        code: Option<ErrorCode>,
    },
    /// The move ended, but `WAVE?` reads back a wavelength too far from the one asked.
    #[error("CS130 asked for {asked_nm} nm, reads back {read_nm} nm (tolerance {tolerance_nm} nm)")]
    NotReached {
        /// Asked for.
        asked_nm: f64,
        /// Read back.
        read_nm: f64,
        /// The config's tolerance.
        tolerance_nm: f64,
    },
}

/// The error code part of [`Cs130Error::NoFilterWheel`]'s message.
fn no_wheel_code(code: &Option<ErrorCode>) -> String {
    code.map(|c| format!(", error {c}")).unwrap_or_default()
}

/// What Gonio relies on about the Cornerstone 130 that no manual page confirms, with
/// how to check it on the unit: `docs/instruments/cs130.md` lists the same.
pub const UNCONFIRMED: &[crate::Unconfirmed] = &[
    crate::Unconfirmed {
        fact: "Serial settings (9600 8N1, no flow control) and echo on at the factory",
        check: "open the port at 9600 8N1 and send `INFO?`: the statement echoed back, then the answer",
    },
    crate::Unconfirmed {
        fact: "That the CS130B answers exactly as the older Model 74000 table says",
        check: "`INFO?`, `GRAT?`, and `FILTER?` with no wheel fitted followed by `STB?` and `ERROR?`",
    },
    crate::Unconfirmed {
        fact: "Error code 7 on the CS130B",
        check: "`GOWAVE` to the wavelength the drive is at, then `ERROR?`",
    },
    crate::Unconfirmed {
        fact: "Turret size (the 74000 has 2 gratings; Gonio accepts 3)",
        check: "`GRAT 3` then `ERROR?`; time `GOWAVE`, `GRAT` and `FILTER` with `*WAI`",
    },
    crate::Unconfirmed {
        fact: "Whether the CS130 echoes at once while a mechanism moves",
        check: "send `GRAT`, `FILTER` and `GOWAVE` back to back and log when each echo arrives",
    },
];
