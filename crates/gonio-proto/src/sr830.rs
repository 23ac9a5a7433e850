//! The Stanford Research SR830 DSP lock-in amplifier's RS-232 protocol (manual
//! Rev. 2.5, chapter 5 "Remote Programming").
//!
//! A command is a four-character mnemonic (`*XXX` for the IEEE-488.2 common
//! commands), `?` for a query, then comma-separated parameters: `SENS 20`, `SENS?`,
//! `SNAP? 1,2`. Several commands may share a line, separated by `;`. The host ends a
//! line with `\n` or `\r`; the instrument ignores case and every space (manual
//! p. 5-1 … 5-3). Only queries reply, with a bare value ended by `\r` and no echo of
//! the command: `SENS?` → `20`. Set commands reply nothing, even when they fail; a
//! failure sets the CMD or EXE bit of the standard event status byte (`*ESR?`).
//!
//! Since a reply carries no echo, it can only be read knowing the query it answers:
//! [`Reply::parse`] takes the [`Command`]. [`Command`] and [`Reply`] format and parse
//! both directions, so the driver and the simulator share one definition.
//!
//! ```
//! use gonio_proto::sr830::{Command, Reply, SnapParam, SnapParams};
//!
//! let snap = Command::Snap(SnapParams::new(&[SnapParam::X, SnapParam::Y]).unwrap());
//! assert_eq!(snap.to_bytes(), b"SNAP? 1,2\n");
//! let reply = Reply::parse(&snap, b"0.951359,0.0253297").unwrap();
//! assert_eq!(reply, Reply::Snap(vec![0.951359, 0.0253297]));
//! ```

use std::fmt;
use std::str::FromStr;

use crate::number;

/// The line terminator the host sends. The manual allows `\n` or `\r` on RS-232
/// (p. 5-1); `\n` is chosen because GPIB takes it as well, so one line suits either port.
pub const TERMINATOR: &[u8] = b"\n";

/// The byte that ends every reply line on RS-232 (p. 5-2; on GPIB it would be LF).
pub const REPLY_TERMINATOR: u8 = b'\r';

/// The instrument's input and output buffers, in characters (p. 5-2). A longer line
/// overflows them: both are cleared and INP or QRY is set in `*ESR?`.
pub const MAX_LINE: usize = 256;

/// Full-scale voltage of each `SENS` index, volts (SENS table, manual ch. 5).
const SENS_VOLTS: [f64; 27] = [
    2e-9, 5e-9, 1e-8, 2e-8, 5e-8, 1e-7, 2e-7, 5e-7, 1e-6, 2e-6, 5e-6, 1e-5, 2e-5, 5e-5, 1e-4, 2e-4,
    5e-4, 1e-3, 2e-3, 5e-3, 1e-2, 2e-2, 5e-2, 0.1, 0.2, 0.5, 1.0,
];

const SENS_LABELS: [&str; 27] = [
    "2 nV", "5 nV", "10 nV", "20 nV", "50 nV", "100 nV", "200 nV", "500 nV", "1 µV", "2 µV",
    "5 µV", "10 µV", "20 µV", "50 µV", "100 µV", "200 µV", "500 µV", "1 mV", "2 mV", "5 mV",
    "10 mV", "20 mV", "50 mV", "100 mV", "200 mV", "500 mV", "1 V",
];

/// Time constant of each `OFLT` index, seconds (OFLT table, manual ch. 5).
const TC_SECONDS: [f64; 20] = [
    1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0,
    1e3, 3e3, 1e4, 3e4,
];

const TC_LABELS: [&str; 20] = [
    "10 µs", "30 µs", "100 µs", "300 µs", "1 ms", "3 ms", "10 ms", "30 ms", "100 ms", "300 ms",
    "1 s", "3 s", "10 s", "30 s", "100 s", "300 s", "1 ks", "3 ks", "10 ks", "30 ks",
];

/// Finds `text` among `labels`, ignoring spaces, and accepting `u` or the Greek `μ`
/// for the micro sign `µ`.
fn find_label(labels: &[&str], text: &str) -> Option<u8> {
    let norm = |s: &str| -> String {
        s.chars()
            .filter(|c| !c.is_whitespace())
            .map(|c| if matches!(c, 'u' | 'μ') { 'µ' } else { c })
            .collect()
    };
    let want = norm(text);
    let i = labels.iter().position(|l| norm(l) == want)?;
    u8::try_from(i).ok()
}

/// Why a table entry could not be read from text.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{text:?} is not a {what} of the SR830 (expected e.g. {example:?})")]
pub struct UnknownLabel {
    /// What was looked up ("sensitivity", "time constant").
    pub what: &'static str,
    /// The text given.
    pub text: String,
    /// A valid example.
    pub example: &'static str,
}

/// A sensitivity (full-scale voltage input range), `SENS` index 0 (2 nV) to 26 (1 V).
///
/// Ordered by index, so a greater value is a larger full scale (less sensitive). With
/// a current input the same index means 1 fA … 1 µA (SENS table); this type
/// speaks volts only.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Sensitivity(u8);

