//! Host to instrument: [`Command`], and the SCPI errors the instrument queues for a
//! command it cannot run.

use super::{EventStatus, FilterType, MIN_NPLC, Range, TERMINATOR};
use crate::number;

/// Most readings one trigger sequence takes, `TRIG:COUN` (Section 8, "Trigger
/// model": 1 to 2048).
pub const MAX_TRIGGER_COUNT: u32 = 2048;

/// A command to the 6485 (SCPI, Sections 12–16 of the manual). Queries answer one
/// line; the rest answer nothing. Encoded in the short form, absolute (each command
/// begins at the root), one per line.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// `*RST`: the reset defaults (IEEE-488.2 common command, Section 12). The session
    /// sets everything it relies on afterwards, so no default is assumed.
    Reset,
    /// `*CLS`: clears the event registers and the error queue.
    Clear,
    /// `*IDN?`: manufacturer, model, serial number, firmware.
    Identify,
    /// `*ESR?`: the standard event status register (reading clears it).
    EventStatus,
    /// `SYST:ERR?`: the oldest entry of the error queue, removed by reading it;
    /// `0,"No error"` when empty.
    NextError,
    /// `SYST:ZCH ON|OFF`: zero check. On, the input is shunted and readings show only
    /// the instrument's own offset (Section 2, "Zero check and zero correct").
    ZeroCheck(bool),
    /// `SYST:ZCOR:ACQ`: take the present (zero-checked) reading as the zero
    /// correction value. Needs zero check on and a reading taken first (`INIT`).
    ZeroCorrectAcquire,
    /// `SYST:ZCOR ON|OFF`: subtract the acquired zero correction value from readings.
    ZeroCorrect(bool),
    /// `CURR:RANG <n>`: the range for an expected current of n amps (Table 4-3).
    SetRange(Range),
    /// `CURR:RANG?`: the range's full scale, amps.
    QueryRange,
    /// `CURR:RANG:AUTO ON|OFF`: the instrument's own autoranging. The session keeps
    /// it off and ranges itself, so that it always knows the range of a reading.
    AutoRange(bool),
    /// `CURR:NPLC <n>`: integration time in power line cycles, 0.01 to 50 (50 Hz) or
    /// 60 (60 Hz) (Table 4-4). The upper limit depends on the line frequency; the
    /// codec checks the widest (60).
    SetNplc(f64),
    /// `AVER:TCON REP|MOV`: the averaging filter type.
    FilterType(FilterType),
    /// `AVER:COUN <n>`: the averaging filter count, 1 to 100 ("a simple average of
    /// one to 100 reading conversions", p. 4-8; [`FILTER_COUNT`](super::FILTER_COUNT)).
    FilterCount(u32),
    /// `AVER ON|OFF`: the averaging filter.
    Filter(bool),
    /// `FORM:ELEM READ,TIME,STAT`: readings carry the current, the timestamp and the
    /// status word (FORMat:ELEMents, p. 13-6). The only element list the codec
    /// writes and reads.
    FormatElements,
    /// `TRIG:COUN <n>`: readings per trigger sequence, 1 to 2048.
    TriggerCount(u32),
    /// `INIT`: take readings (the trigger count) and keep the last for `FETC?`.
    Initiate,
    /// `READ?`: `INIT` then `FETC?`: a fresh reading. It answers only when the
    /// conversion (and the repeat filter's conversions) is done.
    Read,
    /// `FETC?`: the last reading again, without a new conversion.
    Fetch,
    /// `SYST:LFR?`: the line frequency the instrument detected at power-up, 50 or 60.
    LineFrequency,
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
    /// The canonical short-form header (`SYST:ZCH`, `*IDN`), without `?`.
    pub fn header(&self) -> &'static str {
        match self {
            Command::Reset => "*RST",
            Command::Clear => "*CLS",
            Command::Identify => "*IDN",
            Command::EventStatus => "*ESR",
            Command::NextError => "SYST:ERR",
            Command::ZeroCheck(_) => "SYST:ZCH",
            Command::ZeroCorrectAcquire => "SYST:ZCOR:ACQ",
            Command::ZeroCorrect(_) => "SYST:ZCOR",
            Command::SetRange(_) | Command::QueryRange => "CURR:RANG",
            Command::AutoRange(_) => "CURR:RANG:AUTO",
            Command::SetNplc(_) => "CURR:NPLC",
            Command::FilterType(_) => "AVER:TCON",
            Command::FilterCount(_) => "AVER:COUN",
            Command::Filter(_) => "AVER",
            Command::FormatElements => "FORM:ELEM",
            Command::TriggerCount(_) => "TRIG:COUN",
            Command::Initiate => "INIT",
            Command::Read => "READ",
            Command::Fetch => "FETC",
            Command::LineFrequency => "SYST:LFR",
        }
    }

    /// True for queries (written with `?`): exactly the commands that reply.
    pub fn is_query(&self) -> bool {
        matches!(
            self,
            Command::Identify
                | Command::EventStatus
                | Command::NextError
                | Command::QueryRange
                | Command::Read
                | Command::Fetch
                | Command::LineFrequency
        )
    }

    /// Appends the command without terminator (`CURR:RANG 2E-9`, `READ?`).
    pub fn encode_body(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(self.header().as_bytes());
        if self.is_query() {
            out.push(b'?');
        }
        let on_off = |b: bool| if b { " ON" } else { " OFF" };
        match self {
            Command::ZeroCheck(b)
            | Command::ZeroCorrect(b)
            | Command::AutoRange(b)
            | Command::Filter(b) => out.extend_from_slice(on_off(*b).as_bytes()),
            Command::SetRange(r) => {
                // Every full scale is 2 × 10^k: written exactly as the manual's `2E-9`.
                out.extend_from_slice(format!(" 2E{}", i32::from(r.index()) - 9).as_bytes());
            }
            Command::SetNplc(n) => {
                out.push(b' ');
                number::format(*n, out);
            }
            Command::FilterType(t) => {
                out.push(b' ');
                out.extend_from_slice(t.mnemonic().as_bytes());
            }
            Command::FilterCount(n) | Command::TriggerCount(n) => {
                out.extend_from_slice(format!(" {n}").as_bytes());
            }
            Command::FormatElements => out.extend_from_slice(b" READ,TIME,STAT"),
            _ => {}
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
    let header: &'static str = match name.as_str() {
        "*RST" => "*RST",
        "*CLS" => "*CLS",
        "*IDN" => "*IDN",
        "*ESR" => "*ESR",
        "SYST:ERR" => "SYST:ERR",
        "SYST:ZCH" => "SYST:ZCH",
        "SYST:ZCOR:ACQ" => "SYST:ZCOR:ACQ",
        "SYST:ZCOR" => "SYST:ZCOR",
        "CURR:RANG" => "CURR:RANG",
        "CURR:RANG:AUTO" => "CURR:RANG:AUTO",
        "CURR:NPLC" => "CURR:NPLC",
        "AVER:TCON" => "AVER:TCON",
        "AVER:COUN" => "AVER:COUN",
        "AVER" => "AVER",
        "FORM:ELEM" => "FORM:ELEM",
        "TRIG:COUN" => "TRIG:COUN",
        "INIT" => "INIT",
        "READ" => "READ",
        "FETC" => "FETC",
        "SYST:LFR" => "SYST:LFR",
        _ => return Err(unknown()),
    };
    let syntax = || CommandError::Syntax(header);
    let range = || CommandError::OutOfRange(header);
    let boolean = || -> Result<bool, CommandError> {
        match params.to_ascii_uppercase().as_slice() {
            b"ON" | b"1" => Ok(true),
            b"OFF" | b"0" => Ok(false),
            _ => Err(syntax()),
        }
    };
    let num = || number::parse(params).ok_or_else(syntax);
    let count = |lo: u32, hi: u32| -> Result<u32, CommandError> {
        let v = num()?;
        if v.fract() != 0.0 {
            return Err(range());
        }
        if !(f64::from(lo)..=f64::from(hi)).contains(&v) {
            return Err(range());
        }
        // Exact: an integer within lo..=hi.
        Ok(v as u32)
    };
    let none = |c: Command| {
        if params.is_empty() {
            Ok(c)
        } else {
            Err(syntax())
        }
    };
    match (header, query) {
        ("*RST", false) => none(Command::Reset),
        ("*CLS", false) => none(Command::Clear),
        ("*IDN", true) => none(Command::Identify),
        ("*ESR", true) => none(Command::EventStatus),
        ("SYST:ERR", true) => none(Command::NextError),
        ("SYST:ZCH", false) => Ok(Command::ZeroCheck(boolean()?)),
        ("SYST:ZCOR:ACQ", false) => none(Command::ZeroCorrectAcquire),
        ("SYST:ZCOR", false) => Ok(Command::ZeroCorrect(boolean()?)),
        ("CURR:RANG", false) => {
            let v = num()?;
            Ok(Command::SetRange(Range::for_current(v).ok_or_else(range)?))
        }
        ("CURR:RANG", true) => none(Command::QueryRange),
        ("CURR:RANG:AUTO", false) => Ok(Command::AutoRange(boolean()?)),
        ("CURR:NPLC", false) => {
            let v = num()?;
            if !(MIN_NPLC..=60.0).contains(&v) {
                return Err(range());
            }
            Ok(Command::SetNplc(v))
        }
        ("AVER:TCON", false) => match params.to_ascii_uppercase().as_slice() {
            b"REP" | b"REPEAT" => Ok(Command::FilterType(FilterType::Repeat)),
            b"MOV" | b"MOVING" => Ok(Command::FilterType(FilterType::Moving)),
            _ => Err(syntax()),
        },
        ("AVER:COUN", false) => Ok(Command::FilterCount(count(
            *super::FILTER_COUNT.start(),
            *super::FILTER_COUNT.end(),
        )?)),
        ("AVER", false) => Ok(Command::Filter(boolean()?)),
        ("FORM:ELEM", false) => {
            let mut items: Vec<&'static str> = params
                .split(|b| *b == b',')
                .map(|p| element(p.trim_ascii()))
                .collect::<Option<_>>()
                .ok_or_else(syntax)?;
            items.sort_unstable();
            if items == ["READ", "STAT", "TIME"] {
                Ok(Command::FormatElements)
            } else {
                // Other element lists exist (UNIT, VSO on the 6487) but the codec
                // reads only this one.
                Err(syntax())
            }
        }
        ("TRIG:COUN", false) => Ok(Command::TriggerCount(count(1, MAX_TRIGGER_COUNT)?)),
        ("INIT", false) => none(Command::Initiate),
        ("READ", true) => none(Command::Read),
        ("FETC", true) => none(Command::Fetch),
        ("SYST:LFR", true) => none(Command::LineFrequency),
        _ => Err(syntax()),
    }
}

/// A `FORM:ELEM` item in short or long form.
fn element(p: &[u8]) -> Option<&'static str> {
    [("READING", "READ"), ("TIME", "TIME"), ("STATUS", "STAT")]
        .iter()
        .find(|(l, s)| p.eq_ignore_ascii_case(l.as_bytes()) || p.eq_ignore_ascii_case(s.as_bytes()))
        .map(|(_, s)| *s)
}
