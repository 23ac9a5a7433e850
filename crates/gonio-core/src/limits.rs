//! Sane ranges for the numbers Gonio reads from files and flags, and the messages that
//! name them.
//!
//! Every number a config, plan, model or surface file gives is checked against a
//! finite range before anything uses it: NaN and infinities are never accepted, and a
//! value far outside what an instrument or a surface can be (a 1e308 s timeout, a
//! 1e300 roughness) is refused as bad input rather than left to overflow a
//! `Duration`, an allocation or a loop later. A [`Range`] states its limits, so the
//! message says what would have been accepted:
//!
//! ```
//! use gonio_core::limits::Range;
//! const POLL: Range = Range::closed(1.0, 60_000.0, "ms");
//! assert_eq!(
//!     POLL.at("motion.poll_interval_ms", 1.8e19).unwrap_err(),
//!     ("motion.poll_interval_ms".to_string(), "must be at most 60000 ms, got 1.8e19".to_string())
//! );
//! assert_eq!(POLL.check(f64::NAN).unwrap_err(), "must be finite, got NaN");
//! ```
//!
//! The validation functions of the file formats return `Err((field, message))`, which
//! [`crate::tomlfile::parse`] locates in the text; [`Range::at`] and [`count_at`] give
//! that pair directly.

/// A fault found by validation: the field's dotted path and what is wrong.
pub type Fault = (String, String);

/// A finite range of accepted values with its unit: `[min, max]`, or `(min, max]` when
/// the lower end is open (a quantity that must be positive).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    /// The lowest value accepted (excluded when `open_min`).
    pub min: f64,
    /// The highest value accepted.
    pub max: f64,
    /// Whether `min` itself is refused.
    pub open_min: bool,
    /// The unit, for messages (`ms`, `m`, `deg`; empty for a pure number).
    pub unit: &'static str,
}

impl Range {
    /// `[min, max]` in `unit`.
    pub const fn closed(min: f64, max: f64, unit: &'static str) -> Range {
        Range {
            min,
            max,
            open_min: false,
            unit,
        }
    }

    /// `(0, max]` in `unit`: a positive quantity with a ceiling.
    pub const fn positive(max: f64, unit: &'static str) -> Range {
        Range {
            min: 0.0,
            max,
            open_min: true,
            unit,
        }
    }

    /// Whether `v` lies in the range (never for NaN or an infinity).
    pub fn contains(&self, v: f64) -> bool {
        v.is_finite() && v <= self.max && (v > self.min || (!self.open_min && v == self.min))
    }

    /// `v`, or what is wrong with it (`must be finite, got NaN`, `must be at most
    /// 60000 ms, got 1e20`).
    pub fn check(&self, v: f64) -> Result<f64, String> {
        if !v.is_finite() {
            return Err(format!("must be finite, got {}", num(v)));
        }
        if v > self.max {
            return Err(format!(
                "must be at most {}, got {}",
                with_unit(self.max, self.unit),
                num(v)
            ));
        }
        if self.open_min && v <= self.min {
            return Err(if self.min == 0.0 {
                format!("must be positive, got {}", num(v))
            } else {
                format!(
                    "must be greater than {}, got {}",
                    with_unit(self.min, self.unit),
                    num(v)
                )
            });
        }
        if v < self.min {
            return Err(format!(
                "must be at least {}, got {}",
                with_unit(self.min, self.unit),
                num(v)
            ));
        }
        Ok(v)
    }

    /// [`check`](Self::check) with the fault placed at `field`.
    pub fn at(&self, field: impl Into<String>, v: f64) -> Result<f64, Fault> {
        self.check(v).map_err(|m| (field.into(), m))
    }

    /// The range as a document states it: `[0, 60000] ms`, `(0, 100] m`.
    pub fn describe(&self) -> String {
        let open = if self.open_min { '(' } else { '[' };
        let body = format!("{open}{}, {}]", num(self.min), num(self.max));
        if self.unit.is_empty() {
            body
        } else {
            format!("{body} {}", self.unit)
        }
    }
}

/// `v` when `min ≤ v ≤ max`, else what is wrong with it; `unit` names what is counted
/// (`ms`, `rays`; empty for a pure number).
pub fn count(v: u64, min: u64, max: u64, unit: &str) -> Result<u64, String> {
    let u = |x: u64| {
        if unit.is_empty() {
            x.to_string()
        } else {
            format!("{x} {unit}")
        }
    };
    if v > max {
        Err(format!("must be at most {}, got {v}", u(max)))
    } else if v < min {
        Err(format!("must be at least {}, got {v}", u(min)))
    } else {
        Ok(v)
    }
}

/// [`count`] with the fault placed at `field`.
pub fn count_at(
    field: impl Into<String>,
    v: u64,
    min: u64,
    max: u64,
    unit: &str,
) -> Result<u64, Fault> {
    count(v, min, max, unit).map_err(|m| (field.into(), m))
}

/// A number as messages print it: plainly in [1e-3, 1e6), in exponent form outside
/// (`1e308`, not 309 digits).
pub fn num(x: f64) -> String {
    if x.is_nan() {
        return "NaN".into();
    }
    let a = x.abs();
    if a != 0.0 && a.is_finite() && !(1e-3..1e6).contains(&a) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

fn with_unit(x: f64, unit: &str) -> String {
    if unit.is_empty() {
        num(x)
    } else {
        format!("{} {unit}", num(x))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_limit_and_the_value() {
        let r = Range::closed(-1e6, 1e6, "deg");
        assert_eq!(r.check(0.5), Ok(0.5));
        assert_eq!(r.check(1e6), Ok(1e6));
        assert_eq!(
            r.check(f64::INFINITY).unwrap_err(),
            "must be finite, got inf"
        );
        assert_eq!(
            r.check(-2e6).unwrap_err(),
            "must be at least -1e6 deg, got -2e6"
        );
        let p = Range::positive(3600.0, "s");
        assert_eq!(p.check(0.0).unwrap_err(), "must be positive, got 0");
        assert_eq!(
            p.at("budget_s", 1e20).unwrap_err(),
            (
                "budget_s".to_string(),
                "must be at most 3600 s, got 1e20".to_string()
            )
        );
        assert!(!p.contains(0.0) && p.contains(3600.0) && !p.contains(f64::NAN));
        assert_eq!(p.describe(), "(0, 3600] s");
        assert_eq!(Range::closed(0.0, 1.0, "").describe(), "[0, 1]");
        let g = Range {
            min: 1e-4,
            max: 10.0,
            open_min: true,
            unit: "",
        };
        assert_eq!(
            g.check(1e-4).unwrap_err(),
            "must be greater than 1e-4, got 1e-4"
        );
    }

    #[test]
    fn counts() {
        assert_eq!(count(5, 1, 10, "lobes"), Ok(5));
        assert_eq!(
            count(u64::MAX, 1, 60_000, "ms").unwrap_err(),
            "must be at most 60000 ms, got 18446744073709551615"
        );
        assert_eq!(
            count_at("k", 0, 1, 3, "").unwrap_err(),
            ("k".to_string(), "must be at least 1, got 0".to_string())
        );
    }
}
