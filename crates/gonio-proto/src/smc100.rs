//! The Newport SMC100 (CC/PP) ASCII protocol (user's manual EDH0206En2054, §5).
//!
//! A command line is `[nn]AA[xx]` + CR LF: controller address 1–31 (absent or 0 means
//! every controller, for the broadcast commands `ST` and `MM`), a two-letter command,
//! an optional value or `?`. Only queries reply; a reply echoes the address and the
//! command, then the value: `1TP` → `1TP12.5`. Set and action commands reply nothing,
//! even when they fail; the host reads the last error letter with `TE`.
//!
//! [`Frame`] and [`Reply`] format and parse both directions, so that the driver can
//! send commands and read replies, and the simulator can read commands and send
//! replies, from one definition.

use std::fmt;

use crate::number;

/// The line terminator in both directions.
pub const TERMINATOR: &[u8] = b"\r\n";

/// The longest reply line the driver accepts (`VE` and `ID?` strings are the longest,
/// about 50 bytes).
pub const MAX_LINE: usize = 128;

/// Highest controller address on a chain.
pub const MAX_ADDRESS: u8 = 31;

/// A parameter that can be queried with `xxAA?`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Param {
    /// `AC`: acceleration, units/s².
    Acceleration,
    /// `VA`: velocity, units/s.
    Velocity,
    /// `SL`: negative software limit, units.
    NegativeLimit,
    /// `SR`: positive software limit, units.
    PositiveLimit,
    /// `PA`: target of the last absolute move, units.
    AbsoluteTarget,
    /// `PR`: displacement of the last relative move, units.
    RelativeTarget,
    /// `MM`: 1 when READY (enabled), 0 when DISABLE.
    Enabled,
    /// `ID`: stage identifier (a string).
    StageId,
}

impl Param {
    /// The two-letter code.
    pub fn code(self) -> &'static str {
        match self {
            Param::Acceleration => "AC",
            Param::Velocity => "VA",
            Param::NegativeLimit => "SL",
            Param::PositiveLimit => "SR",
            Param::AbsoluteTarget => "PA",
            Param::RelativeTarget => "PR",
            Param::Enabled => "MM",
            Param::StageId => "ID",
        }
    }

    fn from_code(c: &str) -> Option<Param> {
        Some(match c {
            "AC" => Param::Acceleration,
            "VA" => Param::Velocity,
            "SL" => Param::NegativeLimit,
            "SR" => Param::PositiveLimit,
            "PA" => Param::AbsoluteTarget,
            "PR" => Param::RelativeTarget,
            "MM" => Param::Enabled,
            "ID" => Param::StageId,
            _ => return None,
        })
    }
}

/// A command to one controller (or, for `ST` and `MM`, to all).
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// `OR`: start the home search (accepted in NOT REFERENCED only).
    Home,
    /// `PAnn`: move to an absolute position, units.
    MoveAbsolute(f64),
    /// `PRnn`: move by a displacement from the current target, units.
    MoveRelative(f64),
    /// `ST`: stop, decelerating with the configured acceleration.
    Stop,
    /// `RS`: hardware reset, as at power-up; ends in NOT REFERENCED.
    Reset,
    /// `MM1` (leave DISABLE for READY) or `MM0` (READY to DISABLE).
    Enable(bool),
    /// `SLnn`: negative software limit, units.
    SetNegativeLimit(f64),
    /// `SRnn`: positive software limit, units.
    SetPositiveLimit(f64),
    /// `VAnn`: velocity, units/s.
    SetVelocity(f64),
    /// `ACnn`: acceleration, units/s².
    SetAcceleration(f64),
    /// `PTnn`: the time a relative move of |nn| would take (no motion); replies.
    MotionTime(f64),
    /// `TP`: current (encoder) position; replies.
    TellPosition,
    /// `TH`: set-point position; replies.
    TellSetpoint,
    /// `TS`: positioner errors and controller state; replies. Clears latched errors.
    TellStatus,
    /// `TE`: last command error letter; replies. Reading clears it.
    TellError,
    /// `VE`: firmware version string; replies.
    Version,
    /// `xxAA?`: the value of a parameter; replies.
    Query(Param),
}