impl Sensitivity {
    /// Number of sensitivities.
    pub const COUNT: u8 = 27;
    /// The most sensitive range, 2 nV.
    pub const MOST: Sensitivity = Sensitivity(0);
    /// The least sensitive range, 1 V (also the `*RST` default, p. 4-4).
    pub const LEAST: Sensitivity = Sensitivity(26);

    /// The sensitivity with `SENS` index `index`, if it is 0..=26.
    pub fn new(index: u8) -> Option<Self> {
        (index < Self::COUNT).then_some(Sensitivity(index))
    }

    /// Every sensitivity, most sensitive first.
    pub fn all() -> impl Iterator<Item = Sensitivity> {
        (0..Self::COUNT).map(Sensitivity)
    }

    /// The `SENS` index.
    pub fn index(self) -> u8 {
        self.0
    }

    /// Full scale, volts.
    pub fn volts(self) -> f64 {
        SENS_VOLTS[usize::from(self.0)]
    }

    /// The next larger full scale, or `None` at 1 V.
    pub fn less_sensitive(self) -> Option<Self> {
        Self::new(self.0 + 1)
    }

    /// The next smaller full scale, or `None` at 2 nV.
    pub fn more_sensitive(self) -> Option<Self> {
        self.0.checked_sub(1).map(Sensitivity)
    }
}

impl Default for Sensitivity {
    /// 1 V, the `*RST` default (p. 4-4).
    fn default() -> Self {
        Self::LEAST
    }
}

impl fmt::Display for Sensitivity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(SENS_LABELS[usize::from(self.0)])
    }
}

impl FromStr for Sensitivity {
    type Err = UnknownLabel;

    /// Reads a label as [`Display`](fmt::Display) writes it (`"10 mV"`); spaces are
    /// optional and `uV` or `μV` may stand for `µV`. Prefixes are case-sensitive
    /// (`mV` is not `MV`).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        find_label(&SENS_LABELS, s)
            .map(Sensitivity)
            .ok_or_else(|| UnknownLabel {
                what: "sensitivity",
                text: s.to_string(),
                example: "10 mV",
            })
    }
}

/// A low-pass filter time constant, `OFLT` index 0 (10 µs) to 19 (30 ks).
///
/// Values over 30 s cannot be set when the detection frequency is above 200 Hz, and a
/// value below the minimum for the slope and reserve is raised to it (manual, OFLT): the
/// instrument, not this type, knows those.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TimeConstant(u8);

impl TimeConstant {
    /// Number of time constants.
    pub const COUNT: u8 = 20;

    /// The time constant with `OFLT` index `index`, if it is 0..=19.
    pub fn new(index: u8) -> Option<Self> {
        (index < Self::COUNT).then_some(TimeConstant(index))
    }

    /// Every time constant, shortest first.
    pub fn all() -> impl Iterator<Item = TimeConstant> {
        (0..Self::COUNT).map(TimeConstant)
    }

    /// The `OFLT` index.
    pub fn index(self) -> u8 {
        self.0
    }

    /// The time constant, seconds.
    pub fn seconds(self) -> f64 {
        TC_SECONDS[usize::from(self.0)]
    }
}

impl Default for TimeConstant {
    /// 100 ms (`OFLT 8`), the `*RST` default (p. 4-4).
    fn default() -> Self {
        TimeConstant(8)
    }
}

impl fmt::Display for TimeConstant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(TC_LABELS[usize::from(self.0)])
    }
}

impl FromStr for TimeConstant {
    type Err = UnknownLabel;

    /// Reads a label as [`Display`](fmt::Display) writes it (`"100 ms"`, `"1 ks"`);
    /// spaces optional, `us` or `μs` for `µs`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        find_label(&TC_LABELS, s)
            .map(TimeConstant)
            .ok_or_else(|| UnknownLabel {
                what: "time constant",
                text: s.to_string(),
                example: "100 ms",
            })
    }
}

/// The low-pass filter slope, `OFSL` 0..=3 (manual, OFSL).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum FilterSlope {
    /// 6 dB/oct (index 0).
    Db6,
    /// 12 dB/oct (index 1, the `*RST` default).
    Db12,
    /// 18 dB/oct (index 2).
    Db18,
    /// 24 dB/oct (index 3).
    Db24,
}

impl FilterSlope {
    /// Every slope, shallowest first.
    pub const ALL: [FilterSlope; 4] = [
        FilterSlope::Db6,
        FilterSlope::Db12,
        FilterSlope::Db18,
        FilterSlope::Db24,
    ];

    /// The `OFSL` index.
    pub fn index(self) -> u8 {
        self as u8
    }

    /// The slope with `OFSL` index `index`, if it is 0..=3.
    pub fn from_index(index: u8) -> Option<Self> {
        Self::ALL.get(usize::from(index)).copied()
    }

