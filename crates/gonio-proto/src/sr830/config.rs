//! How an SR830 session sets the instrument up and reads it, as written in an
//! instrument config file.

use std::time::Duration;

use super::{FilterSlope, Sensitivity, TimeConstant, UnknownLabel};

/// How an [`Sr830Session`](super::Sr830Session) sets the instrument up and reads it.
/// Embeddable in an instrument config file (TOML); every field has a default, and
/// unknown fields are refused:
///
/// ```toml
/// sensitivity = "10 mV"     # or the SENS index, 20
/// time_constant = "100 ms"  # or the OFLT index, 8
/// slope_db = 24             # 6, 12, 18 or 24
/// samples = 10
/// autorange = true
/// min_fraction = 0.1
/// timeout_ms = 1000
/// reconnect_attempts = 3
/// reconnect_delay_ms = 1000
/// retries = 2
/// settle_residual = 0.01
/// ```
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Sr830Config {
    /// Starting sensitivity (full scale). In a file: the label as the front panel
    /// writes it (`"10 mV"`, `"5 uV"` for 5 µV) or the `SENS` index 0..=26.
    #[serde(deserialize_with = "de_sensitivity")]
    pub sensitivity: Sensitivity,
    /// Time constant. In a file: a label (`"100 ms"`, `"3 ks"`) or the `OFLT` index
    /// 0..=19.
    #[serde(deserialize_with = "de_time_constant")]
    pub time_constant: TimeConstant,
    /// Low-pass slope. In a file, `slope_db`: 6, 12, 18 or 24.
    #[serde(rename = "slope_db", deserialize_with = "de_slope")]
    pub slope: FilterSlope,
    /// Samples averaged per reading, 1..=10000.
    pub samples: usize,
    /// Change the sensitivity on overload or on a small signal.
    pub autorange: bool,
    /// With autorange: a clean reading whose mean R is below this fraction of full scale
    /// steps one range more sensitive. Must be in [0, 0.4): one step shrinks full scale
    /// by at most 2.5×, so the signal then stays under full scale and cannot bounce back.
    pub min_fraction: f64,
    /// How long to wait for each reply, ms (1..=60000).
    pub timeout_ms: u64,
    /// Reconnection attempts after the port vanishes, per command (0..=100).
    pub reconnect_attempts: u32,
    /// Wait before each reconnection attempt, ms (0..=60000).
    pub reconnect_delay_ms: u64,
    /// Re-asks of a read-only query whose answer was lost or garbled (0..=10); the
    /// status bytes, which reading clears, are never re-asked.
    pub retries: u32,
    /// How close to its final value a reading must have settled after a change, as a
    /// fraction of the step: the manual's tables are for 0.01 (99 %); precision work
    /// asks for less (1e-4 waits 15.9 time constants at 24 dB/oct). In (0, 0.5].
    pub settle_residual: f64,
}

impl Sr830Config {
    /// Seconds for the filters at `slope` and `tc` to settle within
    /// `settle_residual` of a step: the manual's rounded table at its own 1 %, the
    /// exact cascade otherwise.
    pub fn settle_seconds(&self, slope: FilterSlope, tc: TimeConstant) -> f64 {
        let factor = if self.settle_residual == 0.01 {
            slope.settle_factor()
        } else {
            slope.settle_factor_for(self.settle_residual)
        };
        factor * tc.seconds()
    }

    /// Seconds one settled reading takes after a move, serial traffic aside: the
    /// settling wait and `samples` snapshots one time constant apart.
    pub fn reading_seconds(&self) -> f64 {
        self.settle_seconds(self.slope, self.time_constant)
            + (self.samples.saturating_sub(1)) as f64 * self.time_constant.seconds()
    }
}

impl Default for Sr830Config {
    /// The `*RST` filter settings (1 V, 100 ms, 12 dB/oct; manual p. 4-4), 10 samples,
    /// autorange on at 0.1 of full scale, 1 s reply timeout, 3 reconnections 1 s apart,
    /// 2 re-asks of a lost read.
    fn default() -> Self {
        Sr830Config {
            sensitivity: Sensitivity::default(),
            time_constant: TimeConstant::default(),
            slope: FilterSlope::default(),
            samples: 10,
            autorange: true,
            min_fraction: 0.1,
            timeout_ms: 1000,
            reconnect_attempts: 3,
            reconnect_delay_ms: 1000,
            retries: 2,
            settle_residual: 0.01,
        }
    }
}

