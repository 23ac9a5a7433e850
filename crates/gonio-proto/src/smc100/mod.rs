//! The Newport SMC100 (CC/PP) ASCII protocol (user's manual EDH0206En2054, §5).
//!
//! A command line is `[nn]AA[xx]` + CR LF: controller address 1–31 (absent or 0 means
//! every controller, for the broadcast commands `ST` and `MM`), a two-letter command,
//! an optional value or `?`. Only queries reply; a reply echoes the address and the
//! command, then the value: `1TP` → `1TP12.5`. Set and action commands reply nothing,
//! even when they fail; the host reads the last error letter with `TE`.
//!
//! [`Frame`] and [`Reply`] format and parse both directions, so that the driver can
//! send commands and read replies, and the simulator can read commands and send
//! replies, from one definition.
//!
//! The codec is split by direction and content: [`Command`] and [`Frame`] (host to
//! controller), the `TS`/`TE` vocabulary ([`ControllerState`], [`ErrorCode`],
//! [`PositionerErrors`]), [`Reply`] (controller to host), and the configuration a
//! `ZT` dump lists ([`Smc100Parameters`], read line by line with [`DumpReader`]).

mod command;
mod config;
mod error;
mod params;
mod reply;
mod session;
mod status;

pub mod fuzz;
pub mod timing;

pub use command::{Command, CommandError, Frame, Param};
pub use config::{AxisConfig, ChainPolicy};
pub use error::{AxisError, ControllerInfo, MotionError, describe_errors};
pub(crate) use error::{Halt, stop};
pub use params::{DumpError, DumpReader, Smc100Parameters};
pub use reply::{Reply, ReplyBody, ReplyError};
pub use session::Smc100Session;
pub use status::{ControllerState, ErrorCode, PositionerErrors, Status};

/// The line terminator in both directions.
pub const TERMINATOR: &[u8] = b"\r\n";

/// The longest reply line the driver accepts (`VE` and `ID?` strings are the longest,
/// about 50 bytes).
pub const MAX_LINE: usize = 128;

/// Highest controller address on a chain.
pub const MAX_ADDRESS: u8 = 31;

/// What Gonio relies on about the SMC100 that no manual page checked confirms, with how
/// to settle it on a controller. `docs/instruments/smc100.md` ("UNCONFIRMED") lists the
/// same facts in the same words; `gonio instrument selftest` names them for a chain it
/// finds. Confirmed facts (with their pages) are in that document's tables.
pub const UNCONFIRMED: &[crate::Unconfirmed] = crate::facts::unconfirmed! {
    "The number format of replies (decimals, sign, exponent)"
        => "read `1TP`, `1VA?` and `1ZT` and note how each value is printed (Gonio parses any form)",
    "The echo of an address written with a leading zero"
        => "send `01TS` and see whether the reply begins `01TS` or `1TS` (Gonio never sends a leading zero)",
    "Silence from an absent address"
        => "on a chain without controller 9, send `9TS` and confirm that nothing comes back",
    "The letter a `PA` or `PR` sent while MOVING or HOMING stores"
        => "send `1PA` with a new target during a move, then `1TE`, and note the letter (Gonio takes `M` or `D`)",
    "The letter a command refused in JOGGING stores"
        => "enter JOGGING from the keypad, send `1PA0`, then `1TE`",
    "The state after `ST` during HOMING, and after a homing time-out"
        => "send `1ST` during a home search, and let another time out (a small `OT`), reading `1TS` after each",
    "The exact spacing of the `TB` text"
        => "send `1TB@` and log the raw bytes (the manual's form, p. 58, is `1TB@ No error`)",
    "Whether `ID?` answers in every state"
        => "send `1ID?` in NOT REFERENCED, READY and MOVING",
    "Whether `RS` is refused in CONFIGURATION"
        => "send `1PW1`, then `1RS` and `1TE` (the RS page, p. 48, contradicts itself)",
    "The line that closes a `ZT` dump"
        => "send `1ZT` and log its last line: `1PW0` (hvl_ccb) or `1PW1` (the manual's p. 67 example); Gonio takes either",
};
