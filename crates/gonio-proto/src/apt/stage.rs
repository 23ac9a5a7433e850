//! The stages, and the conversions between degrees and the controller's units.
//!
//! The manual's section on scaling positions, velocities and accelerations into APT
//! units gives, for a DC servo controller such as the KDC101 with sampling
//! interval T = 2048 / (6 × 10⁶) s: position = EncCnt × x; velocity = EncCnt × T ×
//! 65536 × v; acceleration = EncCnt × T² × 65536 × a, where EncCnt is the encoder
//! counts per unit. The PRM1-Z8 has 1919.6418 counts per degree, hence 42941.66 per
//! deg/s and 14.66 per deg/s². For the K10CR1's stepper drive it gives 136533.33
//! microsteps per degree (200 full steps × 2048 microsteps × a 120:1 worm, over 360°),
//! 7329109 per deg/s and 1502 per deg/s².

use serde::{Deserialize, Serialize};

use super::Direction;

/// T, the KDC101's sampling interval, s.
const KDC101_T: f64 = 2048.0 / 6.0e6;

/// A stage and the controller that drives it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StageKind {
    /// The PRM1-Z8 rotation stage on a KDC101 K-Cube DC servo controller: continuous
    /// 360° rotation, a home switch, no limit switches.
    #[serde(rename = "prm1z8", alias = "kdc101-prm1z8")]
    Prm1Z8,
    /// The K10CR1 stepper rotation mount, controller built in: continuous 360°
    /// rotation, a home switch, no limit switches.
    #[serde(rename = "k10cr1")]
    K10cr1,
}

impl StageKind {
    /// Position counts (encoder counts or microsteps) per degree.
    pub fn counts_per_deg(self) -> f64 {
        match self {
            StageKind::Prm1Z8 => 1919.6418,
            StageKind::K10cr1 => 409_600.0 / 3.0,
        }
    }

    /// APT velocity units per deg/s.
    pub fn velocity_factor(self) -> f64 {
        match self {
            StageKind::Prm1Z8 => self.counts_per_deg() * KDC101_T * 65536.0,
            StageKind::K10cr1 => 7_329_109.0,
        }
    }

    /// APT acceleration units per deg/s².
    pub fn acceleration_factor(self) -> f64 {
        match self {
            StageKind::Prm1Z8 => self.counts_per_deg() * KDC101_T * KDC101_T * 65536.0,
            StageKind::K10cr1 => 1502.0,
        }
    }

    /// `deg` as position counts, rounded (saturating at the i32 range).
    pub fn to_counts(self, deg: f64) -> i32 {
        to_i32(deg * self.counts_per_deg())
    }

    /// Position counts as degrees.
    pub fn to_deg(self, counts: i32) -> f64 {
        f64::from(counts) / self.counts_per_deg()
    }

    /// A velocity in deg/s as APT units.
    pub fn velocity_to_apt(self, deg_s: f64) -> i32 {
        to_i32(deg_s * self.velocity_factor())
    }

    /// APT velocity units as deg/s.
    pub fn velocity_from_apt(self, v: i32) -> f64 {
        f64::from(v) / self.velocity_factor()
    }

    /// An acceleration in deg/s² as APT units.
    pub fn acceleration_to_apt(self, deg_s2: f64) -> i32 {
        to_i32(deg_s2 * self.acceleration_factor())
    }

    /// APT acceleration units as deg/s².
    pub fn acceleration_from_apt(self, a: i32) -> f64 {
        f64::from(a) / self.acceleration_factor()
    }

    /// The controller's model number, as `HW_GET_INFO` reports it.
    pub fn controller(self) -> &'static str {
        match self {
            StageKind::Prm1Z8 => "KDC101",
            StageKind::K10cr1 => "K10CR1",
        }
    }

    /// True for a DC servo drive, whose status is `MOT_GET_DCSTATUSUPDATE`; a stepper
    /// (the K10CR1) answers `MOT_REQ_STATUSUPDATE` instead.
    pub fn is_dc_servo(self) -> bool {
        matches!(self, StageKind::Prm1Z8)
    }

    /// The highest velocity a configuration may set, deg/s: Thorlabs' specified maxima
    /// (PRM1-Z8 25°/s, K10CR1 10°/s; check the current specification sheets).
    pub fn max_velocity(self) -> f64 {
        match self {
            StageKind::Prm1Z8 => 25.0,
            StageKind::K10cr1 => 10.0,
        }
    }

    /// The highest acceleration a configuration may set, deg/s² (PRM1-Z8 25°/s², K10CR1
    /// 20°/s²): conservative bounds of this crate, not values from the manual.
    pub fn max_acceleration(self) -> f64 {
        match self {
            StageKind::Prm1Z8 => 25.0,
            StageKind::K10cr1 => 20.0,
        }
    }

    /// The velocity used when the configuration gives none, deg/s (10°/s, within both
    /// stages' range; this crate's choice).
    pub fn default_velocity(self) -> f64 {
        10.0
    }

    /// The acceleration used when the configuration gives none, deg/s².
    pub fn default_acceleration(self) -> f64 {
        10.0
    }

    /// The direction of the home search: both stages home in reverse onto their home
    /// switch.
    pub fn home_direction(self) -> Direction {
        Direction::Reverse
    }

    /// The `HOMEPARAMS` limit-switch code: 1, the reverse hardware switch.
    pub fn home_limit_switch(self) -> u16 {
        1
    }

    /// The homing velocity, deg/s (this crate's choice, sent in `MOT_SET_HOMEPARAMS`).
    pub fn home_velocity(self) -> f64 {
        10.0
    }

    /// The home position's distance from the home switch, deg (this crate's choice).
    pub fn home_offset(self) -> f64 {
        4.0
    }
}

/// `v` rounded to the nearest i32, saturating (NaN gives 0).
fn to_i32(v: f64) -> i32 {
    // `as` saturates and maps NaN to 0, which is the behaviour wanted here.
    v.round() as i32
}
