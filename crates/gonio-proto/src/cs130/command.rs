//! Host to instrument: [`Command`], its encoding, and [`Command::parse`] for the
//! twin's side.

use super::TERMINATOR;
use crate::codec::{Param, Refusal, command_table};

/// The units `GOWAVE` takes and `WAVE?` answers in (the `UNITS` command). The session
/// always selects nanometres.
///
/// "UNITS tt … Possible parameters are: NM for nanometers, UM for micrometers, WN for
/// wavenumbers (cm-1)" (the Cornerstone 130, Model 74000, command table, transcribed in
/// a public driver; not in the stored CS130B manual; G. Salvato's `cornerstone130.cpp`
/// sends `UNITS NM` too).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Units {
    /// Nanometres.
    Nm,
    /// Micrometres.
    Um,
    /// Wavenumbers, cm⁻¹.
    Wn,
}

impl Units {
    /// The parameter as sent.
    pub fn as_str(self) -> &'static str {
        match self {
            Units::Nm => "NM",
            Units::Um => "UM",
            Units::Wn => "WN",
        }
    }

    /// A value in these units, in nanometres (wavenumbers: 10⁷ / value).
    pub fn to_nm(self, v: f64) -> f64 {
        match self {
            Units::Nm => v,
            Units::Um => v * 1e3,
            Units::Wn => 1e7 / v,
        }
    }

    /// A wavelength in nanometres, in these units.
    pub fn from_nm(self, nm: f64) -> f64 {
        match self {
            Units::Nm => nm,
            Units::Um => nm * 1e-3,
            Units::Wn => 1e7 / nm,
        }
    }
}

command_table! {
    /// A statement to the Cornerstone 130 (CS130B manual, 90088262, Appendix I, §15.3):
    /// a keyword, then for some a parameter separated by at least one space. Queries end
    /// in `?` and are answered by one line; commands are answered by nothing but their
    /// echo (§15.4, standard mode).
    #[derive(Clone, Debug, PartialEq)]
    pub enum Command, keyword, input: &str {
        /// `GOWAVE <λ>`: move the wavelength drive to λ in the present units (§15.4's
        /// example `GOWAVE 500`; §15.8's `gowave 587.1`). A destination outside the
        /// grating's range is refused with error 3 (§15.9). Sent with at most three
        /// decimals.
        GoWave(f64) = "GOWAVE" set;
        /// `WAVE?`: the wavelength, in the present units (§15.4's example answers
        /// `500.01`).
        Wave = "WAVE" query;
        /// `GRAT <n>`: "GRAT x Moves the wavelength drive to the grating specified in
        /// the integer parameter" (Model 74000 command table, whose turret has gratings
        /// 1 and 2).
        Grat(u8) = "GRAT" set;
        /// `GRAT?`: the grating in use, `n,lines,label` (Model 74000 command table; see
        /// [`Reply::Grating`](super::Reply::Grating)).
        GratQuery = "GRAT" query;
        /// `FILTER <n>`: move the filter wheel to position n, "Acceptable values range
        /// from 1 through 6" (Model 74000 command table). Without a wheel the instrument
        /// flags an error (§15.9's code 6, "accessory not present (usually filter
        /// wheel)"), so a session configured without one never sends it.
        Filter(u8) = "FILTER" set;
        /// `FILTER?`: the filter wheel's position; `0`, with an error set in the status
        /// byte, "if there is no filter wheel connected, or if the wheel is out of
        /// position" (Model 74000 command table).
        FilterQuery = "FILTER" query;
        /// `SHUTTER O` / `SHUTTER C`: open or close the shutter (§15.8's example
        /// `shutter o`).
        Shutter(bool) = "SHUTTER" set;
        /// `SHUTTER?`: `O` or `C`, "simply the one character parameter describing the
        /// current state" (Model 74000 command table).
        ShutterQuery = "SHUTTER" query;
        /// `UNITS <u>`: the wavelength units.
        Units(Units) = "UNITS" set;
        /// `STB?`: the status byte; reading it clears it (§15.9).
        Stb = "STB" query;
        /// `ERROR?`: the latest error code; reading it resets it to 0 (§15.9).
        Error = "ERROR" query;
        /// `INFO?`: the model and firmware, `Oriel, Model 74000 Cornerstone
        /// 130,SNXXX,VYY.YY.YY` on the Model 74000 (its command table); any printable
        /// text is accepted, since the CS130B's exact answer was not found.
        Info = "INFO" query;
        /// `ABORT`: "Stops any wavelength motion immediately, i.e. GOSCAN, GOWAVE, STEP"
        /// (Model 74000 command table).
        Abort = "ABORT" set;
        /// `*WAI`: hold every later statement until the pending operations (a move) are
        /// finished (§15.8).
        Wai = "*WAI" set;
    }
}

