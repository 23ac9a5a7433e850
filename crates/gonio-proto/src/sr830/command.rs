//! Host to instrument: [`Command`], multi-command lines, and the errors the instrument
//! flags for a command it cannot run.

use super::buffer::{DisplayDef, EndOfScan, SampleRate, TraceChannel, TraceRange};
use super::{EventStatus, FilterSlope, Sensitivity, TERMINATOR, TimeConstant};
use crate::codec::{Param, Refusal, coded_enum, command_table};
use crate::number;

coded_enum! {
    /// Which interface replies go to, `OUTX` (p. 5-10). Both always listen.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum Interface: u8, index / from_index {
        /// `OUTX 0`: RS-232. A program on the serial port must send this first.
        Rs232 = 0,
        /// `OUTX 1`: GPIB, the factory default.
        Gpib = 1,
    }
}

coded_enum! {
    /// The reference source, `FMOD` (manual, FMOD).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum ReferenceSource: u8, index / from_index {
        /// `FMOD 0`: external reference input.
        External = 0,
        /// `FMOD 1`: internal oscillator (the `*RST` default).
        Internal = 1,
    }
}

coded_enum! {
    /// The quantity `OUTP? i` reads (manual, OUTP?): volts for X, Y, R; degrees for θ.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum Output: u8, code / from_code {
        /// 1: in-phase component X, volts.
        X = 1,
        /// 2: quadrature component Y, volts.
        Y = 2,
        /// 3: magnitude R, volts.
        R = 3,
        /// 4: phase θ, degrees.
        Theta = 4,
    }
}

coded_enum! {
    /// A value `SNAP?` can read (manual, SNAP?): all of one call are taken at one instant
    /// (X with Y, and R with θ, exactly; the two pairs about 10 µs apart).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum SnapParam: u8, code / from_code {
        /// 1: X, volts.
        X = 1,
        /// 2: Y, volts.
        Y = 2,
        /// 3: R, volts.
        R = 3,
        /// 4: θ, degrees.
        Theta = 4,
        /// 5: Aux In 1, volts.
        AuxIn1 = 5,
        /// 6: Aux In 2, volts.
        AuxIn2 = 6,
        /// 7: Aux In 3, volts.
        AuxIn3 = 7,
        /// 8: Aux In 4, volts.
        AuxIn4 = 8,
        /// 9: reference frequency, Hz.
        Frequency = 9,
        /// 10: CH1 display.
        Ch1Display = 10,
        /// 11: CH2 display.
        Ch2Display = 11,
    }
}

/// The 2 to 6 values of one `SNAP?`, in the order they are asked and returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SnapParams {
    params: [SnapParam; SnapParams::MAX],
    len: u8,
}

impl SnapParams {
    /// Fewest values one `SNAP?` takes.
    pub const MIN: usize = 2;
    /// Most values one `SNAP?` takes.
    pub const MAX: usize = 6;
    /// `SNAP? 1,2`: X and Y, the pair a magnitude reading needs.
    pub const XY: SnapParams = SnapParams {
        // Unused entries are always X, so that derived equality ignores them.
        params: [
            SnapParam::X,
            SnapParam::Y,
            SnapParam::X,
            SnapParam::X,
            SnapParam::X,
            SnapParam::X,
        ],
        len: 2,
    };

    /// The list, if it has 2 to 6 entries (repeats are allowed, as on the instrument).
    pub fn new(params: &[SnapParam]) -> Option<Self> {
        if !(Self::MIN..=Self::MAX).contains(&params.len()) {
            return None;
        }
        let mut a = [SnapParam::X; Self::MAX];
        a[..params.len()].copy_from_slice(params);
        Some(SnapParams {
            params: a,
            len: u8::try_from(params.len()).ok()?,
        })
    }

    /// The parameters.
    pub fn as_slice(&self) -> &[SnapParam] {
        &self.params[..usize::from(self.len)]
    }
}

/// A bit number 0..=7 of a status byte, for queries of one bit (`LIAS? 2`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct BitIndex(u8);