impl Command {
    /// The two-letter code.
    pub fn code(&self) -> &'static str {
        match self {
            Command::Home => "OR",
            Command::MoveAbsolute(_) => "PA",
            Command::MoveRelative(_) => "PR",
            Command::Stop => "ST",
            Command::Reset => "RS",
            Command::Enable(_) => "MM",
            Command::SetNegativeLimit(_) => "SL",
            Command::SetPositiveLimit(_) => "SR",
            Command::SetVelocity(_) => "VA",
            Command::SetAcceleration(_) => "AC",
            Command::MotionTime(_) => "PT",
            Command::TellPosition => "TP",
            Command::TellSetpoint => "TH",
            Command::TellStatus => "TS",
            Command::TellError => "TE",
            Command::Version => "VE",
            Command::Query(p) => p.code(),
        }
    }

    /// True when the controller answers this command with a reply line.
    pub fn expects_reply(&self) -> bool {
        matches!(
            self,
            Command::MotionTime(_)
                | Command::TellPosition
                | Command::TellSetpoint
                | Command::TellStatus
                | Command::TellError
                | Command::Version
                | Command::Query(_)
        )
    }

    /// True when sending the command twice has the same effect as sending it once, so
    /// that a driver may re-send it after a lost acknowledgement. An absolute move is;
    /// a relative move is not (it would move twice), nor is `TE` or `TS` (reading
    /// clears what they report), nor a reset or a home search.
    pub fn is_idempotent(&self) -> bool {
        !matches!(
            self,
            Command::MoveRelative(_)
                | Command::TellError
                | Command::TellStatus
                | Command::Reset
                | Command::Home
        )
    }

    /// True for the commands that may go to every controller at once (no address).
    pub fn may_broadcast(&self) -> bool {
        matches!(self, Command::Stop | Command::Enable(_))
    }
}

/// A command with its destination: one controller, or all for a broadcast.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Controller address 1–31, or `None` for every controller.
    pub address: Option<u8>,
    /// The command.
    pub command: Command,
}

/// Why a command line is refused, with the error letter a controller would store.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    /// Unknown command code, or a floating-point address: error `A`.
    #[error("unknown command or malformed address")]
    Unknown,
    /// Address missing (for a command that needs one) or outside 1–31: error `B`.
    #[error("controller address missing or out of range")]
    BadAddress,
    /// Parameter missing or out of range: error `C`.
    #[error("parameter missing or out of range")]
    BadParameter,
}

impl CommandError {
    /// The `TE` letter a controller stores for this fault.
    pub fn error_code(&self) -> ErrorCode {
        match self {
            CommandError::Unknown => ErrorCode::UnknownCommand,
            CommandError::BadAddress => ErrorCode::BadAddress,
            CommandError::BadParameter => ErrorCode::BadParameter,
        }
    }
}

impl Frame {
    /// A command to controller `address`.
    pub fn addressed(address: u8, command: Command) -> Self {
        Frame {
            address: Some(address),
            command,
        }
    }

    /// A command to every controller (only `ST` and `MM` may be broadcast).
    pub fn broadcast(command: Command) -> Self {
        Frame {
            address: None,
            command,
        }
    }

