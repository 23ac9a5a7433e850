//! The status byte and the error codes (CS130B manual, 90088262, §15.9).

use std::fmt;

/// The status byte `STB?` reports. "Cleared to 0 at power-up. Whenever any error is
/// encountered it is set to the value 32. It is cleared again when the CS130B
/// receives a `STB?` query" (§15.9).
///
/// Written on the wire as two hexadecimal digits, `00` or `20`: the Cornerstone 260
/// manual (§16.7, "Read Status Byte with: STB? 00 indicates no error, 20 indicates
/// error condition") prints 32 that way. **UNCONFIRMED** for the CS130B, which gives
/// the value only; parsing as hexadecimal still finds the error bit if it prints
/// decimal `32` (0x32 has bit 5 set too).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StatusByte(pub u8);

impl StatusByte {
    /// Bit 5 (value 32): an error was encountered since the last `STB?` (§15.9).
    pub const ERROR: u8 = 0x20;

    /// True when the error bit is set: `ERROR?` tells which error.
    pub fn error(self) -> bool {
        self.0 & Self::ERROR != 0
    }
}

impl fmt::Display for StatusByte {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:02X}", self.0)
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
