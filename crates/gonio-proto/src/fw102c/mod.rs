//! The Thorlabs FW102C (and FW212C) motorized filter wheel's serial command set:
//! the filter-based bands of a spectral run (issue 21), and an opaque blank usable as a
//! shutter.
//!
//! **Sources.** The FW102C manual Rev H (2014): the command table of §5.2.3, p. 11,
//! and the terminal settings of §5.2; the FW102C User Guide Rev M (2023) as quoted in
//! ISIS's EPICS driver (`thorlabsfw102c.proto`); where neither says, drivers written
//! against real wheels (Odemis `src/odemis/driver/tlfw.py`, ISIS), named as such.
//! `docs/instruments/fw102c.md` lists each fact with its source and keeps the
//! [`UNCONFIRMED`] list.
//!
//! - A command is ASCII ended by CR: "All strings (commands and queries) must be
//!   terminated by a carriage return" (§5.2), and "All commands and queries are in
//!   lower case letters" (p. 11): `*idn?`, `pos=3`, `pos?`, `pcount?`, `speed=1`,
//!   `trig=0`, `sensors=0`, `save`, `baud=0|1` (p. 11). Serial: see [`BAUD`].
//! - The wheel **echoes** every command, CR included (ISIS, Odemis: driver only), then
//!   sends a query's value and CR, then the prompt: "The prompt symbol '>' will appear
//!   on power-up and after a command is accepted" (User Guide Rev M); that a space
//!   follows it, `"> "` unterminated, is Odemis's (driver only). An unknown command or
//!   an empty line is answered `Command error CMD_NOT_DEFINED` and CR before the prompt
//!   (§5.2); a bad value `Command error CMD_ARG_INVALID` (Odemis only, UNCONFIRMED).
//! - `pos=n` answers its prompt only when the wheel has stopped (Odemis waits for the
//!   prompt as the end of the move; UNCONFIRMED).
//!
//! Because the prompt carries no terminator, a CR-framed link sees it at the start of
//! the next line: `"> pos?"`; the power-up prompt likewise begins the first line the
//! host reads (`"> *idn?"`). [`strip_prompt`] removes it; the session therefore cannot
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

/// The line terminator of commands (§5.2: "must be terminated by a carriage return")
/// and of every reply line (ISIS's driver: `terminator = CR`; driver only).
pub const TERMINATOR: u8 = b'\r';

/// The prompt, unterminated: `>` is the User Guide's (Rev M, quoted by ISIS); the
/// space after it is Odemis's, which reads up to `"> "` (UNCONFIRMED).
pub const PROMPT: &[u8] = b"> ";

/// The factory baud rate, 115.2 kbaud (§5.2; `baud=1`, p. 11; `baud=0` selects 9600);
/// 8 data bits, no parity, one stop bit, no flow control (§5.2).
pub const BAUD: u32 = 115_200;

/// The longest reply line a framer should accept: `*idn?` answers about 50
/// characters. A bound for framing, not a device limit.
pub const MAX_LINE: usize = 128;

/// The wheel sizes the firmware knows (`pcount=`): 6 (FW102C) or 12 (FW212C).
pub const POSITION_COUNTS: [u8; 2] = [6, 12];

/// What Gonio relies on that no manual page checked confirms, and how to settle it on
/// a wheel; `docs/instruments/fw102c.md` ("UNCONFIRMED") lists the same facts in the
/// same words, and `gonio instrument selftest` names them.
pub const UNCONFIRMED: &[crate::Unconfirmed] = &[
    crate::Unconfirmed {
        fact: "`Command error CMD_ARG_INVALID` as the answer to a bad value",
        check: "send `speed=3`, and `pos=9` to a 6-position wheel, and log the reply (only Odemis's simulator gives this text)",
    },
    crate::Unconfirmed {
        fact: "The space after the prompt `>`",
        check: "log the raw bytes after a `pos?`: `>` alone or `> `",
    },
    crate::Unconfirmed {
        fact: "That `pos=n` answers its prompt only when the move ends, and whether input is read during a move",
        check: "send `pos=4`, then at once `pos?`, logging each byte with its time",
    },
    crate::Unconfirmed {
        fact: "The move times at either speed, and the shortest-way-round rule",
        check: "time `pos=` moves of 1, 2 and 3 slots at `speed=0` and at `speed=1`",
    },
    crate::Unconfirmed {
        fact: "The exact bytes of the power-up prompt",
        check: "open the port, power the wheel up and log what arrives before any command",
    },
    crate::Unconfirmed {
        fact: "The 2 nm default band tolerance",
        check: "compare with the data sheets of the band-pass filters mounted",
    },
];
