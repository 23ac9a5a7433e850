//! Controller to host: [`Reply`] lines, parsed knowing nothing but the line.

use super::command::{address, split};
use super::{ControllerState, ErrorCode, Frame, Param, PositionerErrors, Status, TERMINATOR};
use crate::number;

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
    /// `AC?`, `VA?`, `SL?`, `PA?`, `HT?`, `PW?`…: the parameter's value; also the
    /// numeric lines of a `ZT` dump (`1PW1`, `1AC320.000000`, …, `1PW0`).
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

impl Reply {
    /// Appends the line as a `ZT` dump writes it (terminator included): real values
    /// with six decimals, as in the manual's `1AC320.000000`, whole numbers without.
    pub fn encode_fixed(&self, out: &mut Vec<u8>) {
        match &self.body {
            ReplyBody::Value(p, v) => {
                out.extend_from_slice(self.address.to_string().as_bytes());
                out.extend_from_slice(p.code().as_bytes());
                p.format_fixed(*v, out);
                out.extend_from_slice(TERMINATOR);
            }
            _ => self.encode(out),
        }
    }
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
        let (digits, code, rest) = split(line);
        if digits.is_empty() || digits.len() > 2 {
            return Err(ReplyError::NoAddress);
        }
        let address = address(digits);
        let code = code.ok_or(ReplyError::UnknownCode)?;
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
