//! The status word of a reading (`FORM:ELEM … STAT`) and the standard event status
//! register (`*ESR?`).

use crate::codec::status_register;

status_register! {
    /// The 16-bit status word sent with each reading when `STAT` is among the format
    /// elements (FORMat:ELEMents, p. 13-6 ff.), sent as a decimal number.
    pub struct StatusWord(u16), has: any {
        /// Bit 0, OFLO: the measurement overflowed (or an input overvoltage).
        OVERFLOW = 1 << 0, "OFLO";
        /// Bit 1, Filter: taken with the averaging filter enabled.
        FILTER = 1 << 1, "FILT";
        /// Bit 2, Math: taken with CALC1 enabled.
        MATH = 1 << 2, "MATH";
        /// Bit 3, Null: null (REL) of CALC2 enabled.
        NULL = 1 << 3, "NULL";
        /// Bit 4, Limits: a limit test (CALC2) enabled.
        LIMITS = 1 << 4, "LIM";
        /// Bits 5 and 6: the limit test result.
        LIMIT_RESULT = 0b11 << 5, "LIMRES";
        /// Bit 7, Overvoltage: taken with an overvoltage on the input.
        OVERVOLTAGE = 1 << 7, "OVV";
        /// Bit 9, Zero Check: zero check was enabled (the input is shunted: not a
        /// measurement of the source).
        ZERO_CHECK = 1 << 9, "ZCH";
        /// Bit 10, Zero Correct: zero correct was enabled.
        ZERO_CORRECT = 1 << 10, "ZCOR";
    }
}

impl StatusWord {
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

status_register! {
    /// The standard event status register, `*ESR?` (IEEE-488.2, Section 10 of the
    /// manual). Reading it clears it.
    pub struct EventStatus(u8), has: all {
        /// Bit 0, OPC: operation complete.
        OPC = 1 << 0, "OPC";
        /// Bit 2, QYE: query error (a reply asked for with nothing to send).
        QYE = 1 << 2, "QYE";
        /// Bit 3, DDE: device-dependent error.
        DDE = 1 << 3, "DDE";
        /// Bit 4, EXE: execution error (a parameter out of range, a command that cannot
        /// run now; SCPI errors −200 … −299).
        EXE = 1 << 4, "EXE";
        /// Bit 5, CME: command error (an unknown header, bad syntax; −100 … −199).
        CME = 1 << 5, "CME";
        /// Bit 7, PON: power on.
        PON = 1 << 7, "PON";
    }
}

impl EventStatus {
    /// True when a command was refused (EXE or CME) or failed in the device (DDE,
    /// QYE).
    pub fn has_error(self) -> bool {
        self.0 & (Self::QYE | Self::DDE | Self::EXE | Self::CME) != 0
    }
}
