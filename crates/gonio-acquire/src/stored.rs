//! What a stored run needs to go on: its instrument and, when simulated, its
//! simulator, rebuilt from the texts the run file keeps.

use gonio_driver::InstrumentConfig;
use gonio_run::{RunMeta, RunStore, StoreError};

/// The instrument side of a stored run.
#[derive(Clone, Debug)]
pub struct Stored {
    /// The instrument config.
    pub instrument: InstrumentConfig,
    /// Simulator config and sample texts.
    pub sim: Option<(String, String)>,
    /// The seed.
    pub seed: Option<u64>,
    /// The reference standard's model text.
    pub standard_model: Option<String>,
    /// The incident filter's transmittance.
    pub transmittance: f64,
    /// The plan's `[reading]` target, if it has one.
    pub reading: Option<crate::engine::ReadTarget>,
    /// All the metadata.
    pub meta: RunMeta,
}

/// Reads back what `gonio_run::create` stored, with the instrument config parsed.
pub fn stored(store: &RunStore) -> Result<Stored, StoreError> {
    let meta = store.run_meta()?;
    let instrument =
        InstrumentConfig::from_toml(&meta.instrument, None).map_err(|e| StoreError::Corrupt {
            path: store.path().to_path_buf(),
            why: format!("stored instrument config: {e}"),
        })?;
    let sim = match (&meta.sim, &meta.sim_sample) {
        (Some(a), Some(b)) => Some((a.clone(), b.clone())),
        _ => None,
    };
    // The table is new with targeted readings: a stored plan that no longer parses
    // predates it, and read a fixed number of snapshots.
    let reading = gonio_plan::Plan::from_toml(&meta.plan, None)
        .ok()
        .and_then(|p| p.reading.as_ref().map(crate::engine::read_target));
    Ok(Stored {
        instrument,
        reading,
        sim,
        seed: meta.seed,
        standard_model: meta.standard_model.clone(),
        transmittance: meta.transmittance,
        meta,
    })
}