impl BitIndex {
    /// The bit number, if it is 0..=7.
    pub fn new(bit: u8) -> Option<Self> {
        (bit < 8).then_some(BitIndex(bit))
    }

    /// The bit number.
    pub fn get(self) -> u8 {
        self.0
    }
}

command_table! {
    /// A command to the SR830 (manual ch. 5's command list): a four-character
    /// mnemonic, `?` for a query, then comma-separated parameters. Queries answer one
    /// line; the rest answer nothing.
    #[derive(Clone, Debug, PartialEq)]
    pub enum Command, mnemonic, input: &[f64] {
        /// `OUTX i`: send replies to this interface (p. 5-10).
        SetInterface(Interface) = "OUTX" set;
        /// `OUTX?`: which interface replies go to.
        QueryInterface = "OUTX" query;
        /// `FMOD i`: reference source (manual, FMOD).
        SetReferenceSource(ReferenceSource) = "FMOD" set;
        /// `FMOD?`.
        QueryReferenceSource = "FMOD" query;
        /// `FREQ f`: internal oscillator frequency, 0.001 ≤ f ≤ 102000 Hz (manual, FREQ). The
        /// limit harmonic × f ≤ 102 kHz depends on the instrument's state; it checks that.
        SetFrequency(f64) = "FREQ" set, read: |v| bounded(v, 0.001, 102_000.0);
        /// `FREQ?`: reference frequency, Hz, in any reference mode.
        QueryFrequency = "FREQ" query;
        /// `SLVL x`: sine output amplitude, 0.004 ≤ x ≤ 5.000 V rms (manual, SLVL).
        SetAmplitude(f64) = "SLVL" set, read: |v| bounded(v, 0.004, 5.0);
        /// `SLVL?`.
        QueryAmplitude = "SLVL" query;
        /// `SENS i`: sensitivity (SENS table).
        SetSensitivity(Sensitivity) = "SENS" set;
        /// `SENS?`.
        QuerySensitivity = "SENS" query;
        /// `OFLT i`: time constant (OFLT table).
        SetTimeConstant(TimeConstant) = "OFLT" set;
        /// `OFLT?`.
        QueryTimeConstant = "OFLT" query;
        /// `OFSL i`: filter slope.
        SetSlope(FilterSlope) = "OFSL" set;
        /// `OFSL?`.
        QuerySlope = "OFSL" query;
        /// `AGAN`: auto gain (manual, AGAN). Slow, and a no-op when the time constant is over
        /// 1 s; wait for it with any status query.
        AutoGain = "AGAN" set;
        /// `OUTP? i`: one output value.
        ReadOutput(Output) = "OUTP" query;
        /// `SNAP? i,j{,k,l,m,n}`: 2 to 6 values at one instant.
        Snap(SnapParams) = "SNAP" query;
        /// `LIAS? {i}`: the LIA status byte, or one bit of it; reading clears what it
        /// reads (p. 5-23).
        LiaStatus(Option<BitIndex>) = "LIAS" query;
        /// `ERRS? {i}`: the error status byte, or one bit; reading clears it.
        ErrorStatus(Option<BitIndex>) = "ERRS" query;
        /// `*ESR? {i}`: the standard event status byte, or one bit; reading clears it.
        EventStatus(Option<BitIndex>) = "*ESR" query;
        /// `*IDN?`: identification string.
        Identify = "*IDN" query;
        /// `*RST`: factory defaults, except communication settings and status registers.
        Reset = "*RST" set;
        /// `*CLS`: clears every status byte (not the enable registers).
        Clear = "*CLS" set;
        /// `DDEF i,j,k`: what display channel i shows, and so stores (p. 5-8).
        SetDisplay(DisplayDef) = "DDEF" set;
        /// `SRAT i`: the buffer's sample rate (p. 5-15).
        SetSampleRate(SampleRate) = "SRAT" set;
        /// `SRAT?`.
        QuerySampleRate = "SRAT" query;
        /// `SEND i`: 1 Shot or Loop at the end of the buffer (p. 5-15).
        SetEndOfScan(EndOfScan) = "SEND" set;
        /// `SEND?`.
        QueryEndOfScan = "SEND" query;
        /// `STRT`: starts or resumes storage; ignored while storing (p. 5-15).
        StartStorage = "STRT" set;
        /// `PAUS`: pauses storage (p. 5-15).
        PauseStorage = "PAUS" set;
        /// `REST`: resets the buffer, at any time (p. 5-15).
        ResetStorage = "REST" set;
        /// `SPTS?`: the points stored, at any time (p. 5-16).
        StoredPoints = "SPTS" query;
        /// `TRCA? i,j,k`: points as ASCII, each followed by a comma (p. 5-16).
        TraceAscii(TraceRange) = "TRCA" query;
        /// `TRCB? i,j,k`: points as IEEE floats, 4 bytes each, no terminator (p. 5-17).
        TraceBinary(TraceRange) = "TRCB" query;
        /// `TRCL? i,j,k`: points as stored, 4 bytes each, no terminator (p. 5-17).
        TraceStored(TraceRange) = "TRCL" query;
    }
}