    /// Appends the command line, terminator included, to `out`. Addresses are written
    /// without leading zeros, values in the shortest decimal form that reads back
    /// exactly.
    pub fn encode(&self, out: &mut Vec<u8>) {
        if let Some(a) = self.address {
            out.extend_from_slice(a.to_string().as_bytes());
        }
        out.extend_from_slice(self.command.code().as_bytes());
        match &self.command {
            Command::MoveAbsolute(v)
            | Command::MoveRelative(v)
            | Command::SetNegativeLimit(v)
            | Command::SetPositiveLimit(v)
            | Command::SetVelocity(v)
            | Command::SetAcceleration(v)
            | Command::MotionTime(v) => number::format(*v, out),
            Command::Enable(on) => out.push(if *on { b'1' } else { b'0' }),
            Command::Query(_) => out.push(b'?'),
            _ => {}
        }
        out.extend_from_slice(TERMINATOR);
    }

    /// The command line as bytes, terminator included.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut v = Vec::new();
        self.encode(&mut v);
        v
    }

    /// Parses a received command line (terminator removed), as a controller does:
    /// case-insensitive, blanks ignored anywhere, characters after the command
    /// ignored (so `1TS?` is `1TS`).
    pub fn parse(line: &[u8]) -> Result<Frame, CommandError> {
        let s: Vec<u8> = line
            .iter()
            .filter(|b| **b != b' ' && **b != b'\t')
            .map(|b| b.to_ascii_uppercase())
            .collect();
        let digits = s.iter().take_while(|b| b.is_ascii_digit()).count();
        if s.get(digits) == Some(&b'.') {
            return Err(CommandError::Unknown);
        }
        let address: Option<u8> = if digits == 0 {
            None
        } else if digits > 2 {
            return Err(CommandError::BadAddress);
        } else {
            // Two ASCII digits at most: always a valid number.
            let a = s[..digits].iter().fold(0u8, |acc, d| acc * 10 + (d - b'0'));
            Some(a)
        };
        let code = s.get(digits..digits + 2).ok_or(CommandError::Unknown)?;
        let code = std::str::from_utf8(code).map_err(|_| CommandError::Unknown)?;
        let rest = &s[digits + 2..];
        let query = rest.first() == Some(&b'?');
        let value = || -> Result<f64, CommandError> {
            // The value is the longest numeric prefix; what follows is ignored.
            let end = rest
                .iter()
                .position(|b| !(b.is_ascii_digit() || matches!(b, b'.' | b'-' | b'+' | b'E')))
                .unwrap_or(rest.len());
            number::parse(&rest[..end]).ok_or(CommandError::BadParameter)
        };
        let command = match code {
            "OR" => Command::Home,
            "ST" => Command::Stop,
            "RS" => Command::Reset,
            "TP" => Command::TellPosition,
            "TH" => Command::TellSetpoint,
            "TS" => Command::TellStatus,
            "TE" => Command::TellError,
            "VE" => Command::Version,
            "ID" if query => Command::Query(Param::StageId),
            "PT" => Command::MotionTime(value()?),
            c => match (Param::from_code(c), query) {
                (Some(p), true) => Command::Query(p),
                (Some(Param::AbsoluteTarget), false) => Command::MoveAbsolute(value()?),
                (Some(Param::RelativeTarget), false) => Command::MoveRelative(value()?),
                (Some(Param::NegativeLimit), false) => Command::SetNegativeLimit(value()?),
                (Some(Param::PositiveLimit), false) => Command::SetPositiveLimit(value()?),
                (Some(Param::Velocity), false) => Command::SetVelocity(value()?),
                (Some(Param::Acceleration), false) => Command::SetAcceleration(value()?),
                (Some(Param::Enabled), false) => match value()? {
                    0.0 => Command::Enable(false),
                    1.0 => Command::Enable(true),
                    _ => return Err(CommandError::BadParameter),
                },
                // Setting the stage name needs CONFIGURATION; not part of this codec.
                (Some(Param::StageId), false) => return Err(CommandError::Unknown),
                (None, _) => return Err(CommandError::Unknown),
            },
        };
        let address = match address {
            Some(0) | None if command.may_broadcast() => None,
            Some(a) if (1..=MAX_ADDRESS).contains(&a) => Some(a),
            _ => return Err(CommandError::BadAddress),
        };
        Ok(Frame { address, command })
    }
}

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

