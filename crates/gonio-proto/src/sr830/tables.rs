//! The instrument's tables: sensitivities, time constants and filter slopes, with the
//! settling and noise-bandwidth figures of the manual's "SR830 Basics".

use crate::codec::{coded_enum, index_table};
use std::fmt;

/// Full-scale voltage of each `SENS` index, volts (SENS table, manual ch. 5).
const SENS_VOLTS: [f64; 27] = [
    2e-9, 5e-9, 1e-8, 2e-8, 5e-8, 1e-7, 2e-7, 5e-7, 1e-6, 2e-6, 5e-6, 1e-5, 2e-5, 5e-5, 1e-4, 2e-4,
    5e-4, 1e-3, 2e-3, 5e-3, 1e-2, 2e-2, 5e-2, 0.1, 0.2, 0.5, 1.0,
];

const SENS_LABELS: [&str; 27] = [
    "2 nV", "5 nV", "10 nV", "20 nV", "50 nV", "100 nV", "200 nV", "500 nV", "1 µV", "2 µV",
    "5 µV", "10 µV", "20 µV", "50 µV", "100 µV", "200 µV", "500 µV", "1 mV", "2 mV", "5 mV",
    "10 mV", "20 mV", "50 mV", "100 mV", "200 mV", "500 mV", "1 V",
];

/// Time constant of each `OFLT` index, seconds (OFLT table, manual ch. 5).
const TC_SECONDS: [f64; 20] = [
    1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0,
    1e3, 3e3, 1e4, 3e4,
];

const TC_LABELS: [&str; 20] = [
    "10 µs", "30 µs", "100 µs", "300 µs", "1 ms", "3 ms", "10 ms", "30 ms", "100 ms", "300 ms",
    "1 s", "3 s", "10 s", "30 s", "100 s", "300 s", "1 ks", "3 ks", "10 ks", "30 ks",
];

/// Why a table entry could not be read from text.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{text:?} is not a {what} of the SR830 (expected e.g. {example:?})")]
pub struct UnknownLabel {
    /// What was looked up ("sensitivity", "time constant").
    pub what: &'static str,
    /// The text given.
    pub text: String,
    /// A valid example.
    pub example: &'static str,
}

index_table! {
    /// A sensitivity (full-scale voltage input range), `SENS` index 0 (2 nV) to 26 (1 V).
    ///
    /// Ordered by index, so a greater value is a larger full scale (less sensitive). With
    /// a current input the same index means 1 fA … 1 µA (SENS table); this type
    /// speaks volts only.
    pub struct Sensitivity, labels: SENS_LABELS, unknown: UnknownLabel = |text| UnknownLabel {
        what: "sensitivity",
        text: text.to_string(),
        example: "10 mV",
    };
}

impl Sensitivity {
    /// The most sensitive range, 2 nV.
    pub const MOST: Sensitivity = Sensitivity(0);
    /// The least sensitive range, 1 V.
    pub const LEAST: Sensitivity = Sensitivity(26);

    /// Full scale, volts.
    pub fn volts(self) -> f64 {
        SENS_VOLTS[usize::from(self.0)]
    }

    /// The next larger full scale, or `None` at 1 V.
    pub fn less_sensitive(self) -> Option<Self> {
        Self::new(self.0 + 1)
    }

    /// The next smaller full scale, or `None` at 2 nV.
    pub fn more_sensitive(self) -> Option<Self> {
        self.0.checked_sub(1).map(Sensitivity)
    }
}

impl Default for Sensitivity {
    /// 1 V, the `*RST` default (p. 4-4).
    fn default() -> Self {
        Self::LEAST
    }
}

index_table! {
    /// A low-pass filter time constant, `OFLT` index 0 (10 µs) to 19 (30 ks).
    ///
    /// Values over 30 s cannot be set when the detection frequency is above 200 Hz, and a
    /// value below the minimum for the slope and reserve is raised to it (manual, OFLT): the
    /// instrument, not this type, knows those.
    pub struct TimeConstant, labels: TC_LABELS, unknown: UnknownLabel = |text| UnknownLabel {
        what: "time constant",
        text: text.to_string(),
        example: "100 ms",
    };
}

