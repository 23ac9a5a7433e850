//! A goniometer: named axes on an SMC100 chain and an SR830 detector.

use crate::clock::{Clock, SystemClock};
use crate::config::InstrumentConfig;
use crate::smc100::{ControllerInfo, MotionError, Smc100Chain};
use crate::sr830::{Reading, Sr830, Sr830Error};
use crate::transport::{SerialTransport, Transport, TransportError};

/// Why a goniometer operation failed.
#[derive(Debug, thiserror::Error)]
pub enum GoniometerError {
    /// A port could not be opened.
    #[error("opening {role} port: {source}")]
    Open {
        /// `motion` or `detector`.
        role: &'static str,
        /// The cause.
        #[source]
        source: TransportError,
    },
    /// The motion chain failed.
    #[error("motion: {0}")]
    Motion(#[from] MotionError),
    /// The detector failed.
    #[error("detector: {0}")]
    Detector(#[from] Sr830Error),
}

/// What the instrument said about itself at start-up.
#[derive(Clone, Debug, PartialEq)]
pub struct StartupReport {
    /// Each axis' name and controller.
    pub axes: Vec<(String, ControllerInfo)>,
    /// The lock-in's `*IDN?` reply.
    pub detector: String,
}

/// The stages and the detector of one instrument, each on its own serial line.
pub struct Goniometer<M: Transport, D: Transport, C: Clock> {
    /// The SMC100 chain.
    pub motion: Smc100Chain<M, C>,
    /// The SR830.
    pub detector: Sr830<D, C>,
}

impl Goniometer<SerialTransport, SerialTransport, SystemClock> {
    /// Opens the ports a validated config names.
    pub fn open(cfg: &InstrumentConfig) -> Result<Self, GoniometerError> {
        let m =
            SerialTransport::open(cfg.motion.serial()).map_err(|source| GoniometerError::Open {
                role: "motion",
                source,
            })?;
        let d = SerialTransport::open(cfg.detector.serial()).map_err(|source| {
            GoniometerError::Open {
                role: "detector",
                source,
            }
        })?;
        Self::from_transports(cfg, m, d, SystemClock::new(), SystemClock::new())
    }
}

impl<M: Transport, D: Transport, C: Clock> Goniometer<M, D, C> {
    /// Builds the instrument over given transports (a simulator, a script).
    pub fn from_transports(
        cfg: &InstrumentConfig,
        motion: M,
        detector: D,
        motion_clock: C,
        detector_clock: C,
    ) -> Result<Self, GoniometerError> {
        let motion = Smc100Chain::new(
            motion,
            motion_clock,
            cfg.motion.axes.clone(),
            cfg.motion.policy(),
        )?;
        let detector = Sr830::new(detector, detector_clock, cfg.detector.lockin.clone())?;
        Ok(Goniometer { motion, detector })
    }

    /// Identifies every controller and sets the lock-in up: what runs before anything
    /// moves.
    pub fn start(&mut self) -> Result<StartupReport, GoniometerError> {
        let infos = self.motion.identify()?;
        let axes = self
            .motion
            .axes()
            .iter()
            .map(|a| a.name.clone())
            .zip(infos)
            .collect();
        let id = self.detector.setup()?;
        Ok(StartupReport {
            axes,
            detector: id.to_string(),
        })
    }

    /// Homes every axis.
    pub fn home(&mut self) -> Result<(), GoniometerError> {
        Ok(self.motion.home_all()?)
    }

    /// Moves the named axes (concurrently) and takes a detector reading there, after
    /// the lock-in's filters have settled on the new signal.
    pub fn measure_at(
        &mut self,
        targets: &[(&str, f64)],
    ) -> Result<(Vec<f64>, Reading), GoniometerError> {
        let positions = self.motion.move_to(targets)?;
        self.detector.input_changed();
        let reading = self.detector.read()?;
        Ok((positions, reading))
    }

    /// Stops every stage.
    pub fn stop(&mut self) -> Result<(), GoniometerError> {
        Ok(self.motion.stop_all()?)
    }
}