/// A config value outside what the driver accepts, naming the field.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{field}: {reason}")]
pub struct ConfigError {
    /// The field, as written in a config file.
    pub field: &'static str,
    /// What is wrong with it.
    pub reason: String,
}

impl Sr830Config {
    /// Checks every field's range; the first bad field is named in the error.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |field, reason: String| Err(ConfigError { field, reason });
        if !(1..=10_000).contains(&self.samples) {
            return bad("samples", format!("{} is not in 1..=10000", self.samples));
        }
        if !(0.0..0.4).contains(&self.min_fraction) {
            return bad(
                "min_fraction",
                format!(
                    "{} is not in [0, 0.4): a range step could then overload and oscillate",
                    self.min_fraction
                ),
            );
        }
        if !(1..=60_000).contains(&self.timeout_ms) {
            return bad(
                "timeout_ms",
                format!("{} is not in 1..=60000", self.timeout_ms),
            );
        }
        if self.reconnect_attempts > 100 {
            return bad(
                "reconnect_attempts",
                format!("{} is not in 0..=100", self.reconnect_attempts),
            );
        }
        if !(self.settle_residual > 0.0 && self.settle_residual <= 0.5) {
            return bad(
                "settle_residual",
                format!("{} is not in (0, 0.5]", self.settle_residual),
            );
        }
        if self.retries > 10 {
            return bad("retries", format!("{} is not in 0..=10", self.retries));
        }
        if self.reconnect_delay_ms > 60_000 {
            return bad(
                "reconnect_delay_ms",
                format!("{} is not in 0..=60000", self.reconnect_delay_ms),
            );
        }
        Ok(())
    }

    /// The reply timeout.
    pub fn timeout(&self) -> Duration {
        Duration::from_millis(self.timeout_ms)
    }

    /// The wait before each reconnection attempt.
    pub fn reconnect_delay(&self) -> Duration {
        Duration::from_millis(self.reconnect_delay_ms)
    }
}

/// Reads a table entry written as an index or as a label.
struct TableVisitor<V> {
    what: &'static str,
    from_index: fn(u8) -> Option<V>,
    from_label: fn(&str) -> Result<V, UnknownLabel>,
}

impl<V> serde::de::Visitor<'_> for TableVisitor<V> {
    type Value = V;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "an SR830 {} as an index or a label", self.what)
    }

    fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<V, E> {
        u8::try_from(v)
            .ok()
            .and_then(self.from_index)
            .ok_or_else(|| E::custom(format!("{v} is not an SR830 {} index", self.what)))
    }

    fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<V, E> {
        u8::try_from(v)
            .ok()
            .and_then(self.from_index)
            .ok_or_else(|| E::custom(format!("{v} is not an SR830 {} index", self.what)))
    }

    fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<V, E> {
        (self.from_label)(v).map_err(E::custom)
    }
}

fn de_sensitivity<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Sensitivity, D::Error> {
    d.deserialize_any(TableVisitor {
        what: "sensitivity",
        from_index: Sensitivity::new,
        from_label: str::parse,
    })
}

fn de_time_constant<'de, D: serde::Deserializer<'de>>(d: D) -> Result<TimeConstant, D::Error> {
    d.deserialize_any(TableVisitor {
        what: "time constant",
        from_index: TimeConstant::new,
        from_label: str::parse,
    })
}

fn de_slope<'de, D: serde::Deserializer<'de>>(d: D) -> Result<FilterSlope, D::Error> {
    use serde::Deserialize;
    let db = u8::deserialize(d)?;
    FilterSlope::from_db(db).ok_or_else(|| {
        serde::de::Error::custom(format!("{db} dB/oct is not an SR830 slope (6, 12, 18, 24)"))
    })
}