/// What a reply carries, by the command it answers.
#[derive(Clone, Debug, PartialEq)]
pub enum ReplyBody {
    /// `TP`: current position.
    Position(f64),
    /// `TH`: set-point position.
    Setpoint(f64),
    /// `TS`: errors and state.
    Status(Status),
    /// `TE`: last error.
    Error(ErrorCode),
    /// `VE`: the version text, opaque (real units and the manual differ).
    Version(String),
    /// `PT`: motion time, s.
    MotionTime(f64),
    /// `ID?`: the stage name.
    StageId(String),
    /// `AC?`, `VA?`, `SL?`, `SR?`, `PA?`, `PR?`, `MM?`: the parameter's value.
    Value(Param, f64),
}

impl ReplyBody {
    /// The two-letter code this reply echoes.
    pub fn code(&self) -> &'static str {
        match self {
            ReplyBody::Position(_) => "TP",
            ReplyBody::Setpoint(_) => "TH",
            ReplyBody::Status(_) => "TS",
            ReplyBody::Error(_) => "TE",
            ReplyBody::Version(_) => "VE",
            ReplyBody::MotionTime(_) => "PT",
            ReplyBody::StageId(_) => "ID",
            ReplyBody::Value(p, _) => p.code(),
        }
    }
}

/// A reply line from a controller.
#[derive(Clone, Debug, PartialEq)]
pub struct Reply {
    /// The replying controller's address.
    pub address: u8,
    /// The content.
    pub body: ReplyBody,
}

/// Why a reply line could not be understood.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ReplyError {
    /// The line is empty.
    #[error("empty reply")]
    Empty,
    /// No address at the start of the line.
    #[error("reply has no controller address")]
    NoAddress,
    /// The command code is missing or not one that replies.
    #[error("unknown reply code")]
    UnknownCode,
    /// The value after the code does not parse.
    #[error("malformed value")]
    BadValue,
    /// A `TS` state code the manual does not define.
    #[error("unknown controller state {0:02X}")]
    UnknownState(u8),
    /// A `TE` letter the manual does not define.
    #[error("unknown error letter {0:?}")]
    UnknownError(char),
}

impl Reply {
    /// Appends the reply line, terminator included (what a controller sends).
    pub fn encode(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(self.address.to_string().as_bytes());
        out.extend_from_slice(self.body.code().as_bytes());
        match &self.body {
            ReplyBody::Position(v)
            | ReplyBody::Setpoint(v)
            | ReplyBody::MotionTime(v)
            | ReplyBody::Value(_, v) => number::format(*v, out),
            ReplyBody::Status(s) => out
                .extend_from_slice(format!("{:04X}{:02X}", s.errors.0, s.state.code()).as_bytes()),
            ReplyBody::Error(e) => out.push(e.letter() as u8),
            ReplyBody::Version(t) | ReplyBody::StageId(t) => out.extend_from_slice(t.as_bytes()),
        }
        out.extend_from_slice(TERMINATOR);
    }

