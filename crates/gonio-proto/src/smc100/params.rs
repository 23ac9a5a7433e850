//! A controller's configuration as its `ZT` dump lists it ([`Smc100Parameters`]), and
//! the reading of a dump line by line ([`DumpReader`]).
//!
//! The dump (manual, ZT command, p. 67) is a script: it opens with `nnPW1`, names the
//! stage with `nnIDxx`, gives one `nnAAvalue` line per configuration parameter in
//! alphabetical order of its command, and closes. How it closes, the sources
//! disagree: the manual's only example ends with a second `nnPW1`; hvl_ccb's
//! SMC100PP driver, written against real controllers, requires `nnPW0` (which, sent
//! back, would also save what the lines before set). Either ends a dump here. A CC
//! controller lists parameters a PP does not have (`KP`, `SC`, `SU`…); they are kept
//! as text in [`Smc100Parameters::other`], so a dump from either model reads.

use super::{Param, Reply, ReplyBody, ReplyError, TERMINATOR};

/// A controller's configuration parameters, from its `ZT` dump.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Smc100Parameters {
    /// The stage name (`ID`).
    pub stage: String,
    /// Every numeric parameter this codec names, in the order of the dump.
    pub values: Vec<(Param, f64)>,
    /// The dump's other lines, without the address (a CC controller's `KP0.5`), in
    /// order: kept rather than refused, since they are the controller's own.
    pub other: Vec<String>,
}

impl Smc100Parameters {
    /// The value of `param`, if the dump listed it.
    pub fn get(&self, param: Param) -> Option<f64> {
        self.values.iter().find(|(p, _)| *p == param).map(|e| e.1)
    }

    /// Sets `param` to `value`, where the dump listed it or at the end.
    pub fn set(&mut self, param: Param, value: f64) {
        match self.values.iter_mut().find(|(p, _)| *p == param) {
            Some(e) => e.1 = value,
            None => self.values.push((param, value)),
        }
    }

    /// Appends the dump a controller at `address` sends for these parameters, every
    /// line with its terminator: `PW1`, `ID`, the values (six decimals for reals), the
    /// other lines, `PW0`.
    pub fn encode_dump(&self, address: u8, out: &mut Vec<u8>) {
        let line = |body| Reply { address, body };
        line(ReplyBody::Value(Param::ConfigurationMode, 1.0)).encode(out);
        line(ReplyBody::StageId(self.stage.clone())).encode(out);
        for (p, v) in &self.values {
            line(ReplyBody::Value(*p, *v)).encode_fixed(out);
        }
        for text in &self.other {
            out.extend_from_slice(address.to_string().as_bytes());
            out.extend_from_slice(text.as_bytes());
            out.extend_from_slice(TERMINATOR);
        }
        line(ReplyBody::Value(Param::ConfigurationMode, 0.0)).encode(out);
    }

    /// Reads a whole dump from `address`, given as lines without terminators.
    pub fn parse_dump<'a>(
        address: u8,
        lines: impl IntoIterator<Item = &'a [u8]>,
    ) -> Result<Smc100Parameters, DumpError> {
        let mut reader = DumpReader::new(address);
        for line in lines {
            if let Some(done) = reader.push(line)? {
                return Ok(done);
            }
        }
        Err(DumpError::Incomplete)
    }
}

/// Why a `ZT` dump could not be read.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DumpError {
    /// A line inside the dump that does not parse.
    #[error("bad line in the ZT dump: {0}")]
    BadLine(ReplyError),
    /// A line inside the dump from another controller.
    #[error("line from controller {0} inside the ZT dump")]
    OtherAddress(u8),
    /// A second `ID` line, or a line after `PW1` that a dump never holds (`TS`, `TE`).
    #[error("unexpected line {0:?} in the ZT dump")]
    Unexpected(String),
    /// The lines ended before the closing `PW0` (or `PW1`).
    #[error("the ZT dump ended before its closing PW0 (or PW1)")]
    Incomplete,
}

/// Reads a `ZT` dump one line at a time, as the lines arrive. Lines before the dump's
/// `PW1` answer earlier commands (late replies) and are skipped.
#[derive(Clone, Debug)]
pub struct DumpReader {
    address: u8,
    started: bool,
    params: Smc100Parameters,
}

impl DumpReader {
    /// A reader of the dump of the controller at `address`.
    pub fn new(address: u8) -> Self {
        DumpReader {
            address,
            started: false,
            params: Smc100Parameters::default(),
        }
    }

    /// True once the dump's `PW1` has been read.
    pub fn started(&self) -> bool {
        self.started
    }

    /// Takes one line (terminator removed): `Ok(Some(_))` at the dump's closing line
    /// (`PW0`, or a second `PW1` as in the manual's example), `Ok(None)` while it goes
    /// on (or before it began), `Err` for a line that cannot belong to it.
    pub fn push(&mut self, line: &[u8]) -> Result<Option<Smc100Parameters>, DumpError> {
        let reply = Reply::parse(line);
        if !self.started {
            if let Ok(Reply {
                address,
                body: ReplyBody::Value(Param::ConfigurationMode, v),
            }) = reply
                && address == self.address
                && v == 1.0
            {
                self.started = true;
            }
            return Ok(None);
        }
        let reply = match reply {
            Ok(r) => r,
            Err(ReplyError::UnknownCode | ReplyError::BadValue) => {
                return self.other(line).map(|()| None);
            }
            Err(e) => return Err(DumpError::BadLine(e)),
        };
        if reply.address != self.address {
            return Err(DumpError::OtherAddress(reply.address));
        }
        match reply.body {
            ReplyBody::Value(Param::ConfigurationMode, v) if v == 0.0 || v == 1.0 => {
                self.started = false;
                Ok(Some(std::mem::take(&mut self.params)))
            }
            ReplyBody::StageId(name) if self.params.stage.is_empty() => {
                self.params.stage = name;
                Ok(None)
            }
            ReplyBody::Value(p, v) if p.is_configuration() => {
                self.params.values.push((p, v));
                Ok(None)
            }
            _ => Err(DumpError::Unexpected(String::from_utf8_lossy(line).into())),
        }
    }

    /// A line this codec has no name for: kept as text when it is this controller's.
    fn other(&mut self, line: &[u8]) -> Result<(), DumpError> {
        let digits = line.iter().take_while(|b| b.is_ascii_digit()).count();
        let address = std::str::from_utf8(&line[..digits])
            .ok()
            .and_then(|a| a.parse::<u8>().ok());
        let text = std::str::from_utf8(&line[digits..]).ok();
        match (address, text) {
            (Some(a), Some(t)) if a == self.address && t.len() >= 2 && t.is_ascii() => {
                if t.bytes().any(|b| b.is_ascii_control()) {
                    return Err(DumpError::Unexpected(t.into()));
                }
                self.params.other.push(t.to_string());
                Ok(())
            }
            (Some(a), Some(_)) if a != self.address => Err(DumpError::OtherAddress(a)),
            _ => Err(DumpError::Unexpected(String::from_utf8_lossy(line).into())),
        }
    }
}