    /// The roll-off, dB per octave.
    pub fn db_per_octave(self) -> u8 {
        6 * (self.index() + 1)
    }

    /// The slope rolling off `db` dB per octave (6, 12, 18 or 24).
    pub fn from_db(db: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.db_per_octave() == db)
    }

    /// Time to reach 99 % of a step, in time constants: 5, 7, 9, 10 ("SR830 Basics", tables p. 3-21 and 3-25).
    /// Readings taken sooner still carry the previous range's transient.
    pub fn settle_factor(self) -> f64 {
        match self {
            FilterSlope::Db6 => 5.0,
            FilterSlope::Db12 => 7.0,
            FilterSlope::Db18 => 9.0,
            FilterSlope::Db24 => 10.0,
        }
    }

    /// Settling time to 99 % for time constant `tc`, seconds.
    pub fn settle_seconds(self, tc: TimeConstant) -> f64 {
        self.settle_factor() * tc.seconds()
    }

    /// Time, in time constants, for the step response of this slope's cascade of
    /// `N` identical RC stages to come within `residual` of its final value: the root
    /// of `e^{−a} Σ_{j<N} a^j/j! = residual`. The manual's table rounds this for 1 %
    /// (it gives 10 T at 24 dB/oct, where the exact figure is 10.05 T); precision work
    /// asks for less, e.g. 1e-4 (15.9 T at 24 dB/oct).
    pub fn settle_factor_for(self, residual: f64) -> f64 {
        let n = self.index() + 1;
        let left = |a: f64| {
            let (mut term, mut sum) = (1.0, 1.0);
            for j in 1..usize::from(n) {
                term *= a / j as f64;
                sum += term;
            }
            (-a).exp() * sum
        };
        let r = residual.clamp(1e-15, 0.5);
        let (mut lo, mut hi) = (0.0, 100.0);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if left(mid) > r {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        hi
    }

    /// Equivalent noise bandwidth for time constant `tc`, Hz: 1/(4T), 1/(8T), 3/(32T),
    /// 5/(64T) (same tables). Noise in a reading scales with its square root.
    pub fn enbw_hz(self, tc: TimeConstant) -> f64 {
        let k = match self {
            FilterSlope::Db6 => 1.0 / 4.0,
            FilterSlope::Db12 => 1.0 / 8.0,
            FilterSlope::Db18 => 3.0 / 32.0,
            FilterSlope::Db24 => 5.0 / 64.0,
        };
        k / tc.seconds()
    }
}

impl Default for FilterSlope {
    /// 12 dB/oct, the `*RST` default (p. 4-4).
    fn default() -> Self {
        FilterSlope::Db12
    }
}

impl fmt::Display for FilterSlope {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} dB/oct", self.db_per_octave())
    }
}

/// Which interface replies go to, `OUTX` (p. 5-10). Both always listen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Interface {
    /// `OUTX 0`: RS-232. A program on the serial port must send this first.
    Rs232,
    /// `OUTX 1`: GPIB, the factory default.
    Gpib,
}

impl Interface {
    /// The `OUTX` index.
    pub fn index(self) -> u8 {
        self as u8
    }

    /// The interface with `OUTX` index `index` (0 or 1).
    pub fn from_index(index: u8) -> Option<Self> {
        match index {
            0 => Some(Interface::Rs232),
            1 => Some(Interface::Gpib),
            _ => None,
        }
    }
}

/// The reference source, `FMOD` (manual, FMOD).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ReferenceSource {
    /// `FMOD 0`: external reference input.
    External,
    /// `FMOD 1`: internal oscillator (the `*RST` default).
    Internal,
}

impl ReferenceSource {
    /// The `FMOD` index.
    pub fn index(self) -> u8 {
        self as u8
    }

    /// The source with `FMOD` index `index` (0 or 1).
    pub fn from_index(index: u8) -> Option<Self> {
        match index {
            0 => Some(ReferenceSource::External),
            1 => Some(ReferenceSource::Internal),
            _ => None,
        }
    }
}

/// The quantity `OUTP? i` reads (manual, OUTP?): volts for X, Y, R; degrees for θ.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Output {
    /// 1: in-phase component X, volts.
    X = 1,
    /// 2: quadrature component Y, volts.
    Y = 2,
    /// 3: magnitude R, volts.
    R = 3,
    /// 4: phase θ, degrees.
    Theta = 4,
}

impl Output {
    /// Every quantity, by code.
    pub const ALL: [Output; 4] = [Output::X, Output::Y, Output::R, Output::Theta];

    /// The `OUTP?` parameter.
    pub fn code(self) -> u8 {
        self as u8
    }

    /// The quantity for an `OUTP?` parameter 1..=4.
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|o| o.code() == code)
    }
}

/// A value `SNAP?` can read (manual, SNAP?): all of one call are taken at one instant (X with
/// Y, and R with θ, exactly; the two pairs about 10 µs apart).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SnapParam {
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

