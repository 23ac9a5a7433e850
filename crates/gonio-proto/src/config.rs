//! What every family's configuration shares: the error that names a bad field as a
//! config file writes it, the range checks a family's `validate` is a list of, the
//! link-policy fields of the line families and the durations they give.

use std::fmt::Display;
use std::ops::RangeInclusive;

/// A config value outside what the driver accepts, naming the field.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{}{field}: {reason}", .family.map_or(String::new(), |f| format!("{f} config ")))]
pub struct ConfigError {
    /// The family the message names first (`cs130 config timeout_ms: …`), if any.
    pub family: Option<&'static str>,
    /// The field, as written in a config file (`gratings[1].max_nm`).
    pub field: String,
    /// What is wrong with it.
    pub reason: String,
}

/// A check's outcome: the first bad field, if any.
type Checked = Result<(), ConfigError>;

/// One integer field's check: its name, its value and its range.
pub(crate) type IntCheck = (&'static str, u64, RangeInclusive<u64>);

/// For a line family's config `$config`: `link_checks()`, the ranges of the link-policy
/// fields every line family has, and `timeout()` and `reconnect_delay()`, and a
/// duration accessor `$name()` for each further field `$field` in ms.
macro_rules! line_config {
    ($config:ty $(, $name:ident: $field:ident)*) => {
        impl $config {
            /// The link-policy fields' checks, in this order: a family checks each
            /// where its order of fields has it.
            fn link_checks(&self) -> [$crate::config::IntCheck; 4] {
                [
                    ("timeout_ms", self.timeout_ms, 1..=60_000),
                    ("retries", self.retries.into(), 0..=10),
                    ("reconnect_attempts", self.reconnect_attempts.into(), 0..=100),
                    ("reconnect_delay_ms", self.reconnect_delay_ms, 0..=60_000),
                ]
            }
            $crate::config::line_config!(@ms timeout: timeout_ms);
            $crate::config::line_config!(@ms reconnect_delay: reconnect_delay_ms);
            $($crate::config::line_config!(@ms $name: $field);)*
        }
    };
    (@ms $name:ident: $field:ident) => {
        #[doc = concat!("`", stringify!($field), "` as a duration.")]
        pub fn $name(&self) -> std::time::Duration {
            std::time::Duration::from_millis(self.$field)
        }
    };
}
pub(crate) use line_config;

/// The checks a family's `validate` is written in. Each names the field as the config
/// file writes it, below a list entry's prefix (`filters[2].`), and carries the family
/// the message names first.
pub(crate) struct Fields {
    family: Option<&'static str>,
    prefix: String,
}

impl Fields {
    /// A config's top-level fields; `family` as [`ConfigError::family`].
    pub(crate) fn new(family: Option<&'static str>) -> Self {
        Fields {
            family,
            prefix: String::new(),
        }
    }

    /// The fields of entry `i` of the list `list` (`filters[2].cut_on_nm`).
    pub(crate) fn entry(&self, list: &str, i: usize) -> Fields {
        Fields {
            family: self.family,
            prefix: format!("{}{list}[{i}].", self.prefix),
        }
    }

    /// Refuses `field` for `reason`.
    pub(crate) fn bad<T>(&self, field: &str, reason: impl Into<String>) -> Result<T, ConfigError> {
        Err(ConfigError {
            family: self.family,
            field: format!("{}{field}", self.prefix),
            reason: reason.into(),
        })
    }

    /// Refuses `field` for `reason()` unless `ok`.
    pub(crate) fn check(&self, ok: bool, field: &str, reason: impl FnOnce() -> String) -> Checked {
        if ok {
            Ok(())
        } else {
            self.bad(field, reason())
        }
    }

    /// An integer in `range`.
    pub(crate) fn int<T: PartialOrd + Display>(
        &self,
        field: &str,
        v: T,
        range: RangeInclusive<T>,
    ) -> Checked {
        self.check(range.contains(&v), field, || {
            format!("{v} is not in {}..={}", range.start(), range.end())
        })
    }

    /// Each of `checks` in turn ([`int`](Self::int)).
    pub(crate) fn ints(&self, checks: impl IntoIterator<Item = IntCheck>) -> Checked {
        checks
            .into_iter()
            .try_for_each(|(field, v, range)| self.int(field, v, range))
    }

    /// A real in (0, `hi`] (so finite).
    pub(crate) fn positive(&self, field: &str, v: f64, hi: f64) -> Checked {
        self.check(v > 0.0 && v <= hi, field, || {
            format!("{v} is not in (0, {hi}]")
        })
    }

    /// A real in [`lo`, `hi`] (so finite).
    pub(crate) fn real(&self, field: &str, v: f64, lo: f64, hi: f64) -> Checked {
        self.check(v >= lo && v <= hi, field, || {
            format!("{v} is not in [{lo}, {hi}]")
        })
    }

    /// A fraction in [0, `hi`), with `why` a larger one is refused.
    pub(crate) fn fraction_below(&self, field: &str, v: f64, hi: f64, why: &str) -> Checked {
        self.check((0.0..hi).contains(&v), field, || {
            format!("{v} is not in [0, {hi}): {why}")
        })
    }

    /// A `what` (`position`) that none of the `earlier` entries has.
    pub(crate) fn unique<T: PartialEq + Display>(
        &self,
        field: &str,
        what: &str,
        v: T,
        mut earlier: impl Iterator<Item = T>,
    ) -> Checked {
        self.check(!earlier.any(|o| o == v), field, || {
            format!("{what} {v} is listed twice")
        })
    }
}

/// Declares a motion family's axis config: its own fields, the limits every motion axis
/// has (`min`, `max` and `tolerance` in `$unit`, `velocity` and `acceleration` as the
/// family documents them, `home_timeout_s`), then its own further fields.
macro_rules! axis_config {
    (
        $(#[$doc:meta])*
        pub struct $name:ident {
            $($(#[$head_attr:meta])* pub $head:ident: $head_ty:ty,)*
            limits in $unit:literal, commanded by the $who:literal;
            $(#[$velocity:meta])* velocity;
            $(#[$acceleration:meta])* acceleration;
            $($(#[$tail_attr:meta])* pub $tail:ident: $tail_ty:ty,)*
        }
    ) => {
        $(#[$doc])*
        #[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
        #[serde(deny_unknown_fields)]
        pub struct $name {
            $($(#[$head_attr])* pub $head: $head_ty,)*
            #[doc = concat!("Lowest position the ", $who, " will ever command, ", $unit, ".")]
            pub min: f64,
            #[doc = concat!("Highest position the ", $who, " will ever command, ", $unit, ".")]
            pub max: f64,
            $(#[$velocity])*
            #[serde(default)]
            pub velocity: Option<f64>,
            $(#[$acceleration])*
            #[serde(default)]
            pub acceleration: Option<f64>,
            #[doc = concat!("Largest |position − target| accepted at the end of a move, ", $unit, ".")]
            #[serde(default = "crate::config::default_tolerance")]
            pub tolerance: f64,
            /// Longest a home search may take, s.
            #[serde(default = "crate::config::default_home_timeout")]
            pub home_timeout_s: f64,
            $($(#[$tail_attr])* pub $tail: $tail_ty,)*
        }
    };
}
pub(crate) use axis_config;

/// The default of a motion axis' `tolerance`, in its units.
pub(crate) fn default_tolerance() -> f64 {
    0.01
}

/// The default of a motion axis' `home_timeout_s`.
pub(crate) fn default_home_timeout() -> f64 {
    120.0
}