/// An index parameter: a non-negative integer (in any number form) of at most 255.
fn index(v: f64) -> Result<u8, Refusal> {
    if v.fract() == 0.0 && (0.0..=255.0).contains(&v) {
        // Exact: an integral value in 0..=255.
        Ok(v as u8)
    } else {
        Err(Refusal::OutOfRange)
    }
}

/// The one value of a command that takes one.
fn one(values: &[f64]) -> Result<f64, Refusal> {
    match values {
        [v] => Ok(*v),
        _ => Err(Refusal::Syntax),
    }
}

/// One value within `lo..=hi`.
fn bounded(values: &[f64], lo: f64, hi: f64) -> Result<f64, Refusal> {
    let v = one(values)?;
    (lo..=hi)
        .contains(&v)
        .then_some(v)
        .ok_or(Refusal::OutOfRange)
}

/// Appends ` i`.
fn write_int(i: u8, out: &mut Vec<u8>) {
    out.extend_from_slice(format!(" {i}").as_bytes());
}

impl Param<&[f64]> for () {
    fn write(&self, _: &mut Vec<u8>) {}
    fn read(values: &[f64]) -> Result<(), Refusal> {
        values.is_empty().then_some(()).ok_or(Refusal::Syntax)
    }
}

impl Param<&[f64]> for f64 {
    fn write(&self, out: &mut Vec<u8>) {
        out.push(b' ');
        number::format(*self, out);
    }
    fn read(values: &[f64]) -> Result<f64, Refusal> {
        one(values)
    }
}

/// The manual's indexed parameters, ` i`: one integer that the type's table lists.
macro_rules! index_param {
    ($($t:ty: $code:ident / $from:ident),+) => {$(
        impl Param<&[f64]> for $t {
            fn write(&self, out: &mut Vec<u8>) {
                write_int(self.$code(), out);
            }
            fn read(values: &[f64]) -> Result<$t, Refusal> {
                <$t>::$from(index(one(values)?)?).ok_or(Refusal::OutOfRange)
            }
        }
    )+};
}
index_param!(
    Interface: index / from_index,
    ReferenceSource: index / from_index,
    Sensitivity: index / new,
    TimeConstant: index / new,
    FilterSlope: index / from_index,
    Output: code / from_code,
    SampleRate: index / from_index,
    EndOfScan: index / from_index
);

/// Appends ` a,b,c`.
fn write_ints(v: [u32; 3], out: &mut Vec<u8>) {
    out.extend_from_slice(format!(" {},{},{}", v[0], v[1], v[2]).as_bytes());
}

/// Three integers, each within its `max`.
fn three(values: &[f64], max: [f64; 3]) -> Result<[u16; 3], Refusal> {
    let [a, b, c] = values else {
        return Err(Refusal::Syntax);
    };
    let mut out = [0u16; 3];
    for (o, (v, m)) in out.iter_mut().zip([a, b, c].into_iter().zip(max)) {
        if v.fract() != 0.0 || !(0.0..=m).contains(v) {
            return Err(Refusal::OutOfRange);
        }
        // Exact: an integral value in 0..=max ≤ 16383.
        *o = *v as u16;
    }
    Ok(out)
}

