//! A plan loaded and prepared on an instrument, as `plan check`, `plan compare` and
//! `acquire` all need it, and the way durations are printed.

use std::path::Path;

use gonio_driver::InstrumentConfig;
use gonio_plan::{Plan, Prepared};

use crate::error::{CliError, CliResult};

/// Seconds as `1h02m03s`.
pub use gonio_plan::schedule::hms;

fn input(e: impl std::fmt::Display) -> CliError {
    CliError::Input(e.to_string())
}

/// An instrument and a plan, loaded and checked, and the plan prepared on it.
pub struct Loaded {
    /// The instrument config.
    pub instrument: InstrumentConfig,
    /// Its text.
    pub instrument_text: String,
    /// The plan.
    pub plan: Plan,
    /// Its text.
    pub plan_text: String,
    /// The plan prepared on the instrument.
    pub prepared: Prepared,
}

/// Loads an instrument and a plan and prepares the plan on it.
pub fn load_and_prepare(instrument: &Path, plan: &Path) -> CliResult<Loaded> {
    let (inst, inst_text) = InstrumentConfig::load_with_text(instrument).map_err(input)?;
    let (plan_cfg, plan_text) = Plan::load(plan).map_err(input)?;
    let mech = inst
        .mechanics()
        .map_err(|e| input(format!("{}: {e}", instrument.display())))?;
    if (inst.has_band_selector() && plan_cfg.channels.is_some()) || plan_cfg.wavelengths.is_some() {
        let bands = plan_cfg.band_wavelengths();
        match bands {
            Some(w) => inst.check_bands(&w).map_err(|e| {
                input(format!(
                    "{}: field `wavelengths`: {} cannot serve it: {e}",
                    plan.display(),
                    instrument.display()
                ))
            })?,
            None if inst.has_band_selector() => {
                return Err(input(format!(
                    "{}: field `channels`: {} selects wavelengths (like \"550nm\"); these bands are not",
                    plan.display(),
                    instrument.display()
                )));
            }
            None => {}
        }
    }
    let prepared = gonio_plan::prepare(&mech, inst.reading_seconds(), &plan_cfg).map_err(input)?;
    Ok(Loaded {
        instrument: inst,
        instrument_text: inst_text,
        plan: plan_cfg,
        plan_text,
        prepared,
    })
}
