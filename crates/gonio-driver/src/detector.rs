//! The instrument's detector, whatever it is: [`DetectorDevice`].
//!
//! A lock-in (the SR830, reading a chopped signal in volts) or a DC instrument reads
//! the light. The run engine takes readings, restores a range after a resume, and
//! decides how to react to a fault, through this one trait; what a reading is stays
//! the family's own ([`Reading`]), and [`Reading::columns`] puts it into the run
//! file's reading row.

use crate::clock::Clock;
use crate::heartbeat::Heartbeat;
use crate::k6485::K6485;
use crate::sr830::{Reading as LockinReading, Sr830, Sr830Error};
use crate::transport::Transport;
use gonio_proto::k6485::{K6485Error, PicoReading, Range as PicoRange};
use gonio_proto::sr830::{ReadTarget, Sensitivity, TimeConstant};

/// A detector on its serial line, whatever its family: what the run engine needs of
/// it. A family plugs in by implementing it over its session's pump ([`Sr830`],
/// [`K6485`]); its readings go into the run file through [`Reading::columns`].
pub trait DetectorDevice: Send {
    /// The family's name (`sr830`, `k6485`).
    fn family(&self) -> &'static str;
    /// Sets the detector up; returns its identity, for the run log.
    fn setup(&mut self) -> Result<String, DetectorError>;
    /// One reading.
    fn read(&mut self) -> Result<Reading, DetectorError>;
    /// One reading to a precision target, the signal expected about `expected` (the
    /// last reading's, in the reading's unit). A family without a targeted mode reads
    /// as [`read`](Self::read) does.
    fn read_to(
        &mut self,
        target: &ReadTarget,
        expected: Option<f64>,
    ) -> Result<Reading, DetectorError> {
        let _ = (target, expected);
        self.read()
    }
    /// The absolute floor of `target` when the plan gives none: the precision its
    /// cap allows on the dimmest signal, from the detector's noise law; `None`
    /// without one.
    fn target_floor(&self, target: &ReadTarget) -> Option<f64> {
        let _ = target;
        None
    }
    /// The light changed (a stage moved): the next reading waits for it to settle.
    fn input_changed(&mut self);
    /// The light changed at `at`, no later than now (the stages stopped then, as
    /// their controllers told it): the next reading's settling is timed from `at`.
    fn input_changed_at(&mut self, at: std::time::Duration) {
        let _ = at;
        self.input_changed();
    }
    /// Does ahead, before the light reaches the detector (while the stages move), what
    /// a [`read_to`](Self::read_to) of `target` and `expected` would first set (a
    /// lock-in's time constant). Nothing for a family without a targeted mode.
    fn prepare(&mut self, target: &ReadTarget, expected: Option<f64>) -> Result<(), DetectorError> {
        let _ = (target, expected);
        Ok(())
    }
    /// The range index in force ([`Columns::range`]).
    fn range(&self) -> u8;
    /// Sets the range by its index ([`Columns::range`]): after a resume, the range the
    /// run left it at, so that autoranging takes the same path. Returns its name, or
    /// `None` for an index the detector does not have.
    fn restore_range(&mut self, index: u8) -> Result<Option<String>, DetectorError>;
    /// The integration setting in force ([`Columns::integration`]: the lock-in's time
    /// constant index).
    fn integration(&self) -> u8 {
        0
    }
    /// Sets the integration setting by its index: after a resume, the one the run's
    /// last reading took, so that a targeted reading starts from the filter state an
    /// uninterrupted run had. Returns its name, or `None` where there is nothing to
    /// set.
    fn restore_integration(&mut self, index: u8) -> Result<Option<String>, DetectorError> {
        let _ = index;
        Ok(None)
    }
    /// Exchanges re-sent after a lost, late or garbled reply.
    fn retried(&self) -> u64;
    /// Joins the instrument's heartbeat, which its waits keep going.
    fn set_heartbeat(&mut self, beats: Heartbeat);
    /// The detector as `Any`, to reach a family's own operations.
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any;
}

impl std::fmt::Debug for dyn DetectorDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "DetectorDevice({})", self.family())
    }
}

