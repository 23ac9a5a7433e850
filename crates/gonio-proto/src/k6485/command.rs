//! Host to instrument: [`Command`], and the SCPI errors the instrument queues for a
//! command it cannot run.

use std::ops::RangeInclusive;

use super::{EventStatus, FILTER_COUNT, FilterType, MIN_NPLC, Range, TERMINATOR};
use crate::codec::{Param, Refusal, command_table};
use crate::number;

/// Most readings one trigger sequence takes, `TRIG:COUN` (Section 8, "Trigger
/// model": 1 to 2048).
pub const MAX_TRIGGER_COUNT: u32 = 2048;

command_table! {
    /// A command to the 6485 (SCPI, Sections 12–16 of the manual). Queries answer one
    /// line; the rest answer nothing. Encoded in the short form, absolute (each command
    /// begins at the root), one per line.
    #[derive(Clone, Debug, PartialEq)]
    pub enum Command, header, input: &[u8] {
        /// `*RST`: the reset defaults (IEEE-488.2 common command, Section 12). The session
        /// sets everything it relies on afterwards, so no default is assumed.
        Reset = "*RST" set;
        /// `*CLS`: clears the event registers and the error queue.
        Clear = "*CLS" set;
        /// `*IDN?`: manufacturer, model, serial number, firmware.
        Identify = "*IDN" query;
        /// `*ESR?`: the standard event status register (reading clears it).
        EventStatus = "*ESR" query;
        /// `SYST:ERR?`: the oldest entry of the error queue, removed by reading it;
        /// `0,"No error"` when empty.
        NextError = "SYST:ERR" query;
        /// `SYST:ZCH ON|OFF`: zero check. On, the input is shunted and readings show only
        /// the instrument's own offset (Section 2, "Zero check and zero correct").
        ZeroCheck(bool) = "SYST:ZCH" set;
        /// `SYST:ZCOR:ACQ`: take the present (zero-checked) reading as the zero
        /// correction value. Needs zero check on and a reading taken first (`INIT`).
        ZeroCorrectAcquire = "SYST:ZCOR:ACQ" set;
        /// `SYST:ZCOR ON|OFF`: subtract the acquired zero correction value from readings.
        ZeroCorrect(bool) = "SYST:ZCOR" set;
        /// `CURR:RANG <n>`: the range for an expected current of n amps (Table 4-3).
        SetRange(Range) = "CURR:RANG" set;
        /// `CURR:RANG?`: the range's full scale, amps.
        QueryRange = "CURR:RANG" query;
        /// `CURR:RANG:AUTO ON|OFF`: the instrument's own autoranging. The session keeps
        /// it off and ranges itself, so that it always knows the range of a reading.
        AutoRange(bool) = "CURR:RANG:AUTO" set;
        /// `CURR:NPLC <n>`: integration time in power line cycles, 0.01 to 50 (50 Hz) or
        /// 60 (60 Hz) (Table 4-4). The upper limit depends on the line frequency; the
        /// codec checks the widest (60).
        SetNplc(f64) = "CURR:NPLC" set, read: |p| {
            let v = f64::read(p)?;
            (MIN_NPLC..=60.0).contains(&v).then_some(v).ok_or(Refusal::OutOfRange)
        };
        /// `AVER:TCON REP|MOV`: the averaging filter type.
        FilterType(FilterType) = "AVER:TCON" set;
        /// `AVER:COUN <n>`: the averaging filter count, [`FILTER_COUNT`](super::FILTER_COUNT).
        FilterCount(u32) = "AVER:COUN" set, read: |p| count(p, FILTER_COUNT);
        /// `AVER ON|OFF`: the averaging filter.
        Filter(bool) = "AVER" set;
        /// `FORM:ELEM READ,TIME,STAT`: readings carry the current, the timestamp and the
        /// status word (FORMat:ELEMents, p. 13-6). The only element list the codec
        /// writes and reads.
        FormatElements = "FORM:ELEM" set, read: format_elements;
        /// `TRIG:COUN <n>`: readings per trigger sequence, 1 to 2048.
        TriggerCount(u32) = "TRIG:COUN" set, read: |p| count(p, 1..=MAX_TRIGGER_COUNT);
        /// `INIT`: take readings (the trigger count) and keep the last for `FETC?`.
        Initiate = "INIT" set;
        /// `READ?`: `INIT` then `FETC?`: a fresh reading. It answers only when the
        /// conversion (and the repeat filter's conversions) is done.
        Read = "READ" query;
        /// `FETC?`: the last reading again, without a new conversion.
        Fetch = "FETC" query;
        /// `SYST:LFR?`: the line frequency the instrument detected at power-up, 50 or 60.
        LineFrequency = "SYST:LFR" query;
    }
}

impl Param<&[u8]> for () {
    fn write(&self, _: &mut Vec<u8>) {}
    fn read(params: &[u8]) -> Result<(), Refusal> {
        params.is_empty().then_some(()).ok_or(Refusal::Syntax)
    }
}

