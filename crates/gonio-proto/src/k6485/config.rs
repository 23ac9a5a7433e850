//! How a 6485 session sets the instrument up and reads it, as written in an
//! instrument config file.

pub use crate::config::ConfigError;
use crate::config::Fields;

use super::{FILTER_COUNT, FilterType, LineFrequency, MIN_NPLC, Range};

/// How a [`K6485Session`](super::K6485Session) sets the picoammeter up and reads it.
/// Embeddable in an instrument config file (TOML); every field has a default, and
/// unknown fields are refused:
///
/// ```toml
/// range = "2 uA"          # a label ("2 nA" … "20 mA", u for µ) or the full scale in amps, 2e-6
/// autorange = true
/// min_fraction = 0.05
/// nplc = 1.0
/// line_frequency_hz = 50
/// filter_count = 1        # 1: filter off; 2..=100: averaging filter on
/// filter_type = "repeat"  # or "moving"
/// samples = 10
/// zero_correct = true
/// range_settle_ms = 100
/// settle_residual = 1e-4
/// timeout_ms = 1000
/// retries = 2
/// reconnect_attempts = 3
/// reconnect_delay_ms = 1000
/// ```
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct K6485Config {
    /// Starting range (the only range without autoranging). In a file: a label or the
    /// full scale in amps.
    #[serde(deserialize_with = "de_range")]
    pub range: Range,
    /// Range from the host, up one on an overflow, down one per `min_fraction`, and read
    /// again (the instrument's own autorange stays off, so that every reading's range is
    /// known).
    pub autorange: bool,
    /// With autorange: a clean reading under this fraction of full scale steps one
    /// range down. In [0, 0.1): the next range is 10× smaller and overflows at 1.05 of
    /// its full scale, so a signal under 0.1 of this one cannot bounce back.
    pub min_fraction: f64,
    /// Integration time, power line cycles: [`MIN_NPLC`](super::MIN_NPLC) up to
    /// [`LineFrequency::max_nplc`](super::LineFrequency::max_nplc).
    pub nplc: f64,
    /// The mains frequency, Hz (50 or 60): what 1 PLC is, and what `SYST:LFR?` must
    /// answer at set-up.
    pub line_frequency_hz: u32,
    /// Averaging filter count, [`FILTER_COUNT`](super::FILTER_COUNT). 1 turns the
    /// filter off (`AVER OFF`), 2..=100 turn it on (`AVER:COUN n`, `AVER ON`).
    ///
    /// Why off rather than `AVER:COUN 1` with the filter on: an average of one
    /// conversion is that conversion, so the readings are the same, but with the
    /// filter off every reading's status word keeps its filter bit
    /// ([`StatusWord::FILTER`](super::StatusWord::FILTER)) clear, so a run's log shows
    /// that no averaging was done, and set-up sends one command instead of three.
    pub filter_count: u32,
    /// Averaging filter type: `"repeat"` (independent readings) or `"moving"`.
    pub filter_type: FilterType,
    /// `READ?` readings averaged per reading, 1..=10000.
    pub samples: usize,
    /// Acquire and enable zero correction at set-up (zero check on, `INIT`,
    /// `SYST:ZCOR:ACQ`, `SYST:ZCOR ON`); off sends `SYST:ZCOR OFF`.
    pub zero_correct: bool,
    /// Wait after a range change before the next reading, ms (0..=60000). The manual
    /// gives step responses settling "<100 ms" at 1 to 10 PLC (p. 4-5); the default is
    /// 100.
    pub range_settle_ms: u64,
    /// After [`input_changed`](super::K6485Session::input_changed), readings wait until
    /// the analog front end is within this fraction of the step (from the range's
    /// rise time, Appendix A). In (0, 0.5].
    pub settle_residual: f64,
    /// How long to wait for each reply beyond the instrument's own measuring time, ms
    /// (1..=60000).
    pub timeout_ms: u64,
    /// Re-asks of a read-only query whose answer was lost or garbled (0..=10); the
    /// error queue and `*ESR?`, which reading clears, are never re-asked.
    pub retries: u32,
    /// Reconnection attempts after the port vanishes, per command (0..=100).
    pub reconnect_attempts: u32,
    /// Wait before each reconnection attempt, ms (0..=60000).
    pub reconnect_delay_ms: u64,
}

