//! How a chain's stages are configured and what timing and retry policy its session
//! follows.

use std::time::Duration;

crate::config::axis_config! {
    /// What a stage is and how the driver may move it.
    pub struct AxisConfig {
        /// The axis' name in plans and configs (`source`, `detector`, `sample_rot`).
        pub name: String,
        /// Controller address on the chain, 1–31.
        pub address: u8,
        /// Position units of the stage (`deg` for rotation stages).
        #[serde(default = "default_units")]
        pub units: String,
        limits in "units", commanded by the "driver";
        /// Velocity applied after homing (`VA`), units/s; the controller's own otherwise.
        velocity;
        /// Acceleration applied after homing (`AC`), units/s².
        acceleration;
    }
}

fn default_units() -> String {
    "deg".into()
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

impl ChainPolicy {
    /// How long a move may take: the margin plus the factor times the move's
    /// estimated duration, `estimate_s`.
    pub(crate) fn allowance(&self, estimate_s: f64) -> Duration {
        self.move_margin
            .saturating_add(crate::engine::secs(estimate_s * self.move_factor))
    }
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
