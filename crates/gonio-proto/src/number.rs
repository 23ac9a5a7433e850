//! Numbers as the instruments write and read them.

/// `v` in the shortest decimal form that reads back to the same `f64` (`Display`'s),
/// without an exponent: both instruments accept plain decimals, and the ranges a
/// goniometer uses need no exponent.
pub(crate) fn format(v: f64, out: &mut Vec<u8>) {
    use std::io::Write;
    let _ = write!(out, "{v}");
}

/// Parses a number as the manuals allow it: optional sign, digits with an optional
/// decimal point (`.5` included), optional exponent (`1.5e-3`, `-4.17234e-007`).
/// Refuses `inf`, `nan`, hex, and anything else Rust's parser would accept beyond that.
pub(crate) fn parse(s: &[u8]) -> Option<f64> {
    let (mut i, n) = (0, s.len());
    if i < n && (s[i] == b'+' || s[i] == b'-') {
        i += 1;
    }
    let int_start = i;
    while i < n && s[i].is_ascii_digit() {
        i += 1;
    }
    let mut digits = i - int_start;
    if i < n && s[i] == b'.' {
        i += 1;
        let frac_start = i;
        while i < n && s[i].is_ascii_digit() {
            i += 1;
        }
        digits += i - frac_start;
    }
    if digits == 0 {
        return None;
    }
    if i < n && (s[i] == b'e' || s[i] == b'E') {
        i += 1;
        if i < n && (s[i] == b'+' || s[i] == b'-') {
            i += 1;
        }
        let exp_start = i;
        while i < n && s[i].is_ascii_digit() {
            i += 1;
        }
        if i == exp_start {
            return None;
        }
    }
    if i != n {
        return None;
    }
    let text = std::str::from_utf8(s).ok()?;
    let v: f64 = text.parse().ok()?;
    v.is_finite().then_some(v)
}

/// A plain decimal integer of 1 to `max_digits` digits (no sign, point or blank), as
/// the Cornerstone 130 and the FW102C write one.
pub(crate) fn decimal<T: std::str::FromStr>(s: &str, max_digits: usize) -> Option<T> {
    if s.is_empty() || s.len() > max_digits || !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    s.parse().ok()
}

/// Why a reply value is not the number its query returns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum ValueError {
    /// Not a number, or not the integer expected.
    Bad,
    /// A number outside what the query can return.
    OutOfRange(f64),
}

/// A number in any of the forms [`parse`] reads, surrounding blanks ignored.
pub(crate) fn real(s: &[u8]) -> Result<f64, ValueError> {
    parse(s.trim_ascii()).ok_or(ValueError::Bad)
}

/// An integer in `0..=max`, in any number form (`5`, `5.0`, `+5.000000E+00`).
pub(crate) fn integer(s: &[u8], max: f64) -> Result<f64, ValueError> {
    let v = real(s)?;
    if v.fract() != 0.0 {
        return Err(ValueError::Bad);
    }
    if !(0.0..=max).contains(&v) {
        return Err(ValueError::OutOfRange(v));
    }
    Ok(v)
}

/// The reply error of an SCPI-style family (SR830, 6485): the four refusals both
/// share, then the family's own variants. Generates the enum, the conversion from
/// [`ValueError`] and `query_line`, the check every reply parser begins with.
macro_rules! scpi_reply_error {
    ($(#[$meta:meta])* pub enum $name:ident { $($extra:tt)* }) => {
        $(#[$meta])*
        #[derive(Clone, Debug, PartialEq, thiserror::Error)]
        pub enum $name {
            /// The line is empty.
            #[error("empty reply")]
            Empty,
            /// The command is not a query: the instrument never answers it.
            #[error("{0} sends no reply")]
            NotAQuery(&'static str),
            /// A value that is not a number, or not the integer the query returns.
            #[error("malformed value")]
            BadValue,
            /// A value (an index, a status byte) outside what the query can return.
            #[error("value {0} out of range for this query")]
            OutOfRange(f64),
            $($extra)*
        }

        impl From<$crate::number::ValueError> for $name {
            fn from(e: $crate::number::ValueError) -> Self {
                match e {
                    $crate::number::ValueError::Bad => $name::BadValue,
                    $crate::number::ValueError::OutOfRange(v) => $name::OutOfRange(v),
                }
            }
        }

        impl $name {
            /// `line` trimmed, if it can answer the command `mnemonic`: a query, and
            /// not empty.
            fn query_line<'a>(
                query: bool,
                mnemonic: &'static str,
                line: &'a [u8],
            ) -> Result<&'a [u8], Self> {
                let line = line.trim_ascii();
                if !query {
                    return Err($name::NotAQuery(mnemonic));
                }
                if line.is_empty() {
                    return Err($name::Empty);
                }
                Ok(line)
            }
        }
    };
}
pub(crate) use scpi_reply_error;

/// Mean and sample standard deviation of a detector's readings (n − 1; 0 for one
/// value; NaN for none).
pub(crate) fn mean_std(v: &[f64]) -> (f64, f64) {
    if v.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    if v.len() < 2 {
        return (mean, 0.0);
    }
    let ss: f64 = v.iter().map(|x| (x - mean).powi(2)).sum();
    (mean, (ss / (n - 1.0)).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn manual_number_forms() {
        for (s, v) in [
            ("5", 5.0),
            ("5.0", 5.0),
            (".5E1", 5.0),
            ("-1.01026", -1.01026),
            ("1000.00", 1000.0),
            ("-4.17234e-007", -4.17234e-7),
            ("-1.234567e-009", -1.234567e-9),
            ("+2", 2.0),
            ("7.5e-6", 7.5e-6),
        ] {
            assert_eq!(parse(s.as_bytes()), Some(v), "{s}");
        }
        for s in [
            "", "-", ".", "e5", "1e", "inf", "NaN", "0x10", "1.2.3", "1 2", "1e999",
        ] {
            assert_eq!(parse(s.as_bytes()), None, "{s:?}");
        }
    }

    proptest! {
        #[test]
        fn format_parse_round_trip(v in -1e12..1e12f64) {
            let mut out = Vec::new();
            format(v, &mut out);
            prop_assert_eq!(parse(&out), Some(v));
        }

        #[test]
        fn parse_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            let _ = parse(&bytes);
        }
    }
}
