//! Instrument to host: [`Reply`] lines, read knowing the query they answer.

use super::buffer::{self, EndOfScan, SampleRate, StoredValue};
use super::{
    Command, ErrorStatus, EventStatus, FilterSlope, Interface, LiaStatus, REPLY_TERMINATOR,
    ReferenceSource, Sensitivity, TimeConstant,
};
use crate::number;

pub use crate::idn::Identity;

impl Identity {
    /// True when the model field is `SR830`.
    pub fn is_sr830(&self) -> bool {
        self.model == "SR830"
    }
}

/// A reply line's content, by the query it answers.
#[derive(Clone, Debug, PartialEq)]
pub enum Reply {
    /// `OUTX?`.
    Interface(Interface),
    /// `FMOD?`.
    ReferenceSource(ReferenceSource),
    /// `FREQ?`: Hz.
    Frequency(f64),
    /// `SLVL?`: V rms.
    Amplitude(f64),
    /// `SENS?`.
    Sensitivity(Sensitivity),
    /// `OFLT?`.
    TimeConstant(TimeConstant),
    /// `OFSL?`.
    Slope(FilterSlope),
    /// `OUTP?`: volts (degrees for θ).
    Output(f64),
    /// `SNAP?`: the values in the order asked.
    Snap(Vec<f64>),
    /// `LIAS?`.
    LiaStatus(LiaStatus),
    /// `ERRS?`.
    ErrorStatus(ErrorStatus),
    /// `*ESR?`.
    EventStatus(EventStatus),
    /// `LIAS? i`, `ERRS? i`, `*ESR? i`: the one bit asked, `0` or `1`.
    Bit(bool),
    /// `*IDN?`.
    Identity(Identity),
    /// `SRAT?`.
    SampleRate(SampleRate),
    /// `SEND?`.
    EndOfScan(EndOfScan),
    /// `SPTS?`: points stored.
    StoredPoints(u16),
    /// `TRCA?`: the points, in the trace's unit.
    TraceAscii(Vec<f64>),
    /// `TRCB?`: the points as IEEE single floats (binary, no terminator).
    TraceBinary(Vec<f32>),
    /// `TRCL?`: the points as stored (binary, no terminator).
    TraceStored(Vec<StoredValue>),
}

crate::number::scpi_reply_error! {
    /// Why a reply line could not be understood.
    pub enum ReplyError {
        /// `SNAP?` returned a different number of values than asked.
        #[error("expected {expected} values, got {got}")]
        WrongCount {
            /// Values asked.
            expected: usize,
            /// Values in the reply.
            got: usize,
        },
    }
}

/// One value, as [`Reply::encode_body`] writes it.
fn format_value(v: f64, out: &mut Vec<u8>) {
    use std::io::Write;
    if v == 0.0 || (1e-4..1e9).contains(&v.abs()) {
        number::format(v, out);
    } else {
        let _ = write!(out, "{v:e}");
    }
}

impl Reply {
    /// Appends the reply as the instrument sends it: the body, then CR, except a binary
    /// trace (`TRCB?`, `TRCL?`), which has no terminator (p. 5-17).
    pub fn encode(&self, out: &mut Vec<u8>) {
        self.encode_body(out);
        if !self.is_binary() {
            out.push(REPLY_TERMINATOR);
        }
    }

    /// The reply as bytes, as [`encode`](Self::encode) writes them.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut v = Vec::new();
        self.encode(&mut v);
        v
    }

    /// True for the binary traces, sent without a terminator.
    pub fn is_binary(&self) -> bool {
        matches!(self, Reply::TraceBinary(_) | Reply::TraceStored(_))
    }
}

impl crate::codec::Encode for Reply {
    fn encode_body(&self, out: &mut Vec<u8>) {
        Reply::encode_body(self, out)
    }
}