impl TimeConstant {
    /// The time constant, seconds.
    pub fn seconds(self) -> f64 {
        TC_SECONDS[usize::from(self.0)]
    }
}

impl Default for TimeConstant {
    /// 100 ms (`OFLT 8`), the `*RST` default (p. 4-4).
    fn default() -> Self {
        TimeConstant(8)
    }
}

coded_enum! {
    /// The low-pass filter slope, `OFSL` 0..=3 (manual, OFSL).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
    pub enum FilterSlope: u8, index / from_index {
        /// 6 dB/oct (index 0).
        Db6 = 0,
        /// 12 dB/oct (index 1).
        Db12 = 1,
        /// 18 dB/oct (index 2).
        Db18 = 2,
        /// 24 dB/oct (index 3).
        Db24 = 3,
    }
}

impl FilterSlope {
    /// The roll-off, dB per octave.
    pub fn db_per_octave(self) -> u8 {
        6 * (self.index() + 1)
    }

    /// The slope rolling off `db` dB per octave (6, 12, 18 or 24).
    pub fn from_db(db: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.db_per_octave() == db)
    }

    /// Time to reach 99 % of a step, in time constants: 5, 7, 9, 10 ("SR830 Basics", tables p. 3-21 and 3-25).
    /// Readings taken sooner still carry the previous range's transient.
    pub fn settle_factor(self) -> f64 {
        match self {
            FilterSlope::Db6 => 5.0,
            FilterSlope::Db12 => 7.0,
            FilterSlope::Db18 => 9.0,
            FilterSlope::Db24 => 10.0,
        }
    }

    /// Settling time to 99 % for time constant `tc`, seconds.
    pub fn settle_seconds(self, tc: TimeConstant) -> f64 {
        self.settle_factor() * tc.seconds()
    }

    /// Time, in time constants, for the step response of this slope's cascade of
    /// `N` identical RC stages to come within `residual` of its final value: the root
    /// of `e^{−a} Σ_{j<N} a^j/j! = residual`. The manual's table rounds this for 1 %
    /// (it gives 10 T at 24 dB/oct, where the exact figure is 10.05 T); precision work
    /// asks for less, e.g. 1e-4 (15.9 T at 24 dB/oct).
    pub fn settle_factor_for(self, residual: f64) -> f64 {
        let n = self.index() + 1;
        let left = |a: f64| {
            let (mut term, mut sum) = (1.0, 1.0);
            for j in 1..usize::from(n) {
                term *= a / j as f64;
                sum += term;
            }
            (-a).exp() * sum
        };
        let r = residual.clamp(1e-15, 0.5);
        let (mut lo, mut hi) = (0.0, 100.0);
        for _ in 0..100 {
            let mid = 0.5 * (lo + hi);
            if left(mid) > r {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        hi
    }

    /// Equivalent noise bandwidth for time constant `tc`, Hz: 1/(4T), 1/(8T), 3/(32T),
    /// 5/(64T) (same tables). Noise in a reading scales with its square root.
    pub fn enbw_hz(self, tc: TimeConstant) -> f64 {
        let k = match self {
            FilterSlope::Db6 => 1.0 / 4.0,
            FilterSlope::Db12 => 1.0 / 8.0,
            FilterSlope::Db18 => 3.0 / 32.0,
            FilterSlope::Db24 => 5.0 / 64.0,
        };
        k / tc.seconds()
    }
}

impl Default for FilterSlope {
    /// 12 dB/oct, the `*RST` default (p. 4-4).
    fn default() -> Self {
        FilterSlope::Db12
    }
}

impl fmt::Display for FilterSlope {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} dB/oct", self.db_per_octave())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::find_label;

    #[test]
    fn labels_accept_spacing_and_micro_spellings() {
        assert_eq!(find_label(&SENS_LABELS, "10mV"), Some(20));
        assert_eq!(find_label(&SENS_LABELS, "5 uV"), Some(10));
        assert_eq!(find_label(&SENS_LABELS, "5 μV"), Some(10));
        assert_eq!(find_label(&SENS_LABELS, "10 MV"), None);
        assert_eq!(find_label(&TC_LABELS, "30 ks"), Some(19));
    }
}
