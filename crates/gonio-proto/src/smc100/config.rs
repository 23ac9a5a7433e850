//! How a chain's stages are configured and what timing and retry policy its session
//! follows.

use std::time::Duration;

/// What a stage is and how the driver may move it.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct AxisConfig {
    /// The axis' name in plans and configs (`source`, `detector`, `sample_rot`).
    pub name: String,
    /// Controller address on the chain, 1–31.
    pub address: u8,
    /// Position units of the stage (`deg` for rotation stages).
    #[serde(default = "default_units")]
    pub units: String,
    /// Lowest position the driver will ever command, units.
    pub min: f64,
    /// Highest position the driver will ever command, units.
    pub max: f64,
    /// Velocity applied after homing (`VA`), units/s; the controller's own otherwise.
    #[serde(default)]
    pub velocity: Option<f64>,
    /// Acceleration applied after homing (`AC`), units/s².
    #[serde(default)]
    pub acceleration: Option<f64>,
    /// Largest |position − target| accepted at the end of a move, units.
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// Longest a home search may take, s.
    #[serde(default = "default_home_timeout")]
    pub home_timeout_s: f64,
}

fn default_units() -> String {
    "deg".into()
}
fn default_tolerance() -> f64 {
    0.01
}
fn default_home_timeout() -> f64 {
    120.0
}

/// Timing and retry policy for a chain.
#[derive(Clone, Debug, PartialEq)]
pub struct ChainPolicy {
    /// How long to wait for a reply line (a `TP` takes 10–16 ms).
    pub reply_timeout: Duration,
    /// Pause between status polls while stages move.
    pub poll_interval: Duration,
    /// Re-sends of an idempotent command after a lost or garbled reply.
    pub retries: usize,
    /// Attempts to reopen a vanished port before giving up.
    pub reconnect_attempts: usize,
    /// Pause between reconnection attempts.
    pub reconnect_delay: Duration,
    /// Extra time allowed beyond the controller's own estimate (`PT`) for a move.
    pub move_margin: Duration,
    /// Factor on the controller's estimate for a move's deadline.
    pub move_factor: f64,
}

impl Default for ChainPolicy {
    fn default() -> Self {
        ChainPolicy {
            reply_timeout: Duration::from_millis(100),
            poll_interval: Duration::from_millis(50),
            retries: 2,
            reconnect_attempts: 5,
            reconnect_delay: Duration::from_millis(500),
            move_margin: Duration::from_secs(2),
            move_factor: 1.5,
        }
    }
}