/// `ON|OFF`, read also as `1|0`.
impl Param<&[u8]> for bool {
    fn write(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(if *self { b" ON" } else { b" OFF" });
    }
    fn read(params: &[u8]) -> Result<bool, Refusal> {
        match params.to_ascii_uppercase().as_slice() {
            b"ON" | b"1" => Ok(true),
            b"OFF" | b"0" => Ok(false),
            _ => Err(Refusal::Syntax),
        }
    }
}

impl Param<&[u8]> for f64 {
    fn write(&self, out: &mut Vec<u8>) {
        out.push(b' ');
        number::format(*self, out);
    }
    fn read(params: &[u8]) -> Result<f64, Refusal> {
        number::parse(params).ok_or(Refusal::Syntax)
    }
}

impl Param<&[u8]> for u32 {
    fn write(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(format!(" {self}").as_bytes());
    }
    fn read(params: &[u8]) -> Result<u32, Refusal> {
        count(params, 0..=u32::MAX)
    }
}

/// The range for an expected current; every full scale is 2 × 10^k, written exactly
/// as the manual's `2E-9`.
impl Param<&[u8]> for Range {
    fn write(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(format!(" 2E{}", i32::from(self.index()) - 9).as_bytes());
    }
    fn read(params: &[u8]) -> Result<Range, Refusal> {
        Range::for_current(f64::read(params)?).ok_or(Refusal::OutOfRange)
    }
}

impl Param<&[u8]> for FilterType {
    fn write(&self, out: &mut Vec<u8>) {
        out.push(b' ');
        out.extend_from_slice(self.mnemonic().as_bytes());
    }
    fn read(params: &[u8]) -> Result<FilterType, Refusal> {
        match params.to_ascii_uppercase().as_slice() {
            b"REP" | b"REPEAT" => Ok(FilterType::Repeat),
            b"MOV" | b"MOVING" => Ok(FilterType::Moving),
            _ => Err(Refusal::Syntax),
        }
    }
}

/// An integer count within `range`, in any number form.
fn count(params: &[u8], range: RangeInclusive<u32>) -> Result<u32, Refusal> {
    let v = f64::read(params)?;
    let range = f64::from(*range.start())..=f64::from(*range.end());
    if v.fract() != 0.0 || !range.contains(&v) {
        return Err(Refusal::OutOfRange);
    }
    // Exact: an integer within the range.
    Ok(v as u32)
}

/// `READ,TIME,STAT` in any order and form. Other element lists exist (UNIT, VSO on
/// the 6487) but the codec reads only this one.
fn format_elements(params: &[u8]) -> Result<(), Refusal> {
    let mut items: Vec<&'static str> = params
        .split(|b| *b == b',')
        .map(|p| element(p.trim_ascii()))
        .collect::<Option<_>>()
        .ok_or(Refusal::Syntax)?;
    items.sort_unstable();
    (items == ["READ", "STAT", "TIME"])
        .then_some(())
        .ok_or(Refusal::Syntax)
}

/// Why a received command is refused: the SCPI error the instrument queues (read with
/// `SYST:ERR?`) and the `*ESR?` bit it sets. Set commands are refused silently; a
/// refused query sends no reply.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    /// A header the instrument does not know: −113 "Undefined header" (CME).
    #[error("unknown command {0:?}")]
    Unknown(String),
    /// A known header used wrongly: a missing, extra or non-numeric parameter, a query
    /// form it lacks: −109 "Missing parameter" or −104 "Data type error" reported as
    /// −102 "Syntax error" here (CME); the exact code is not modelled.
    #[error("{0}: syntax error (query form, parameter count or type)")]
    Syntax(&'static str),
    /// A parameter outside its range: −222 "Parameter data out of range" (EXE).
    #[error("{0}: parameter out of range")]
    OutOfRange(&'static str),
}

impl CommandError {
    /// The SCPI error number the instrument queues.
    pub fn code(&self) -> i32 {
        match self {
            CommandError::Unknown(_) => -113,
            CommandError::Syntax(_) => -102,
            CommandError::OutOfRange(_) => -222,
        }
    }

    /// The SCPI error message (the standard's text).
    pub fn message(&self) -> &'static str {
        match self {
            CommandError::Unknown(_) => "Undefined header",
            CommandError::Syntax(_) => "Syntax error",
            CommandError::OutOfRange(_) => "Parameter data out of range",
        }
    }

    /// The `*ESR?` bit it sets: CME for command errors, EXE for execution errors.
    pub fn event_status(&self) -> EventStatus {
        match self {
            CommandError::Unknown(_) | CommandError::Syntax(_) => EventStatus(EventStatus::CME),
            CommandError::OutOfRange(_) => EventStatus(EventStatus::EXE),
        }
    }
}

crate::codec::line_encoding!(Command, TERMINATOR);

impl Command {
    /// Appends the command without terminator (`CURR:RANG 2E-9`, `READ?`).
    pub fn encode_body(&self, out: &mut Vec<u8>) {
        self.encode_row(out);
        if let Command::FormatElements = self {
            out.extend_from_slice(b" READ,TIME,STAT");
        }
    }

