//! The IEEE 488.2 `*IDN?` reply that the SCPI-style instruments share: four
//! comma-separated fields (IEEE 488.2, 10.14). Each family adds what it reads from
//! it ([`crate::k6485`]: which picoammeter; [`crate::sr830`]: whether an SR830).

use std::fmt;

/// The `*IDN?` reply: manufacturer, model, serial number, firmware, e.g.
/// `Stanford_Research_Systems,SR830,s/n00111,ver1.000` (SR830 manual, *IDN?) or
/// `KEITHLEY INSTRUMENTS INC.,MODEL 6485,1234567,B03   Sep 25 2002 10:53:29/A02  /E`
/// (6485 manual, *IDN?).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Identity {
    /// `Stanford_Research_Systems`, `KEITHLEY INSTRUMENTS INC.`
    pub manufacturer: String,
    /// `SR830` (an SR810 or SR850 answers its own name), `MODEL 6485`.
    pub model: String,
    /// `s/n00111`, `1234567`.
    pub serial: String,
    /// Firmware revision levels, free text (`ver1.000` in the SR830 manual; real units
    /// report e.g. `ver1.07`).
    pub firmware: String,
}

impl Identity {
    /// Parses the four fields; each is trimmed and must be non-empty printable ASCII.
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
