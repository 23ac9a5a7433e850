//! The simulated lock-in's config (`[lockin]`): its physics, its noise, its identity.

use crate::twin::FieldError;

/// Physics and noise of the simulated lock-in and its detector front end.
///
/// In a TOML file (`[lockin]`) every field is optional (the defaults are
/// [`Default`]'s) and unknown fields are refused.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LockInConfig {
    /// Lock-in R (V rms) per volt of detector signal. A chopped signal is a square wave
    /// from 0 to V (V peak-to-peak); its fundamental has peak amplitude 2V/π, and the
    /// lock-in reads the rms value of the fundamental: √2·V/π = 0.4502·V. Default 0.45.
    pub chop_gain: f64,
    /// Signal phase relative to the reference, degrees: X = R cos φ, Y = R sin φ.
    pub phase_deg: f64,
    /// Signal-independent noise density at the output, V/√Hz. Default 20 nV/√Hz.
    pub amplifier_noise: f64,
    /// Shot noise, V/√Hz per √V of signal R: density `shot_noise·√R`. Default 2e-6.
    pub shot_noise: f64,
    /// Detector amplitude above which INPUT overload latches, volts. Default 1.4, the
    /// input limit (1.4 V peak).
    pub input_overload_v: f64,
    /// The chopper's frequency, Hz: what `FREQ?` and `SNAP? 9` read on the external
    /// reference (`FMOD 0`). Default 1000.
    pub chopper_hz: f64,
    /// Serial number field of `*IDN?`. Default `s/n00111`.
    pub serial: String,
    /// Firmware field of `*IDN?`. Default `ver1.07`.
    pub firmware: String,
    /// How the filters start at each point (`"settled"` or `"previous"`; see the module
    /// docs, "Where a point starts"). Default `"settled"`.
    pub point_start: PointStart,
}

/// How the output filters start at a point ([`LockInConfig::point_start`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PointStart {
    /// Settled on the present input: no transient ([`LockIn::restart`](super::LockIn::restart)).
    #[default]
    Settled,
    /// Every stage at the previous reading's X and Y, then the step response to the
    /// present input ([`LockIn::restart_from`](super::LockIn::restart_from)).
    Previous,
}

impl Default for LockInConfig {
    fn default() -> Self {
        LockInConfig {
            chop_gain: 0.45,
            phase_deg: 0.0,
            amplifier_noise: 20e-9,
            shot_noise: 2e-6,
            input_overload_v: 1.4,
            chopper_hz: 1000.0,
            serial: "s/n00111".to_string(),
            firmware: "ver1.07".to_string(),
            point_start: PointStart::Settled,
        }
    }
}

impl LockInConfig {
    /// Checks that every number is finite and in range, and that the `*IDN?` fields are
    /// printable ASCII without commas.
    pub fn validate(&self) -> Result<(), FieldError> {
        use gonio_core::limits::Range;
        // Finite ranges, so that no reading can overflow: a gain or an overload level
        // of up to 1000, noise densities of up to 1 V/√Hz, a phase within a turn.
        FieldError::ranges(&[
            ("chop_gain", self.chop_gain, Range::positive(1e3, "")),
            (
                "input_overload_v",
                self.input_overload_v,
                Range::positive(1e3, "V"),
            ),
            (
                "amplifier_noise",
                self.amplifier_noise,
                Range::closed(0.0, 1.0, "V/√Hz"),
            ),
            (
                "shot_noise",
                self.shot_noise,
                Range::closed(0.0, 1.0, "V/√Hz per √V"),
            ),
            (
                "phase_deg",
                self.phase_deg,
                Range::closed(-360.0, 360.0, "deg"),
            ),
        ])?;
        if !(0.001..=102_000.0).contains(&self.chopper_hz) {
            return Err(FieldError::new(
                "chopper_hz",
                "must be in 0.001..=102000 Hz",
            ));
        }
        FieldError::identity("serial", &self.serial, false)?;
        FieldError::identity("firmware", &self.firmware, false)
    }
}
