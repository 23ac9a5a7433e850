//! Host-to-wheel commands: typed, encoded into a caller's buffer, and parsed back (the
//! simulated wheel's side). The command words are UNCONFIRMED against the manual (see
//! the module docs); each is the one the drivers cited there send.

use std::fmt;

use super::{POSITION_COUNTS, TERMINATOR};
use crate::codec::{Param, Refusal, coded_enum, command_table};

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

command_table! {
    /// One command to the wheel (p. 11's table): a lower-case word, `?` for a query,
    /// `=n` for a value.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum Command, word, input: Option<&str> {
        /// `*idn?`: the identification string.
        Identify = "*idn" query;
        /// `pos=n`: move to position n (1-based). The wheel refuses n outside
        /// 1..=pcount with `CMD_ARG_INVALID` (the twin's model; UNCONFIRMED).
        SetPosition(u8) = "pos" set, read: |v| nonzero(v);
        /// `pos?`: the present position.
        QueryPosition = "pos" query;
        /// `pcount=n`: the number of positions of the mounted wheel, 6 or 12.
        SetPositionCount(u8) = "pcount" set, read: |v| {
            digits(v).and_then(|n| POSITION_COUNTS.contains(&n).then_some(n).ok_or(Refusal::OutOfRange))
        };
        /// `pcount?`.
        QueryPositionCount = "pcount" query;
        /// `speed=n`.
        SetSpeed(Speed) = "speed" set;
        /// `speed?`.
        QuerySpeed = "speed" query;
        /// `trig=n`.
        SetTrigger(TriggerMode) = "trig" set;
        /// `trig?`.
        QueryTrigger = "trig" query;
        /// `sensors=n`.
        SetSensors(SensorMode) = "sensors" set;
        /// `sensors?`.
        QuerySensors = "sensors" query;
        /// `save`: keeps the present settings over a power cycle.
        Save = "save" set;
    }
}

/// A value after `=`: 1 to 3 decimal digits, 0..=255. No `=` at all is another
/// command (`pos` alone is not defined).
fn digits(value: Option<&str>) -> Result<u8, Refusal> {
    let v = value.ok_or(Refusal::Unknown)?;
    crate::number::decimal(v, 3).ok_or(Refusal::Syntax)
}

/// A position: digits, not 0.
fn nonzero(value: Option<&str>) -> Result<u8, Refusal> {
    digits(value).and_then(|n| {
        if n == 0 {
            Err(Refusal::OutOfRange)
        } else {
            Ok(n)
        }
    })
}

impl Param<Option<&str>> for () {
    fn write(&self, _: &mut Vec<u8>) {}
    fn read(value: Option<&str>) -> Result<(), Refusal> {
        value.map_or(Ok(()), |_| Err(Refusal::Unknown))
    }
}

impl Param<Option<&str>> for u8 {
    fn write(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(format!("={self}").as_bytes());
    }
    fn read(value: Option<&str>) -> Result<u8, Refusal> {
        digits(value)
    }
}

/// The digit-coded settings: `=d`.
macro_rules! digit_param {
    ($($t:ty),+) => {$(
        impl Param<Option<&str>> for $t {
            fn write(&self, out: &mut Vec<u8>) {
                <u8 as Param<Option<&str>>>::write(&self.digit(), out);
            }
            fn read(value: Option<&str>) -> Result<$t, Refusal> {
                <$t>::from_digit(digits(value)?).ok_or(Refusal::OutOfRange)
            }
        }
    )+};
}
digit_param!(Speed, TriggerMode, SensorMode);

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
    /// Writes the command without its terminator.
    pub fn encode_body(&self, out: &mut Vec<u8>) {
        self.encode_row(out);
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
        let (word, value) = match text.split_once('=') {
            Some((word, value)) => (word, Some(value)),
            None => (text.as_str(), None),
        };
        let (word, query) = match word.strip_suffix('?') {
            Some(w) if value.is_none() => (w, true),
            _ => (word, false),
        };
        match Command::from_row(word, query, value) {
            Some((_, Ok(c))) => Ok(c),
            None | Some((_, Err(Refusal::Unknown))) => Err(CommandError::NotDefined),
            Some((_, Err(_))) => Err(CommandError::ArgInvalid),
        }
    }
}

impl fmt::Display for Command {
    /// The command as sent, without its terminator.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&String::from_utf8_lossy(&crate::codec::Encode::body(self)))
    }
}
