//! The simulator's bench: the light path under program control, so that a
//! simulated run's calibrations (dark, incident beam, reference standard) and band
//! changes happen without an operator.

use gonio_brdf::Brdf;
use gonio_driver::bench::{Bench, BenchError, Setup};

use crate::optics::LightPath;
use crate::transport::{SharedSim, lock};

/// The simulator's bench: shutter, sample holder, filter and band under program
/// control.
pub struct SimBench {
    sim: SharedSim,
    /// The standard while the sample is off, or the sample while the standard is on.
    other: Option<(Box<dyn Brdf>, usize)>,
    standard_on: bool,
}

impl SimBench {
    /// A bench for `sim`, with the reference standard `standard` (a model and its
    /// channel) when the plan has one.
    pub fn new(sim: SharedSim, standard: Option<(Box<dyn Brdf>, usize)>) -> Self {
        SimBench {
            sim,
            other: standard,
            standard_on: false,
        }
    }
}

impl Bench for SimBench {
    fn set_up(&mut self, setup: Setup) -> Result<(), BenchError> {
        let want_standard = setup == Setup::Standard;
        let mut s = lock(&self.sim);
        if want_standard != self.standard_on {
            let (b, ch) = self.other.take().ok_or_else(|| {
                BenchError::Declined("mount a reference standard: the plan has none".into())
            })?;
            self.other = Some(s.swap_sample(b, ch));
            self.standard_on = want_standard;
        }
        s.set_light_path(match setup {
            Setup::Sample | Setup::Standard => LightPath::Sample,
            Setup::Dark => LightPath::Dark,
            Setup::Incident { transmittance } => LightPath::Incident { transmittance },
        });
        Ok(())
    }

    fn select_channel(&mut self, channel: &str) -> Result<(), BenchError> {
        let mut s = lock(&self.sim);
        if s.select_channel(channel) {
            Ok(())
        } else {
            Err(BenchError::UnknownChannel(channel.into()))
        }
    }

    fn at_step(&mut self, step_id: i64, previous: Option<[f64; 2]>) {
        lock(&self.sim).begin_point(step_id as u64, previous);
    }

    fn at_step_since(
        &mut self,
        step_id: i64,
        previous: Option<[f64; 2]>,
        since: std::time::Duration,
    ) {
        lock(&self.sim).begin_point_since(step_id as u64, previous, since.as_secs_f64());
    }
}