/// One reading, in the detector's own terms.
#[derive(Clone, Debug, PartialEq)]
pub enum Reading {
    /// A lock-in reading (volts).
    Lockin(LockinReading),
    /// A DC current reading (amps), and the power-line frequency its integration time
    /// (in power-line cycles) counts, Hz.
    Current(PicoReading, u32),
}

/// A reading as the run file's `readings` row stores it (see `docs/run-file.md`): the
/// lock-in's columns, which a DC detector fills with its own range and integration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Columns {
    /// Range index (`sensitivity`).
    pub range: u8,
    /// Full scale of the range, in the reading's unit (`sensitivity_v`).
    pub full_scale: f64,
    /// Integration setting index (`time_constant`).
    pub integration: u8,
    /// Integration time, s (`time_constant_s`).
    pub integration_s: f64,
    /// Filter slope, dB/octave (`slope_db`; 0 for a DC detector).
    pub slope_db: u8,
    /// Mean signal (`r_mean`).
    pub mean: f64,
    /// Standard deviation of the samples (`r_std`).
    pub std: f64,
    /// In-phase mean (`x_mean`; the signal itself for a DC detector).
    pub x: f64,
    /// Quadrature mean (`y_mean`; 0 for a DC detector).
    pub y: f64,
    /// Samples averaged.
    pub n: usize,
    /// Range changes made while reading.
    pub autorange_steps: usize,
    /// The instrument's status byte as read (`lias`).
    pub status: u8,
    /// The reading reached its time cap before its target precision.
    pub capped: bool,
}

impl Reading {
    /// The lock-in reading, when it is one.
    pub fn lockin(&self) -> Option<&LockinReading> {
        match self {
            Reading::Lockin(r) => Some(r),
            Reading::Current(..) => None,
        }
    }

    /// True when nothing flagged it and every number is finite.
    pub fn is_valid(&self) -> bool {
        match self {
            Reading::Lockin(r) => r.is_valid(),
            Reading::Current(r, _) => r.is_valid(),
        }
    }

    /// What flagged it, for the run log.
    pub fn flags_text(&self) -> String {
        match self {
            Reading::Lockin(r) => format!("{:?}", r.flags),
            Reading::Current(r, _) => format!("{:?}", r.flags),
        }
    }

    /// The run file's columns.
    pub fn columns(&self) -> Columns {
        match self {
            Reading::Lockin(r) => Columns {
                range: r.sensitivity.index(),
                full_scale: r.sensitivity.volts(),
                integration: r.time_constant.index(),
                integration_s: r.time_constant.seconds(),
                slope_db: r.slope.db_per_octave(),
                mean: r.r_mean,
                std: r.r_std,
                x: r.x_mean,
                y: r.y_mean,
                n: r.n,
                autorange_steps: r.autorange_steps,
                status: r.status.0,
                capped: r.capped,
            },
            Reading::Current(r, line_hz) => Columns {
                range: r.range.index(),
                full_scale: r.range.amps(),
                integration: 0,
                integration_s: r.nplc * f64::from(r.filter_count.max(1))
                    / f64::from((*line_hz).max(1)),
                slope_db: 0,
                mean: r.mean_a,
                std: r.std_a,
                x: r.mean_a,
                y: 0.0,
                n: r.n,
                autorange_steps: r.autorange_steps,
                status: dc_status(r),
                capped: false,
            },
        }
    }
}

/// A DC reading's flags in the lock-in status bits the run file keeps (`lias`, see
/// `docs/run-file.md`): an overflow or overvoltage as an input overload (bit 0), an
/// invalid sample as an output overload (bit 2), zero check on as "no signal" (bit
/// 3, the lock-in's unlock).
fn dc_status(r: &PicoReading) -> u8 {
    u8::from(r.flags.overflow || r.flags.overvoltage)
        | u8::from(r.flags.invalid) << 2
        | u8::from(r.flags.zero_check) << 3
}

