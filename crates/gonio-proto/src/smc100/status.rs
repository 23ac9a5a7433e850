//! The controller's status vocabulary: `TE` error letters, `TS` states and positioner
//! error bits.

use std::fmt;

/// The `TE` error letters, each with the manual's description (manual, TE command):
/// the enum and its table from one row each.
macro_rules! error_codes {
    ($($(#[$doc:meta])* $v:ident $letter:literal $text:literal,)*) => {
        /// The `TE` error letters (manual, TE command).
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum ErrorCode {
            $(#[doc = concat!("`", $letter, "`: ", $text, ".")] $(#[$doc])* $v,)*
        }

        impl ErrorCode {
            const TABLE: &[(char, ErrorCode, &'static str)] =
                &[$(($letter, ErrorCode::$v, $text)),*];
        }
    };
}

error_codes! {
    None '@' "no error",
    UnknownCommand 'A' "unknown message code or floating point controller address",
    BadAddress 'B' "controller address not correct",
    BadParameter 'C' "parameter missing or out of range",
    /// (Execution not allowed.)
    NotAllowed 'D' "command not allowed",
    HomeStarted 'E' "home sequence already started",
    UnknownStage 'F' "ESP stage name unknown",
    OutOfLimits 'G' "displacement out of limits",
    NotReferenced 'H' "command not allowed in NOT REFERENCED state",
    InConfiguration 'I' "command not allowed in CONFIGURATION state",
    InDisable 'J' "command not allowed in DISABLE state",
    InReady 'K' "command not allowed in READY state",
    InHoming 'L' "command not allowed in HOMING state",
    InMoving 'M' "command not allowed in MOVING state",
    PositionOutOfLimit 'N' "current position out of software limit",
    CommunicationTimeout 'S' "communication time-out",
    Eeprom 'U' "error during EEPROM access",
    Execution 'V' "error during command execution",
    NotForPp 'W' "command not allowed for PP version",
    NotForCc 'X' "command not allowed for CC version",
}

impl ErrorCode {
    /// The letter `TE` reports.
    pub fn letter(self) -> char {
        Self::TABLE
            .iter()
            .find(|(_, c, _)| *c == self)
            .map_or('?', |(l, _, _)| *l)
    }

    /// The code for a `TE` letter; `None` for letters the manual does not define.
    pub fn from_letter(l: u8) -> Option<ErrorCode> {
        Self::TABLE
            .iter()
            .find(|(b, _, _)| *b == char::from(l))
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

/// The controller states with their codes: the enum and its table from one row each.
macro_rules! controller_states {
    ($($(#[$doc:meta])* $v:ident = $code:literal,)*) => {
        /// The controller state, the last two hex digits of a `TS` reply (manual, TS command).
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum ControllerState {
            $($(#[$doc])* $v,)*
        }

        impl ControllerState {
            /// Every state, with its code.
            pub const ALL: [(u8, ControllerState); [$($code),*].len()] =
                [$(($code, ControllerState::$v)),*];
        }
    };
}

controller_states! {
    /// `0A`: NOT REFERENCED from reset (after power-up or `RS`).
    NotReferencedFromReset = 0x0A,
    /// `0B`: NOT REFERENCED from HOMING.
    NotReferencedFromHoming = 0x0B,
    /// `0C`: NOT REFERENCED from CONFIGURATION.
    NotReferencedFromConfiguration = 0x0C,
    /// `0D`: NOT REFERENCED from DISABLE.
    NotReferencedFromDisable = 0x0D,
    /// `0E`: NOT REFERENCED from READY.
    NotReferencedFromReady = 0x0E,
    /// `0F`: NOT REFERENCED from MOVING.
    NotReferencedFromMoving = 0x0F,
    /// `10`: NOT REFERENCED, ESP stage error.
    NotReferencedStageError = 0x10,
    /// `11`: NOT REFERENCED from JOGGING.
    NotReferencedFromJogging = 0x11,
    /// `14`: CONFIGURATION.
    Configuration = 0x14,
    /// `1E`: HOMING commanded over RS-232.
    HomingRemote = 0x1E,
    /// `1F`: HOMING commanded by keypad.
    HomingKeypad = 0x1F,
    /// `28`: MOVING.
    Moving = 0x28,
    /// `32`: READY from HOMING.
    ReadyFromHoming = 0x32,
    /// `33`: READY from MOVING.
    ReadyFromMoving = 0x33,
    /// `34`: READY from DISABLE.
    ReadyFromDisable = 0x34,
    /// `35`: READY from JOGGING.
    ReadyFromJogging = 0x35,
    /// `3C`: DISABLE from READY.
    DisableFromReady = 0x3C,
    /// `3D`: DISABLE from MOVING (e.g. a following error).
    DisableFromMoving = 0x3D,
    /// `3E`: DISABLE from JOGGING.
    DisableFromJogging = 0x3E,
    /// `46`: JOGGING from READY.
    JoggingFromReady = 0x46,
    /// `47`: JOGGING from DISABLE.
    JoggingFromDisable = 0x47,
}

impl ControllerState {
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
    crate::codec::status_bits! {
        impl u16;
        /// Negative end of run (limit switch).
        NEGATIVE_END_OF_RUN = 0x0001 "negative end of run",
        /// Positive end of run.
        POSITIVE_END_OF_RUN = 0x0002 "positive end of run",
        /// Peak current limit.
        PEAK_CURRENT = 0x0004 "peak current limit",
        /// RMS current limit.
        RMS_CURRENT = 0x0008 "RMS current limit",
        /// Short-circuit detection.
        SHORT_CIRCUIT = 0x0010 "short circuit",
        /// Following error.
        FOLLOWING_ERROR = 0x0020 "following error",
        /// Homing time-out.
        HOMING_TIMEOUT = 0x0040 "homing time-out",
        /// Wrong ESP stage (detected at boot).
        WRONG_STAGE = 0x0080 "wrong ESP stage",
        /// DC voltage too low.
        LOW_VOLTAGE = 0x0100 "DC voltage too low",
        /// 80 W output power exceeded.
        OVER_POWER = 0x0200 "80 W output power exceeded",
    }

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
