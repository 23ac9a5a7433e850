//! Host to controller: [`Command`], addressed in a [`Frame`], and the errors a controller
//! stores for a line it cannot run.

use super::{ErrorCode, MAX_ADDRESS, TERMINATOR};
use crate::number;

/// How a parameter's value is written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    /// A real number: a `ZT` dump writes six decimals.
    Real,
    /// A whole number, written without decimals everywhere.
    Integer,
    /// Text (`ID`).
    Text,
}

/// The parameters, one row each: the command code, the kind of value, and whether it
/// is configuration (settable in CONFIGURATION and listed by `ZT`, in the order the
/// dump lists them: alphabetical by code). Each variant's doc begins with its code.
macro_rules! params {
    (
        configuration { $($(#[$cdoc:meta])* $c:ident $ccode:literal $ckind:ident,)* }
        other { $($(#[$odoc:meta])* $o:ident $ocode:literal $okind:ident,)* }
    ) => {
        /// A parameter that can be queried with `xxAA?`; most can also be set, and those the
        /// `ZT` dump lists are the controller's configuration (manual §2, command pages).
        ///
        /// Codes of three letters (`QIL`, `FRM`) are the manual's sub-commands: `QI` (motor
        /// current limits) and `FR` (stepper motor configuration) with their third letter.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum Param {
            $(#[doc = concat!("`", $ccode, "`:")] $(#[$cdoc])* $c,)*
            $(#[doc = concat!("`", $ocode, "`:")] $(#[$odoc])* $o,)*
        }

        /// Every parameter: code, kind, and whether it is configuration.
        const PARAMS: &[(Param, &str, Kind, bool)] = &[
            $((Param::$c, $ccode, Kind::$ckind, true),)*
            $((Param::$o, $ocode, Kind::$okind, false),)*
        ];

        impl Param {
            /// Every numeric configuration parameter of an SMC100PP (the manual's command
            /// table, p. 18, less the CC-only `DV`, `FD`, `FE`, `FF`, `KD`, `KI`, `KP`, `KV`, `SC`,
            /// `SU`), in alphabetical order of its code.
            pub const CONFIGURATION: [Param; [$($ccode),*].len()] = [$(Param::$c),*];
        }
    };
}

params! {
    configuration {
    /// Acceleration, units/s².
    Acceleration "AC" Real,
    /// Backlash compensation, units.
    Backlash "BA" Real,
    /// Hysteresis compensation, units.
    Hysteresis "BH" Real,
    /// Micro-steps per full step (PP only).
    MicroSteps "FRM" Integer,
    /// The motion of one full step, units (PP only; it defines the units).
    FullStep "FRS" Real,
    /// Home search type, 0–4 (0 MZ switch and index, 1 current position, 2 MZ
    /// switch only, 3 EoR− switch and index, 4 EoR− switch only).
    HomeType "HT" Integer,
    /// Jerk time, s.
    JerkTime "JR" Real,
    /// Home search velocity, units/s.
    HomeVelocity "OH" Real,
    /// Home search time-out, s.
    HomeTimeout "OT" Real,
    /// Motor peak current limit, A.
    PeakCurrent "QIL" Real,
    /// Motor rms current limit, A.
    RmsCurrent "QIR" Real,
    /// Averaging time of the rms current, s.
    RmsTime "QIT" Real,
    /// RS-485 address.
    RsAddress "SA" Integer,
    /// Negative software limit, units.
    NegativeLimit "SL" Real,
    /// Positive software limit, units.
    PositiveLimit "SR" Real,
    /// Velocity, units/s.
    Velocity "VA" Real,
    /// Base velocity, units/s (PP only).
    BaseVelocity "VB" Real,
    /// ESP stage check, 1–3 (1 off, 2 read the stage's EEPROM, 3 check at
    /// power-up).
    StageCheck "ZX" Integer,
    }
    other {
    /// Target of the last absolute move, units.
    AbsoluteTarget "PA" Real,
    /// Displacement of the last relative move, units.
    RelativeTarget "PR" Real,
    /// 1 when READY (enabled), 0 when DISABLE.
    Enabled "MM" Integer,
    /// Stage identifier (a string).
    StageId "ID" Text,
    /// 1 in CONFIGURATION, 0 otherwise.
    ConfigurationMode "PW" Integer,
    }
}

impl Param {
    /// True for a parameter an SMC100PP's `ZT` dump lists: every configuration
    /// parameter but `QIR` and `QIT` (p. 45), which are set and asked for but not
    /// listed. The manual gives only an example dump (p. 67); this is the list
    /// hvl_ccb's `NewportSMC100PP` (0.19.6), written against real controllers,
    /// requires line for line, in [`CONFIGURATION`](Self::CONFIGURATION)'s order:
    /// `AC BA BH FRM FRS HT JR OH OT QIL SA SL SR VA VB ZX`.
    pub fn in_pp_dump(self) -> bool {
        self.is_configuration() && !matches!(self, Param::RmsCurrent | Param::RmsTime)
    }

    fn entry(self) -> (Param, &'static str, Kind, bool) {
        // Every variant has its row; the fallback is never taken.
        PARAMS
            .iter()
            .copied()
            .find(|(p, ..)| *p == self)
            .unwrap_or((self, "", Kind::Real, false))
    }

    /// The command code (two letters, or three for `QIx` and `FRx`).
    pub fn code(self) -> &'static str {
        self.entry().1
    }

    /// True for a numeric configuration parameter: set in CONFIGURATION, saved by `PW0`,
    /// listed by `ZT`.
    pub fn is_configuration(self) -> bool {
        self.entry().3
    }

    /// True when the value is a whole number (`HT`, `SA`, `ZX`, `FRM`, `MM`, `PW`).
    pub fn is_integer(self) -> bool {
        self.entry().2 == Kind::Integer
    }

    /// True when a controller takes `value` for this parameter in CONFIGURATION: the
    /// ranges of the manual's command pages (a value outside is refused with `C`).
    /// Where the manual gives only "> 1E-6 and < 1E12" that is the range. Relations
    /// between parameters (`QIR` ≤ `QIL`, `VB` ≤ `VA`, `BA` and `BH` not both) are not
    /// checked here.
    pub fn accepts(self, value: f64) -> bool {
        let open = |lo: f64, hi: f64| value > lo && value < hi;
        let whole = |lo: f64, hi: f64| value.fract() == 0.0 && value >= lo && value <= hi;
        if !value.is_finite() {
            return false;
        }
        match self {
            Param::Acceleration | Param::Velocity | Param::HomeVelocity | Param::FullStep => {
                open(1e-6, 1e12)
            }
            // QI page (p. 45): QIL "≥ 0.05 and ≤ 3.0" A, QIR "≥ 0.05 and ≤ 1.5" A,
            // QIT "> 0.01 and ≤ 100" s.
            Param::PeakCurrent => (0.05..=3.0).contains(&value),
            Param::RmsCurrent => (0.05..=1.5).contains(&value),
            Param::RmsTime => value > 0.01 && value <= 100.0,
            // JR page (p. 32): "> 0.001 and < 1E12" s.
            Param::JerkTime => open(1e-3, 1e12),
            Param::Backlash | Param::Hysteresis | Param::BaseVelocity => {
                (0.0..1e12).contains(&value)
            }
            Param::HomeTimeout => open(1.0, 1e3),
            Param::NegativeLimit => value > -1e12 && value <= 0.0,
            Param::PositiveLimit => (0.0..1e12).contains(&value),
            Param::HomeType => whole(0.0, 4.0),
            Param::MicroSteps => whole(1.0, 2000.0),
            // SA page (p. 49): "2 to 31"; the controller on RS-232 is address 1
            // whatever its SA.
            Param::RsAddress => whole(2.0, 31.0),
            Param::StageCheck => whole(1.0, 3.0),
            Param::Enabled | Param::ConfigurationMode => whole(0.0, 1.0),
            Param::AbsoluteTarget | Param::RelativeTarget => open(-1e12, 1e12),
            Param::StageId => false,
        }
    }

    /// The parameter a code names; `None` for codes that are not parameters.
    pub fn from_code(c: &str) -> Option<Param> {
        PARAMS.iter().find(|(_, code, ..)| *code == c).map(|e| e.0)
    }

    /// Writes `value` as a `ZT` dump does: six decimals for a real (`1AC320.000000`),
    /// none for a whole number (`1HT1`). A value that six decimals would not give back
    /// exactly is written in full, so that a dump never changes what it reports.
    pub(super) fn format_fixed(self, value: f64, out: &mut Vec<u8>) {
        let fixed = format!("{value:.6}");
        if !self.is_integer() && fixed.parse::<f64>().ok() == Some(value) {
            out.extend_from_slice(fixed.as_bytes());
        } else {
            crate::number::format(value, out);
        }
    }
}

/// A command to one controller (or, for `ST` and `MM`, to all).
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// `OR`: start the home search (accepted in NOT REFERENCED only).
    Home,
    /// `PAnn`: move to an absolute position, units.
    MoveAbsolute(f64),
    /// `PRnn`: move by a displacement from the current target, units.
    MoveRelative(f64),
    /// `ST`: stop, decelerating with the configured acceleration.
    Stop,
    /// `RS`: hardware reset, as at power-up; ends in NOT REFERENCED.
    Reset,
    /// `MM1` (leave DISABLE for READY) or `MM0` (READY to DISABLE).
    Enable(bool),
    /// `SLnn`: negative software limit, units.
    SetNegativeLimit(f64),
    /// `SRnn`: positive software limit, units.
    SetPositiveLimit(f64),
    /// `VAnn`: velocity, units/s.
    SetVelocity(f64),
    /// `ACnn`: acceleration, units/s².
    SetAcceleration(f64),
    /// `PTnn`: the time a relative move of |nn| would take (no motion); replies.
    MotionTime(f64),
    /// `TP`: current (encoder) position; replies.
    TellPosition,
    /// `TH`: set-point position; replies.
    TellSetpoint,
    /// `TS`: positioner errors and controller state; replies. Clears latched errors.
    TellStatus,
    /// `TE`: last command error letter; replies. Reading clears it.
    TellError,
    /// `VE`: firmware version string; replies.
    Version,
    /// `xxAA?`: the value of a parameter; replies.
    Query(Param),
    /// `xxAAnn`: sets a configuration parameter that has no variant of its own (`BA`,
    /// `HT`, `OH`, `QIL`…); accepted in CONFIGURATION only. Build it with
    /// [`Command::set`], which picks the dedicated variant where there is one.
    Set(Param, f64),
    /// `IDxx`: names the stage (1–31 characters; CONFIGURATION only).
    SetStageId(String),
    /// `PW1` enters CONFIGURATION (from NOT REFERENCED only); `PW0` saves the
    /// configuration to the controller's memory and leaves for NOT REFERENCED. The
    /// controller answers nothing while it saves (up to 10 s, manual PW command).
    ConfigurationMode(bool),
    /// `ZT`: every configuration parameter, one line each (manual ZT command); the
    /// lines are the commands that would set them, from `PW1` to `PW0`.
    DumpConfiguration,
}

impl Command {
    /// The two-letter code.
    pub fn code(&self) -> &'static str {
        match self {
            Command::Home => "OR",
            Command::MoveAbsolute(_) => "PA",
            Command::MoveRelative(_) => "PR",
            Command::Stop => "ST",
            Command::Reset => "RS",
            Command::Enable(_) => "MM",
            Command::SetNegativeLimit(_) => "SL",
            Command::SetPositiveLimit(_) => "SR",
            Command::SetVelocity(_) => "VA",
            Command::SetAcceleration(_) => "AC",
            Command::MotionTime(_) => "PT",
            Command::TellPosition => "TP",
            Command::TellSetpoint => "TH",
            Command::TellStatus => "TS",
            Command::TellError => "TE",
            Command::Version => "VE",
            Command::Query(p) | Command::Set(p, _) => p.code(),
            Command::SetStageId(_) => "ID",
            Command::ConfigurationMode(_) => "PW",
            Command::DumpConfiguration => "ZT",
        }
    }

    /// The command that sets `param` to `value`: the dedicated variant for `SL`, `SR`,
    /// `VA` and `AC` (so that it is what the controller's parser reads back), the
    /// generic [`Command::Set`] for the others.
    pub fn set(param: Param, value: f64) -> Command {
        match param {
            Param::NegativeLimit => Command::SetNegativeLimit(value),
            Param::PositiveLimit => Command::SetPositiveLimit(value),
            Param::Velocity => Command::SetVelocity(value),
            Param::Acceleration => Command::SetAcceleration(value),
            p => Command::Set(p, value),
        }
    }

    /// True when the controller answers this command with a reply line.
    pub fn expects_reply(&self) -> bool {
        matches!(
            self,
            Command::MotionTime(_)
                | Command::TellPosition
                | Command::TellSetpoint
                | Command::TellStatus
                | Command::TellError
                | Command::Version
                | Command::Query(_)
                | Command::DumpConfiguration
        )
    }

    /// True when sending the command twice has the same effect as sending it once, so
    /// that a driver may re-send it after a lost acknowledgement. An absolute move is;
    /// a relative move is not (it would move twice), nor is `TE` or `TS` (reading
    /// clears what they report), nor a reset, a home search, or `PW` (a second `PW1`
    /// is refused in CONFIGURATION; a second `PW0` finds the controller saving).
    pub fn is_idempotent(&self) -> bool {
        !matches!(
            self,
            Command::MoveRelative(_)
                | Command::TellError
                | Command::TellStatus
                | Command::Reset
                | Command::Home
                | Command::ConfigurationMode(_)
        )
    }

    /// True for the commands that may go to every controller at once (no address).
    pub fn may_broadcast(&self) -> bool {
        matches!(self, Command::Stop | Command::Enable(_))
    }
}

/// A command with its destination: one controller, or all for a broadcast.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Controller address 1–31, or `None` for every controller.
    pub address: Option<u8>,
    /// The command.
    pub command: Command,
}

/// Why a command line is refused, with the error letter a controller would store.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    /// Unknown command code, or a floating-point address: error `A`.
    #[error("unknown command or malformed address")]
    Unknown,
    /// Address missing (for a command that needs one) or outside 1–31: error `B`.
    #[error("controller address missing or out of range")]
    BadAddress,
    /// Parameter missing or out of range: error `C`.
    #[error("parameter missing or out of range")]
    BadParameter,
}

impl CommandError {
    /// The `TE` letter a controller stores for this fault.
    pub fn error_code(&self) -> ErrorCode {
        match self {
            CommandError::Unknown => ErrorCode::UnknownCommand,
            CommandError::BadAddress => ErrorCode::BadAddress,
            CommandError::BadParameter => ErrorCode::BadParameter,
        }
    }
}

impl Frame {
    /// A command to controller `address`.
    pub fn addressed(address: u8, command: Command) -> Self {
        Frame {
            address: Some(address),
            command,
        }
    }

    /// A command to every controller (only `ST` and `MM` may be broadcast).
    pub fn broadcast(command: Command) -> Self {
        Frame {
            address: None,
            command,
        }
    }

    /// Appends the command line, terminator included, to `out`. Addresses are written
    /// without leading zeros, values in the shortest decimal form that reads back
    /// exactly.
    pub fn encode(&self, out: &mut Vec<u8>) {
        if let Some(a) = self.address {
            out.extend_from_slice(a.to_string().as_bytes());
        }
        out.extend_from_slice(self.command.code().as_bytes());
        match &self.command {
            Command::MoveAbsolute(v)
            | Command::MoveRelative(v)
            | Command::SetNegativeLimit(v)
            | Command::SetPositiveLimit(v)
            | Command::SetVelocity(v)
            | Command::SetAcceleration(v)
            | Command::Set(_, v)
            | Command::MotionTime(v) => number::format(*v, out),
            Command::Enable(on) | Command::ConfigurationMode(on) => {
                out.push(if *on { b'1' } else { b'0' })
            }
            Command::SetStageId(name) => out.extend_from_slice(name.as_bytes()),
            Command::Query(_) => out.push(b'?'),
            _ => {}
        }
        out.extend_from_slice(TERMINATOR);
    }

    /// The command line as bytes, terminator included.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut v = Vec::new();
        self.encode(&mut v);
        v
    }

    /// Parses a received command line (terminator removed), as a controller does:
    /// case-insensitive, blanks ignored anywhere, characters after the command
    /// ignored (so `1TS?` is `1TS`).
    pub fn parse(line: &[u8]) -> Result<Frame, CommandError> {
        let s: Vec<u8> = line
            .iter()
            .filter(|b| **b != b' ' && **b != b'\t')
            .map(|b| b.to_ascii_uppercase())
            .collect();
        let (digits, code, rest) = split(&s);
        if s.get(digits.len()) == Some(&b'.') {
            return Err(CommandError::Unknown);
        }
        let address = match digits.len() {
            0 => None,
            // Two ASCII digits at most: always a valid number.
            1 | 2 => Some(address(digits)),
            _ => return Err(CommandError::BadAddress),
        };
        let code = code.ok_or(CommandError::Unknown)?;
        let code = std::str::from_utf8(code).map_err(|_| CommandError::Unknown)?;
        let query = rest.first() == Some(&b'?');
        let value = || -> Result<f64, CommandError> {
            // The value is the longest numeric prefix; what follows is ignored.
            let end = rest
                .iter()
                .position(|b| !(b.is_ascii_digit() || matches!(b, b'.' | b'-' | b'+' | b'E')))
                .unwrap_or(rest.len());
            number::parse(&rest[..end]).ok_or(CommandError::BadParameter)
        };
        let command = match code {
            "OR" => Command::Home,
            "ST" => Command::Stop,
            "RS" => Command::Reset,
            "TP" => Command::TellPosition,
            "TH" => Command::TellSetpoint,
            "TS" => Command::TellStatus,
            "TE" => Command::TellError,
            "VE" => Command::Version,
            "ID" if query => Command::Query(Param::StageId),
            "ID" => Command::SetStageId(stage_name(rest)?),
            "PT" => Command::MotionTime(value()?),
            "ZT" => Command::DumpConfiguration,
            "PW" if !query => match value()? {
                0.0 => Command::ConfigurationMode(false),
                1.0 => Command::ConfigurationMode(true),
                _ => return Err(CommandError::BadParameter),
            },
            c => match (Param::from_code(c), query) {
                (Some(p), true) => Command::Query(p),
                (Some(Param::AbsoluteTarget), false) => Command::MoveAbsolute(value()?),
                (Some(Param::RelativeTarget), false) => Command::MoveRelative(value()?),
                (Some(Param::NegativeLimit), false) => Command::SetNegativeLimit(value()?),
                (Some(Param::PositiveLimit), false) => Command::SetPositiveLimit(value()?),
                (Some(Param::Velocity), false) => Command::SetVelocity(value()?),
                (Some(Param::Acceleration), false) => Command::SetAcceleration(value()?),
                (Some(Param::Enabled), false) => match value()? {
                    0.0 => Command::Enable(false),
                    1.0 => Command::Enable(true),
                    _ => return Err(CommandError::BadParameter),
                },
                (Some(Param::StageId | Param::ConfigurationMode), false) => {
                    return Err(CommandError::Unknown);
                }
                (Some(p), false) => Command::Set(p, value()?),
                (None, _) => return Err(CommandError::Unknown),
            },
        };
        let address = match address {
            Some(0) | None if command.may_broadcast() => None,
            Some(a) if (1..=MAX_ADDRESS).contains(&a) => Some(a),
            _ => return Err(CommandError::BadAddress),
        };
        Ok(Frame { address, command })
    }
}

/// The address digits at the start of `line`, the command code after them (two letters,
/// or three for `QI` and `FR` with their third, `QIL`, `FRM`; `None` when the line ends
/// first) and the rest: how a controller reads a command and a host a reply.
pub(super) fn split(line: &[u8]) -> (&[u8], Option<&[u8]>, &[u8]) {
    let digits = line.iter().take_while(|b| b.is_ascii_digit()).count();
    let len = match line.get(digits..digits + 2) {
        Some(b"QI" | b"FR") => 3,
        _ => 2,
    };
    match line.get(digits..digits + len) {
        Some(code) => (&line[..digits], Some(code), &line[digits + len..]),
        None => (&line[..digits], None, &[]),
    }
}

/// One or two address digits as a number.
pub(super) fn address(digits: &[u8]) -> u8 {
    digits.iter().fold(0u8, |acc, d| acc * 10 + (d - b'0'))
}

/// A stage name as `IDxx` carries it: 1–31 printable ASCII characters (the line has
/// already lost its blanks and been upper-cased, as the controller reads it).
fn stage_name(rest: &[u8]) -> Result<String, CommandError> {
    if rest.is_empty() || rest.len() > 31 || !rest.iter().all(u8::is_ascii_graphic) {
        return Err(CommandError::BadParameter);
    }
    String::from_utf8(rest.to_vec()).map_err(|_| CommandError::BadParameter)
}