impl Reply {
    /// Appends the reply without terminator (what the instrument sends). Values must
    /// be finite; each is the shortest decimal that reads back exactly, with an exponent
    /// outside 1e-4 ≤ |v| < 1e9 so that six values of a `SNAP?` always fit the 256-byte
    /// output buffer. The firmware's own rule ([`Reply::parse`]) is unconfirmed; parsers
    /// accept both.
    pub fn encode_body(&self, out: &mut Vec<u8>) {
        let int = |i: u8, out: &mut Vec<u8>| out.extend_from_slice(i.to_string().as_bytes());
        match self {
            Reply::Interface(i) => int(i.index(), out),
            Reply::ReferenceSource(s) => int(s.index(), out),
            Reply::Sensitivity(s) => int(s.index(), out),
            Reply::TimeConstant(t) => int(t.index(), out),
            Reply::Slope(s) => int(s.index(), out),
            Reply::LiaStatus(s) => int(s.0, out),
            Reply::ErrorStatus(s) => int(s.0, out),
            Reply::EventStatus(s) => int(s.0, out),
            Reply::Bit(b) => int(u8::from(*b), out),
            Reply::Frequency(v) | Reply::Amplitude(v) | Reply::Output(v) => format_value(*v, out),
            Reply::Snap(vs) => {
                for (k, v) in vs.iter().enumerate() {
                    if k > 0 {
                        out.push(b',');
                    }
                    format_value(*v, out);
                }
            }
            Reply::Identity(id) => out.extend_from_slice(id.to_string().as_bytes()),
            Reply::SampleRate(r) => int(r.index(), out),
            Reply::EndOfScan(e) => int(e.index(), out),
            Reply::StoredPoints(n) => out.extend_from_slice(n.to_string().as_bytes()),
            Reply::TraceAscii(vs) => {
                for v in vs {
                    format_value(*v, out);
                    out.push(b',');
                }
            }
            Reply::TraceBinary(vs) => {
                for v in vs {
                    out.extend_from_slice(&v.to_le_bytes());
                }
            }
            Reply::TraceStored(vs) => {
                for v in vs {
                    out.extend_from_slice(&v.to_bytes());
                }
            }
        }
    }

