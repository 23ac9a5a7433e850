//! The status word of a reading (`FORM:ELEM … STAT`) and the standard event status
//! register (`*ESR?`).

use std::fmt;

/// The 16-bit status word sent with each reading when `STAT` is among the format
/// elements (FORMat:ELEMents, p. 13-6 ff.), sent as a decimal number.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct StatusWord(pub u16);

impl StatusWord {
    /// Bit 0, OFLO: the measurement overflowed (or an input overvoltage).
    pub const OVERFLOW: u16 = 1 << 0;
    /// Bit 1, Filter: taken with the averaging filter enabled.
    pub const FILTER: u16 = 1 << 1;
    /// Bit 2, Math: taken with CALC1 enabled.
    pub const MATH: u16 = 1 << 2;
    /// Bit 3, Null: null (REL) of CALC2 enabled.
    pub const NULL: u16 = 1 << 3;
    /// Bit 4, Limits: a limit test (CALC2) enabled.
    pub const LIMITS: u16 = 1 << 4;
    /// Bits 5 and 6: the limit test result.
    pub const LIMIT_RESULT: u16 = 0b11 << 5;
    /// Bit 7, Overvoltage: taken with an overvoltage on the input.
    pub const OVERVOLTAGE: u16 = 1 << 7;
    /// Bit 9, Zero Check: zero check was enabled (the input is shunted: not a
    /// measurement of the source).
    pub const ZERO_CHECK: u16 = 1 << 9;
    /// Bit 10, Zero Correct: zero correct was enabled.
    pub const ZERO_CORRECT: u16 = 1 << 10;

    const NAMES: [(u16, &'static str); 9] = [
        (Self::OVERFLOW, "OFLO"),
        (Self::FILTER, "FILT"),
        (Self::MATH, "MATH"),
        (Self::NULL, "NULL"),
        (Self::LIMITS, "LIM"),
        (Self::LIMIT_RESULT, "LIMRES"),
        (Self::OVERVOLTAGE, "OVV"),
        (Self::ZERO_CHECK, "ZCH"),
        (Self::ZERO_CORRECT, "ZCOR"),
    ];

    /// True when any bit of `mask` is set.
    pub fn has(self, mask: u16) -> bool {
        self.0 & mask != 0
    }

    /// Bit 0: the reading overflowed.
    pub fn overflow(self) -> bool {
        self.has(Self::OVERFLOW)
    }

    /// Bit 7: input overvoltage.
    pub fn overvoltage(self) -> bool {
        self.has(Self::OVERVOLTAGE)
    }

    /// Bit 9: zero check on.
    pub fn zero_check(self) -> bool {
        self.has(Self::ZERO_CHECK)
    }

    /// Bit 10: zero correct on.
    pub fn zero_correct(self) -> bool {
        self.has(Self::ZERO_CORRECT)
    }
}

impl fmt::Display for StatusWord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut first = true;
        for (mask, name) in Self::NAMES {
            if self.0 & mask != 0 {
                if !first {
                    f.write_str("|")?;
                }
                f.write_str(name)?;
                first = false;
            }
        }
        let unnamed = self.0 & !Self::NAMES.iter().fold(0, |acc, (m, _)| acc | m);
        if unnamed != 0 {
            if !first {
                f.write_str("|")?;
            }
            write!(f, "0x{unnamed:04X}")?;
            first = false;
        }
        if first {
            f.write_str("none")?;
        }
        Ok(())
    }
}

/// The standard event status register, `*ESR?` (IEEE-488.2, Section 10 of the manual).
/// Reading it clears it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct EventStatus(pub u8);

impl EventStatus {
    /// Bit 0, OPC: operation complete.
    pub const OPC: u8 = 1 << 0;
    /// Bit 2, QYE: query error (a reply asked for with nothing to send).
    pub const QYE: u8 = 1 << 2;
    /// Bit 3, DDE: device-dependent error.
    pub const DDE: u8 = 1 << 3;
    /// Bit 4, EXE: execution error (a parameter out of range, a command that cannot
    /// run now; SCPI errors −200 … −299).
    pub const EXE: u8 = 1 << 4;
    /// Bit 5, CME: command error (an unknown header, bad syntax; −100 … −199).
    pub const CME: u8 = 1 << 5;
    /// Bit 7, PON: power on.
    pub const PON: u8 = 1 << 7;

    /// True when a command was refused (EXE or CME) or failed in the device (DDE,
    /// QYE).
    pub fn has_error(self) -> bool {
        self.0 & (Self::QYE | Self::DDE | Self::EXE | Self::CME) != 0
    }
}