/// Why a detector operation failed.
#[derive(Debug, thiserror::Error)]
pub enum DetectorError {
    /// The SR830 failed.
    #[error(transparent)]
    Sr830(#[from] Sr830Error),
    /// The picoammeter failed.
    #[error(transparent)]
    K6485(#[from] K6485Error),
}

/// What the run engine should do after a detector error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Disposition {
    /// The point cannot be read (no range fits): skip it.
    Skip,
    /// A link fault that survived the driver's retries: measure the step again.
    Again,
    /// Anything else: stop the session.
    Stop,
}

impl DetectorError {
    /// How the engine should react.
    pub fn disposition(&self) -> Disposition {
        match self {
            DetectorError::Sr830(Sr830Error::Autorange { .. }) => Disposition::Skip,
            DetectorError::Sr830(
                Sr830Error::Transport { .. }
                | Sr830Error::Protocol { .. }
                | Sr830Error::Interrupted { .. },
            ) => Disposition::Again,
            DetectorError::Sr830(_) => Disposition::Stop,
            DetectorError::K6485(K6485Error::Autorange { .. }) => Disposition::Skip,
            DetectorError::K6485(
                K6485Error::Transport { .. }
                | K6485Error::Protocol { .. }
                | K6485Error::Interrupted { .. },
            ) => Disposition::Again,
            DetectorError::K6485(_) => Disposition::Stop,
        }
    }
}

impl<T: Transport + 'static, C: Clock + 'static> DetectorDevice for Sr830<T, C> {
    fn set_heartbeat(&mut self, beats: Heartbeat) {
        Sr830::set_heartbeat(self, beats);
    }
    fn family(&self) -> &'static str {
        "sr830"
    }
    fn setup(&mut self) -> Result<String, DetectorError> {
        Ok(Sr830::setup(self)?.to_string())
    }
    fn read(&mut self) -> Result<Reading, DetectorError> {
        Ok(Reading::Lockin(Sr830::read(self)?))
    }
    fn read_to(
        &mut self,
        target: &ReadTarget,
        expected: Option<f64>,
    ) -> Result<Reading, DetectorError> {
        Ok(Reading::Lockin(Sr830::read_targeted(
            self, target, expected,
        )?))
    }
    fn target_floor(&self, target: &ReadTarget) -> Option<f64> {
        Sr830::target_floor(self, target)
    }
    fn input_changed(&mut self) {
        Sr830::input_changed(self);
    }
    fn input_changed_at(&mut self, at: std::time::Duration) {
        Sr830::input_changed_at(self, at);
    }
    fn prepare(&mut self, target: &ReadTarget, expected: Option<f64>) -> Result<(), DetectorError> {
        Ok(Sr830::prepare_targeted(self, target, expected)?)
    }
    fn range(&self) -> u8 {
        self.sensitivity().index()
    }
    fn restore_range(&mut self, index: u8) -> Result<Option<String>, DetectorError> {
        match Sensitivity::new(index) {
            Some(s) => {
                self.set_sensitivity(s)?;
                Ok(Some(s.to_string()))
            }
            None => Ok(None),
        }
    }
    fn integration(&self) -> u8 {
        self.time_constant().index()
    }
    fn restore_integration(&mut self, index: u8) -> Result<Option<String>, DetectorError> {
        match TimeConstant::new(index) {
            Some(t) => {
                self.set_time_constant(t)?;
                Ok(Some(t.to_string()))
            }
            None => Ok(None),
        }
    }
    fn retried(&self) -> u64 {
        Sr830::retried(self)
    }
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}

impl<T: Transport + 'static, C: Clock + 'static> DetectorDevice for K6485<T, C> {
    fn set_heartbeat(&mut self, beats: Heartbeat) {
        K6485::set_heartbeat(self, beats);
    }
    fn family(&self) -> &'static str {
        "k6485"
    }
    fn setup(&mut self) -> Result<String, DetectorError> {
        Ok(K6485::setup(self)?.to_string())
    }
    fn read(&mut self) -> Result<Reading, DetectorError> {
        let hz = self.config().line_frequency_hz;
        Ok(Reading::Current(K6485::read(self)?, hz))
    }
    fn input_changed(&mut self) {
        K6485::input_changed(self);
    }
    fn range(&self) -> u8 {
        K6485::range(self).index()
    }
    fn restore_range(&mut self, index: u8) -> Result<Option<String>, DetectorError> {
        match PicoRange::new(index) {
            Some(r) => {
                self.set_range(r)?;
                Ok(Some(r.to_string()))
            }
            None => Ok(None),
        }
    }
    fn retried(&self) -> u64 {
        K6485::retried(self)
    }
    fn as_any_mut(&mut self) -> &mut dyn std::any::Any {
        self
    }
}
