//! What a read returns: an averaged [`Reading`] with its [`ReadingFlags`], or an
//! [`Sr830Error`].

use super::{
    ConfigError, EventStatus, FilterSlope, Identity, LiaStatus, ReplyError, Sensitivity,
    TimeConstant,
};
use crate::TransportError;

/// Most range changes one read ([`Sr830Session::start_read`](super::Sr830Session::start_read))
/// makes before giving up: one more than it takes to cross the whole table (26), so
/// only an oscillating signal reaches it.
pub const MAX_AUTORANGE_STEPS: usize = 27;

/// What went wrong while a reading could be trusted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct ReadingFlags {
    /// LIAS bit 0: input or reserve overload.
    pub input_overload: bool,
    /// LIAS bit 1: time-constant filter overload.
    pub filter_overload: bool,
    /// LIAS bit 2: an output over 1.09 × full scale.
    pub output_overload: bool,
    /// LIAS bit 3: the reference is unlocked; R is meaningless.
    pub unlock: bool,
}

impl ReadingFlags {
    /// The flags a LIA status byte raises.
    pub fn from_status(s: LiaStatus) -> Self {
        ReadingFlags {
            input_overload: s.input_overload(),
            filter_overload: s.filter_overload(),
            output_overload: s.output_overload(),
            unlock: s.unlocked(),
        }
    }

    /// True when any flag is raised.
    pub fn any(self) -> bool {
        self.input_overload || self.filter_overload || self.output_overload || self.unlock
    }
}

/// One averaged lock-in reading, with the settings it was taken at and what went wrong.
/// Use [`Reading::r`] (or check [`Reading::is_valid`]) before trusting the numbers.
#[derive(Clone, Debug, PartialEq)]
pub struct Reading {
    /// Mean of R = hypot(X, Y) over the samples, volts.
    pub r_mean: f64,
    /// Sample standard deviation of R (n − 1 denominator; 0 for one sample), volts.
    pub r_std: f64,
    /// Mean of X, volts.
    pub x_mean: f64,
    /// Mean of Y, volts.
    pub y_mean: f64,
    /// Samples averaged.
    pub n: usize,
    /// Sensitivity the samples were taken at.
    pub sensitivity: Sensitivity,
    /// Time constant.
    pub time_constant: TimeConstant,
    /// Filter slope.
    pub slope: FilterSlope,
    /// The `LIAS?` byte read after the samples (bits latched while sampling).
    pub status: LiaStatus,
    /// Flags from `status`.
    pub flags: ReadingFlags,
    /// Range changes autoranging made before this reading.
    pub autorange_steps: usize,
    /// A targeted reading reached its time cap before its target precision: kept, at
    /// the precision it reached.
    pub capped: bool,
    /// A targeted reading whose values are the settled values fitted through the
    /// filter's transient from all `n` snapshots (`r_std` the residuals' snapshot σ),
    /// not a window's means.
    pub fitted: bool,
    /// A targeted reading by snapshots: their mean interval, s, as the session's clock
    /// measured it (the spacing their correlation follows); `None` for one snapshot
    /// or a fixed reading.
    pub snapshot_interval_s: Option<f64>,
    /// Read through the data buffer at this rate (its samples 1/rate apart), rather
    /// than by `SNAP?`: the spacing the samples' correlation follows.
    pub sample_rate: Option<super::SampleRate>,
}

impl Reading {
    /// True when no flag is raised and the values are finite: only then is the reading
    /// a measurement.
    pub fn is_valid(&self) -> bool {
        !self.flags.any()
            && self.n > 0
            && [self.r_mean, self.r_std, self.x_mean, self.y_mean]
                .iter()
                .all(|v| v.is_finite())
    }

    /// The mean R, volts, only when the reading is valid.
    pub fn r(&self) -> Option<f64> {
        self.is_valid().then_some(self.r_mean)
    }

    /// Mean R as a fraction of full scale.
    pub fn fraction_of_full_scale(&self) -> f64 {
        self.r_mean / self.sensitivity.volts()
    }
}

/// Why the SR830 could not be set up or read. No variant carries a usable reading.
#[derive(Debug, thiserror::Error)]
pub enum Sr830Error {
    /// The configuration is out of range.
    #[error("SR830 config: {0}")]
    Config(#[from] ConfigError),
    /// A command got no reply in time, a NUL byte, an overlong line, or a transport
    /// fault other than a vanished port.
    #[error("SR830 {command}: {source}")]
    Transport {
        /// The command, as sent (without terminator).
        command: String,
        /// The transport's error (`Timeout`, `Nul`, `LineTooLong`, ...).
        source: TransportError,
    },
    /// A reply that does not parse as the answer to its query (garbage, truncated, a
    /// wrong count of values).
    #[error("SR830 {command}: unreadable reply {:?}: {source}", String::from_utf8_lossy(.reply))]
    Protocol {
        /// The query, as sent.
        command: String,
        /// The reply line, terminator removed.
        reply: Vec<u8>,
        /// Why it does not parse.
        source: ReplyError,
    },
    /// The port vanished and every reconnection attempt failed.
    #[error("SR830 port {port} lost; {attempts} reconnection attempts failed: {source}")]
    Disconnected {
        /// The port's name.
        port: String,
        /// Attempts made.
        attempts: u32,
        /// The last failure.
        source: TransportError,
    },
    /// `*IDN?` named another instrument.
    #[error("not an SR830: *IDN? answered {0}")]
    WrongInstrument(Identity),
    /// `*ESR?` reports a refused command (EXE or CMD) or a lost one (INP or QRY: a
    /// buffer overflowed and was cleared) after set-up.
    #[error("the SR830 refused or lost a command (*ESR? = {0})")]
    Rejected(EventStatus),
    /// Autoranging changed range [`MAX_AUTORANGE_STEPS`] times without settling on one.
    #[error("autorange gave up after {steps} range changes (last reading at {})", .last.sensitivity)]
    Autorange {
        /// Range changes made.
        steps: usize,
        /// The last (flagged or out-of-range) reading, for diagnosis only.
        last: Box<Reading>,
    },
    /// The port was lost and reopened again and again during one reading.
    #[error("SR830 reading restarted {restarts} times after the port was lost")]
    Interrupted {
        /// Restarts made.
        restarts: usize,
    },
}
