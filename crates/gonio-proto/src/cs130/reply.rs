//! Instrument to host: the echo of each statement, and [`Reply`], the answer to a
//! query.

use super::{Command, ErrorCode, REPLY_TERMINATOR, StatusByte};

/// The answer to a query, parsed knowing the query (the answers carry no keyword).
#[derive(Clone, Debug, PartialEq)]
pub enum Reply {
    /// `WAVE?`: the wavelength in the present units (§15.4: `500.01`).
    Wavelength(f64),
    /// `GRAT?`: the grating number, then its lines/mm and label, separated by commas
    /// (`1,1200,UV`): "The response to GRAT? contains three parameters separated by
    /// commas without spaces … grating number, then the lines/mm, then the label"
    /// (Model 74000 command table; the Tango CornerStone130 and oriel-cornerstone-260
    /// drivers read it so). Only the leading number is relied on, and a bare number
    /// is accepted too.
    Grating {
        /// The grating's number.
        number: u8,
        /// Its lines per mm, when answered.
        lines_per_mm: Option<u32>,
        /// Its label, when answered.
        label: Option<String>,
    },
    /// `FILTER?`: the filter wheel's position, 1 to 6; `0` without a wheel (see
    /// [`Command::FilterQuery`]).
    Filter(u8),
    /// `SHUTTER?`: true when open (`O`), false when closed (`C`) (see
    /// [`Command::ShutterQuery`]).
    Shutter(bool),
    /// `STB?`: the status byte (§15.9; [`StatusByte`]).
    Status(StatusByte),
    /// `ERROR?`: the latest error code (§15.9).
    Error(ErrorCode),
    /// `INFO?`: the instrument's description, as sent.
    Info(String),
}

/// Why a line is not the answer to its query, or not the echo of its statement.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ReplyError {
    /// The statement has no answer (a command, not a query).
    #[error("a command has no answer")]
    NotAQuery,
    /// The line is not the number, position or letter the query answers.
    #[error("not a valid answer")]
    BadValue,
    /// The line is not the statement that was sent (the echo, §15.4).
    #[error("not the echo of the statement sent")]
    BadEcho,
}

/// True when `line` (terminator removed) is the echo of `command`: the instrument
/// "echoes back all characters it receives on the RS232 port" (§15.4); case and
/// surrounding blanks are ignored, so a statement typed in lower case still matches.
pub fn is_echo(command: &Command, line: &[u8]) -> bool {
    crate::codec::echoes(command, line.trim_ascii())
}

impl Reply {
    /// `line` (terminator removed, blanks ignored) as the answer to `query`.
    pub fn parse(query: &Command, line: &[u8]) -> Result<Reply, ReplyError> {
        let text = std::str::from_utf8(line).map_err(|_| ReplyError::BadValue)?;
        let text = text.trim_matches(|c: char| c.is_ascii_whitespace());
        let bad = ReplyError::BadValue;
        match query {
            Command::Wave => text
                .parse::<f64>()
                .ok()
                .filter(|v| {
                    v.is_finite()
                        && text
                            .bytes()
                            .all(|b| b.is_ascii_digit() || b"+-.eE".contains(&b))
                })
                .map(Reply::Wavelength)
                .ok_or(bad),
            Command::GratQuery => {
                let mut fields = text.split(',').map(str::trim);
                let number = fields.next().and_then(int::<u8>).ok_or(bad.clone())?;
                let lines_per_mm = match fields.next() {
                    None => None,
                    Some(f) => Some(int::<u32>(f).ok_or(bad.clone())?),
                };
                let label = fields.next().map(str::to_string);
                if fields.next().is_some()
                    || label
                        .as_deref()
                        .is_some_and(|l| !l.is_ascii() || l.contains(','))
                {
                    return Err(bad);
                }
                Ok(Reply::Grating {
                    number,
                    lines_per_mm,
                    label,
                })
            }
            Command::FilterQuery => int::<u8>(text).map(Reply::Filter).ok_or(bad),
            Command::ShutterQuery => match text {
                "O" | "o" => Ok(Reply::Shutter(true)),
                "C" | "c" => Ok(Reply::Shutter(false)),
                _ => Err(bad),
            },
            // Decimal, `32` or `00` (§15.9; Model 74000 table): see StatusByte.
            Command::Stb => StatusByte::parse(text).map(Reply::Status).ok_or(bad),
            Command::Error => int::<u8>(text)
                .map(|v| Reply::Error(ErrorCode(v)))
                .ok_or(bad),
            Command::Info => {
                if text.is_empty() || !text.bytes().all(|b| b.is_ascii_graphic() || b == b' ') {
                    return Err(bad);
                }
                Ok(Reply::Info(text.to_string()))
            }
            _ => Err(ReplyError::NotAQuery),
        }
    }

    /// Appends the answer without terminator, as the twin sends it.
    pub fn encode_body(&self, out: &mut Vec<u8>) {
        let text = match self {
            Reply::Wavelength(v) => format!("{v:.2}"),
            Reply::Grating {
                number,
                lines_per_mm,
                label,
            } => {
                let mut s = number.to_string();
                if let Some(l) = lines_per_mm {
                    s.push_str(&format!(",{l}"));
                    if let Some(label) = label {
                        s.push_str(&format!(",{label}"));
                    }
                }
                s
            }
            Reply::Filter(n) => n.to_string(),
            Reply::Shutter(open) => if *open { "O" } else { "C" }.into(),
            Reply::Status(s) => s.to_string(),
            Reply::Error(e) => e.0.to_string(),
            Reply::Info(s) => s.clone(),
        };
        out.extend_from_slice(text.as_bytes());
    }
}

// Answers end CR LF (§15.3).
crate::codec::line_encoding!(Reply, &[b'\r', REPLY_TERMINATOR]);

/// A plain decimal integer.
fn int<T: std::str::FromStr>(field: &str) -> Option<T> {
    crate::number::decimal(field, usize::MAX)
}