impl SnapParam {
    /// Every parameter, by code.
    pub const ALL: [SnapParam; 11] = [
        SnapParam::X,
        SnapParam::Y,
        SnapParam::R,
        SnapParam::Theta,
        SnapParam::AuxIn1,
        SnapParam::AuxIn2,
        SnapParam::AuxIn3,
        SnapParam::AuxIn4,
        SnapParam::Frequency,
        SnapParam::Ch1Display,
        SnapParam::Ch2Display,
    ];

    /// The `SNAP?` parameter.
    pub fn code(self) -> u8 {
        self as u8
    }

    /// The value for a `SNAP?` parameter 1..=11.
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.code() == code)
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

/// A command to the SR830. Queries answer one line; the rest answer nothing.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// `OUTX i`: send replies to this interface (p. 5-10).
    SetInterface(Interface),
    /// `OUTX?`: which interface replies go to.
    QueryInterface,
    /// `FMOD i`: reference source (manual, FMOD).
    SetReferenceSource(ReferenceSource),
    /// `FMOD?`.
    QueryReferenceSource,
    /// `FREQ f`: internal oscillator frequency, 0.001 ≤ f ≤ 102000 Hz (manual, FREQ). The
    /// limit harmonic × f ≤ 102 kHz depends on the instrument's state; it checks that.
    SetFrequency(f64),
    /// `FREQ?`: reference frequency, Hz, in any reference mode.
    QueryFrequency,
    /// `SLVL x`: sine output amplitude, 0.004 ≤ x ≤ 5.000 V rms (manual, SLVL).
    SetAmplitude(f64),
    /// `SLVL?`.
    QueryAmplitude,
    /// `SENS i`: sensitivity (SENS table).
    SetSensitivity(Sensitivity),
    /// `SENS?`.
    QuerySensitivity,
    /// `OFLT i`: time constant (OFLT table).
    SetTimeConstant(TimeConstant),
    /// `OFLT?`.
    QueryTimeConstant,
    /// `OFSL i`: filter slope.
    SetSlope(FilterSlope),
    /// `OFSL?`.
    QuerySlope,
    /// `AGAN`: auto gain (manual, AGAN). Slow, and a no-op when the time constant is over
    /// 1 s; wait for it with any status query.
    AutoGain,
    /// `OUTP? i`: one output value.
    ReadOutput(Output),
    /// `SNAP? i,j{,k,l,m,n}`: 2 to 6 values at one instant.
    Snap(SnapParams),
    /// `LIAS? {i}`: the LIA status byte, or one bit of it; reading clears what it
    /// reads (p. 5-23).
    LiaStatus(Option<BitIndex>),
    /// `ERRS? {i}`: the error status byte, or one bit; reading clears it.
    ErrorStatus(Option<BitIndex>),
    /// `*ESR? {i}`: the standard event status byte, or one bit; reading clears it.
    EventStatus(Option<BitIndex>),
    /// `*IDN?`: identification string.
    Identify,
    /// `*RST`: factory defaults, except communication settings and status registers.
    Reset,
    /// `*CLS`: clears every status byte (not the enable registers).
    Clear,
}

/// Every mnemonic the codec knows, as it appears on the line (upper case).
const MNEMONICS: [&str; 16] = [
    "OUTX", "FMOD", "FREQ", "SLVL", "SENS", "OFLT", "OFSL", "AGAN", "OUTP", "SNAP", "LIAS", "ERRS",
    "*ESR", "*IDN", "*RST", "*CLS",
];

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
    /// The `*ESR?` bit number the instrument sets: 5 (CMD) or 4 (EXE).
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

