//! Host to controller: [`Command`], addressed in a [`Frame`], and the errors a controller
//! stores for a line it cannot run.

use super::{ErrorCode, MAX_ADDRESS, TERMINATOR};
use crate::number;

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

    pub(super) fn from_code(c: &str) -> Option<Param> {
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
