//! Instrument to host: [`Reply`] lines, read knowing the query they answer.

use std::fmt;

use super::{
    Command, EventStatus, LineFrequency, NAN_VALUE, OVERFLOW_VALUE, REPLY_TERMINATOR, Range,
    StatusWord,
};
use crate::number;

/// Which instrument `*IDN?` named.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Model {
    /// Model 6485 picoammeter.
    K6485,
    /// Model 6487 picoammeter / voltage source: the same ammeter and commands.
    K6487,
}

pub use crate::idn::Identity;

impl Identity {
    /// The model, when the model field names a 6485 or a 6487.
    pub fn picoammeter(&self) -> Option<Model> {
        let m = self.model.to_ascii_uppercase();
        let m = m.trim_start_matches("MODEL").trim();
        match m {
            "6485" => Some(Model::K6485),
            "6487" => Some(Model::K6487),
            _ => None,
        }
    }
}

/// One entry of the error queue, `SYST:ERR?`: `-113,"Undefined header"`; code 0 is
/// `0,"No error"`.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct ScpiError {
    /// The error number (negative: SCPI standard errors; positive: the instrument's).
    pub code: i32,
    /// The message, quotes removed.
    pub message: String,
}

impl ScpiError {
    /// The empty queue's answer.
    pub fn none() -> Self {
        ScpiError {
            code: 0,
            message: "No error".into(),
        }
    }

    /// True for `0,"No error"`.
    pub fn is_none(&self) -> bool {
        self.code == 0
    }
}

impl fmt::Display for ScpiError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{},\"{}\"", self.code, self.message)
    }
}

/// The current element of a reading: a value, or one of the two codes the
/// instrument sends instead (FORMat:ELEMents, p. 13-6). The codes are typed so that
/// no overflow is ever averaged as 9.9E37 A.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Current {
    /// A reading, amps.
    Amps(f64),
    /// `+9.9E37`: overflow (over 1.05 × full scale) or input overvoltage.
    Overflow,
    /// `+9.91E37`: NAN, invalid data.
    Invalid,
}

impl Current {
    /// The value, when it is one.
    pub fn amps(self) -> Option<f64> {
        match self {
            Current::Amps(a) => Some(a),
            _ => None,
        }
    }
}

/// One reading as `FORM:ELEM READ,TIME,STAT` sends it:
/// `+1.234567E-09A,+2.236299E+02,+0.000000E+00`: the current with its unit suffix `A`,
/// the timestamp (seconds since power-on or the last reset, wrapping after 99 999.99 s)
/// and the status word, all in scientific notation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// The current.
    pub current: Current,
    /// The timestamp, seconds.
    pub time_s: f64,
    /// The status word.
    pub status: StatusWord,
}

/// A reply line's content, by the query it answers.
#[derive(Clone, Debug, PartialEq)]
pub enum Reply {
    /// `*IDN?`.
    Identity(Identity),
    /// `*ESR?`.
    EventStatus(EventStatus),
    /// `SYST:ERR?`.
    Error(ScpiError),
    /// `CURR:RANG?`.
    Range(Range),
    /// `SYST:LFR?`.
    LineFrequency(LineFrequency),
    /// `READ?`, `FETC?`.
    Sample(Sample),
}

crate::number::scpi_reply_error! {
    /// Why a reply line could not be understood.
    pub enum ReplyError {
        /// A reading with another number of elements than READ,TIME,STAT.
        #[error("expected 3 elements (READ,TIME,STAT), got {0}")]
        WrongCount(usize),
    }
}

/// Writes `v` as the instrument does: sign, one digit, six decimals, `E`, signed
/// two-digit exponent (`+1.234567E-09`).
pub(crate) fn format_sci(v: f64, out: &mut Vec<u8>) {
    let text = format!("{:.6E}", v.abs());
    let (mantissa, exp) = text.split_once('E').unwrap_or((&text, "0"));
    let exp: i32 = exp.parse().unwrap_or(0);
    let sign = if v.is_sign_negative() && v != 0.0 {
        '-'
    } else {
        '+'
    };
    let esign = if exp < 0 { '-' } else { '+' };
    out.extend_from_slice(format!("{sign}{mantissa}E{esign}{:02}", exp.abs()).as_bytes());
}

/// Classifies a received current value: the overflow and NAN codes compared in the
/// 7 digits they are sent with, so that a value and its re-encoding classify alike.
fn classify(v: f64) -> Current {
    let seven = |x: f64| {
        let mut b = Vec::new();
        format_sci(x, &mut b);
        b
    };
    let s = seven(v.abs());
    if s == seven(OVERFLOW_VALUE) {
        Current::Overflow
    } else if s == seven(NAN_VALUE) {
        Current::Invalid
    } else {
        Current::Amps(v)
    }
}