impl Command {
    /// The four-character mnemonic, upper case.
    pub fn mnemonic(&self) -> &'static str {
        match self {
            Command::SetInterface(_) | Command::QueryInterface => "OUTX",
            Command::SetReferenceSource(_) | Command::QueryReferenceSource => "FMOD",
            Command::SetFrequency(_) | Command::QueryFrequency => "FREQ",
            Command::SetAmplitude(_) | Command::QueryAmplitude => "SLVL",
            Command::SetSensitivity(_) | Command::QuerySensitivity => "SENS",
            Command::SetTimeConstant(_) | Command::QueryTimeConstant => "OFLT",
            Command::SetSlope(_) | Command::QuerySlope => "OFSL",
            Command::AutoGain => "AGAN",
            Command::ReadOutput(_) => "OUTP",
            Command::Snap(_) => "SNAP",
            Command::LiaStatus(_) => "LIAS",
            Command::ErrorStatus(_) => "ERRS",
            Command::EventStatus(_) => "*ESR",
            Command::Identify => "*IDN",
            Command::Reset => "*RST",
            Command::Clear => "*CLS",
        }
    }

    /// True for queries (written with `?`).
    pub fn is_query(&self) -> bool {
        matches!(
            self,
            Command::QueryInterface
                | Command::QueryReferenceSource
                | Command::QueryFrequency
                | Command::QueryAmplitude
                | Command::QuerySensitivity
                | Command::QueryTimeConstant
                | Command::QuerySlope
                | Command::ReadOutput(_)
                | Command::Snap(_)
                | Command::LiaStatus(_)
                | Command::ErrorStatus(_)
                | Command::EventStatus(_)
                | Command::Identify
        )
    }

    /// True when the instrument answers with a reply line: every valid query does,
    /// nothing else does (p. 5-2).
    pub fn expects_reply(&self) -> bool {
        self.is_query()
    }

    /// Appends the command without terminator: the mnemonic, `?` for a query, then a
    /// space and the comma-separated parameters (`SNAP? 1,2`, `SENS 20`, `LIAS?`).
    /// Values are written in the shortest decimal form that reads back exactly.
    pub fn encode_body(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(self.mnemonic().as_bytes());
        if self.is_query() {
            out.push(b'?');
        }
        let mut int = |i: u8| {
            out.push(b' ');
            out.extend_from_slice(i.to_string().as_bytes());
        };
        match self {
            Command::SetInterface(i) => int(i.index()),
            Command::SetReferenceSource(s) => int(s.index()),
            Command::SetSensitivity(s) => int(s.index()),
            Command::SetTimeConstant(t) => int(t.index()),
            Command::SetSlope(s) => int(s.index()),
            Command::ReadOutput(o) => int(o.code()),
            Command::LiaStatus(Some(b))
            | Command::ErrorStatus(Some(b))
            | Command::EventStatus(Some(b)) => int(b.get()),
            Command::SetFrequency(v) | Command::SetAmplitude(v) => {
                out.push(b' ');
                number::format(*v, out);
            }
            Command::Snap(p) => {
                for (k, q) in p.as_slice().iter().enumerate() {
                    out.push(if k == 0 { b' ' } else { b',' });
                    out.extend_from_slice(q.code().to_string().as_bytes());
                }
            }
            _ => {}
        }
    }

    /// Appends the command line, terminator included (`SENS 20\n`).
    pub fn encode(&self, out: &mut Vec<u8>) {
        self.encode_body(out);
        out.extend_from_slice(TERMINATOR);
    }

    /// The command line as bytes, terminator included.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut v = Vec::new();
        self.encode(&mut v);
        v
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
    line.split(|b| matches!(b, b';' | b'\r' | b'\n'))
        .map(clean)
        .filter(|s| !s.is_empty())
        .map(|s| parse_clean(&s))
        .collect()
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
    let name = *MNEMONICS
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
    let range = || CommandError::OutOfRange(name);
    // An index parameter: a non-negative integer (in any number form) of at most 255.
    let index = |v: f64| -> Result<u8, CommandError> {
        if v.fract() == 0.0 && (0.0..=255.0).contains(&v) {
            // Exact: an integral value in 0..=255.
            Ok(v as u8)
        } else {
            Err(range())
        }
    };
    let bit = |v: f64| index(v).and_then(|i| BitIndex::new(i).ok_or_else(range));
    let bounded = |v: f64, lo: f64, hi: f64| {
        if (lo..=hi).contains(&v) {
            Ok(v)
        } else {
            Err(range())
        }
    };
    let command = match (name, query, values.as_slice()) {
        ("OUTX", false, [i]) => {
            Command::SetInterface(Interface::from_index(index(*i)?).ok_or_else(range)?)
        }
        ("OUTX", true, []) => Command::QueryInterface,
        ("FMOD", false, [i]) => {
            Command::SetReferenceSource(ReferenceSource::from_index(index(*i)?).ok_or_else(range)?)
        }
        ("FMOD", true, []) => Command::QueryReferenceSource,
        ("FREQ", false, [f]) => Command::SetFrequency(bounded(*f, 0.001, 102_000.0)?),
        ("FREQ", true, []) => Command::QueryFrequency,
        ("SLVL", false, [x]) => Command::SetAmplitude(bounded(*x, 0.004, 5.0)?),
        ("SLVL", true, []) => Command::QueryAmplitude,
        ("SENS", false, [i]) => {
            Command::SetSensitivity(Sensitivity::new(index(*i)?).ok_or_else(range)?)
        }
        ("SENS", true, []) => Command::QuerySensitivity,
        ("OFLT", false, [i]) => {
            Command::SetTimeConstant(TimeConstant::new(index(*i)?).ok_or_else(range)?)
        }
        ("OFLT", true, []) => Command::QueryTimeConstant,
        ("OFSL", false, [i]) => {
            Command::SetSlope(FilterSlope::from_index(index(*i)?).ok_or_else(range)?)
        }
        ("OFSL", true, []) => Command::QuerySlope,
        ("AGAN", false, []) => Command::AutoGain,
        ("OUTP", true, [i]) => {
            Command::ReadOutput(Output::from_code(index(*i)?).ok_or_else(range)?)
        }
        ("SNAP", true, v) if (SnapParams::MIN..=SnapParams::MAX).contains(&v.len()) => {
            let p = v
                .iter()
                .map(|x| SnapParam::from_code(index(*x)?).ok_or_else(range))
                .collect::<Result<Vec<_>, _>>()?;
            Command::Snap(SnapParams::new(&p).ok_or_else(range)?)
        }
        ("LIAS", true, []) => Command::LiaStatus(None),
        ("LIAS", true, [i]) => Command::LiaStatus(Some(bit(*i)?)),
        ("ERRS", true, []) => Command::ErrorStatus(None),
        ("ERRS", true, [i]) => Command::ErrorStatus(Some(bit(*i)?)),
        ("*ESR", true, []) => Command::EventStatus(None),
        ("*ESR", true, [i]) => Command::EventStatus(Some(bit(*i)?)),
        ("*IDN", true, []) => Command::Identify,
        ("*RST", false, []) => Command::Reset,
        ("*CLS", false, []) => Command::Clear,
        _ => return Err(CommandError::Syntax(name)),
    };
    Ok(command)
}

