//! The status bytes: `LIAS?`, `*ESR?` and `ERRS?`.

use crate::codec::status_register;

status_register! {
    /// The LIA status byte, `LIAS?` (p. 5-23). Bits latch until read or cleared by `*CLS`,
    /// so read it once to clear, take the readings, then read it again.
    pub struct LiaStatus(u8), has: all {
        /// Bit 0, INPUT/RESRV: input or amplifier (reserve) overload.
        INPUT_OVERLOAD = 1 << 0, "INPUT/RESRV";
        /// Bit 1, FILTR: time-constant filter overload.
        FILTER_OVERLOAD = 1 << 1, "FILTR";
        /// Bit 2, OUTPT: an output exceeds 1.09 × full scale.
        OUTPUT_OVERLOAD = 1 << 2, "OUTPT";
        /// Bit 3, UNLK: reference unlock.
        UNLOCK = 1 << 3, "UNLK";
        /// Bit 4, RANGE: the detection frequency crossed 200 Hz (changed range).
        RANGE = 1 << 4, "RANGE";
        /// Bit 5, TC: the time constant changed indirectly (range, reserve, slope,
        /// expand).
        TIME_CONSTANT_CHANGED = 1 << 5, "TC";
        /// Bit 6, TRIG: data storage triggered.
        TRIGGERED = 1 << 6, "TRIG";
    }
}

impl LiaStatus {
    /// Bit 0: input or reserve overload.
    pub fn input_overload(self) -> bool {
        self.has(Self::INPUT_OVERLOAD)
    }

    /// Bit 1: filter overload.
    pub fn filter_overload(self) -> bool {
        self.has(Self::FILTER_OVERLOAD)
    }

    /// Bit 2: output overload.
    pub fn output_overload(self) -> bool {
        self.has(Self::OUTPUT_OVERLOAD)
    }

    /// Bit 3: reference unlock.
    pub fn unlocked(self) -> bool {
        self.has(Self::UNLOCK)
    }
}

status_register! {
    /// The standard event status byte, `*ESR?` (manual, status byte definitions).
    pub struct EventStatus(u8), has: all {
        /// Bit 0, INP: input queue overflow.
        INP = 1 << 0, "INP";
        /// Bit 2, QRY: output queue overflow.
        QRY = 1 << 2, "QRY";
        /// Bit 4, EXE: a command could not execute, or a parameter was out of range.
        EXE = 1 << 4, "EXE";
        /// Bit 5, CMD: illegal command.
        CMD = 1 << 5, "CMD";
        /// Bit 6, URQ: a key was pressed or the knob turned.
        URQ = 1 << 6, "URQ";
        /// Bit 7, PON: power on.
        PON = 1 << 7, "PON";
    }
}

impl EventStatus {
    /// True when a command was refused (EXE or CMD): the instrument is not in the
    /// state the host asked for.
    pub fn has_command_error(self) -> bool {
        self.0 & (Self::EXE | Self::CMD) != 0
    }
}

status_register! {
    /// The error status byte, `ERRS?` (manual, status byte definitions). Bits 0 and 3 are unused.
    pub struct ErrorStatus(u8), has: all {
        /// Bit 1: battery-backed memory lost at power-up.
        BACKUP = 1 << 1, "BACKUP";
        /// Bit 2: RAM test failed.
        RAM = 1 << 2, "RAM";
        /// Bit 4: ROM test failed.
        ROM = 1 << 4, "ROM";
        /// Bit 5: GPIB fast data transfer aborted.
        GPIB = 1 << 5, "GPIB";
        /// Bit 6: DSP test failed.
        DSP = 1 << 6, "DSP";
        /// Bit 7: internal math error.
        MATH = 1 << 7, "MATH";
    }
}