crate::codec::line_encoding!(Reply, &[REPLY_TERMINATOR]);

impl Reply {
    /// Appends the reply without terminator (what the instrument sends).
    pub fn encode_body(&self, out: &mut Vec<u8>) {
        match self {
            Reply::Identity(id) => out.extend_from_slice(id.to_string().as_bytes()),
            Reply::EventStatus(s) => out.extend_from_slice(s.0.to_string().as_bytes()),
            Reply::Error(e) => out.extend_from_slice(e.to_string().as_bytes()),
            Reply::Range(r) => format_sci(r.amps(), out),
            Reply::LineFrequency(f) => out.extend_from_slice(f.hz().to_string().as_bytes()),
            Reply::Sample(s) => {
                let v = match s.current {
                    Current::Amps(a) => a,
                    Current::Overflow => OVERFLOW_VALUE,
                    Current::Invalid => NAN_VALUE,
                };
                format_sci(v, out);
                out.push(b'A');
                out.push(b',');
                format_sci(s.time_s, out);
                out.push(b',');
                format_sci(f64::from(s.status.0), out);
            }
        }
    }

    /// Parses the reply line (terminator removed) to `command`. Surrounding whitespace
    /// is ignored; numbers in any form (`50`, `+5.000000E+01`); the current's `A`
    /// suffix is optional.
    pub fn parse(command: &Command, line: &[u8]) -> Result<Reply, ReplyError> {
        let line = ReplyError::query_line(command.is_query(), command.header(), line)?;
        let num = |s: &[u8]| number::real(s).map_err(ReplyError::from);
        let int = |s: &[u8], max: f64| number::integer(s, max).map_err(ReplyError::from);
        let reply = match command {
            Command::Identify => {
                Reply::Identity(Identity::parse(line).ok_or(ReplyError::BadValue)?)
            }
            // Exact: an integer in 0..=255.
            Command::EventStatus => Reply::EventStatus(EventStatus(int(line, 255.0)? as u8)),
            Command::NextError => {
                let text = std::str::from_utf8(line).map_err(|_| ReplyError::BadValue)?;
                let (code, message) = text.split_once(',').ok_or(ReplyError::BadValue)?;
                let code: i32 = code.trim().parse().map_err(|_| ReplyError::BadValue)?;
                let message = message.trim();
                let message = message
                    .strip_prefix('"')
                    .and_then(|m| m.strip_suffix('"'))
                    .ok_or(ReplyError::BadValue)?;
                if message.contains('"')
                    || !message.bytes().all(|b| b.is_ascii_graphic() || b == b' ')
                {
                    return Err(ReplyError::BadValue);
                }
                Reply::Error(ScpiError {
                    code,
                    message: message.to_string(),
                })
            }
            Command::QueryRange => {
                let v = num(line)?;
                let r = Range::for_current(v).ok_or(ReplyError::OutOfRange(v))?;
                // Only a full scale itself is an answer.
                if (v - r.amps()).abs() > 1e-6 * r.amps() {
                    return Err(ReplyError::OutOfRange(v));
                }
                Reply::Range(r)
            }
            Command::LineFrequency => {
                let v = int(line, 1000.0)?;
                // Exact: an integer within 0..=1000.
                Reply::LineFrequency(
                    LineFrequency::from_hz(v as u32).ok_or(ReplyError::OutOfRange(v))?,
                )
            }
            Command::Read | Command::Fetch => {
                let fields: Vec<&[u8]> = line.split(|b| *b == b',').collect();
                let [reading, time, status] = fields.as_slice() else {
                    return Err(ReplyError::WrongCount(fields.len()));
                };
                let reading = reading.trim_ascii();
                let reading = reading.strip_suffix(b"A").unwrap_or(reading);
                let current = classify(num(reading)?);
                let time_s = num(time)?;
                // Exact: an integer in 0..=65535.
                let status = StatusWord(int(status, 65535.0)? as u16);
                Reply::Sample(Sample {
                    current,
                    time_s,
                    status,
                })
            }
            _ => return Err(ReplyError::NotAQuery(command.header())),
        };
        Ok(reply)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scientific_format_is_the_instruments() {
        let f = |v: f64| {
            let mut out = Vec::new();
            format_sci(v, &mut out);
            String::from_utf8(out).unwrap()
        };
        assert_eq!(f(1.234567e-9), "+1.234567E-09");
        assert_eq!(f(-2.5e-12), "-2.500000E-12");
        assert_eq!(f(0.0), "+0.000000E+00");
        assert_eq!(f(223.6299), "+2.236299E+02");
        assert_eq!(f(138.0), "+1.380000E+02");
        assert_eq!(f(9.9e37), "+9.900000E+37");
        assert_eq!(f(1e-300), "+1.000000E-300");
    }
}
