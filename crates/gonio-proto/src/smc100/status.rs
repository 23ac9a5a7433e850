//! The controller's status vocabulary: `TE` error letters, `TS` states and positioner
//! error bits.

use std::fmt;

/// The `TE` error letters (manual, TE command).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorCode {
    /// `@`: no error.
    None,
    /// `A`: unknown message code or floating-point controller address.
    UnknownCommand,
    /// `B`: controller address not correct.
    BadAddress,
    /// `C`: parameter missing or out of range.
    BadParameter,
    /// `D`: command not allowed (execution not allowed).
    NotAllowed,
    /// `E`: home sequence already started.
    HomeStarted,
    /// `F`: ESP stage name unknown.
    UnknownStage,
    /// `G`: displacement out of limits.
    OutOfLimits,
    /// `H`: command not allowed in NOT REFERENCED state.
    NotReferenced,
    /// `I`: command not allowed in CONFIGURATION state.
    InConfiguration,
    /// `J`: command not allowed in DISABLE state.
    InDisable,
    /// `K`: command not allowed in READY state.
    InReady,
    /// `L`: command not allowed in HOMING state.
    InHoming,
    /// `M`: command not allowed in MOVING state.
    InMoving,
    /// `N`: current position out of software limit.
    PositionOutOfLimit,
    /// `S`: communication time-out.
    CommunicationTimeout,
    /// `U`: error during EEPROM access.
    Eeprom,
    /// `V`: error during command execution.
    Execution,
    /// `W`: command not allowed for PP version.
    NotForPp,
    /// `X`: command not allowed for CC version.
    NotForCc,
}

impl ErrorCode {
    const TABLE: [(u8, ErrorCode, &'static str); 20] = [
        (b'@', ErrorCode::None, "no error"),
        (
            b'A',
            ErrorCode::UnknownCommand,
            "unknown message code or floating point controller address",
        ),
        (
            b'B',
            ErrorCode::BadAddress,
            "controller address not correct",
        ),
        (
            b'C',
            ErrorCode::BadParameter,
            "parameter missing or out of range",
        ),
        (b'D', ErrorCode::NotAllowed, "command not allowed"),
        (
            b'E',
            ErrorCode::HomeStarted,
            "home sequence already started",
        ),
        (b'F', ErrorCode::UnknownStage, "ESP stage name unknown"),
        (b'G', ErrorCode::OutOfLimits, "displacement out of limits"),
        (
            b'H',
            ErrorCode::NotReferenced,
            "command not allowed in NOT REFERENCED state",
        ),
        (
            b'I',
            ErrorCode::InConfiguration,
            "command not allowed in CONFIGURATION state",
        ),
        (
            b'J',
            ErrorCode::InDisable,
            "command not allowed in DISABLE state",
        ),
        (
            b'K',
            ErrorCode::InReady,
            "command not allowed in READY state",
        ),
        (
            b'L',
            ErrorCode::InHoming,
            "command not allowed in HOMING state",
        ),
        (
            b'M',
            ErrorCode::InMoving,
            "command not allowed in MOVING state",
        ),
        (
            b'N',
            ErrorCode::PositionOutOfLimit,
            "current position out of software limit",
        ),
        (
            b'S',
            ErrorCode::CommunicationTimeout,
            "communication time-out",
        ),
        (b'U', ErrorCode::Eeprom, "error during EEPROM access"),
        (b'V', ErrorCode::Execution, "error during command execution"),
        (
            b'W',
            ErrorCode::NotForPp,
            "command not allowed for PP version",
        ),
        (
            b'X',
            ErrorCode::NotForCc,
            "command not allowed for CC version",
        ),
    ];

    /// The letter `TE` reports.
    pub fn letter(self) -> char {
        Self::TABLE
            .iter()
            .find(|(_, c, _)| *c == self)
            .map_or('?', |(l, _, _)| *l as char)
    }

    /// The code for a `TE` letter; `None` for letters the manual does not define.
    pub fn from_letter(l: u8) -> Option<ErrorCode> {
        Self::TABLE
            .iter()
            .find(|(b, _, _)| *b == l)
            .map(|(_, c, _)| *c)
    }

    /// The manual's description.
    pub fn description(self) -> &'static str {
        Self::TABLE
            .iter()
            .find(|(_, c, _)| *c == self)
            .map_or("", |(_, _, d)| d)
    }
}

impl fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} ({})", self.letter(), self.description())
    }
}

/// The controller state, the last two hex digits of a `TS` reply (manual, TS command).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ControllerState {
    /// `0A`: NOT REFERENCED from reset (after power-up or `RS`).
    NotReferencedFromReset,
    /// `0B`: NOT REFERENCED from HOMING.
    NotReferencedFromHoming,
    /// `0C`: NOT REFERENCED from CONFIGURATION.
    NotReferencedFromConfiguration,
    /// `0D`: NOT REFERENCED from DISABLE.
    NotReferencedFromDisable,
    /// `0E`: NOT REFERENCED from READY.
    NotReferencedFromReady,
    /// `0F`: NOT REFERENCED from MOVING.
    NotReferencedFromMoving,
    /// `10`: NOT REFERENCED, ESP stage error.
    NotReferencedStageError,
    /// `11`: NOT REFERENCED from JOGGING.
    NotReferencedFromJogging,
    /// `14`: CONFIGURATION.
    Configuration,
    /// `1E`: HOMING commanded over RS-232.
    HomingRemote,
    /// `1F`: HOMING commanded by keypad.
    HomingKeypad,
    /// `28`: MOVING.
    Moving,
    /// `32`: READY from HOMING.
    ReadyFromHoming,
    /// `33`: READY from MOVING.
    ReadyFromMoving,
    /// `34`: READY from DISABLE.
    ReadyFromDisable,
    /// `35`: READY from JOGGING.
    ReadyFromJogging,
    /// `3C`: DISABLE from READY.
    DisableFromReady,
    /// `3D`: DISABLE from MOVING (e.g. a following error).
    DisableFromMoving,
    /// `3E`: DISABLE from JOGGING.
    DisableFromJogging,
    /// `46`: JOGGING from READY.
    JoggingFromReady,
    /// `47`: JOGGING from DISABLE.
    JoggingFromDisable,
}

