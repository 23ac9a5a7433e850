//! What a read returns: an averaged [`PicoReading`] with its [`PicoFlags`], or a
//! [`K6485Error`].

use super::{ConfigError, Identity, Range, ReplyError, ScpiError, StatusWord, accuracy_a};
use crate::TransportError;

/// Most range changes one read makes before giving up: one more than it takes to
/// cross the whole table (7), so only an oscillating signal reaches it.
pub const MAX_AUTORANGE_STEPS: usize = 8;

/// What makes a reading untrustworthy.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct PicoFlags {
    /// A sample overflowed (`+9.9E37`, status bit 0): the current is over 1.05 × full
    /// scale on the reading's range.
    pub overflow: bool,
    /// A sample's current was sent as NAN (`+9.91E37`).
    pub invalid: bool,
    /// Status bit 7: an overvoltage on the input.
    pub overvoltage: bool,
    /// Status bit 9: zero check was on; the input was shunted, so the samples are the
    /// instrument's offset, not the source.
    pub zero_check: bool,
}

impl PicoFlags {
    /// True when any flag is raised.
    pub fn any(self) -> bool {
        self.overflow || self.invalid || self.overvoltage || self.zero_check
    }
}

/// One averaged picoammeter reading, with the settings it was taken at and what went
/// wrong. Use [`PicoReading::current`] (or check [`PicoReading::is_valid`]) before
/// trusting the numbers.
#[derive(Clone, Debug, PartialEq)]
pub struct PicoReading {
    /// Mean of the samples' currents, amps (over the samples that carried a value; NaN
    /// when none did).
    pub mean_a: f64,
    /// Sample standard deviation of the currents (n − 1; 0 for one sample), amps. With
    /// the moving filter consecutive samples are correlated and this underestimates
    /// the mean's scatter.
    pub std_a: f64,
    /// Samples that carried a value.
    pub n: usize,
    /// Samples asked for.
    pub samples: usize,
    /// The range the samples were taken on.
    pub range: Range,
    /// Integration time, PLC.
    pub nplc: f64,
    /// Averaging filter count (1: off).
    pub filter_count: u32,
    /// Flags from the samples.
    pub flags: PicoFlags,
    /// Range changes autoranging made before this reading.
    pub autorange_steps: usize,
    /// The OR of the samples' status words.
    pub status: StatusWord,
    /// The instrument's timestamp of the last sample, seconds.
    pub timestamp_s: f64,
}

impl PicoReading {
    /// True when no flag is raised, every sample carried a value, and the numbers are
    /// finite: only then is the reading a measurement.
    pub fn is_valid(&self) -> bool {
        !self.flags.any()
            && self.n > 0
            && self.n == self.samples
            && self.mean_a.is_finite()
            && self.std_a.is_finite()
    }

    /// The mean current, amps, only when the reading is valid.
    pub fn current(&self) -> Option<f64> {
        self.is_valid().then_some(self.mean_a)
    }

    /// Mean current as a fraction of full scale.
    pub fn fraction_of_full_scale(&self) -> f64 {
        self.mean_a / self.range.amps()
    }

    /// The manufacturer's 1-year accuracy bound for the mean, amps ([`accuracy_a`]).
    pub fn accuracy_a(&self) -> f64 {
        accuracy_a(self.range, self.mean_a)
    }
}

/// Why the 6485 could not be set up or read. No variant carries a usable reading.
#[derive(Debug, thiserror::Error)]
pub enum K6485Error {
    /// The configuration is out of range.
    #[error("6485 config: {0}")]
    Config(#[from] ConfigError),
    /// A command got no reply in time, a NUL byte, an overlong line, or a transport
    /// fault other than a vanished port.
    #[error("6485 {command}: {source}")]
    Transport {
        /// The command, as sent (without terminator).
        command: String,
        /// The transport's error.
        source: TransportError,
    },
    /// A reply that does not parse as the answer to its query.
    #[error("6485 {command}: unreadable reply {:?}: {source}", String::from_utf8_lossy(.reply))]
    Protocol {
        /// The query, as sent.
        command: String,
        /// The reply line, terminator removed.
        reply: Vec<u8>,
        /// Why it does not parse.
        source: ReplyError,
    },
    /// The port vanished and every reconnection attempt failed.
    #[error("6485 port {port} lost; {attempts} reconnection attempts failed: {source}")]
    Disconnected {
        /// The port's name.
        port: String,
        /// Attempts made.
        attempts: u32,
        /// The last failure.
        source: TransportError,
    },
    /// `*IDN?` named another instrument.
    #[error("not a 6485 or 6487: *IDN? answered {0}")]
    WrongInstrument(Identity),
    /// The instrument detected another line frequency than the config's.
    #[error("line frequency: the config says {configured} Hz, SYST:LFR? answered {instrument} Hz")]
    LineFrequency {
        /// The config's.
        configured: u32,
        /// The instrument's.
        instrument: u32,
    },
    /// `SYST:ERR?` reported an error after set-up: a command was refused.
    #[error("the 6485 refused a command: SYST:ERR? = {0}")]
    Rejected(ScpiError),
    /// Autoranging changed range [`MAX_AUTORANGE_STEPS`] times without settling.
    #[error("autorange gave up after {steps} range changes (last reading on {})", .last.range)]
    Autorange {
        /// Range changes made.
        steps: usize,
        /// The last reading, for diagnosis only.
        last: Box<PicoReading>,
    },
    /// The port was lost and reopened again and again during one reading.
    #[error("6485 reading restarted {restarts} times after the port was lost")]
    Interrupted {
        /// Restarts made.
        restarts: usize,
    },
}