/// Writes the names of the set bits of `byte`, `|`-separated, or `none`.
fn write_bits(f: &mut fmt::Formatter<'_>, byte: u8, names: &[(u8, &str)]) -> fmt::Result {
    let mut first = true;
    for (mask, name) in names {
        if byte & mask != 0 {
            if !first {
                f.write_str("|")?;
            }
            f.write_str(name)?;
            first = false;
        }
    }
    let unnamed = byte & !names.iter().fold(0, |acc, (m, _)| acc | m);
    if unnamed != 0 {
        if !first {
            f.write_str("|")?;
        }
        write!(f, "0x{unnamed:02X}")?;
        first = false;
    }
    if first {
        f.write_str("none")?;
    }
    Ok(())
}

/// The LIA status byte, `LIAS?` (p. 5-23). Bits latch until read or cleared by `*CLS`,
/// so read it once to clear, take the readings, then read it again.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct LiaStatus(pub u8);

impl LiaStatus {
    /// Bit 0, INPUT/RESRV: input or amplifier (reserve) overload.
    pub const INPUT_OVERLOAD: u8 = 1 << 0;
    /// Bit 1, FILTR: time-constant filter overload.
    pub const FILTER_OVERLOAD: u8 = 1 << 1;
    /// Bit 2, OUTPT: an output exceeds 1.09 × full scale.
    pub const OUTPUT_OVERLOAD: u8 = 1 << 2;
    /// Bit 3, UNLK: reference unlock.
    pub const UNLOCK: u8 = 1 << 3;
    /// Bit 4, RANGE: the detection frequency crossed 200 Hz (changed range).
    pub const RANGE: u8 = 1 << 4;
    /// Bit 5, TC: the time constant changed indirectly (range, reserve, slope,
    /// expand).
    pub const TIME_CONSTANT_CHANGED: u8 = 1 << 5;
    /// Bit 6, TRIG: data storage triggered.
    pub const TRIGGERED: u8 = 1 << 6;

    const NAMES: [(u8, &'static str); 7] = [
        (Self::INPUT_OVERLOAD, "INPUT/RESRV"),
        (Self::FILTER_OVERLOAD, "FILTR"),
        (Self::OUTPUT_OVERLOAD, "OUTPT"),
        (Self::UNLOCK, "UNLK"),
        (Self::RANGE, "RANGE"),
        (Self::TIME_CONSTANT_CHANGED, "TC"),
        (Self::TRIGGERED, "TRIG"),
    ];

    /// True when every bit of `mask` is set.
    pub fn has(self, mask: u8) -> bool {
        self.0 & mask == mask
    }

    /// True when no bit is set.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Bit 0: input or reserve overload.
    pub fn input_overload(self) -> bool {
        self.has(Self::INPUT_OVERLOAD)
    }

    /// Bit 1: filter overload.
    pub fn filter_overload(self) -> bool {
        self.has(Self::FILTER_OVERLOAD)
    }

    /// Bit 2: output overload.
    pub fn output_overload(self) -> bool {
        self.has(Self::OUTPUT_OVERLOAD)
    }

    /// Bit 3: reference unlock.
    pub fn unlocked(self) -> bool {
        self.has(Self::UNLOCK)
    }
}

impl fmt::Display for LiaStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_bits(f, self.0, &Self::NAMES)
    }
}

/// The standard event status byte, `*ESR?` (manual, status byte definitions).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct EventStatus(pub u8);

impl EventStatus {
    /// Bit 0, INP: input queue overflow.
    pub const INP: u8 = 1 << 0;
    /// Bit 2, QRY: output queue overflow.
    pub const QRY: u8 = 1 << 2;
    /// Bit 4, EXE: a command could not execute, or a parameter was out of range.
    pub const EXE: u8 = 1 << 4;
    /// Bit 5, CMD: illegal command.
    pub const CMD: u8 = 1 << 5;
    /// Bit 6, URQ: a key was pressed or the knob turned.
    pub const URQ: u8 = 1 << 6;
    /// Bit 7, PON: power on.
    pub const PON: u8 = 1 << 7;

