//! The account a reduction gives of itself: which calibration, how much drift, what
//! was left out. `gonio-reduce` writes it from a run file; reports and exports show
//! it. Plain data, so that the crates that show it need not read run files.

use std::collections::BTreeMap;

use serde::Serialize;

/// One term of a channel's uncertainty budget: a source of error, how it was
/// estimated, how it is shared between samples, and its size.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BudgetTerm {
    /// The term: `noise`, `resolution`, `dark`, `calibration`, `drift` or `standard`.
    pub term: &'static str,
    /// Where the error comes from and how its size was estimated.
    pub source: String,
    /// How it is shared: `independent` (each sample its own error), `common` (one
    /// error, scaled per sample, shared by every sample of the channel) or `segment`
    /// (shared by the samples between the same two drift references).
    pub correlation: &'static str,
    /// Its relative standard uncertainty: the median over the channel's samples.
    pub rel_median: f64,
    /// Its largest relative standard uncertainty over the channel's samples.
    pub rel_max: f64,
}

/// What the reduction did, per channel.
///
/// Its JSON names the detector signal's unit in the keys: `dark_v` and `incident_v`
/// for a lock-in's volts (as every report before DC runs), `dark_a` and `incident_a`
/// for a picoammeter's amps, with `unit: "A"`.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelReport {
    /// The channel.
    pub channel: String,
    /// The calibration used (`incident` or `standard`).
    pub calibration: &'static str,
    /// The detector signal's unit: `V` (a lock-in's X, Y) or `A` (a DC current).
    pub unit: &'static str,
    /// Dark X and Y in [`Self::unit`] (a DC run's dark is [I, 0]).
    pub dark_v: [f64; 2],
    /// Incident flux C (at g = 1), in [`Self::unit`].
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
    /// The uncertainty budget: every term that makes up the samples' σ (their
    /// quadrature sum), with its source.
    pub budget: Vec<BudgetTerm>,
}

impl Serialize for ChannelReport {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        // Every report before DC runs had `dark_v`, `incident_v`: a lock-in's stay so.
        let (dark, incident) = match self.unit {
            "A" => ("dark_a", "incident_a"),
            _ => ("dark_v", "incident_v"),
        };
        let mut m = s.serialize_map(None)?;
        m.serialize_entry("channel", &self.channel)?;
        m.serialize_entry("calibration", self.calibration)?;
        // A lock-in's report stays byte for byte what it was; a DC one says its unit.
        if self.unit != "V" {
            m.serialize_entry("unit", self.unit)?;
        }
        m.serialize_entry(dark, &self.dark_v)?;
        m.serialize_entry(incident, &self.incident_v)?;
        m.serialize_entry("incident_rel_sigma", &self.incident_rel_sigma)?;
        m.serialize_entry("calibration_readings", &self.calibration_readings)?;
        m.serialize_entry("drift_readings", &self.drift_readings)?;
        m.serialize_entry("drift_max", &self.drift_max)?;
        m.serialize_entry("samples", &self.samples)?;
        m.serialize_entry("budget", &self.budget)?;
        m.end()
    }
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
    /// Readings used that reached the plan's `reading.max_s` before their target
    /// precision (flag `capped`): kept, with the precision they reached. Absent
    /// from the JSON when 0, as in every report before reading time.
    #[serde(skip_serializing_if = "is_zero")]
    pub capped: usize,
}

/// Whether a count is 0 (serde's `skip_serializing_if` takes a reference).
fn is_zero(n: &usize) -> bool {
    *n == 0
}
