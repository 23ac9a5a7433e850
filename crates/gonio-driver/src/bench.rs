//! The bench: what changes in the light path between kinds of readings (blocking
//! the source, removing the sample, mounting a standard, changing the band). On a
//! real instrument an operator does it when asked ([`OperatorBench`]); a shutter,
//! filter wheel or monochromator under program control implements [`Bench`] too, as
//! the simulator does.

use std::io::{BufRead, Write};

/// What the light path must be for a reading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Setup {
    /// The sample in the beam (sample and drift-reference steps).
    Sample,
    /// The source blocked.
    Dark,
    /// The sample removed, the detector in the beam behind a filter of this
    /// transmittance.
    Incident {
        /// Filter transmittance.
        transmittance: f64,
    },
    /// The reference standard in place of the sample.
    Standard,
}

impl Setup {
    /// What the operator is asked to do.
    pub fn instruction(self) -> String {
        match self {
            Setup::Sample => "mount the sample, unblock the source".into(),
            Setup::Dark => "block the source beam (shutter closed)".into(),
            Setup::Incident { transmittance } => format!(
                "remove the sample and put the neutral density filter of transmittance \
                 {transmittance} in the beam"
            ),
            Setup::Standard => "mount the reference standard in place of the sample".into(),
        }
    }
}

/// Why the bench could not be set up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BenchError {
    /// No operator answered (no terminal, end of input).
    #[error("no operator to {0}")]
    NoOperator(String),
    /// The operator declined.
    #[error("the operator declined to {0}")]
    Declined(String),
    /// The bench cannot select this band.
    #[error("channel {0:?} is not available on this bench")]
    UnknownChannel(String),
}

/// Changes the light path between kinds of readings.
pub trait Bench: Send {
    /// Puts the light path in `setup` (before the first step that needs it).
    fn set_up(&mut self, setup: Setup) -> Result<(), BenchError>;

    /// Selects the band `channel` (before the first step in it).
    fn select_channel(&mut self, channel: &str) -> Result<(), BenchError>;

    /// The stages are at step `step_id` and the detector is about to read: the hook
    /// where a simulator makes the reading reproducible. `previous` is the lock-in's
    /// mean X and Y (V) of the last reading the run committed before this step, what
    /// the filters held before the move: a simulator starts the point's transient
    /// from it. Nothing on real hardware.
    fn at_step(&mut self, step_id: i64, previous: Option<[f64; 2]>) {
        let _ = (step_id, previous);
    }

    /// [`at_step`](Self::at_step), the stages having stopped at `since` (no later than
    /// now, on the instrument's clock): the light has been the point's from then on,
    /// so a simulator starts the transient there.
    fn at_step_since(
        &mut self,
        step_id: i64,
        previous: Option<[f64; 2]>,
        since: std::time::Duration,
    ) {
        let _ = since;
        self.at_step(step_id, previous);
    }

    /// True when a person makes the changes, so that a call may take minutes: the
    /// engine then keeps the instrument's lines alive meanwhile (the APT keep-alive).
    fn waits_for_a_person(&self) -> bool {
        false
    }
}

/// An operator at a terminal: each change is asked for on `prompt` and confirmed by
/// a line on `answers` (empty or `y` goes on; `n` or `q` declines; end of input means
/// nobody is there).
pub struct OperatorBench<R: BufRead + Send, W: Write + Send> {
    answers: R,
    prompt: W,
}

impl<R: BufRead + Send, W: Write + Send> OperatorBench<R, W> {
    /// An operator reading from `answers`, asked on `prompt`.
    pub fn new(answers: R, prompt: W) -> Self {
        OperatorBench { answers, prompt }
    }

    fn ask(&mut self, what: String) -> Result<(), BenchError> {
        let _ = write!(self.prompt, "gonio: {what}, then press Enter (n to stop): ");
        let _ = self.prompt.flush();
        let mut line = String::new();
        match self.answers.read_line(&mut line) {
            Ok(0) | Err(_) => Err(BenchError::NoOperator(what)),
            Ok(_) => match line.trim() {
                "" | "y" | "Y" | "yes" => Ok(()),
                _ => Err(BenchError::Declined(what)),
            },
        }
    }
}

impl<R: BufRead + Send, W: Write + Send> Bench for OperatorBench<R, W> {
    fn set_up(&mut self, setup: Setup) -> Result<(), BenchError> {
        self.ask(setup.instruction())
    }

    fn select_channel(&mut self, channel: &str) -> Result<(), BenchError> {
        self.ask(format!("select the band {channel:?}"))
    }

    fn waits_for_a_person(&self) -> bool {
        true
    }
}
