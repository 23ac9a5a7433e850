//! The instrument's tables: current ranges with their specifications, integration
//! (NPLC) limits by line frequency, and the averaging filter's limits.
//!
//! Sources: Model 6485 Picoammeter Instruction Manual (Keithley 6485-901-01), Table 4-1
//! "Measurement ranges" and Table 4-3 "Ranges and values" (p. 4-2, 4-5), "Rate" (p. 4-5,
//! 4-6), and Appendix A "Specifications" for accuracy, noise and rise time.
//!
//! The ranges, the 5 % over-range, the NPLC limits and the overflow codes were checked
//! against the manual's pages. The Appendix A numbers (accuracy, typical rms noise,
//! rise time) are the 6485 data sheet's as transcribed here, not re-checked against a
//! copy of Appendix A (UNCONFIRMED): verify them against the unit's own manual
//! revision before a reduction relies on them.

use crate::codec::{coded_enum, index_table};

/// Full scale of each range, amps (Table 4-3), most sensitive first.
const RANGE_AMPS: [f64; 8] = [2e-9, 2e-8, 2e-7, 2e-6, 2e-5, 2e-4, 2e-3, 2e-2];

const RANGE_LABELS: [&str; 8] = [
    "2 nA", "20 nA", "200 nA", "2 µA", "20 µA", "200 µA", "2 mA", "20 mA",
];

/// (fraction of reading, offset amps) per range, for [`accuracy_a`].
const ACCURACY: [(f64, f64); 8] = [
    (0.004, 400e-15),
    (0.004, 1e-12),
    (0.002, 10e-12),
    (0.0015, 100e-12),
    (0.001, 1e-9),
    (0.001, 10e-9),
    (0.001, 100e-9),
    (0.001, 1e-6),
];

/// Typical rms input noise per range, amps (Appendix A, "typical RMS noise"), taken
/// here as the noise of one conversion at 1 PLC, the rate the manual calls optimal
/// (p. 4-5, Figure 4-1).
const NOISE_RMS: [f64; 8] = [20e-15, 100e-15, 1e-12, 10e-12, 100e-12, 1e-9, 10e-9, 100e-9];

/// Analog rise time (10 % to 90 %) per range, seconds (Appendix A); the nA ranges'
/// large feedback resistor makes theirs slow.
const RISE_S: [f64; 8] = [8e-3, 8e-3, 500e-6, 500e-6, 500e-6, 500e-6, 500e-6, 500e-6];

/// A reading over this multiple of full scale overflows (p. 4-2: "full scale readings
/// for every measurement range are 5 % over range"; display `OVRFLOW`).
pub const OVERRANGE_FACTOR: f64 = 1.05;

/// The value an overflowed (or overvoltage) reading is sent as (FORMat:ELEMents,
/// p. 13-6): `+9.9E37`.
pub const OVERFLOW_VALUE: f64 = 9.9e37;

/// The value an invalid element is sent as, "NAN" (p. 13-6): `+9.91E37`.
pub const NAN_VALUE: f64 = 9.91e37;

index_table! {
    /// A current range of the 6485, 2 nA (index 0) to 20 mA (index 7). Ordered by index:
    /// a greater range has a larger full scale.
    pub struct Range, labels: RANGE_LABELS, unknown: UnknownRange = |text| UnknownRange(text.to_string());
}

impl Range {
    /// 2 nA, the most sensitive range.
    pub const MOST: Range = Range(0);
    /// 20 mA, the least sensitive range.
    pub const LEAST: Range = Range(7);

    /// Full scale, amps.
    pub fn amps(self) -> f64 {
        RANGE_AMPS[usize::from(self.0)]
    }

    /// The range `CURR:RANG <n>` selects: the most sensitive one whose full scale is at
    /// least |n| (the manual: "the expected reading", Table 4-2). `None` above 20 mA
    /// (the instrument accepts up to 0.021, which lands on 20 mA too) or for a
    /// non-finite value.
    pub fn for_current(amps: f64) -> Option<Self> {
        if !amps.is_finite() {
            return None;
        }
        let a = amps.abs();
        // A relative tolerance so that `2E-9` written in decimal selects 2 nA, not 20 nA.
        Self::all()
            .find(|r| a <= r.amps() * (1.0 + 1e-9))
            .or_else(|| (a <= 0.021 * (1.0 + 1e-9)).then_some(Range::LEAST))
    }

