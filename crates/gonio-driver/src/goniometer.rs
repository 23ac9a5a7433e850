//! A goniometer: named axes on whatever controllers the lab owns, and a detector.

use std::time::Duration;

use crate::apt::AptAxis;
use crate::clock::{Clock, SystemClock};
use crate::config::{DetectorConfig, DetectorKind, InstrumentConfig, LineKind, MotionLine};
use crate::cs130::Cs130;
use crate::detector::{DetectorDevice, DetectorError, Reading};
use crate::fw102c::Fw102c;
use crate::heartbeat::Heartbeat;
use crate::k6485::K6485;
use crate::motion::{AxisInfo, Motion, MotionDevice};
use crate::smc100::{MotionError, Smc100Chain};
use crate::spectral::{
    BandSelector, FilterWheelConfig, MonochromatorConfig, SpectralError, WheelBands,
};
use crate::sr830::Sr830;
use crate::transport::{SerialSettings, SerialTransport, Transport, TransportError};

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
    /// The motion system failed.
    #[error("motion: {0}")]
    Motion(#[from] MotionError),
    /// The detector failed.
    #[error("detector: {0}")]
    Detector(#[from] DetectorError),
    /// The band selector failed.
    #[error("wavelength: {0}")]
    Spectral(#[from] SpectralError),
    /// Transports given do not match the config's lines.
    #[error("{0}")]
    Lines(String),
}

/// What the instrument said about itself at start-up.
#[derive(Clone, Debug, PartialEq)]
pub struct StartupReport {
    /// Each axis' name and controller.
    pub axes: Vec<(String, AxisInfo)>,
    /// The detector's identity.
    pub detector: String,
    /// The band selector's identity, when there is one.
    pub spectral: Option<String>,
}

/// What a port is opened for: handed to the opener of [`Goniometer::from_ports`].
#[derive(Clone, Copy, Debug)]
pub enum PortUse<'a> {
    /// A motion line and what it carries.
    Motion(&'a MotionLine),
    /// The detector.
    Detector(&'a DetectorConfig),
    /// The monochromator.
    Monochromator(&'a MonochromatorConfig),
    /// The filter wheel.
    FilterWheel(&'a FilterWheelConfig),
}

/// The stages and the detector of one instrument, each line its own transport.
#[derive(Debug)]
pub struct Goniometer<C: Clock + Clone> {
    /// Every motion axis.
    pub motion: Motion<C>,
    /// The detector.
    pub detector: Box<dyn DetectorDevice>,
    /// What selects the wavelength (a monochromator, a filter wheel), if anything.
    pub spectral: Option<Box<dyn BandSelector>>,
}

impl Goniometer<SystemClock> {
    /// Opens the ports a validated config names.
    pub fn open(cfg: &InstrumentConfig) -> Result<Self, GoniometerError> {
        Self::from_ports(
            cfg,
            |_, settings| Ok(Box::new(SerialTransport::open(settings)?)),
            SystemClock::new(),
        )
    }
}

impl<C: Clock + Clone + 'static> Goniometer<C> {
    /// Builds the instrument, opening each line with `open` (given what the line is
    /// for and the settings a serial port would need).
    pub fn from_ports(
        cfg: &InstrumentConfig,
        mut open: impl FnMut(PortUse<'_>, SerialSettings) -> Result<Box<dyn Transport>, TransportError>,
        clock: C,
    ) -> Result<Self, GoniometerError> {
        let mut lines = Vec::new();
        for line in cfg.motion.lines() {
            let t =
                open(PortUse::Motion(&line), cfg.motion.line_serial(&line)).map_err(|source| {
                    GoniometerError::Open {
                        role: "motion",
                        source,
                    }
                })?;
            lines.push(Self::line(cfg, &line, t, clock.clone())?);
        }
        let d =
            open(PortUse::Detector(&cfg.detector), cfg.detector.serial()).map_err(|source| {
                GoniometerError::Open {
                    role: "detector",
                    source,
                }
            })?;
        let detector = Self::detector(cfg, d, clock.clone())?;
        let spectral = Self::spectral(cfg, &mut open, clock.clone())?;
        Ok(Goniometer {
            motion: Motion::new(lines, clock)?,
            detector,
            spectral,
        }
        .beating())
    }

    /// Builds the instrument over given transports (a simulator, a script), for a
    /// config whose axes are all on one line.
    pub fn from_transports<M: Transport + 'static, D: Transport + 'static>(
        cfg: &InstrumentConfig,
        motion: M,
        detector: D,
        motion_clock: C,
        detector_clock: C,
    ) -> Result<Self, GoniometerError> {
        let lines = cfg.motion.lines();
        let [line] = lines.as_slice() else {
            return Err(GoniometerError::Lines(format!(
                "the config has {} motion lines; one transport was given",
                lines.len()
            )));
        };
        let line = Self::line(cfg, line, Box::new(motion), motion_clock.clone())?;
        let detector = Self::detector(cfg, Box::new(detector), detector_clock)?;
        Ok(Goniometer {
            motion: Motion::new(vec![line], motion_clock)?,
            detector,
            spectral: None,
        }
        .beating())
    }

    /// The instrument with one heartbeat on every device: the motion lines' (which
    /// holds their keep-alives), so that every wait of every device keeps them going.
    fn beating(mut self) -> Self {
        let beats = self.motion.heartbeat().clone();
        self.detector.set_heartbeat(beats.clone());
        if let Some(s) = &mut self.spectral {
            s.set_heartbeat(beats);
        }
        self
    }

    fn line(
        cfg: &InstrumentConfig,
        line: &MotionLine,
        t: Box<dyn Transport>,
        clock: C,
    ) -> Result<Box<dyn MotionDevice>, GoniometerError> {
        Ok(match &line.kind {
            LineKind::Smc100(axes) => Box::new(Smc100Chain::new(
                t,
                clock,
                axes.clone(),
                cfg.motion.policy(),
            )?),
            LineKind::Apt(axis, serial) => Box::new(AptAxis::new(
                t,
                clock,
                axis.clone(),
                cfg.motion.policy(),
                *serial,
            )?),
        })
    }

    /// The band selector the config names, on its own line.
    fn spectral(
        cfg: &InstrumentConfig,
        open: &mut impl FnMut(PortUse<'_>, SerialSettings) -> Result<Box<dyn Transport>, TransportError>,
        clock: C,
    ) -> Result<Option<Box<dyn BandSelector>>, GoniometerError> {
        let opened = |source| GoniometerError::Open {
            role: "wavelength",
            source,
        };
        let failed = |device: &'static str| {
            move |e: &dyn std::fmt::Display| SpectralError::Device {
                device,
                message: e.to_string(),
            }
        };
        if let Some(m) = &cfg.monochromator {
            let t = open(PortUse::Monochromator(m), m.serial()).map_err(opened)?;
            let mono = Cs130::new(t, clock, m.cs130.clone()).map_err(|e| failed("cs130")(&e))?;
            return Ok(Some(Box::new(mono)));
        }
        if let Some(w) = &cfg.filter_wheel {
            let t = open(PortUse::FilterWheel(w), w.serial()).map_err(opened)?;
            let wheel =
                Fw102c::new(t, clock, w.fw102c.clone()).map_err(|e| failed("fw102c")(&e))?;
            return Ok(Some(Box::new(WheelBands::new(wheel))));
        }
        Ok(None)
    }

    fn detector(
        cfg: &InstrumentConfig,
        t: Box<dyn Transport>,
        clock: C,
    ) -> Result<Box<dyn DetectorDevice>, GoniometerError> {
        Ok(match cfg.detector.kind {
            DetectorKind::Sr830 => {
                Box::new(Sr830::new(t, clock, cfg.lockin()).map_err(DetectorError::from)?)
            }
            DetectorKind::K6485 => Box::new(
                K6485::new(t, clock, cfg.detector.picoammeter()).map_err(DetectorError::from)?,
            ),
        })
    }
}

impl<C: Clock + Clone> Goniometer<C> {
    /// Identifies every controller and sets the detector up: what runs before anything
    /// moves.
    pub fn start(&mut self) -> Result<StartupReport, GoniometerError> {
        let axes = self.motion.identify()?;
        let detector = self.detector.setup()?;
        let spectral = match &mut self.spectral {
            Some(s) => Some(s.setup()?),
            None => None,
        };
        Ok(StartupReport {
            axes,
            detector,
            spectral,
        })
    }

    /// Homes every axis.
    pub fn home(&mut self) -> Result<(), GoniometerError> {
        Ok(self.motion.home_all()?)
    }

    /// Moves the named axes (concurrently) and takes a detector reading there, after
    /// the detector has settled on the new signal.
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

    /// The heartbeat every device's waits keep going (the APT lines' keep-alives).
    pub fn heartbeat(&self) -> &Heartbeat {
        self.motion.heartbeat()
    }

    /// Waits on the instrument's clock until `at`, sending every line's keep-alive as
    /// it falls due: how the instrument spends a wait of its own (a controller
    /// booting). With `at` already past it sends only what is due.
    pub fn idle_until(&self, at: Duration) {
        self.heartbeat().sleep_until(self.motion.clock(), at);
    }

    /// Sends the keep-alives due now, waiting for nothing: what a loop paced by a
    /// person (a paused run) calls at each turn. On a simulated clock that only moves
    /// when the instrument waits, nothing falls due, so the run stays the same bytes
    /// however long the person took.
    pub fn keep_alive(&self) {
        self.heartbeat().beat(self.motion.clock().now());
    }

    /// Runs `f`, which waits for a person (an operator's answer), on a thread of its
    /// own, and keeps the instrument's lines alive here meanwhile, every 50 ms of wall
    /// time ([`keep_alive`](Self::keep_alive)).
    pub fn while_a_person_answers<T: Send>(&self, f: impl FnOnce() -> T + Send) -> T {
        std::thread::scope(|scope| {
            let answer = scope.spawn(f);
            while !answer.is_finished() {
                std::thread::sleep(Duration::from_millis(50));
                self.keep_alive();
            }
            answer
                .join()
                .unwrap_or_else(|p| std::panic::resume_unwind(p))
        })
    }
}