    const NAMES: [(u8, &'static str); 6] = [
        (Self::INP, "INP"),
        (Self::QRY, "QRY"),
        (Self::EXE, "EXE"),
        (Self::CMD, "CMD"),
        (Self::URQ, "URQ"),
        (Self::PON, "PON"),
    ];

    /// True when every bit of `mask` is set.
    pub fn has(self, mask: u8) -> bool {
        self.0 & mask == mask
    }

    /// True when no bit is set.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// True when a command was refused (EXE or CMD): the instrument is not in the
    /// state the host asked for.
    pub fn has_command_error(self) -> bool {
        self.0 & (Self::EXE | Self::CMD) != 0
    }
}

impl fmt::Display for EventStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_bits(f, self.0, &Self::NAMES)
    }
}

/// The error status byte, `ERRS?` (manual, status byte definitions). Bits 0 and 3 are unused.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct ErrorStatus(pub u8);

impl ErrorStatus {
    /// Bit 1: battery-backed memory lost at power-up.
    pub const BACKUP: u8 = 1 << 1;
    /// Bit 2: RAM test failed.
    pub const RAM: u8 = 1 << 2;
    /// Bit 4: ROM test failed.
    pub const ROM: u8 = 1 << 4;
    /// Bit 5: GPIB fast data transfer aborted.
    pub const GPIB: u8 = 1 << 5;
    /// Bit 6: DSP test failed.
    pub const DSP: u8 = 1 << 6;
    /// Bit 7: internal math error.
    pub const MATH: u8 = 1 << 7;

    const NAMES: [(u8, &'static str); 6] = [
        (Self::BACKUP, "BACKUP"),
        (Self::RAM, "RAM"),
        (Self::ROM, "ROM"),
        (Self::GPIB, "GPIB"),
        (Self::DSP, "DSP"),
        (Self::MATH, "MATH"),
    ];

    /// True when every bit of `mask` is set.
    pub fn has(self, mask: u8) -> bool {
        self.0 & mask == mask
    }

    /// True when no bit is set.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }
}

impl fmt::Display for ErrorStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_bits(f, self.0, &Self::NAMES)
    }
}

/// The `*IDN?` reply: four comma-separated fields,
/// `Stanford_Research_Systems,SR830,s/n00111,ver1.000` (manual, *IDN?).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Identity {
    /// `Stanford_Research_Systems`.
    pub manufacturer: String,
    /// `SR830` (an SR810 or SR850 answers its own name).
    pub model: String,
    /// `s/n00111`.
    pub serial: String,
    /// `ver1.000` in the manual; real units report e.g. `ver1.07`.
    pub firmware: String,
}

impl Identity {
    /// True when the model field is `SR830`.
    pub fn is_sr830(&self) -> bool {
        self.model == "SR830"
    }

    /// Parses the four fields. Each is trimmed, must be non-empty printable ASCII.
    pub fn parse(text: &[u8]) -> Option<Identity> {
        let text = std::str::from_utf8(text).ok()?;
        let fields: Vec<&str> = text.split(',').map(str::trim).collect();
        let ok = |f: &&str| !f.is_empty() && f.bytes().all(|b| b.is_ascii_graphic() || b == b' ');
        match fields.as_slice() {
            [m, n, s, v] if [m, n, s, v].into_iter().all(ok) => Some(Identity {
                manufacturer: m.to_string(),
                model: n.to_string(),
                serial: s.to_string(),
                firmware: v.to_string(),
            }),
            _ => None,
        }
    }
}

impl fmt::Display for Identity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{},{},{},{}",
            self.manufacturer, self.model, self.serial, self.firmware
        )
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
}

/// Why a reply line could not be understood.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ReplyError {
    /// The line is empty.
    #[error("empty reply")]
    Empty,
    /// The command is not a query: the instrument never answers it.
    #[error("{0} sends no reply")]
    NotAQuery(&'static str),
    /// A value is not a number, or not the integer the query returns.
    #[error("malformed value")]
    BadValue,
    /// An index or status value outside what the query can return.
    #[error("value {0} out of range for this query")]
    OutOfRange(f64),
    /// `SNAP?` returned a different number of values than asked.
    #[error("expected {expected} values, got {got}")]
    WrongCount {
        /// Values asked.
        expected: usize,
        /// Values in the reply.
        got: usize,
    },
}

/// Writes a reply value: the shortest decimal that reads back exactly, with an
/// exponent outside 1e-4 ≤ |v| < 1e9 so that six values of a `SNAP?` always fit the
/// 256-byte output buffer. The firmware's own rule (`1000.00`, `-4.17234e-007`) is
/// unconfirmed; parsers accept both.
fn format_value(v: f64, out: &mut Vec<u8>) {
    use std::io::Write;
    if v == 0.0 || (1e-4..1e9).contains(&v.abs()) {
        number::format(v, out);
    } else {
        let _ = write!(out, "{v:e}");
    }
}