    /// One range less sensitive, if any.
    pub fn up(self) -> Option<Self> {
        Range::new(self.0 + 1)
    }

    /// One range more sensitive, if any.
    pub fn down(self) -> Option<Self> {
        self.0.checked_sub(1).map(Range)
    }

    /// Largest reading before overflow, amps: 1.05 × full scale.
    pub fn overflow_amps(self) -> f64 {
        OVERRANGE_FACTOR * self.amps()
    }

    /// Typical rms noise of one conversion at 1 PLC, amps (Appendix A).
    pub fn noise_rms_a(self) -> f64 {
        NOISE_RMS[usize::from(self.0)]
    }

    /// Analog rise time 10 %–90 %, seconds (Appendix A).
    pub fn rise_time_s(self) -> f64 {
        RISE_S[usize::from(self.0)]
    }

    /// Seconds for the analog front end to come within `residual` of a step: a single
    /// pole, whose 10–90 % rise is ln 9 ≈ 2.197 time constants, needs ln(1/residual)
    /// time constants.
    pub fn settle_s(self, residual: f64) -> f64 {
        let tau = self.rise_time_s() / 9f64.ln();
        tau * (1.0 / residual).ln().max(0.0)
    }
}

impl Default for Range {
    /// 20 mA, the `*RST` range (the least sensitive, safe for any input).
    fn default() -> Self {
        Range::LEAST
    }
}

/// The 1-year accuracy bound of a reading, amps: ±(% rdg + offset) of Appendix A for
/// `range`, at 18–28 °C, 0–70 % RH, after zero correction.
///
/// This is the manufacturer's **stated bound** (a limit, not a standard deviation).
/// A reduction that wants a standard uncertainty should treat it as the half-width of a
/// rectangular distribution (GUM 4.3.7) and divide by √3.
pub fn accuracy_a(range: Range, reading_a: f64) -> f64 {
    let (gain, offset) = ACCURACY[usize::from(range.0)];
    gain * reading_a.abs() + offset
}

coded_enum! {
    /// The mains frequency the instrument integrates against (`SYST:LFR?`): 1 PLC is
    /// 1/50 s or 1/60 s (p. 4-5; 400 Hz mains counts as 50 Hz).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
    pub enum LineFrequency: u32, hz / from_hz {
        /// 50 Hz (and 400 Hz) mains: 1 PLC = 20 ms, NPLC up to 50.
        #[default]
        Hz50 = 50,
        /// 60 Hz mains: 1 PLC = 16.67 ms, NPLC up to 60.
        Hz60 = 60,
    }
}

impl LineFrequency {
    /// One power line cycle, seconds.
    pub fn plc_s(self) -> f64 {
        1.0 / f64::from(self.hz())
    }

    /// The largest NPLC the instrument accepts at this frequency: one second (p. 4-6).
    pub fn max_nplc(self) -> f64 {
        f64::from(self.hz())
    }
}

/// The smallest NPLC (p. 4-6).
pub const MIN_NPLC: f64 = 0.01;

/// The averaging filter's count limits, `AVER:COUN`: "Both are a simple average of
/// one to 100 reading conversions" (Model 6485 Instruction Manual, p. 4-8, "Filters",
/// of the repeating and moving filters).
pub const FILTER_COUNT: std::ops::RangeInclusive<u32> = 1..=100;

/// The averaging filter's type, `AVER:TCON` (p. 4-8, "Filters").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FilterType {
    /// `REP`: each reading averages `count` fresh conversions, then the stack is
    /// cleared: readings are independent.
    #[default]
    Repeat,
    /// `MOV`: a first-in first-out stack; each reading adds one conversion to the
    /// average of the last `count`: consecutive readings are correlated.
    Moving,
}

impl FilterType {
    /// The SCPI mnemonic, `REP` or `MOV`.
    pub fn mnemonic(self) -> &'static str {
        match self {
            FilterType::Repeat => "REP",
            FilterType::Moving => "MOV",
        }
    }
}

/// Why a range could not be read from text.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0:?} is not a 6485 range (expected a label like \"2 nA\", \"20 uA\", \"2 mA\")")]
pub struct UnknownRange(pub String);
