//! The values of an angle or a wavelength: a list, one value, or a range with a step,
//! read by hand so that a value of none of the forms names the forms.

use gonio_core::Channels;
use gonio_core::limits::{Fault, Range, num};
use serde::de::{self, MapAccess, SeqAccess, Visitor};
use serde::{Deserialize, Serialize};

use super::MAX_POINTS;

/// Values of one angle: a list, or an inclusive range with a step.
///
/// Written untagged (a list, a table or a number); read by hand, so that a value of
/// none of the three forms is refused with the forms listed rather than serde's
/// "data did not match any variant of untagged enum".
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Values {
    /// Explicit values, degrees.
    List(Vec<f64>),
    /// `from`, `from + step`, … up to `to` (included when it falls on the grid).
    Range {
        /// First value, degrees.
        from: f64,
        /// Last value, degrees.
        to: f64,
        /// Step, degrees (> 0).
        step: f64,
    },
    /// A single value, degrees.
    One(f64),
}

/// What an angle's value may be, for messages.
const VALUES_FORMS: &str = "a list of angles like [0, 30, 60], one angle like 45, or a range like { from = 0, to = 60, step = 30 }";

impl<'de> Deserialize<'de> for Values {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(ValuesVisitor(VALUES_FORMS))
    }
}

/// Reads [`Values`]; the text names the forms accepted, for messages.
struct ValuesVisitor(&'static str);

impl<'de> Visitor<'de> for ValuesVisitor {
    type Value = Values;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.0)
    }

    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Values, E> {
        Ok(Values::One(v))
    }

    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Values, E> {
        Ok(Values::One(v as f64))
    }

    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Values, E> {
        Ok(Values::One(v as f64))
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Values, A::Error> {
        let mut v = Vec::new();
        while let Some(x) = seq.next_element::<f64>()? {
            v.push(x);
        }
        Ok(Values::List(v))
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Values, A::Error> {
        let (mut from, mut to, mut step) = (None, None, None);
        while let Some(key) = map.next_key::<String>()? {
            let slot = match key.as_str() {
                "from" => &mut from,
                "to" => &mut to,
                "step" => &mut step,
                _ => {
                    return Err(de::Error::custom(format!(
                        "unknown key `{key}` in a range: a range is {}",
                        self.range_example()
                    )));
                }
            };
            *slot = Some(map.next_value::<f64>()?);
        }
        match (from, to, step) {
            (Some(from), Some(to), Some(step)) => Ok(Values::Range { from, to, step }),
            _ => {
                let missing: Vec<&str> = [("from", from), ("to", to), ("step", step)]
                    .iter()
                    .filter(|(_, v)| v.is_none())
                    .map(|(k, _)| *k)
                    .collect();
                Err(de::Error::custom(format!(
                    "a range needs from, to and step (missing {}): {}",
                    missing.join(", "),
                    self.range_example()
                )))
            }
        }
    }
}

impl ValuesVisitor {
    /// The range form of the values read, as an example.
    fn range_example(&self) -> &'static str {
        if self.0 == WAVELENGTH_FORMS {
            "{ from = 400, to = 700, step = 10 }"
        } else {
            "{ from = 0, to = 60, step = 30 }"
        }
    }
}

/// The wavelengths a plan measures at, nm: a list, one wavelength, or an inclusive
/// range with a step (see [`Wavelengths::expand`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(transparent)]
pub struct Wavelengths(pub Values);

/// What a plan's wavelengths may be, for messages.
const WAVELENGTH_FORMS: &str = "a list of wavelengths in nm like [450, 550, 650], one like 550, or a range like { from = 400, to = 700, step = 10 }";

/// Wavelengths a plan may name, nm: from 1 nm (soft X-rays) to 100 µm (far infrared),
/// well past any selector Gonio drives; outside it a number is a typo.
pub const WAVELENGTH: Range = Range::closed(1.0, 100_000.0, "nm");
/// The smallest step of a wavelength range, nm: a picometre is far below any
/// selector's bandwidth, and range values are rounded to 10⁻⁶ nm.
pub const WAVELENGTH_STEP: Range = Range::closed(0.001, 100_000.0, "nm");
/// Most wavelengths a plan may name (1 nm steps over 10 µm).
pub const MAX_WAVELENGTHS: usize = 10_000;