/// What follows the keyword (from its first blank on, `""` for none), trimmed by each
/// reader. Any refusal is error 2.
impl Param<&str> for () {
    fn write(&self, _: &mut Vec<u8>) {}
    fn read(p: &str) -> Result<(), Refusal> {
        p.is_empty().then_some(()).ok_or(Refusal::Syntax)
    }
}

/// A wavelength: any finite number, sent with at most three decimals.
impl Param<&str> for f64 {
    fn write(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(format!(" {}", format_value(*self)).as_bytes());
    }
    fn read(p: &str) -> Result<f64, Refusal> {
        p.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or(Refusal::Syntax)
    }
}

/// A grating or filter position, 0..=255 written as a plain integer.
impl Param<&str> for u8 {
    fn write(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(format!(" {self}").as_bytes());
    }
    fn read(p: &str) -> Result<u8, Refusal> {
        crate::number::decimal(p.trim(), usize::MAX).ok_or(Refusal::Syntax)
    }
}

/// The shutter, `O` (open) or `C`.
impl Param<&str> for bool {
    fn write(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(if *self { b" O" } else { b" C" });
    }
    fn read(p: &str) -> Result<bool, Refusal> {
        match p.trim().to_ascii_uppercase().as_str() {
            "O" => Ok(true),
            "C" => Ok(false),
            _ => Err(Refusal::Syntax),
        }
    }
}

impl Param<&str> for Units {
    fn write(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(format!(" {}", self.as_str()).as_bytes());
    }
    fn read(p: &str) -> Result<Units, Refusal> {
        let p = p.trim().to_ascii_uppercase();
        [Units::Nm, Units::Um, Units::Wn]
            .into_iter()
            .find(|u| u.as_str() == p)
            .ok_or(Refusal::Syntax)
    }
}

/// Why a received line is not a statement the instrument runs: the error code it
/// records (§15.9), which the twin reports through `STB?` and `ERROR?`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    /// Not a keyword the codec knows: error 1, "Command not understood".
    #[error("command not understood: {0:?}")]
    Unknown(String),
    /// A known keyword with a missing, extra or bad parameter: error 2, "Bad parameter
    /// used in command".
    #[error("{0}: bad parameter")]
    BadParameter(&'static str),
}

impl CommandError {
    /// The manual's error code (§15.9).
    pub fn code(&self) -> u8 {
        match self {
            CommandError::Unknown(_) => 1,
            CommandError::BadParameter(_) => 2,
        }
    }
}

crate::codec::line_encoding!(Command, TERMINATOR);

impl Command {
    /// True for the statements that start or wait for a mechanism move: after them
    /// the session allows `move_timeout` for the next echoes and answers.
    pub fn moves(&self) -> bool {
        matches!(
            self,
            Command::GoWave(_) | Command::Grat(_) | Command::Filter(_) | Command::Wai
        )
    }

    /// True when sending it twice does what sending it once does: all but `STB?` and
    /// `ERROR?`, whose reading clears what they report (§15.9); set commands are
    /// absolute (a wavelength, a position, a state).
    pub fn is_repeatable(&self) -> bool {
        !matches!(self, Command::Stb | Command::Error)
    }

    /// Appends the statement without terminator.
    pub fn encode_body(&self, out: &mut Vec<u8>) {
        self.encode_row(out);
    }

    /// Parses one received statement (terminator removed), as the instrument does:
    /// case ignored (§15.3), the parameter after at least one space, surrounding
    /// blanks ignored.
    pub fn parse(line: &[u8]) -> Result<Command, CommandError> {
        let text = String::from_utf8_lossy(line);
        let text = text.trim_matches(|c: char| c.is_ascii_whitespace());
        let (keyword, param) = match text.find(|c: char| c.is_ascii_whitespace()) {
            Some(i) => text.split_at(i),
            None => (text, ""),
        };
        let (keyword, query) = match keyword.strip_suffix('?') {
            Some(k) => (k, true),
            None => (keyword, false),
        };
        match Command::from_row(keyword, query, param) {
            Some((_, Ok(command))) => Ok(command),
            Some((name, Err(_))) => Err(CommandError::BadParameter(name)),
            None => Err(CommandError::Unknown(text.to_string())),
        }
    }
}

/// A number with at most three decimals and no trailing zeros (`500`, `587.1`).
pub(super) fn format_value(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}