    /// Parses one command (no `;`, no terminator) as the instrument does: case
    /// ignored, short or long keywords (`SYST:ZCH`, `:system:zcheck`), the optional
    /// `SENS` root and `STAT` leaf, `ON|OFF|1|0` for booleans.
    pub fn parse(text: &[u8]) -> Result<Command, CommandError> {
        parse_one(text)
    }
}

/// Parses a received line (terminator removed) into its commands, in order:
/// `;`-separated, empty ones skipped; `\r` and `\n` inside also separate. Each command
/// stands alone, rooted (the codec never writes SCPI's relative paths after `;`, and
/// refuses them rather than guess).
pub fn parse_line(line: &[u8]) -> Vec<Result<Command, CommandError>> {
    crate::codec::parse_commands(line, |s| {
        let s = s.trim_ascii();
        (!s.is_empty()).then(|| parse_one(s))
    })
}

/// SCPI keywords: long form, short form. A node matches either, case ignored.
const KEYWORDS: [(&str, &str); 22] = [
    ("SYSTEM", "SYST"),
    ("ZCHECK", "ZCH"),
    ("ZCORRECT", "ZCOR"),
    ("ACQUIRE", "ACQ"),
    ("CURRENT", "CURR"),
    ("RANGE", "RANG"),
    ("AUTO", "AUTO"),
    ("NPLCYCLES", "NPLC"),
    ("AVERAGE", "AVER"),
    ("TCONTROL", "TCON"),
    ("COUNT", "COUN"),
    ("STATE", "STAT"),
    ("FORMAT", "FORM"),
    ("ELEMENTS", "ELEM"),
    ("TRIGGER", "TRIG"),
    ("INITIATE", "INIT"),
    ("READ", "READ"),
    ("FETCH", "FETC"),
    ("ERROR", "ERR"),
    ("LFREQUENCY", "LFR"),
    ("SENSE", "SENS"),
    ("NEXT", "NEXT"),
];

/// The short form of a node, if it is a keyword in either form.
fn keyword(node: &[u8]) -> Option<&'static str> {
    KEYWORDS
        .iter()
        .find(|(long, short)| {
            node.eq_ignore_ascii_case(long.as_bytes())
                || node.eq_ignore_ascii_case(short.as_bytes())
        })
        .map(|(_, short)| *short)
}

/// The canonical header of short-form nodes: the optional `SENS` root, `STAT` leaf and
/// `NEXT` (of `SYST:ERR:NEXT`) removed, joined by `:`.
fn canonical(nodes: &[&'static str]) -> String {
    let mut v: Vec<&str> = nodes.to_vec();
    // `[:SENSe]` is optional before CURR and AVER.
    if v.first() == Some(&"SENS") {
        v.remove(0);
    }
    // `[:STATe]` is optional at the end of the on/off commands.
    if v.len() > 1 && v.last() == Some(&"STAT") {
        v.pop();
    }
    // `SYST:ERR[:NEXT]?`.
    if v == ["SYST", "ERR", "NEXT"] {
        v.pop();
    }
    v.join(":")
}

fn parse_one(text: &[u8]) -> Result<Command, CommandError> {
    let text = text.trim_ascii();
    let unknown = || CommandError::Unknown(String::from_utf8_lossy(text).into_owned());
    let split = text
        .iter()
        .position(|b| b.is_ascii_whitespace())
        .unwrap_or(text.len());
    let (head, params) = text.split_at(split);
    let params = params.trim_ascii();
    let (head, query) = match head.strip_suffix(b"?") {
        Some(h) => (h, true),
        None => (head, false),
    };
    let name: String = if head.first() == Some(&b'*') {
        String::from_utf8_lossy(head).to_ascii_uppercase()
    } else {
        let head = head.strip_prefix(b":").unwrap_or(head);
        let nodes = head
            .split(|b| *b == b':')
            .map(keyword)
            .collect::<Option<Vec<_>>>()
            .ok_or_else(unknown)?;
        canonical(&nodes)
    };
    // The header as a `&'static str` for errors.
    let header = *Command::MNEMONICS
        .iter()
        .find(|h| **h == name)
        .ok_or_else(unknown)?;
    match Command::from_row(header, query, params) {
        Some((_, Ok(command))) => Ok(command),
        Some((_, Err(Refusal::OutOfRange))) => Err(CommandError::OutOfRange(header)),
        _ => Err(CommandError::Syntax(header)),
    }
}

/// A `FORM:ELEM` item in short or long form.
fn element(p: &[u8]) -> Option<&'static str> {
    [("READING", "READ"), ("TIME", "TIME"), ("STATUS", "STAT")]
        .iter()
        .find(|(l, s)| p.eq_ignore_ascii_case(l.as_bytes()) || p.eq_ignore_ascii_case(s.as_bytes()))
        .map(|(_, s)| *s)
}