    /// Parses the reply line (terminator removed) to `command`. Surrounding
    /// whitespace is ignored. Floats are read in any of the forms the firmware is
    /// seen to print (`-1.01026`, `1000.00`, `-4.17234e-007`; its rule is not in the
    /// manual); indices and status bytes must be integers in their range.
    pub fn parse(command: &Command, line: &[u8]) -> Result<Reply, ReplyError> {
        // A binary trace is its bytes, untrimmed: 4 a point, no terminator (p. 5-17).
        let wrong = |expected: u16| ReplyError::WrongCount {
            expected: usize::from(expected),
            got: line.len() / buffer::POINT_BYTES,
        };
        match command {
            Command::TraceBinary(r) if line.len() == r.binary_len() => {
                // The instrument stores finite values only.
                let v = buffer::decode_trcb(line)
                    .filter(|v| v.iter().all(|x| x.is_finite()))
                    .ok_or(ReplyError::BadValue)?;
                return Ok(Reply::TraceBinary(v));
            }
            Command::TraceStored(r) if line.len() == r.binary_len() => {
                let v = buffer::decode_trcl(line).ok_or(ReplyError::BadValue)?;
                return Ok(Reply::TraceStored(v));
            }
            Command::TraceBinary(r) | Command::TraceStored(r) => return Err(wrong(r.count)),
            _ => {}
        }
        let line = ReplyError::query_line(command.is_query(), command.mnemonic(), line)?;
        let num = |s: &[u8]| number::real(s).map_err(ReplyError::from);
        // Exact: an integral value in 0..=max.
        let int = |max: u8| Ok::<_, ReplyError>(number::integer(line, f64::from(max))? as u8);
        let out_of_range = |i: u8| ReplyError::OutOfRange(f64::from(i));
        let reply = match command {
            Command::QueryInterface => {
                let i = int(1)?;
                Reply::Interface(Interface::from_index(i).ok_or(out_of_range(i))?)
            }
            Command::QueryReferenceSource => {
                let i = int(1)?;
                Reply::ReferenceSource(ReferenceSource::from_index(i).ok_or(out_of_range(i))?)
            }
            Command::QueryFrequency => Reply::Frequency(num(line)?),
            Command::QueryAmplitude => Reply::Amplitude(num(line)?),
            Command::QuerySensitivity => {
                let i = int(Sensitivity::COUNT - 1)?;
                Reply::Sensitivity(Sensitivity::new(i).ok_or(out_of_range(i))?)
            }
            Command::QueryTimeConstant => {
                let i = int(TimeConstant::COUNT - 1)?;
                Reply::TimeConstant(TimeConstant::new(i).ok_or(out_of_range(i))?)
            }
            Command::QuerySlope => {
                let i = int(3)?;
                Reply::Slope(FilterSlope::from_index(i).ok_or(out_of_range(i))?)
            }
            Command::ReadOutput(_) => Reply::Output(num(line)?),
            Command::Snap(p) => {
                let values = line
                    .split(|b| *b == b',')
                    .map(num)
                    .collect::<Result<Vec<f64>, _>>()?;
                let expected = p.as_slice().len();
                if values.len() != expected {
                    return Err(ReplyError::WrongCount {
                        expected,
                        got: values.len(),
                    });
                }
                Reply::Snap(values)
            }
            Command::LiaStatus(Some(_))
            | Command::ErrorStatus(Some(_))
            | Command::EventStatus(Some(_)) => Reply::Bit(int(1)? == 1),
            Command::LiaStatus(None) => Reply::LiaStatus(LiaStatus(int(255)?)),
            Command::ErrorStatus(None) => Reply::ErrorStatus(ErrorStatus(int(255)?)),
            Command::EventStatus(None) => Reply::EventStatus(EventStatus(int(255)?)),
            Command::Identify => {
                Reply::Identity(Identity::parse(line).ok_or(ReplyError::BadValue)?)
            }
            Command::QuerySampleRate => {
                let i = int(14)?;
                Reply::SampleRate(SampleRate::from_index(i).ok_or(out_of_range(i))?)
            }
            Command::QueryEndOfScan => {
                let i = int(1)?;
                Reply::EndOfScan(EndOfScan::from_index(i).ok_or(out_of_range(i))?)
            }
            Command::StoredPoints => {
                let n = number::integer(line, f64::from(buffer::BUFFER_POINTS))?;
                // Exact: an integral value in 0..=16383.
                Reply::StoredPoints(n as u16)
            }
            Command::TraceAscii(r) => {
                let body = line.strip_suffix(b",").unwrap_or(line);
                let values = body
                    .split(|b| *b == b',')
                    .map(num)
                    .collect::<Result<Vec<f64>, _>>()?;
                if values.len() != usize::from(r.count) {
                    return Err(ReplyError::WrongCount {
                        expected: usize::from(r.count),
                        got: values.len(),
                    });
                }
                Reply::TraceAscii(values)
            }
            _ => return Err(ReplyError::NotAQuery(command.mnemonic())),
        };
        Ok(reply)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reply_values_use_an_exponent_only_outside_the_plain_range() {
        let f = |v: f64| {
            let mut out = Vec::new();
            format_value(v, &mut out);
            String::from_utf8(out).unwrap()
        };
        assert_eq!(f(0.951359), "0.951359");
        assert_eq!(f(-1.01026), "-1.01026");
        assert_eq!(f(1000.0), "1000");
        assert_eq!(f(0.0), "0");
        assert_eq!(f(-4.17234e-7), "-4.17234e-7");
        assert_eq!(f(1e-300), "1e-300");
        assert_eq!(f(2.5e12), "2.5e12");
    }
}
