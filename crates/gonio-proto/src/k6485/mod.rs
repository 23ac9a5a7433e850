//! The Keithley 6485 picoammeter's SCPI protocol over RS-232 (Model 6485 Picoammeter
//! Instruction Manual, 6485-901-01: Section 9 "Remote Operation", Sections 12–16 for
//! the commands, Appendix A for the specifications). The 6487 answers the same
//! ammeter commands and is accepted too.
//!
//! A command is a SCPI header (`SYST:ZCH`, long or short form, case ignored), `?` for a
//! query, then a space and its parameter: `CURR:RANG 2E-9`, `READ?`. The host ends a
//! line with CR: "incoming commands are processed after the `<CR>` character is
//! received" (RS-232 settings, p. 9-17). The instrument ends each reply with the
//! terminator selected on its front panel (CR, LF, CRLF or LFCR, p. 9-17); Gonio
//! requires **CR**, 8 data bits, no parity, one stop bit, no flow control (the 6485 has
//! no hardware handshake). Only queries reply; a refused command is silent, queues a
//! SCPI error (`SYST:ERR?`) and sets a bit of `*ESR?`.
//!
//! With `FORM:ELEM READ,TIME,STAT`, `READ?` answers one reading:
//! `+1.234567E-09A,+2.236299E+02,+0.000000E+00`: the current with its unit, the
//! timestamp and the [`StatusWord`]. An overflow is sent as `+9.9E37` and becomes
//! [`Current::Overflow`], never a number.
//!
//! ```
//! use gonio_proto::k6485::{Command, Current, Range, Reply};
//!
//! assert_eq!(Command::SetRange(Range::MOST).to_bytes(), b"CURR:RANG 2E-9\r");
//! let Ok(Reply::Sample(s)) = Reply::parse(&Command::Read, b"+9.900000E+37A,+1.0E+00,+1") else {
//!     panic!()
//! };
//! assert_eq!(s.current, Current::Overflow);
//! assert!(s.status.overflow());
//! ```

mod command;
mod config;
mod reading;
mod reply;
mod session;
mod status;
mod tables;

pub mod fuzz;

pub use command::{Command, CommandError, MAX_TRIGGER_COUNT, parse_line};
pub use config::{ConfigError, K6485Config};
pub use reading::{K6485Error, MAX_AUTORANGE_STEPS, PicoFlags, PicoReading};
pub use reply::{Current, Identity, Model, Reply, ReplyError, Sample, ScpiError};
pub use session::K6485Session;
pub use status::{EventStatus, StatusWord};
pub use tables::{
    FILTER_COUNT, FilterType, LineFrequency, MIN_NPLC, NAN_VALUE, OVERFLOW_VALUE, OVERRANGE_FACTOR,
    Range, UnknownRange, accuracy_a,
};

/// The line terminator the host sends: CR (p. 9-17).
pub const TERMINATOR: &[u8] = b"\r";

/// The byte that ends every reply line: CR, the terminator Gonio requires the
/// instrument to be set to (p. 9-17).
pub const REPLY_TERMINATOR: u8 = b'\r';

/// The longest reply line a framer should accept. A reading with three elements is
/// 43 characters and an `*IDN?` about 70; the manual gives no input buffer size for
/// RS-232, so this is a generous bound for framing, not an instrument limit.
pub const MAX_LINE: usize = 256;

/// What Gonio relies on about the Keithley 6485 that no manual page checked confirms,
/// with how to check it on the unit: `docs/instruments/k6485.md` lists the same.
pub const UNCONFIRMED: &[crate::Unconfirmed] = &[
    crate::Unconfirmed {
        fact: "Appendix A numbers (accuracy, rms noise, rise time) as used by the code.",
        check: "compare `gonio instrument selftest`'s dark noise floor and the unit's calibration sheet with `k6485/tables.rs`",
    },
    crate::Unconfirmed {
        fact: "The `*RST` defaults the twin assumes",
        check: "`*RST` then query `CURR:RANG?`, `CURR:NPLC?`, `AVER?`, `SYST:ZCH?` on the unit",
    },
    crate::Unconfirmed {
        fact: "The exact SCPI error code for a misused known header",
        check: "send `CURR:RANG:AUTO` with a bad value, then `SYST:ERR?`",
    },
    crate::Unconfirmed {
        fact: "The factory default baud rate (p. 9-17 does not state it).",
        check: "read the front panel's RS-232 menu of a unit after `SYST:PRES`",
    },
    crate::Unconfirmed {
        fact: "The status word's bit meanings (p. 13-7 not found)",
        check: "read with `FORM:ELEM READ,TIME,STAT` while overloaded, filtered and in zero check",
    },
];
