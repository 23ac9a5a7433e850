//! How an SR830 session sets the instrument up and reads it, as written in an
//! instrument config file.

pub use crate::config::ConfigError;
use crate::config::Fields;

use super::{FilterSlope, NoiseDensity, Sensitivity, TimeConstant, UnknownLabel};

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
/// # Only for plans with a [reading] target:
/// noise = { floor = 20e-9, shot = 2e-6 }
/// time_constant_range = ["10 ms", "300 ms"]
/// buffer = true
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
    /// The output noise as white densities (`noise = { floor = 20e-9, shot = 2e-6 }`,
    /// V/√Hz and V/√Hz per √V): what a reading to a precision target predicts its
    /// scatter from, and chooses its time constant by. Absent, a targeted reading
    /// trusts its own scatter and keeps `time_constant`.
    pub noise: Option<NoiseDensity>,
    /// Time constants a targeted reading may choose from, the shortest and longest
    /// (labels or `OFLT` indices); it needs `noise`. Absent: `time_constant` always.
    #[serde(deserialize_with = "de_time_constant_range")]
    pub time_constant_range: Option<[TimeConstant; 2]>,
    /// A targeted reading may read through the instrument's data buffer (`SRAT`,
    /// `STRT`, `SPTS?`, `TRCL?`) instead of `SNAP?` polling, when its estimate says that
    /// is faster at the port's baud rate ([`buffer`](super::buffer)). Needs `noise`.
    /// Default off.
    pub buffer: bool,
    /// Seconds one `SNAP?` exchange takes on the wire (36 characters both ways at the
    /// port's baud rate): set from the instrument config, never read from a file.
    #[serde(skip)]
    pub exchange_s: f64,
    /// The port's baud rate, for the time of the exchanges
    /// ([`timing`](super::timing)): set from the instrument config with
    /// [`with_baud`](Self::with_baud), never read from a file.
    #[serde(skip, default = "default_baud")]
    pub baud: u32,
}

/// The SR830's baud rate as shipped (manual p. 4-4).
fn default_baud() -> u32 {
    9600
}

/// One `SNAP?` exchange's characters, both ways, at 10 bits a character.
const EXCHANGE_BITS: f64 = 36.0 * 10.0;

impl Sr830Config {
    /// Checks every field's range; the first bad field is named in the error.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let f = Fields::new(None);
        let [timeout, retries, attempts, delay] = self.link_checks();
        f.int("samples", self.samples, 1..=10_000)?;
        let why = "a range step could then overload and oscillate";
        f.fraction_below("min_fraction", self.min_fraction, 0.4, why)?;
        f.ints([timeout, attempts])?;
        f.positive("settle_residual", self.settle_residual, 0.5)?;
        if let Some(n) = &self.noise {
            f.real("noise.floor", n.floor, 0.0, 1.0)?;
            f.real("noise.shot", n.shot, 0.0, 1.0)?;
            f.check(n.floor != 0.0 || n.shot != 0.0, "noise", || {
                "floor and shot are both 0: no reading is noiseless".into()
            })?;
        }
        if let Some([lo, hi]) = self.time_constant_range {
            let field = "time_constant_range";
            f.check(lo <= hi, field, || {
                format!("{lo} is longer than {hi}: give the shortest first")
            })?;
            f.check(self.noise.is_some(), field, || {
                "needs `noise`: the choice weighs settling against the noise".into()
            })?;
        }
        f.ints([retries, delay])
    }

    /// Sets [`exchange_s`](Self::exchange_s) and [`baud`](Self::baud) for a port at
    /// `baud`.
    pub fn with_baud(mut self, baud: u32) -> Self {
        self.exchange_s = EXCHANGE_BITS / f64::from(baud.max(1));
        self.baud = baud;
        self
    }

    /// The time constants a targeted reading may choose from, shortest first: the
    /// range's, or `time_constant` alone.
    pub fn time_constant_choices(&self) -> Vec<TimeConstant> {
        match self.time_constant_range {
            Some([lo, hi]) => (lo.index()..=hi.index())
                .filter_map(TimeConstant::new)
                .collect(),
            None => vec![self.time_constant],
        }
    }

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
    /// The `*RST` filter settings (1 V, 100 ms, 12 dB/oct; manual p. 4-4), with autorange.
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
            noise: None,
            time_constant_range: None,
            buffer: false,
            exchange_s: EXCHANGE_BITS / 9600.0,
            baud: default_baud(),
        }
    }
}

crate::config::line_config!(Sr830Config);

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

fn de_time_constant_range<'de, D: serde::Deserializer<'de>>(
    d: D,
) -> Result<Option<[TimeConstant; 2]>, D::Error> {
    use serde::Deserialize;
    /// One entry, as a label or an index.
    struct Tc(TimeConstant);
    impl<'de> Deserialize<'de> for Tc {
        fn deserialize<D2: serde::Deserializer<'de>>(d: D2) -> Result<Self, D2::Error> {
            de_time_constant(d).map(Tc)
        }
    }
    let [lo, hi] = <[Tc; 2]>::deserialize(d)?;
    Ok(Some([lo.0, hi.0]))
}

fn de_slope<'de, D: serde::Deserializer<'de>>(d: D) -> Result<FilterSlope, D::Error> {
    use serde::Deserialize;
    let db = u8::deserialize(d)?;
    FilterSlope::from_db(db).ok_or_else(|| {
        serde::de::Error::custom(format!("{db} dB/oct is not an SR830 slope (6, 12, 18, 24)"))
    })
}