impl<'de> Deserialize<'de> for Wavelengths {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(ValuesVisitor(WAVELENGTH_FORMS))
            .map(Wavelengths)
    }
}

impl Wavelengths {
    /// The wavelengths, nm, or the fault (field under `wavelengths`, message).
    ///
    /// A range gives `from + k·step` for k = 0, 1, … up to `to` (included when it
    /// lies within 10⁻⁹ steps of the grid), each rounded to 10⁻⁶ nm: 400 to 700 by
    /// 10 is exactly 31 wavelengths, and 400 to 401 by 0.1 names its channels
    /// `400.1nm`, not `400.09999999999997nm`. A list is kept as written. Every
    /// wavelength lies in [`WAVELENGTH`], they strictly increase, and there are at
    /// most [`MAX_WAVELENGTHS`].
    pub fn expand(&self) -> Result<Vec<f64>, Fault> {
        const F: &str = "wavelengths";
        let v = match &self.0 {
            Values::One(x) => vec![*x],
            Values::List(v) => v.clone(),
            Values::Range { from, to, step } => {
                WAVELENGTH.at(format!("{F}.from"), *from)?;
                WAVELENGTH.at(format!("{F}.to"), *to)?;
                WAVELENGTH_STEP.at(format!("{F}.step"), *step)?;
                if from > to {
                    return Err((
                        F.into(),
                        format!("range from {from} to {to} must have from ≤ to"),
                    ));
                }
                let n = ((to - from) / step + 1e-9).floor();
                if n + 1.0 > MAX_WAVELENGTHS as f64 {
                    return Err((
                        format!("{F}.step"),
                        format!(
                            "{from} to {to} by {step} nm is more than {MAX_WAVELENGTHS} wavelengths"
                        ),
                    ));
                }
                // Below MAX_WAVELENGTHS: the cast is exact.
                (0..=n as usize)
                    .map(|k| ((from + k as f64 * step) * 1e6).round() / 1e6)
                    .collect()
            }
        };
        if v.is_empty() {
            return Err((F.into(), "name at least one wavelength".into()));
        }
        if v.len() > MAX_WAVELENGTHS {
            return Err((
                F.into(),
                format!("{} wavelengths, more than {MAX_WAVELENGTHS}", v.len()),
            ));
        }
        for (k, x) in v.iter().enumerate() {
            let field = if matches!(self.0, Values::List(_)) {
                format!("{F}[{k}]")
            } else {
                F.to_string()
            };
            WAVELENGTH.at(field.clone(), *x)?;
            if k > 0 && *x <= v[k - 1] {
                return Err((
                    field,
                    format!(
                        "{} nm does not follow {} nm: wavelengths must be strictly increasing",
                        num(*x),
                        num(v[k - 1])
                    ),
                ));
            }
        }
        Ok(v)
    }

    /// The channel names of the wavelengths, as `gonio_core::Channels` writes them
    /// (`550nm`, `412.5nm`), which read back to the same numbers.
    pub fn names(&self) -> Result<Vec<String>, Fault> {
        let v = self.expand()?;
        Channels::wavelengths(&v)
            .map(|c| c.names())
            .map_err(|e| ("wavelengths".to_string(), e.to_string()))
    }
}

impl Values {
    /// The values, or why there are none.
    pub fn expand(&self) -> Result<Vec<f64>, String> {
        let v = match self {
            Values::One(x) => vec![*x],
            Values::List(v) => v.clone(),
            Values::Range { from, to, step } => {
                if !(step.is_finite() && *step > 0.0) {
                    return Err(format!("step {step} must be positive"));
                }
                if !(from.is_finite() && to.is_finite() && from <= to) {
                    return Err(format!("range from {from} to {to} must have from ≤ to"));
                }
                // A point within 1e-9 steps of `to` counts as on the grid.
                let n = ((to - from) / step + 1e-9).floor();
                if n >= MAX_POINTS as f64 {
                    return Err(format!("more than {MAX_POINTS} values"));
                }
                (0..=n as usize).map(|k| from + k as f64 * step).collect()
            }
        };
        if v.is_empty() {
            return Err("no values".into());
        }
        if let Some(x) = v.iter().find(|x| !x.is_finite()) {
            return Err(format!("{x} is not a finite angle"));
        }
        Ok(v)
    }
}
