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

pub mod buffer;
mod command;
mod config;
pub mod ranging;
mod reading;
mod reply;
mod session;
mod status;
mod tables;
pub mod target;
pub mod timing;

pub mod fuzz;

pub use buffer::{
    DisplayDef, EndOfScan, SampleRate, Sr830Framer, StoredValue, TraceChannel, TraceRange,
};
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

/// The instrument's input and output buffers, in characters: "The SR830 has a 256
/// character input buffer ... a 256 character output buffer ... If either buffer
/// overflows, both buffers are cleared and an error reported" (manual, ch. 5 command
/// syntax, p. 5-2; read as quoted verbatim in a public SR830 driver's docstring, the
/// page itself not re-checked). The error is INP (input) or QRY (output) in `*ESR?`
/// (SR850 manual p. 1-10). A line of this many characters or more, not counting its
/// terminator, overflows the input buffer; Gonio's lines are far shorter.
pub const MAX_LINE: usize = 256;

/// What Gonio relies on about the SR830 that no manual page checked confirms, with how
/// to settle it on the instrument. `docs/instruments/sr830.md` ("UNCONFIRMED") lists
/// the same facts in the same words; `gonio instrument selftest` names them for a
/// lock-in it finds. Confirmed facts (with their pages) are in that document's tables.
pub const UNCONFIRMED: &[crate::Unconfirmed] = &[
    crate::Unconfirmed {
        fact: "The stop bits, and the exact list of baud rates",
        check: "try 1 and 2 stop bits at each rate the [Setup] menu offers (Gonio uses 1)",
    },
    crate::Unconfirmed {
        fact: "Baud 300 to 19 200 with 9600 the default, parity none by default, 8 data bits",
        check: "power up with [Setup] held and read the RS-232 settings on the front panel (manual p. 4-4 and p. 5-1, not re-checked)",
    },
    crate::Unconfirmed {
        fact: "The power-up and `*RST` defaults",
        check: "power up with [Setup] held, then send `OUTX 0` and read `SENS?`, `OFLT?`, `OFSL?`, `FMOD?`, `FREQ?` (manual p. 4-4, not re-checked: 26, 8, 1, 1, 1000)",
    },
    crate::Unconfirmed {
        fact: "Whether an illegal query answers anything",
        check: "send `FOO?` and `AGAN?` and log what comes back within a second (Gonio assumes nothing)",
    },
    crate::Unconfirmed {
        fact: "The value `OUTP?` and `SNAP?` return while an output overloads",
        check: "drive the output over full scale and compare `SNAP? 1,2` with the input (Gonio never trusts a flagged reading)",
    },
    crate::Unconfirmed {
        fact: "The firmware's number format",
        check: "log raw `SNAP? 1,2` replies over several ranges (the manual prints `1000.00` and `-4.17234e-007`)",
    },
    crate::Unconfirmed {
        fact: "`AGAN` doing nothing when the time constant is over 1 s",
        check: "at `OFLT 11` (3 s) with the signal off range, send `AGAN`, then `SENS?`",
    },
    crate::Unconfirmed {
        fact: "The settling times 5, 7, 9 and 10 T to 99 % at 6, 12, 18 and 24 dB/oct",
        check: "step the input and time the output to 99 % at each slope (the manual's tables, p. 3-21 and p. 3-25, read only second-hand)",
    },
    crate::Unconfirmed {
        fact: "The overload thresholds: input above 1.4 V peak, output above 1.09 × full scale",
        check: "raise a known input through full scale and through 1.4 V peak, reading `LIAS?` bits 2 and 0",
    },
];