impl Param<&[f64]> for DisplayDef {
    fn write(&self, out: &mut Vec<u8>) {
        let v = [self.channel.code(), self.quantity, self.ratio];
        write_ints(v.map(u32::from), out);
    }
    fn read(values: &[f64]) -> Result<DisplayDef, Refusal> {
        let [i, j, k] = three(values, [2.0, 4.0, 2.0])?;
        let channel = u8::try_from(i)
            .ok()
            .and_then(TraceChannel::from_code)
            .ok_or(Refusal::OutOfRange)?;
        // Exact: j ≤ 4 and k ≤ 2.
        DisplayDef::new(channel, j as u8, k as u8).ok_or(Refusal::OutOfRange)
    }
}

impl Param<&[f64]> for TraceRange {
    fn write(&self, out: &mut Vec<u8>) {
        let v = [
            self.channel.code().into(),
            self.start.into(),
            self.count.into(),
        ];
        write_ints(v, out);
    }
    fn read(values: &[f64]) -> Result<TraceRange, Refusal> {
        let max = f64::from(super::buffer::BUFFER_POINTS);
        let [i, j, k] = three(values, [2.0, max, max])?;
        let channel = u8::try_from(i)
            .ok()
            .and_then(TraceChannel::from_code)
            .ok_or(Refusal::OutOfRange)?;
        TraceRange::new(channel, j, k).ok_or(Refusal::OutOfRange)
    }
}

impl Param<&[f64]> for SnapParams {
    fn write(&self, out: &mut Vec<u8>) {
        for (k, q) in self.as_slice().iter().enumerate() {
            out.push(if k == 0 { b' ' } else { b',' });
            out.extend_from_slice(q.code().to_string().as_bytes());
        }
    }
    fn read(values: &[f64]) -> Result<SnapParams, Refusal> {
        if !(SnapParams::MIN..=SnapParams::MAX).contains(&values.len()) {
            return Err(Refusal::Syntax);
        }
        let p = values
            .iter()
            .map(|x| SnapParam::from_code(index(*x)?).ok_or(Refusal::OutOfRange))
            .collect::<Result<Vec<_>, _>>()?;
        SnapParams::new(&p).ok_or(Refusal::OutOfRange)
    }
}

impl Param<&[f64]> for Option<BitIndex> {
    fn write(&self, out: &mut Vec<u8>) {
        if let Some(b) = self {
            write_int(b.get(), out);
        }
    }
    fn read(values: &[f64]) -> Result<Option<BitIndex>, Refusal> {
        match values {
            [] => Ok(None),
            [v] => BitIndex::new(index(*v)?)
                .map(Some)
                .ok_or(Refusal::OutOfRange),
            _ => Err(Refusal::Syntax),
        }
    }
}

