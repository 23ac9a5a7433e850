//! The status byte and the error codes (CS130B manual, 90088262, §15.9).

use std::fmt;

/// The status byte `STB?` reports. "Cleared to 0 at power-up. Whenever any error is
/// encountered it is set to the value 32. It is cleared again when the CS130B
/// receives a `STB?` query" (§15.9).
///
/// # On the wire: decimal
///
/// Both manuals give it in decimal: the CS130B's §15.9 ("set to the value 32"), and
/// the Model 74000 command table: "STB? … The response will be 32 when an error
/// occurred or 00 when no error is present. Reading this code clears the status
/// byte." (second-hand text, see `docs/instruments/cs130.md`). (Gonio once read it as
/// hexadecimal, `00`/`20`, after the Cornerstone 260 manual's §16.7; both CS130 texts
/// contradict that.)
///
/// [`StatusByte::parse`]'s rule, right for what the manuals say and safe otherwise:
///
/// - 1 to 3 decimal digits, 0..=255 (`0`, `00`, `32`); anything else (a sign, a hex
///   letter, a fraction) fails the exchange, so it is never taken for a clean byte;
/// - **zero means no error; any nonzero value means an error is flagged**, and the
///   session reads `ERROR?`. Zero is zero in every base and nonzero digits are
///   nonzero in every base, so a unit printing 32 as the CS260's hexadecimal `20` is
///   still seen to flag an error (kept as decimal 20, which only changes the log).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StatusByte(pub u8);

impl StatusByte {
    /// The value the status byte takes on any error (§15.9: "set to the value 32"),
    /// bit 5. The twin sets this; [`error`](Self::error) accepts any nonzero value.
    pub const ERROR: u8 = 32;

    /// An `STB?` answer (terminator and blanks removed) by the rule above.
    pub fn parse(text: &str) -> Option<StatusByte> {
        crate::number::decimal(text, 3).map(StatusByte)
    }

    /// True when an error is flagged: any nonzero value; `ERROR?` tells which.
    pub fn error(self) -> bool {
        self.0 != 0
    }
}

impl fmt::Display for StatusByte {
    /// Decimal, at least two digits: `00` and `32`, as the Model 74000 table writes
    /// the two answers.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:02}", self.0)
    }
}

/// The code `ERROR?` answers, and resets to 0 (§15.9, table "Error code / Cause").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ErrorCode(pub u8);

impl ErrorCode {
    /// 0: no error.
    pub const NONE: ErrorCode = ErrorCode(0);
    /// 1: command not understood.
    pub const NOT_UNDERSTOOD: ErrorCode = ErrorCode(1);
    /// 2: bad parameter used in command.
    pub const BAD_PARAMETER: ErrorCode = ErrorCode(2);
    /// 3: destination position for wavelength motion not allowed.
    pub const DESTINATION: ErrorCode = ErrorCode(3);
    /// 6: accessory not present (usually filter wheel).
    pub const NO_ACCESSORY: ErrorCode = ErrorCode(6);
    /// 8: could not home wavelength drive.
    pub const HOME: ErrorCode = ErrorCode(8);
    /// 9: label too long.
    pub const LABEL: ErrorCode = ErrorCode(9);
    /// 10: system error.
    pub const SYSTEM: ErrorCode = ErrorCode(10);

    /// The manual's cause for this code; `None` for a code the CS130B table does not
    /// list (the Cornerstone 260 manual, §16.7, also has 7, "Accessory already in
    /// specified position": **UNCONFIRMED** for the CS130B).
    pub fn cause(self) -> Option<&'static str> {
        Some(match self.0 {
            0 => "no error",
            1 => "command not understood",
            2 => "bad parameter used in command",
            3 => "destination position for wavelength motion not allowed",
            6 => "accessory not present (usually filter wheel)",
            8 => "could not home wavelength drive",
            9 => "label too long",
            10 => "system error",
            _ => return None,
        })
    }
}

impl fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.cause() {
            Some(c) => write!(f, "{} ({c})", self.0),
            None => write!(f, "{} (not in the manual's table)", self.0),
        }
    }
}