    /// The reply line as bytes, terminator included.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut v = Vec::new();
        self.encode(&mut v);
        v
    }

    /// Parses a reply line (terminator removed). Numbers are read leniently (sign,
    /// any number of decimals, exponent), since the firmware's format varies.
    pub fn parse(line: &[u8]) -> Result<Reply, ReplyError> {
        if line.is_empty() {
            return Err(ReplyError::Empty);
        }
        let digits = line.iter().take_while(|b| b.is_ascii_digit()).count();
        if digits == 0 || digits > 2 {
            return Err(ReplyError::NoAddress);
        }
        let address = line[..digits]
            .iter()
            .fold(0u8, |acc, d| acc * 10 + (d - b'0'));
        let code = line
            .get(digits..digits + 2)
            .ok_or(ReplyError::UnknownCode)?;
        let rest = &line[digits + 2..];
        let num = || number::parse(trim(rest)).ok_or(ReplyError::BadValue);
        let text = || {
            std::str::from_utf8(rest)
                .map(|s| s.trim().to_string())
                .map_err(|_| ReplyError::BadValue)
        };
        let body = match code {
            b"TP" => ReplyBody::Position(num()?),
            b"TH" => ReplyBody::Setpoint(num()?),
            b"PT" => ReplyBody::MotionTime(num()?),
            b"VE" => ReplyBody::Version(text()?),
            b"ID" => ReplyBody::StageId(text()?),
            b"TE" => {
                let r = trim(rest);
                match r {
                    [l] => ReplyBody::Error(
                        ErrorCode::from_letter(*l).ok_or(ReplyError::UnknownError(*l as char))?,
                    ),
                    _ => return Err(ReplyError::BadValue),
                }
            }
            b"TS" => {
                let r = trim(rest);
                if r.len() != 6 || !r.iter().all(u8::is_ascii_hexdigit) {
                    return Err(ReplyError::BadValue);
                }
                let hex = |s: &[u8]| {
                    s.iter().fold(0u16, |acc, d| {
                        acc * 16 + (*d as char).to_digit(16).unwrap_or(0) as u16
                    })
                };
                let errors = PositionerErrors(hex(&r[..4]));
                let code = hex(&r[4..]) as u8;
                let state =
                    ControllerState::from_code(code).ok_or(ReplyError::UnknownState(code))?;
                ReplyBody::Status(Status { errors, state })
            }
            other => {
                let c = std::str::from_utf8(other).map_err(|_| ReplyError::UnknownCode)?;
                match Param::from_code(c) {
                    Some(Param::StageId) | None => return Err(ReplyError::UnknownCode),
                    Some(p) => ReplyBody::Value(p, num()?),
                }
            }
        };
        Ok(Reply { address, body })
    }

    /// True when this reply answers `frame` (same address, and the code it echoes).
    pub fn answers(&self, frame: &Frame) -> bool {
        frame.address == Some(self.address)
            && frame.command.expects_reply()
            && self.body.code() == frame.command.code()
    }
}

fn trim(s: &[u8]) -> &[u8] {
    let start = s.iter().position(|b| *b != b' ').unwrap_or(s.len());
    let end = s.iter().rposition(|b| *b != b' ').map_or(start, |e| e + 1);
    &s[start..end.max(start)]
}

/// Bodies for the `cargo fuzz` targets in `fuzz/`: feed arbitrary bytes to every
/// parser of this protocol. They must never panic; they also check that whatever
/// parses re-encodes into something that parses to the same value.
pub mod fuzz {
    use super::{Frame, Reply};
    use crate::LineFramer;

    /// Parses `data` as a command line (the simulator's side), and round-trips it.
    pub fn command_line(data: &[u8]) {
        if let Ok(f) = Frame::parse(data) {
            let bytes = f.to_bytes();
            let again = Frame::parse(&bytes[..bytes.len() - 2]);
            assert_eq!(again.as_ref().ok(), Some(&f), "re-encoded {bytes:?}");
        }
    }

    /// Parses `data` as a reply line (the driver's side), and round-trips it.
    pub fn reply_line(data: &[u8]) {
        if let Ok(r) = Reply::parse(data) {
            let bytes = r.to_bytes();
            let again = Reply::parse(&bytes[..bytes.len() - 2]);
            assert_eq!(again.as_ref().ok(), Some(&r), "re-encoded {bytes:?}");
        }
    }

    /// Frames `data` as a stream of reply lines and parses each.
    pub fn stream(data: &[u8]) {
        let mut f = LineFramer::new(b'\n', super::MAX_LINE);
        f.push(data);
        while let Some(line) = f.next_line() {
            if let Ok(l) = line {
                reply_line(&l);
            }
        }
    }
}