impl Reply {
    /// Appends the reply line, terminator included (what the instrument sends).
    /// Values must be finite; floats are written as described at [`Reply::parse`].
    pub fn encode(&self, out: &mut Vec<u8>) {
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
        }
        out.push(REPLY_TERMINATOR);
    }

    /// The reply line as bytes, terminator included.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut v = Vec::new();
        self.encode(&mut v);
        v
    }

    /// Parses the reply line (terminator removed) to `command`. Surrounding
    /// whitespace is ignored. Floats are read in any of the forms the firmware is
    /// seen to print (`-1.01026`, `1000.00`, `-4.17234e-007`; its rule is not in the
    /// manual); indices and status bytes must be integers in their range.
    pub fn parse(command: &Command, line: &[u8]) -> Result<Reply, ReplyError> {
        let line = line.trim_ascii();
        if !command.is_query() {
            return Err(ReplyError::NotAQuery(command.mnemonic()));
        }
        if line.is_empty() {
            return Err(ReplyError::Empty);
        }
        let num = |s: &[u8]| number::parse(s.trim_ascii()).ok_or(ReplyError::BadValue);
        let int = |max: u8| -> Result<u8, ReplyError> {
            let v = num(line)?;
            if v.fract() != 0.0 {
                return Err(ReplyError::BadValue);
            }
            if !(0.0..=f64::from(max)).contains(&v) {
                return Err(ReplyError::OutOfRange(v));
            }
            // Exact: an integral value in 0..=max.
            Ok(v as u8)
        };
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
            _ => return Err(ReplyError::NotAQuery(command.mnemonic())),
        };
        Ok(reply)
    }
}

/// Fuzz bodies: feed arbitrary bytes to the parsers. Each must return normally on
/// every input; a panic means a codec bug (a parser that panics, or a value that does
/// not survive encode → parse). A `cargo fuzz` target is one line:
/// `fuzz_target!(|d: &[u8]| gonio_proto::sr830::fuzz::fuzz_parse_line(d));`.
pub mod fuzz {
    use super::*;

    /// Parses `data` as a received command line; every command that parses is
    /// encoded and parsed again and must come back equal.
    pub fn fuzz_parse_line(data: &[u8]) {
        for command in parse_line(data).into_iter().flatten() {
            let mut out = Vec::new();
            command.encode_body(&mut out);
            assert_eq!(parse_line(&out), vec![Ok(command)], "re-parse of {out:?}");
        }
    }

    /// Parses `data[1..]` as the reply to a query chosen by `data[0]`; a reply that
    /// parses is encoded and parsed again and must come back equal.
    pub fn fuzz_parse_reply(data: &[u8]) {
        let Some((&selector, line)) = data.split_first() else {
            return;
        };
        let queries = sample_queries();
        let Some(command) = queries.get(usize::from(selector) % queries.len()) else {
            return;
        };
        if let Ok(reply) = Reply::parse(command, line) {
            let bytes = reply.to_bytes();
            let body = bytes.strip_suffix(&[REPLY_TERMINATOR]).unwrap_or(&bytes);
            assert_eq!(
                Reply::parse(command, body),
                Ok(reply),
                "re-parse of {bytes:?}"
            );
        }
    }

    /// One query of each reply kind.
    fn sample_queries() -> Vec<Command> {
        let mut q = vec![
            Command::QueryInterface,
            Command::QueryReferenceSource,
            Command::QueryFrequency,
            Command::QueryAmplitude,
            Command::QuerySensitivity,
            Command::QueryTimeConstant,
            Command::QuerySlope,
            Command::ReadOutput(Output::R),
            Command::LiaStatus(None),
            Command::LiaStatus(BitIndex::new(2)),
            Command::ErrorStatus(None),
            Command::EventStatus(None),
            Command::Identify,
            // Not a query: must be refused, not parsed.
            Command::Clear,
        ];
        for n in SnapParams::MIN..=SnapParams::MAX {
            if let Some(p) = SnapParams::new(&SnapParam::ALL[..n]) {
                q.push(Command::Snap(p));
            }
        }
        q
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

    #[test]
    fn labels_accept_spacing_and_micro_spellings() {
        assert_eq!(find_label(&SENS_LABELS, "10mV"), Some(20));
        assert_eq!(find_label(&SENS_LABELS, "5 uV"), Some(10));
        assert_eq!(find_label(&SENS_LABELS, "5 μV"), Some(10));
        assert_eq!(find_label(&SENS_LABELS, "10 MV"), None);
        assert_eq!(find_label(&TC_LABELS, "30 ks"), Some(19));
    }

    #[test]
    fn command_errors_name_their_status_bit() {
        assert_eq!(
            CommandError::Unknown("X".into()).event_status(),
            EventStatus(32)
        );
        assert_eq!(CommandError::Syntax("SENS").bit(), 5);
        assert_eq!(
            CommandError::OutOfRange("SENS").event_status(),
            EventStatus(16)
        );
    }
}
