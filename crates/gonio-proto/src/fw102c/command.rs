//! Host-to-wheel commands: typed, encoded into a caller's buffer, and parsed back (the
//! simulated wheel's side). The command words are UNCONFIRMED against the manual (see
//! the module docs); each is the one the drivers cited there send.

use std::fmt;

use super::TERMINATOR;
use crate::codec::coded_enum;

coded_enum! {
    /// The wheel's rotation speed (`speed=`): 0 slow, 1 high (UNCONFIRMED). In a config
    /// file, `"low"` or `"high"`.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Deserialize)]
    #[serde(rename_all = "lowercase")]
    pub enum Speed: u8, digit / from_digit {
        /// `speed=0`.
        Low = 0,
        /// `speed=1`.
        #[default]
        High = 1,
    }
}

coded_enum! {
    /// The trigger connector's mode (`trig=`): 0 input (a pulse moves the wheel one
    /// position), 1 output (UNCONFIRMED). Gonio does not use the trigger.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum TriggerMode: u8, digit / from_digit {
        /// `trig=0`.
        Input = 0,
        /// `trig=1`.
        Output = 1,
    }
}

coded_enum! {
    /// The position sensors' mode (`sensors=`): 0 switches them off while the wheel is
    /// idle, "to eliminate stray light", 1 keeps them on (UNCONFIRMED wording; Thorlabs
    /// describes the sensors as optical).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum SensorMode: u8, digit / from_digit {
        /// `sensors=0`: off while idle.
        OffWhenIdle = 0,
        /// `sensors=1`: always on.
        AlwaysOn = 1,
    }
}

/// One command to the wheel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Command {
    /// `*idn?`: the identification string.
    Identify,
    /// `pos=n`: move to position n (1-based). The wheel refuses n outside
    /// 1..=pcount with `CMD_ARG_INVALID` (the twin's model; UNCONFIRMED).
    SetPosition(u8),
    /// `pos?`: the present position.
    QueryPosition,
    /// `pcount=n`: the number of positions of the mounted wheel, 6 or 12.
    SetPositionCount(u8),
    /// `pcount?`.
    QueryPositionCount,
    /// `speed=n`.
    SetSpeed(Speed),
    /// `speed?`.
    QuerySpeed,
    /// `trig=n`.
    SetTrigger(TriggerMode),
    /// `trig?`.
    QueryTrigger,
    /// `sensors=n`.
    SetSensors(SensorMode),
    /// `sensors?`.
    QuerySensors,
    /// `save`: keeps the present settings over a power cycle.
    Save,
}

/// Why a received line is not a command, as the wheel answers it: the text after
/// `Command error ` (UNCONFIRMED; Odemis and InstrumentKit match these two).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    /// An unknown command word (also an empty line).
    #[error("CMD_NOT_DEFINED")]
    NotDefined,
    /// A known command with an argument it does not take.
    #[error("CMD_ARG_INVALID")]
    ArgInvalid,
}

crate::codec::line_encoding!(Command, &[TERMINATOR]);

impl Command {
    /// Whether the wheel answers with a value line.
    pub fn is_query(&self) -> bool {
        matches!(
            self,
            Command::Identify
                | Command::QueryPosition
                | Command::QueryPositionCount
                | Command::QuerySpeed
                | Command::QueryTrigger
                | Command::QuerySensors
        )
    }

    /// Writes the command without its terminator.
    pub fn encode_body(&self, out: &mut Vec<u8>) {
        let text = self.to_string();
        out.extend_from_slice(text.as_bytes());
    }

    /// Parses one received line, terminator removed: what the wheel does on receipt.
    /// Surrounding spaces are ignored and the word's case too (the case rule is the
    /// twin's, UNCONFIRMED). A value must be decimal digits only; a value out of the
    /// command's set (speed 2, pcount 7) is [`CommandError::ArgInvalid`], while the
    /// position's upper bound is the wheel's to check (it depends on `pcount`).
    pub fn parse(line: &[u8]) -> Result<Command, CommandError> {
        let text = std::str::from_utf8(line)
            .map_err(|_| CommandError::NotDefined)?
            .trim_matches(|c: char| c == ' ' || c == '\t')
            .to_ascii_lowercase();
        let simple = match text.as_str() {
            "*idn?" => Some(Command::Identify),
            "pos?" => Some(Command::QueryPosition),
            "pcount?" => Some(Command::QueryPositionCount),
            "speed?" => Some(Command::QuerySpeed),
            "trig?" => Some(Command::QueryTrigger),
            "sensors?" => Some(Command::QuerySensors),
            "save" => Some(Command::Save),
            _ => None,
        };
        if let Some(c) = simple {
            return Ok(c);
        }
        let Some((word, value)) = text.split_once('=') else {
            return Err(CommandError::NotDefined);
        };
        let number = || -> Result<u8, CommandError> {
            if value.is_empty() || value.len() > 3 || !value.bytes().all(|b| b.is_ascii_digit()) {
                return Err(CommandError::ArgInvalid);
            }
            value.parse::<u8>().map_err(|_| CommandError::ArgInvalid)
        };
        match word {
            "pos" => match number()? {
                0 => Err(CommandError::ArgInvalid),
                n => Ok(Command::SetPosition(n)),
            },
            "pcount" => match number()? {
                n @ (6 | 12) => Ok(Command::SetPositionCount(n)),
                _ => Err(CommandError::ArgInvalid),
            },
            "speed" => Speed::from_digit(number()?)
                .map(Command::SetSpeed)
                .ok_or(CommandError::ArgInvalid),
            "trig" => TriggerMode::from_digit(number()?)
                .map(Command::SetTrigger)
                .ok_or(CommandError::ArgInvalid),
            "sensors" => SensorMode::from_digit(number()?)
                .map(Command::SetSensors)
                .ok_or(CommandError::ArgInvalid),
            _ => Err(CommandError::NotDefined),
        }
    }
}

impl fmt::Display for Command {
    /// The command as sent, without its terminator.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Command::Identify => f.write_str("*idn?"),
            Command::SetPosition(n) => write!(f, "pos={n}"),
            Command::QueryPosition => f.write_str("pos?"),
            Command::SetPositionCount(n) => write!(f, "pcount={n}"),
            Command::QueryPositionCount => f.write_str("pcount?"),
            Command::SetSpeed(s) => write!(f, "speed={}", s.digit()),
            Command::QuerySpeed => f.write_str("speed?"),
            Command::SetTrigger(t) => write!(f, "trig={}", t.digit()),
            Command::QueryTrigger => f.write_str("trig?"),
            Command::SetSensors(s) => write!(f, "sensors={}", s.digit()),
            Command::QuerySensors => f.write_str("sensors?"),
            Command::Save => f.write_str("save"),
        }
    }
}
