//! The Stanford Research SR830 DSP lock-in amplifier's RS-232 protocol (manual
//! Rev. 2.5, chapter 5 "Remote Programming").
//!
//! A command is a four-character mnemonic (`*XXX` for the IEEE-488.2 common
//! commands), `?` for a query, then comma-separated parameters: `SENS 20`, `SENS?`,
//! `SNAP? 1,2`. Several commands may share a line, separated by `;`. The host ends a
//! line with `\n` or `\r`; the instrument ignores case and every space (manual
//! p. 5-1 … 5-3). Only queries reply, with a bare value ended by `\r` and no echo of
//! the command: `SENS?` → `20`. Set commands reply nothing, even when they fail; a
//! failure sets the CMD or EXE bit of the standard event status byte (`*ESR?`).
//!
//! Since a reply carries no echo, it can only be read knowing the query it answers:
//! [`Reply::parse`] takes the [`Command`]. [`Command`] and [`Reply`] format and parse
//! both directions, so the driver and the simulator share one definition.
//!
//! ```
//! use gonio_proto::sr830::{Command, Reply, SnapParam, SnapParams};
//!
//! let snap = Command::Snap(SnapParams::new(&[SnapParam::X, SnapParam::Y]).unwrap());
//! assert_eq!(snap.to_bytes(), b"SNAP? 1,2\n");
//! let reply = Reply::parse(&snap, b"0.951359,0.0253297").unwrap();
//! assert_eq!(reply, Reply::Snap(vec![0.951359, 0.0253297]));
//! ```
//!
//! The codec is split by subject: the instrument's tables ([`Sensitivity`],
//! [`TimeConstant`], [`FilterSlope`]), [`Command`] (host to instrument), the status
//! bytes ([`LiaStatus`], [`EventStatus`], [`ErrorStatus`]) and [`Reply`] (instrument
//! to host).

mod command;
mod config;
mod reading;
mod reply;
mod session;
mod status;
mod tables;
pub mod target;

pub mod fuzz;

pub use command::{
    BitIndex, Command, CommandError, Interface, Output, ReferenceSource, SnapParam, SnapParams,
    encode_line, parse_line,
};
pub use config::{ConfigError, Sr830Config};
pub use reading::{MAX_AUTORANGE_STEPS, Reading, ReadingFlags, Sr830Error};
pub use reply::{Identity, Reply, ReplyError};
pub use session::Sr830Session;
pub use status::{ErrorStatus, EventStatus, LiaStatus};
pub use tables::{FilterSlope, Sensitivity, TimeConstant, UnknownLabel};
pub use target::{NoiseDensity, ReadTarget};

/// The line terminator the host sends. The manual allows `\n` or `\r` on RS-232
/// (p. 5-1); `\n` is chosen because GPIB takes it as well, so one line suits either port.
pub const TERMINATOR: &[u8] = b"\n";

/// The byte that ends every reply line on RS-232 (p. 5-2; on GPIB it would be LF).
pub const REPLY_TERMINATOR: u8 = b'\r';

/// The instrument's input and output buffers, in characters (p. 5-2). A longer line
/// overflows them: both are cleared and INP or QRY is set in `*ESR?`.
pub const MAX_LINE: usize = 256;
