//! Wheel-to-host lines: the prompt, the echo, error lines and values. Formats are
//! UNCONFIRMED against the manual (see the module docs).

use std::fmt;

use super::{Command, CommandError, SensorMode, Speed, TERMINATOR, TriggerMode};

/// `line` without leading prompts (`>` and spaces: a lost command can leave two) and
/// without trailing spaces, tabs or LF (a wheel or adapter may send CR LF).
pub fn strip_prompt(line: &[u8]) -> &[u8] {
    let mut rest = line;
    while let Some((&first, tail)) = rest.split_first() {
        if first == b'>' || first == b' ' {
            rest = tail;
        } else {
            break;
        }
    }
    while let Some((&last, head)) = rest.split_last() {
        if matches!(last, b' ' | b'\t' | b'\n') {
            rest = head;
        } else {
            break;
        }
    }
    rest
}

/// The code after `Command error `.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ErrorCode {
    /// `CMD_NOT_DEFINED`: unknown command.
    NotDefined,
    /// `CMD_ARG_INVALID`: bad argument (a position beyond `pcount`, speed 2).
    ArgInvalid,
    /// Any other code, kept as sent.
    Other(String),
}

impl From<CommandError> for ErrorCode {
    fn from(e: CommandError) -> Self {
        match e {
            CommandError::NotDefined => ErrorCode::NotDefined,
            CommandError::ArgInvalid => ErrorCode::ArgInvalid,
        }
    }
}

impl fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // The two known codes are written as `CommandError` names them.
        match self {
            ErrorCode::NotDefined => CommandError::NotDefined.fmt(f),
            ErrorCode::ArgInvalid => CommandError::ArgInvalid.fmt(f),
            ErrorCode::Other(s) => f.write_str(s),
        }
    }
}

/// A refusal line: `Command error <code>`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceError {
    /// What the wheel reported.
    pub code: ErrorCode,
}

impl DeviceError {
    const PREFIX: &'static [u8] = b"Command error ";

    /// The refusal in `line` (prompt already stripped), if it is one.
    pub fn parse(line: &[u8]) -> Option<DeviceError> {
        let rest = line.strip_prefix(Self::PREFIX)?;
        let known = [CommandError::NotDefined, CommandError::ArgInvalid]
            .into_iter()
            .find(|e| e.to_string().as_bytes() == rest);
        let code = known.map_or_else(
            || ErrorCode::Other(String::from_utf8_lossy(rest).into_owned()),
            ErrorCode::from,
        );
        Some(DeviceError { code })
    }

    /// The line as the wheel sends it, CR included.
    pub fn encode(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(Self::PREFIX);
        out.extend_from_slice(self.code.to_string().as_bytes());
        out.push(TERMINATOR);
    }
}

impl fmt::Display for DeviceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Command error {}", self.code)
    }
}

/// One received line, classified.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Line<'a> {
    /// Nothing but the prompt or spaces.
    Blank,
    /// A refusal.
    Error(DeviceError),
    /// Anything else (an echo or a value), prompt stripped.
    Text(&'a [u8]),
}

impl<'a> Line<'a> {
    /// Classifies a line, terminator removed.
    pub fn classify(line: &'a [u8]) -> Line<'a> {
        let text = strip_prompt(line);
        if text.is_empty() {
            return Line::Blank;
        }
        match DeviceError::parse(text) {
            Some(e) => Line::Error(e),
            None => Line::Text(text),
        }
    }
}

/// Whether `text` (prompt stripped) echoes `command`, case ignored.
pub(crate) fn is_echo(command: &Command, text: &[u8]) -> bool {
    crate::codec::echoes(command, text)
}

/// A query's value.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Reply {
    /// `*idn?`: e.g. `THORLABS FW102C/FW212C Filter Wheel version 1.04` (the form
    /// Odemis quotes; UNCONFIRMED).
    Identity(String),
    /// `pos?`.
    Position(u8),
    /// `pcount?`.
    PositionCount(u8),
    /// `speed?`.
    Speed(Speed),
    /// `trig?`.
    Trigger(TriggerMode),
    /// `sensors?`.
    Sensors(SensorMode),
}

/// Why a value line does not answer its query.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ReplyError {
    /// The command is not a query: it has no value line.
    #[error("not a query")]
    NotAQuery,
    /// The line is not a value of the query's kind.
    #[error("not a value of the query's kind")]
    BadValue,
}

impl Reply {
    /// The value line answering `query`, terminator removed: decimal digits,
    /// surrounding spaces ignored.
    pub fn parse(query: &Command, line: &[u8]) -> Result<Reply, ReplyError> {
        let text = strip_prompt(line);
        let bad = ReplyError::BadValue;
        let digit = || -> Result<u8, ReplyError> {
            let t = std::str::from_utf8(text).map_err(|_| bad)?;
            crate::number::decimal(t.trim(), 3).ok_or(bad)
        };
        let nonzero = || digit().and_then(|n| (n != 0).then_some(n).ok_or(bad));
        match query {
            Command::Identify => {
                let t = std::str::from_utf8(text).map_err(|_| bad)?;
                if t.is_empty() || t.chars().any(char::is_control) {
                    return Err(bad);
                }
                Ok(Reply::Identity(t.to_string()))
            }
            Command::QueryPosition => nonzero().map(Reply::Position),
            Command::QueryPositionCount => nonzero().map(Reply::PositionCount),
            Command::QuerySpeed => Speed::from_digit(digit()?).map(Reply::Speed).ok_or(bad),
            Command::QueryTrigger => TriggerMode::from_digit(digit()?)
                .map(Reply::Trigger)
                .ok_or(bad),
            Command::QuerySensors => SensorMode::from_digit(digit()?)
                .map(Reply::Sensors)
                .ok_or(bad),
            _ => Err(ReplyError::NotAQuery),
        }
    }

    /// The value line as the wheel sends it, without its CR.
    pub fn encode_body(&self, out: &mut Vec<u8>) {
        let text = match self {
            Reply::Identity(s) => s.clone(),
            Reply::Position(n) | Reply::PositionCount(n) => n.to_string(),
            Reply::Speed(s) => s.digit().to_string(),
            Reply::Trigger(t) => t.digit().to_string(),
            Reply::Sensors(s) => s.digit().to_string(),
        };
        out.extend_from_slice(text.as_bytes());
    }
}

crate::codec::line_encoding!(Reply, &[TERMINATOR]);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn echoes_match_their_command_only() {
        assert!(is_echo(&Command::SetPosition(3), b"pos=3"));
        assert!(is_echo(&Command::Identify, b"*IDN?"));
        assert!(!is_echo(&Command::SetPosition(3), b"pos=4"));
        assert!(!is_echo(&Command::QueryPosition, b"3"));
    }
}
