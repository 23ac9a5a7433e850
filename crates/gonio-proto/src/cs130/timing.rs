//! What the monochromator's operations cost on the wire, for planning, as the
//! session's operations make them, echoes included when configured (§15.4).

use gonio_core::spectral_timing::ChangeExchanges;

use super::{Command, Cs130Config, Reply, StatusByte, Units};
use crate::timing::wire_s;

/// The monochromator's time to answer beyond the bytes' own time on the wire, s. No
/// manual page gives one; none is assumed, and the simulated monochromator answers at
/// once.
pub const REPLY_LATENCY_S: f64 = 0.0;

impl Cs130Config {
    /// Bytes of a statement, its echo (when the instrument echoes) and its answer.
    fn exchange_bytes(&self, command: &Command, answer: Option<Reply>) -> usize {
        let out = command.to_bytes().len();
        let echo = if self.echo { out } else { 0 };
        out + echo + answer.map_or(0, |a| a.to_bytes().len())
    }

    /// One statement exchanged at `baud`, s.
    fn exchange_s(&self, command: &Command, answer: Option<Reply>, baud: u32) -> f64 {
        let latency = if self.echo || answer.is_some() {
            REPLY_LATENCY_S
        } else {
            0.0
        };
        wire_s(self.exchange_bytes(command, answer), baud) + latency
    }

    /// The session's `init` (`INFO?`, `UNITS NM`, `GRAT?`, `FILTER?` with a wheel,
    /// `SHUTTER?`, `WAVE?`, `STB?`), s.
    pub fn init_s(&self, baud: u32) -> f64 {
        let mut statements = vec![
            (
                Command::Info,
                Some(Reply::Info(
                    "Oriel, Model 74000 Cornerstone 130,SN001,V01.00.00".into(),
                )),
            ),
            (Command::Units(Units::Nm), None),
            (
                Command::GratQuery,
                Some(Reply::Grating {
                    number: 1,
                    lines_per_mm: Some(1200),
                    label: Some("BLAZE500".into()),
                }),
            ),
        ];
        if self.filter_wheel {
            statements.push((Command::FilterQuery, Some(Reply::Filter(1))));
        }
        statements.extend([
            (Command::ShutterQuery, Some(Reply::Shutter(true))),
            (Command::Wave, Some(Reply::Wavelength(500.0))),
            (Command::Stb, Some(Reply::Status(StatusByte(0)))),
        ]);
        statements
            .into_iter()
            .map(|(c, a)| self.exchange_s(&c, a, baud))
            .sum()
    }

    /// The statements of a change of wavelength (the session's `go`) around the
    /// drive's own moves: `GOWAVE`, whose arrival starts the drive, then its echo,
    /// `*WAI` and `WAVE?` while it moves, `WAVE?`'s answer once it stops, and `STB?`.
    /// A move down first goes below the wavelength and comes back up (`approach_nm`),
    /// which adds a `GOWAVE` while the drive moves; a `GRAT` or `FILTER` change is
    /// taken as starting the drive in `GOWAVE`'s place.
    pub fn change_exchanges(&self, baud: u32) -> ChangeExchanges {
        let go = Command::GoWave(512.5);
        let s = |c: &Command, a| self.exchange_s(c, a, baud);
        let echo = |c: &Command| {
            if self.echo {
                wire_s(c.to_bytes().len(), baud)
            } else {
                0.0
            }
        };
        let wave = Command::Wave;
        ChangeExchanges {
            lead_s: wire_s(go.to_bytes().len(), baud),
            during_s: echo(&go)
                + s(&Command::Wai, None)
                + wire_s(wave.to_bytes().len(), baud)
                + echo(&wave),
            trail_s: wire_s(Reply::Wavelength(512.5).to_bytes().len(), baud)
                + s(&Command::Stb, Some(Reply::Status(StatusByte(0)))),
            approach_s: s(&go, None),
        }
    }
}