impl ControllerState {
    /// Every state, with its code.
    pub const ALL: [(u8, ControllerState); 21] = [
        (0x0A, ControllerState::NotReferencedFromReset),
        (0x0B, ControllerState::NotReferencedFromHoming),
        (0x0C, ControllerState::NotReferencedFromConfiguration),
        (0x0D, ControllerState::NotReferencedFromDisable),
        (0x0E, ControllerState::NotReferencedFromReady),
        (0x0F, ControllerState::NotReferencedFromMoving),
        (0x10, ControllerState::NotReferencedStageError),
        (0x11, ControllerState::NotReferencedFromJogging),
        (0x14, ControllerState::Configuration),
        (0x1E, ControllerState::HomingRemote),
        (0x1F, ControllerState::HomingKeypad),
        (0x28, ControllerState::Moving),
        (0x32, ControllerState::ReadyFromHoming),
        (0x33, ControllerState::ReadyFromMoving),
        (0x34, ControllerState::ReadyFromDisable),
        (0x35, ControllerState::ReadyFromJogging),
        (0x3C, ControllerState::DisableFromReady),
        (0x3D, ControllerState::DisableFromMoving),
        (0x3E, ControllerState::DisableFromJogging),
        (0x46, ControllerState::JoggingFromReady),
        (0x47, ControllerState::JoggingFromDisable),
    ];

    /// The state's code.
    pub fn code(self) -> u8 {
        Self::ALL
            .iter()
            .find(|(_, s)| *s == self)
            .map_or(0, |(c, _)| *c)
    }

    /// The state for a code; `None` for codes the manual does not define.
    pub fn from_code(code: u8) -> Option<ControllerState> {
        Self::ALL.iter().find(|(c, _)| *c == code).map(|(_, s)| *s)
    }

    /// NOT REFERENCED (any cause): needs a home search before moves.
    pub fn is_not_referenced(self) -> bool {
        (0x0A..=0x11).contains(&self.code())
    }

    /// CONFIGURATION.
    pub fn is_configuration(self) -> bool {
        self == ControllerState::Configuration
    }

    /// HOMING.
    pub fn is_homing(self) -> bool {
        matches!(
            self,
            ControllerState::HomingRemote | ControllerState::HomingKeypad
        )
    }

    /// MOVING.
    pub fn is_moving(self) -> bool {
        self == ControllerState::Moving
    }

    /// READY (any cause): accepts moves.
    pub fn is_ready(self) -> bool {
        (0x32..=0x35).contains(&self.code())
    }

    /// DISABLE: motor not energised.
    pub fn is_disabled(self) -> bool {
        (0x3C..=0x3E).contains(&self.code())
    }

    /// JOGGING (keypad).
    pub fn is_jogging(self) -> bool {
        matches!(
            self,
            ControllerState::JoggingFromReady | ControllerState::JoggingFromDisable
        )
    }
}

impl fmt::Display for ControllerState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:02X} ({self:?})", self.code())
    }
}

/// The positioner error bits, the first four hex digits of a `TS` reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct PositionerErrors(pub u16);

impl PositionerErrors {
    /// Negative end of run (limit switch).
    pub const NEGATIVE_END_OF_RUN: u16 = 0x0001;
    /// Positive end of run.
    pub const POSITIVE_END_OF_RUN: u16 = 0x0002;
    /// Peak current limit.
    pub const PEAK_CURRENT: u16 = 0x0004;
    /// RMS current limit.
    pub const RMS_CURRENT: u16 = 0x0008;
    /// Short-circuit detection.
    pub const SHORT_CIRCUIT: u16 = 0x0010;
    /// Following error.
    pub const FOLLOWING_ERROR: u16 = 0x0020;
    /// Homing time-out.
    pub const HOMING_TIMEOUT: u16 = 0x0040;
    /// Wrong ESP stage (detected at boot).
    pub const WRONG_STAGE: u16 = 0x0080;
    /// DC voltage too low.
    pub const LOW_VOLTAGE: u16 = 0x0100;
    /// 80 W output power exceeded.
    pub const OVER_POWER: u16 = 0x0200;

    /// True when every bit of `mask` is set.
    pub fn has(self, mask: u16) -> bool {
        self.0 & mask == mask
    }

    /// True when no bit is set.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }
}

/// A `TS` reply: positioner errors and controller state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Status {
    /// Positioner error bits.
    pub errors: PositionerErrors,
    /// Controller state.
    pub state: ControllerState,
}