/// Why a received command is refused, with the `*ESR?` bit the instrument sets for it
/// (p. 5-2): an illegal command sets CMD (bit 5); one that cannot execute or has
/// a parameter out of range sets EXE (bit 4). Neither produces a reply.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    /// Not a mnemonic the instrument knows: CMD.
    #[error("unknown command {0:?}")]
    Unknown(String),
    /// A known mnemonic used wrongly: a query form it does not have (`AGAN?`, `OUTP 1`),
    /// the wrong number of parameters, or a parameter that is not a number: CMD.
    /// Which bit the firmware sets for a wrong parameter count is not in the manual;
    /// CMD is assumed.
    #[error("{0}: illegal form (query form, parameter count or a non-number)")]
    Syntax(&'static str),
    /// A parameter outside its range, or not an integer where an index is expected:
    /// EXE. (Whether the firmware rounds `SENS 2.5` instead is not in the manual; the
    /// codec refuses it so that a driver bug shows.)
    #[error("{0}: parameter out of range")]
    OutOfRange(&'static str),
}

impl CommandError {
    /// The `*ESR?` bit number the instrument sets.
    pub fn bit(&self) -> u8 {
        match self {
            CommandError::Unknown(_) | CommandError::Syntax(_) => 5,
            CommandError::OutOfRange(_) => 4,
        }
    }

    /// The same bit as a standard event status byte.
    pub fn event_status(&self) -> EventStatus {
        EventStatus(1 << self.bit())
    }
}

crate::codec::line_encoding!(Command, TERMINATOR);

impl Command {
    /// True when the instrument answers with a reply line: every valid query does,
    /// nothing else does (p. 5-2).
    pub fn expects_reply(&self) -> bool {
        self.is_query()
    }

    /// True for `TRCB?` and `TRCL?`, whose replies are binary, 4 bytes a point, with no
    /// terminator (p. 5-17).
    pub fn is_binary_trace(&self) -> bool {
        matches!(self, Command::TraceBinary(_) | Command::TraceStored(_))
    }

    /// Appends the command without terminator: the mnemonic, `?` for a query, then a
    /// space and the comma-separated parameters (`SNAP? 1,2`, `SENS 20`, `LIAS?`).
    /// Values are written in the shortest decimal form that reads back exactly.
    pub fn encode_body(&self, out: &mut Vec<u8>) {
        self.encode_row(out);
    }

    /// Parses one command (no `;`, no terminator) as the instrument does:
    /// case-insensitive, spaces ignored anywhere, numbers in integer, float or
    /// exponent form (`5`, `5.0`, `.5E1`).
    pub fn parse(text: &[u8]) -> Result<Command, CommandError> {
        parse_clean(&clean(text))
    }
}

/// Appends several commands as one line, separated by `;`, terminator included
/// (`SENS?;OFLT?;OFSL?\n`). The instrument runs the whole line before anything else
/// and answers each query with its own line (p. 5-2).
pub fn encode_line(commands: &[Command], out: &mut Vec<u8>) {
    for (k, c) in commands.iter().enumerate() {
        if k > 0 {
            out.push(b';');
        }
        c.encode_body(out);
    }
    out.extend_from_slice(TERMINATOR);
}

/// Parses a received line (terminator removed) into its commands, in order, as the
/// instrument reads it: commands separated by `;`, empty ones skipped. `\r` and `\n`
/// inside the line also separate commands, since either ends a line on RS-232.
///
/// Each command succeeds or fails on its own, so that a simulator can run the good
/// ones and set the status bit of each bad one ([`CommandError::bit`]). Whether the
/// firmware still runs the rest of a line after an illegal command is not in the
/// manual.
pub fn parse_line(line: &[u8]) -> Vec<Result<Command, CommandError>> {
    crate::codec::parse_commands(line, |s| {
        let s = clean(s);
        (!s.is_empty()).then(|| parse_clean(&s))
    })
}

/// Removes spaces and tabs, and upper-cases (what the instrument's own queue display
/// shows, p. 5-3).
fn clean(text: &[u8]) -> Vec<u8> {
    text.iter()
        .filter(|b| !matches!(b, b' ' | b'\t'))
        .map(u8::to_ascii_uppercase)
        .collect()
}

/// Parses one cleaned command.
fn parse_clean(s: &[u8]) -> Result<Command, CommandError> {
    let unknown = || CommandError::Unknown(String::from_utf8_lossy(s).into_owned());
    let Some((mn, rest)) = s.split_at_checked(4) else {
        return Err(unknown());
    };
    let name = *Command::MNEMONICS
        .iter()
        .find(|m| m.as_bytes() == mn)
        .ok_or_else(unknown)?;
    let (query, params) = match rest.split_first() {
        Some((b'?', p)) => (true, p),
        _ => (false, rest),
    };
    let values: Vec<f64> = if params.is_empty() {
        Vec::new()
    } else {
        params
            .split(|b| *b == b',')
            .map(|p| number::parse(p).ok_or(CommandError::Syntax(name)))
            .collect::<Result<_, _>>()?
    };
    match Command::from_row(name, query, &values) {
        Some((_, Ok(command))) => Ok(command),
        Some((_, Err(Refusal::OutOfRange))) => Err(CommandError::OutOfRange(name)),
        _ => Err(CommandError::Syntax(name)),
    }
}