impl Default for K6485Config {
    /// 20 mA, safe for any input, with autorange and zero correction; filter off.
    fn default() -> Self {
        K6485Config {
            range: Range::LEAST,
            autorange: true,
            min_fraction: 0.05,
            nplc: 1.0,
            line_frequency_hz: 50,
            filter_count: 1,
            filter_type: FilterType::Repeat,
            samples: 10,
            zero_correct: true,
            range_settle_ms: 100,
            settle_residual: 1e-4,
            timeout_ms: 1000,
            retries: 2,
            reconnect_attempts: 3,
            reconnect_delay_ms: 1000,
        }
    }
}

crate::config::line_config!(K6485Config, range_settle: range_settle_ms);

impl K6485Config {
    /// Checks every field's range; the first bad field is named in the error.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let f = Fields::new(None);
        let Some(lf) = LineFrequency::from_hz(self.line_frequency_hz) else {
            let hz = self.line_frequency_hz;
            return f.bad("line_frequency_hz", format!("{hz} is not 50 or 60"));
        };
        let max = lf.max_nplc();
        f.check(self.nplc >= MIN_NPLC && self.nplc <= max, "nplc", || {
            format!(
                "{} is not in {MIN_NPLC}..={max} at {} Hz",
                self.nplc,
                lf.hz()
            )
        })?;
        f.check(
            FILTER_COUNT.contains(&self.filter_count),
            "filter_count",
            || {
                let (lo, hi) = (FILTER_COUNT.start(), FILTER_COUNT.end());
                format!(
                    "{} is not in {lo}..={hi} (1: filter off)",
                    self.filter_count
                )
            },
        )?;
        f.int("samples", self.samples, 1..=10_000)?;
        let why = "a range step down could then overflow and oscillate";
        f.fraction_below("min_fraction", self.min_fraction, 0.1, why)?;
        f.int("range_settle_ms", self.range_settle_ms, 0..=60_000)?;
        f.positive("settle_residual", self.settle_residual, 0.5)?;
        f.ints(self.link_checks())
    }

    /// The line frequency (50 Hz for a value [`validate`](Self::validate) refuses).
    pub fn line_frequency(&self) -> LineFrequency {
        LineFrequency::from_hz(self.line_frequency_hz).unwrap_or_default()
    }

    /// True when the averaging filter is on: a count of 2 or more (1 is sent as
    /// `AVER OFF`, see [`filter_count`](Self::filter_count)).
    pub fn filter_on(&self) -> bool {
        self.filter_count >= 2
    }

    /// Seconds of one A/D conversion: NPLC / line frequency.
    pub fn conversion_s(&self) -> f64 {
        self.nplc * self.line_frequency().plc_s()
    }

    /// Conversions behind one `READ?`: the count with the repeat filter, else one (the
    /// moving filter adds one conversion to its stack per reading).
    pub fn conversions_per_reading(&self) -> u32 {
        if self.filter_on() && self.filter_type == FilterType::Repeat {
            self.filter_count
        } else {
            1
        }
    }

    /// Seconds the instrument measures for one `READ?`, serial traffic aside.
    pub fn read_s(&self) -> f64 {
        f64::from(self.conversions_per_reading()) * self.conversion_s()
    }

    /// Seconds one averaged reading takes once settled, serial traffic aside:
    /// `samples` × [`read_s`](Self::read_s).
    pub fn reading_seconds(&self) -> f64 {
        self.samples as f64 * self.read_s()
    }
}

/// A range written as a label (`"2 nA"`, `"20 uA"`) or as its full scale in amps.
fn de_range<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Range, D::Error> {
    struct V;
    impl serde::de::Visitor<'_> for V {
        type Value = Range;
        fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("a 6485 range: a label (\"2 nA\" … \"20 mA\") or a full scale in amps")
        }
        fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Range, E> {
            Range::all()
                .find(|r| (v - r.amps()).abs() <= 1e-9 * r.amps())
                .ok_or_else(|| E::custom(format!("{v} A is not a 6485 full scale (2e-9 … 2e-2)")))
        }
        fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Range, E> {
            v.parse().map_err(E::custom)
        }
    }
    d.deserialize_any(V)
}
