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

pub use command::{Command, CommandError, Frame, Param};
pub use config::{AxisConfig, ChainPolicy};
pub use error::{AxisError, ControllerInfo, MotionError, describe_errors};
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
