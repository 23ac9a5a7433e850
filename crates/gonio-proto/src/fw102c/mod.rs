//! The Thorlabs FW102C (and FW212C) motorized filter wheel's serial command set:
//! the filter-based bands of a spectral run (issue 21), and an opaque blank usable as a
//! shutter.
//!
//! **Sources.** The FW102C manual's command table was not in the reference corpus
//! this module was written against, so no section or page of it is cited: every fact
//! below is **UNCONFIRMED** against the manual. What is stated comes from drivers that
//! talk to real wheels (Odemis `src/odemis/driver/tlfw.py`; InstrumentKit's
//! `thorlabs_utils.py`; a wrapper of the Thorlabs SDK DLL) and is marked as such; `docs/instruments/fw102c.md`
//! lists each fact with its source.
//!
//! - A command is lower-case ASCII ended by CR: `*idn?`, `pos=3`, `pos?`, `pcount?`,
//!   `speed=1`, `trig=0`, `sensors=0`, `save`. Serial: 115200 baud, 8N1, no flow
//!   control (the factory setting; `baud=0` would select 9600).
//! - The wheel **echoes** every command, CR included, then sends a query's value and
//!   CR, then the prompt `"> "` (greater-than, space, no CR). A refused command is
//!   answered `Command error CMD_NOT_DEFINED` or `Command error CMD_ARG_INVALID` and
//!   CR before the prompt.
//! - `pos=n` answers its prompt only when the wheel has stopped (Odemis waits for the
//!   prompt as the end of the move).
//!
//! Because the prompt carries no terminator, a CR-framed link sees it at the start of
//! the next line: `"> pos?"`. [`strip_prompt`] removes it; the session therefore cannot
//! see a set command end, and reads back (`pos?`, `speed?`) what it set instead.
//!
//! ```
//! use gonio_proto::fw102c::{Command, Reply};
//!
//! assert_eq!(Command::SetPosition(3).to_bytes(), b"pos=3\r");
//! assert_eq!(Command::parse(b"pos=3"), Ok(Command::SetPosition(3)));
//! assert_eq!(Reply::parse(&Command::QueryPosition, b"3"), Ok(Reply::Position(3)));
//! ```

mod command;
mod config;
mod error;
mod reply;
mod session;

pub mod fuzz;

pub use command::{Command, CommandError, SensorMode, Speed, TriggerMode};
pub use config::{
    CENTRE_UNCERTAINTY_NM, ConfigError, DEFAULT_BAND_TOLERANCE_NM, Filter, Fw102cConfig,
};
pub use error::Fw102cError;
pub use reply::{DeviceError, ErrorCode, Line, Reply, ReplyError, strip_prompt};
pub use session::Fw102cSession;

/// The line terminator of commands and of every reply line: CR (UNCONFIRMED; Odemis
/// and InstrumentKit send and read CR).
pub const TERMINATOR: u8 = b'\r';

/// The prompt the wheel sends when it is ready for the next command, unterminated
/// (UNCONFIRMED; Odemis reads up to `"> "`).
pub const PROMPT: &[u8] = b"> ";

/// The factory baud rate (UNCONFIRMED; Odemis and the SDK default to 115200); 8 data
/// bits, no parity, one stop bit, no flow control.
pub const BAUD: u32 = 115_200;

/// The longest reply line a framer should accept: `*idn?` answers about 50
/// characters. A bound for framing, not a device limit.
pub const MAX_LINE: usize = 128;

/// The wheel sizes the firmware knows (`pcount=`): 6 (FW102C) or 12 (FW212C).
pub const POSITION_COUNTS: [u8; 2] = [6, 12];
