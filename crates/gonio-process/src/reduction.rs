//! The account a reduction gives of itself: which calibration, how much drift, what
//! was left out. `gonio-reduce` writes it from a run file; reports and exports show
//! it. Plain data, so that the crates that show it need not read run files.

use std::collections::BTreeMap;

use serde::Serialize;

/// What the reduction did, per channel.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ChannelReport {
    /// The channel.
    pub channel: String,
    /// The calibration used (`incident` or `standard`).
    pub calibration: &'static str,
    /// Dark X and Y, V.
    pub dark_v: [f64; 2],
    /// Incident flux C (at g = 1), in detector volts.
    pub incident_v: f64,
    /// Its relative standard uncertainty (common to every sample of the channel).
    pub incident_rel_sigma: f64,
    /// Calibration readings used.
    pub calibration_readings: usize,
    /// Drift reference readings used.
    pub drift_readings: usize,
    /// Largest |g − 1| over the run (0 without drift correction).
    pub drift_max: f64,
    /// Samples produced.
    pub samples: usize,
}

/// The reduction's account of itself.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    /// Per channel.
    pub channels: Vec<ChannelReport>,
    /// The detector's solid angle Ω, sr.
    pub solid_angle_sr: f64,
    /// Sample readings left out, by reason.
    pub rejected: BTreeMap<String, usize>,
    /// Largest difference between read-back and commanded directions, degrees.
    pub max_position_error_deg: f64,
    /// Sample steps not measured (pending or failed).
    pub unmeasured: usize,
}
