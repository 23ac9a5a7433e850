//! The status bytes: `LIAS?`, `*ESR?` and `ERRS?`.

use std::fmt;

/// Writes the names of the set bits of `byte`, `|`-separated, or `none`.
fn write_bits(f: &mut fmt::Formatter<'_>, byte: u8, names: &[(u8, &str)]) -> fmt::Result {
    let mut first = true;
    for (mask, name) in names {
        if byte & mask != 0 {
            if !first {
                f.write_str("|")?;
            }
            f.write_str(name)?;
            first = false;
        }
    }
    let unnamed = byte & !names.iter().fold(0, |acc, (m, _)| acc | m);
    if unnamed != 0 {
        if !first {
            f.write_str("|")?;
        }
        write!(f, "0x{unnamed:02X}")?;
        first = false;
    }
    if first {
        f.write_str("none")?;
    }
    Ok(())
}

/// The LIA status byte, `LIAS?` (p. 5-23). Bits latch until read or cleared by `*CLS`,
/// so read it once to clear, take the readings, then read it again.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct LiaStatus(pub u8);

impl LiaStatus {
    /// Bit 0, INPUT/RESRV: input or amplifier (reserve) overload.
    pub const INPUT_OVERLOAD: u8 = 1 << 0;
    /// Bit 1, FILTR: time-constant filter overload.
    pub const FILTER_OVERLOAD: u8 = 1 << 1;
    /// Bit 2, OUTPT: an output exceeds 1.09 × full scale.
    pub const OUTPUT_OVERLOAD: u8 = 1 << 2;
    /// Bit 3, UNLK: reference unlock.
    pub const UNLOCK: u8 = 1 << 3;
    /// Bit 4, RANGE: the detection frequency crossed 200 Hz (changed range).
    pub const RANGE: u8 = 1 << 4;
    /// Bit 5, TC: the time constant changed indirectly (range, reserve, slope,
    /// expand).
    pub const TIME_CONSTANT_CHANGED: u8 = 1 << 5;
    /// Bit 6, TRIG: data storage triggered.
    pub const TRIGGERED: u8 = 1 << 6;

    const NAMES: [(u8, &'static str); 7] = [
        (Self::INPUT_OVERLOAD, "INPUT/RESRV"),
        (Self::FILTER_OVERLOAD, "FILTR"),
        (Self::OUTPUT_OVERLOAD, "OUTPT"),
        (Self::UNLOCK, "UNLK"),
        (Self::RANGE, "RANGE"),
        (Self::TIME_CONSTANT_CHANGED, "TC"),
        (Self::TRIGGERED, "TRIG"),
    ];

    /// True when every bit of `mask` is set.
    pub fn has(self, mask: u8) -> bool {
        self.0 & mask == mask
    }

    /// True when no bit is set.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

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

impl fmt::Display for LiaStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_bits(f, self.0, &Self::NAMES)
    }
}

/// The standard event status byte, `*ESR?` (manual, status byte definitions).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct EventStatus(pub u8);

impl EventStatus {
    /// Bit 0, INP: input queue overflow.
    pub const INP: u8 = 1 << 0;
    /// Bit 2, QRY: output queue overflow.
    pub const QRY: u8 = 1 << 2;
    /// Bit 4, EXE: a command could not execute, or a parameter was out of range.
    pub const EXE: u8 = 1 << 4;
    /// Bit 5, CMD: illegal command.
    pub const CMD: u8 = 1 << 5;
    /// Bit 6, URQ: a key was pressed or the knob turned.
    pub const URQ: u8 = 1 << 6;
    /// Bit 7, PON: power on.
    pub const PON: u8 = 1 << 7;

    const NAMES: [(u8, &'static str); 6] = [
        (Self::INP, "INP"),
        (Self::QRY, "QRY"),
        (Self::EXE, "EXE"),
        (Self::CMD, "CMD"),
        (Self::URQ, "URQ"),
        (Self::PON, "PON"),
    ];

    /// True when every bit of `mask` is set.
    pub fn has(self, mask: u8) -> bool {
        self.0 & mask == mask
    }

    /// True when no bit is set.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// True when a command was refused (EXE or CMD): the instrument is not in the
    /// state the host asked for.
    pub fn has_command_error(self) -> bool {
        self.0 & (Self::EXE | Self::CMD) != 0
    }
}

impl fmt::Display for EventStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_bits(f, self.0, &Self::NAMES)
    }
}

/// The error status byte, `ERRS?` (manual, status byte definitions). Bits 0 and 3 are unused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct ErrorStatus(pub u8);

impl ErrorStatus {
    /// Bit 1: battery-backed memory lost at power-up.
    pub const BACKUP: u8 = 1 << 1;
    /// Bit 2: RAM test failed.
    pub const RAM: u8 = 1 << 2;
    /// Bit 4: ROM test failed.
    pub const ROM: u8 = 1 << 4;
    /// Bit 5: GPIB fast data transfer aborted.
    pub const GPIB: u8 = 1 << 5;
    /// Bit 6: DSP test failed.
    pub const DSP: u8 = 1 << 6;
    /// Bit 7: internal math error.
    pub const MATH: u8 = 1 << 7;

    const NAMES: [(u8, &'static str); 6] = [
        (Self::BACKUP, "BACKUP"),
        (Self::RAM, "RAM"),
        (Self::ROM, "ROM"),
        (Self::GPIB, "GPIB"),
        (Self::DSP, "DSP"),
        (Self::MATH, "MATH"),
    ];

    /// True when every bit of `mask` is set.
    pub fn has(self, mask: u8) -> bool {
        self.0 & mask == mask
    }

    /// True when no bit is set.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }
}

impl fmt::Display for ErrorStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_bits(f, self.0, &Self::NAMES)
    }
}
