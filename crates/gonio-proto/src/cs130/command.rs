//! Host to instrument: [`Command`], its encoding, and [`Command::parse`] for the
//! twin's side.

use super::TERMINATOR;

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

/// A statement to the Cornerstone 130 (CS130B manual, 90088262, Appendix I, §15.3):
/// a keyword, then for some a parameter separated by at least one space. Queries end
/// in `?` and are answered by one line; commands are answered by nothing but their
/// echo (§15.4, standard mode).
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// `GOWAVE <λ>`: move the wavelength drive to λ in the present units (§15.4's
    /// example `GOWAVE 500`; §15.8's `gowave 587.1`). A destination outside the
    /// grating's range is refused with error 3 (§15.9). Sent with at most three
    /// decimals.
    GoWave(f64),
    /// `WAVE?`: the wavelength, in the present units (§15.4's example answers
    /// `500.01`).
    Wave,
    /// `GRAT <n>`: select grating n (the drive turns the turret): "GRAT x Moves the
    /// wavelength drive to the grating specified in the integer parameter" (Model
    /// 74000 command table, whose turret has gratings 1 and 2).
    Grat(u8),
    /// `GRAT?`: the grating in use, `n,lines,label` (Model 74000 command table; see
    /// [`Reply::Grating`](super::Reply::Grating)).
    GratQuery,
    /// `FILTER <n>`: move the filter wheel to position n, "Acceptable values range
    /// from 1 through 6" (Model 74000 command table). Without a wheel the instrument
    /// flags an error (§15.9's code 6, "accessory not present (usually filter
    /// wheel)"), so a session configured without one never sends it.
    Filter(u8),
    /// `FILTER?`: the filter wheel's position; `0`, with an error set in the status
    /// byte, "if there is no filter wheel connected, or if the wheel is out of
    /// position" (Model 74000 command table).
    FilterQuery,
    /// `SHUTTER O` / `SHUTTER C`: open or close the shutter (§15.8's example
    /// `shutter o`).
    Shutter(bool),
    /// `SHUTTER?`: `O` or `C`, "simply the one character parameter describing the
    /// current state" (Model 74000 command table).
    ShutterQuery,
    /// `UNITS <u>`: the wavelength units.
    Units(Units),
    /// `STB?`: the status byte; reading it clears it (§15.9).
    Stb,
    /// `ERROR?`: the latest error code; reading it resets it to 0 (§15.9).
    Error,
    /// `INFO?`: the model and firmware, `Oriel, Model 74000 Cornerstone
    /// 130,SNXXX,VYY.YY.YY` on the Model 74000 (its command table); any printable
    /// text is accepted, since the CS130B's exact answer was not found.
    Info,
    /// `ABORT`: "Stops any wavelength motion immediately, i.e. GOSCAN, GOWAVE, STEP"
    /// (Model 74000 command table).
    Abort,
    /// `*WAI`: hold every later statement until the pending operations (a move) are
    /// finished (§15.8). The session's way of knowing a move is done: the query sent
    /// after it is answered only then.
    Wai,
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
    /// True for queries, which the instrument answers with a line after the echo.
    pub fn is_query(&self) -> bool {
        matches!(
            self,
            Command::Wave
                | Command::GratQuery
                | Command::FilterQuery
                | Command::ShutterQuery
                | Command::Stb
                | Command::Error
                | Command::Info
        )
    }

    /// True for the statements that start or wait for a mechanism move (`GOWAVE`,
    /// `GRAT`, `FILTER`, `*WAI`): after them the session allows `move_timeout` for
    /// the next echoes and answers.
    pub fn moves(&self) -> bool {
        matches!(
            self,
            Command::GoWave(_) | Command::Grat(_) | Command::Filter(_) | Command::Wai
        )
    }

    /// True when sending it twice does what sending it once does: everything but the
    /// queries whose reading clears what they report (`STB?`, `ERROR?`, §15.9). Set
    /// commands are absolute (a wavelength, a position, a state), so a lost echo may
    /// be answered by sending the command again.
    pub fn is_repeatable(&self) -> bool {
        !matches!(self, Command::Stb | Command::Error)
    }

    /// Appends the statement without terminator.
    pub fn encode_body(&self, out: &mut Vec<u8>) {
        let text = match self {
            Command::GoWave(nm) => format!("GOWAVE {}", format_value(*nm)),
            Command::Wave => "WAVE?".into(),
            Command::Grat(n) => format!("GRAT {n}"),
            Command::GratQuery => "GRAT?".into(),
            Command::Filter(n) => format!("FILTER {n}"),
            Command::FilterQuery => "FILTER?".into(),
            Command::Shutter(open) => format!("SHUTTER {}", if *open { 'O' } else { 'C' }),
            Command::ShutterQuery => "SHUTTER?".into(),
            Command::Units(u) => format!("UNITS {}", u.as_str()),
            Command::Stb => "STB?".into(),
            Command::Error => "ERROR?".into(),
            Command::Info => "INFO?".into(),
            Command::Abort => "ABORT".into(),
            Command::Wai => "*WAI".into(),
        };
        out.extend_from_slice(text.as_bytes());
    }

    /// Parses one received statement (terminator removed), as the instrument does:
    /// case ignored (§15.3), the parameter after at least one space, surrounding
    /// blanks ignored.
    pub fn parse(line: &[u8]) -> Result<Command, CommandError> {
        let text = String::from_utf8_lossy(line);
        let text = text.trim_matches(|c: char| c.is_ascii_whitespace());
        let (keyword, param) = match text.find(|c: char| c.is_ascii_whitespace()) {
            Some(i) => (&text[..i], Some(text[i..].trim())),
            None => (text, None),
        };
        let keyword = keyword.to_ascii_uppercase();
        let bare = |c: Command, name: &'static str| match param {
            None => Ok(c),
            Some(_) => Err(CommandError::BadParameter(name)),
        };
        match keyword.as_str() {
            "GOWAVE" => param
                .and_then(|p| p.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .map(Command::GoWave)
                .ok_or(CommandError::BadParameter("GOWAVE")),
            "GRAT" => small_int(param)
                .map(Command::Grat)
                .ok_or(CommandError::BadParameter("GRAT")),
            "FILTER" => small_int(param)
                .map(Command::Filter)
                .ok_or(CommandError::BadParameter("FILTER")),
            "SHUTTER" => match param.map(str::to_ascii_uppercase).as_deref() {
                Some("O") => Ok(Command::Shutter(true)),
                Some("C") => Ok(Command::Shutter(false)),
                _ => Err(CommandError::BadParameter("SHUTTER")),
            },
            "UNITS" => match param.map(str::to_ascii_uppercase).as_deref() {
                Some("NM") => Ok(Command::Units(Units::Nm)),
                Some("UM") => Ok(Command::Units(Units::Um)),
                Some("WN") => Ok(Command::Units(Units::Wn)),
                _ => Err(CommandError::BadParameter("UNITS")),
            },
            "WAVE?" => bare(Command::Wave, "WAVE?"),
            "GRAT?" => bare(Command::GratQuery, "GRAT?"),
            "FILTER?" => bare(Command::FilterQuery, "FILTER?"),
            "SHUTTER?" => bare(Command::ShutterQuery, "SHUTTER?"),
            "STB?" => bare(Command::Stb, "STB?"),
            "ERROR?" => bare(Command::Error, "ERROR?"),
            "INFO?" => bare(Command::Info, "INFO?"),
            "ABORT" => bare(Command::Abort, "ABORT"),
            "*WAI" => bare(Command::Wai, "*WAI"),
            _ => Err(CommandError::Unknown(text.to_string())),
        }
    }
}

/// A parameter 0..=255 written as a plain integer.
fn small_int(param: Option<&str>) -> Option<u8> {
    let p = param?;
    if p.is_empty() || !p.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    p.parse().ok()
}

/// A number with at most three decimals and no trailing zeros (`500`, `587.1`).
pub(super) fn format_value(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}
