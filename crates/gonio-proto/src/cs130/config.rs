//! How a CS130 session drives the monochromator, as written in an instrument config
//! file, and the two choices it makes for a wavelength: the grating
//! ([`Cs130Config::grating_for`]) and the order-sorting filter
//! ([`Cs130Config::order_filter_for`]).

use std::time::Duration;

/// Most gratings a turret holds, as far as the config accepts. **UNCONFIRMED** for the
/// CS130B: its turret size was not found in the stored manual (the older Model 74000
/// takes "either '1' or '2'"); 3 is a generous bound.
pub const MAX_GRATINGS: u8 = 3;

/// The standard uncertainty of a Cornerstone 130's wavelength scale that the
/// reduction assumes when the instrument config states none, nm: a ±0.35 nm accuracy
/// with a 1200 l/mm grating taken as a rectangular bound (**UNCONFIRMED**: the
/// specification pages are not in the stored manual).
pub const WAVELENGTH_UNCERTAINTY_NM: f64 = 0.2;
/// The bandpass (FWHM of the triangular slit function) assumed when the instrument
/// config states none, nm.
pub const BANDWIDTH_NM: f64 = 2.0;

/// Filter wheel positions: "FILTER x … Acceptable values range from 1 through 6"
/// (Cornerstone 130, Model 74000, command table).
pub const MAX_FILTER_POSITION: u8 = 6;

/// The filter position a session reports when the config has no filter wheel
/// (`filter_wheel = false`): 0, what `FILTER?` answers when "there is no filter wheel
/// connected" (Model 74000 command table).
pub const NO_FILTER_WHEEL: u8 = 0;

/// One grating on the turret: its number (`GRAT n`), groove density and the range
/// the session uses it for.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GratingSpec {
    /// Its number on the turret, 1..=[`MAX_GRATINGS`].
    pub index: u8,
    /// Grooves per mm (informative: the run log and the light model name it).
    pub lines_per_mm: u32,
    /// Shortest wavelength it is used for, nm.
    pub min_nm: f64,
    /// Longest wavelength it is used for, nm.
    pub max_nm: f64,
}

/// One long-pass order-sorting filter on the wheel.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrderFilterSpec {
    /// Its wheel position (`FILTER n`), 1..=[`MAX_FILTER_POSITION`].
    pub position: u8,
    /// Its cut-on wavelength, nm: it blocks shorter wavelengths and passes longer.
    pub cut_on_nm: f64,
}

/// How a [`Cs130Session`](super::Cs130Session) drives the monochromator. Every field
/// has a default and unknown fields are refused:
///
/// ```toml
/// filter_wheel = true        # false: the unit has no filter wheel (see the field)
/// auto_order_filter = true
/// open_filter = 1            # the wheel position with no filter
/// shortest_nm = 250.0        # shortest wavelength in the beam (lamp, optics)
/// filter_margin_nm = 10.0
/// position_tolerance_nm = 2.0
/// echo = true
/// timeout_ms = 1000
/// move_timeout_ms = 60000
/// retries = 2
/// reconnect_attempts = 3
/// reconnect_delay_ms = 1000
///
/// [[gratings]]
/// index = 1
/// lines_per_mm = 1200
/// min_nm = 250.0
/// max_nm = 900.0
///
/// [[gratings]]
/// index = 2
/// lines_per_mm = 600
/// min_nm = 900.0
/// max_nm = 2000.0
///
/// [[filters]]
/// position = 2
/// cut_on_nm = 335.0
/// ```
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Cs130Config {
    /// The gratings and the range each is used for. Default: 1200 l/mm for
    /// 250–900 nm, 600 l/mm for 900–2000 nm.
    pub gratings: Vec<GratingSpec>,
    /// The order-sorting filters on the wheel. Default: cut-ons 335, 590, 1000 and
    /// 1500 nm at positions 2 to 5.
    pub filters: Vec<OrderFilterSpec>,
    /// The wheel position with no filter (the open position), 1..=6. Default 1.
    pub open_filter: u8,
    /// The monochromator has a filter wheel (default true, so configs written before
    /// this field keep their meaning). A unit without one answers `FILTER?` with `0`
    /// and flags an error in the status byte (Model 74000 command table), so with
    /// `false` the session never sends `FILTER?` or `FILTER n`, and reports filter
    /// position [`NO_FILTER_WHEEL`]. It needs `auto_order_filter = false`: there is no
    /// wheel to sort orders with, and above 2 × `shortest_nm` the second order must
    /// then be blocked some other way (the config says so rather than letting it pass
    /// silently). `filters` and `open_filter` are not used. With `true`, a `FILTER?`
    /// answered `0` fails the operation with
    /// [`Cs130Error::NoFilterWheel`](super::Cs130Error::NoFilterWheel).
    pub filter_wheel: bool,
    /// Choose and set the order-sorting filter before every move (`FILTER`). Needs
    /// `filter_wheel`.
    pub auto_order_filter: bool,
    /// The shortest wavelength present in the beam, nm (the lamp's, or the optics'
    /// cut-off): below twice it there is no second-order light, and the open position
    /// is used. In (0, 10000].
    pub shortest_nm: f64,
    /// How far a filter's cut-on must stay from λ and from λ/2, nm: a filter's edge
    /// has a width, and its transmission near the edge is neither 0 nor 1. In
    /// [0, 500].
    pub filter_margin_nm: f64,
    /// How far below each wavelength the drive starts its last approach, nm, in
    /// [0, 100]: a move that would come down onto a wavelength (or start from an
    /// unknown position) first goes this far below it, so that the drive's backlash
    /// is always taken up upwards. 0 turns it off. Default 5 nm.
    pub approach_nm: f64,
    /// The largest difference between the wavelength asked for and the one `WAVE?`
    /// reads back after the move, nm, in (0, 100]: more is an error.
    pub position_tolerance_nm: f64,
    /// The instrument echoes each statement on RS-232 (factory setting; §15.4).
    pub echo: bool,
    /// How long to wait for an echo or an answer, ms (1..=60000).
    pub timeout_ms: u64,
    /// How long a query sent after `*WAI` may wait for the move before it, ms
    /// (1..=600000): the longest grating change, filter change and slew together.
    pub move_timeout_ms: u64,
    /// Re-sends of a statement whose echo or answer was lost or garbled (0..=10);
    /// `STB?` and `ERROR?`, which reading clears, are never re-sent.
    pub retries: u32,
    /// Reconnection attempts after the port vanishes, per statement (0..=100).
    pub reconnect_attempts: u32,
    /// Wait before each reconnection attempt, ms (0..=60000).
    pub reconnect_delay_ms: u64,
}

impl Default for Cs130Config {
    fn default() -> Self {
        Cs130Config {
            gratings: vec![
                GratingSpec {
                    index: 1,
                    lines_per_mm: 1200,
                    min_nm: 250.0,
                    max_nm: 900.0,
                },
                GratingSpec {
                    index: 2,
                    lines_per_mm: 600,
                    min_nm: 900.0,
                    max_nm: 2000.0,
                },
            ],
            filters: [(2, 335.0), (3, 590.0), (4, 1000.0), (5, 1500.0)]
                .into_iter()
                .map(|(position, cut_on_nm)| OrderFilterSpec {
                    position,
                    cut_on_nm,
                })
                .collect(),
            open_filter: 1,
            filter_wheel: true,
            auto_order_filter: true,
            shortest_nm: 250.0,
            filter_margin_nm: 10.0,
            approach_nm: 5.0,
            position_tolerance_nm: 2.0,
            echo: true,
            timeout_ms: 1000,
            move_timeout_ms: 60_000,
            retries: 2,
            reconnect_attempts: 3,
            reconnect_delay_ms: 1000,
        }
    }
}

/// A config value out of range: the field (as a config file writes it) and why.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("cs130 config {field}: {reason}")]
pub struct ConfigError {
    /// The field, as written in a config file (`gratings[1].max_nm`).
    pub field: String,
    /// What is wrong with it.
    pub reason: String,
}

/// A wavelength the configured monochromator cannot deliver cleanly: refused before
/// any byte is sent.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SelectError {
    /// No grating's range holds it (or it is not a finite number).
    #[error("{nm} nm is outside every grating's range ({ranges})")]
    OutOfRange {
        /// The wavelength asked for.
        nm: f64,
        /// The configured ranges, for the message.
        ranges: String,
    },
    /// Second-order light would pass and no filter blocks it while passing λ.
    #[error("no order-sorting filter has a cut-on in [{low} nm, {high} nm] for {nm} nm")]
    NoOrderFilter {
        /// The wavelength asked for.
        nm: f64,
        /// λ/2 + margin: the lowest cut-on that blocks the second order.
        low: f64,
        /// λ − margin: the highest cut-on that passes λ.
        high: f64,
    },
}

impl Cs130Config {
    /// Checks every field's range; the first bad field is named in the error.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |field: String, reason: String| Err(ConfigError { field, reason });
        if self.gratings.is_empty() {
            return bad("gratings".into(), "at least one grating is needed".into());
        }
        for (i, g) in self.gratings.iter().enumerate() {
            if !(1..=MAX_GRATINGS).contains(&g.index) {
                return bad(
                    format!("gratings[{i}].index"),
                    format!("{} is not in 1..={MAX_GRATINGS}", g.index),
                );
            }
            if self.gratings[..i].iter().any(|o| o.index == g.index) {
                return bad(
                    format!("gratings[{i}].index"),
                    format!("grating {} is listed twice", g.index),
                );
            }
            if !(1..=10_000).contains(&g.lines_per_mm) {
                return bad(
                    format!("gratings[{i}].lines_per_mm"),
                    format!("{} is not in 1..=10000", g.lines_per_mm),
                );
            }
            if !(g.min_nm > 0.0 && g.min_nm < g.max_nm && g.max_nm <= 100_000.0) {
                return bad(
                    format!("gratings[{i}].max_nm"),
                    format!(
                        "range {}..={} nm is not 0 < min < max <= 100000",
                        g.min_nm, g.max_nm
                    ),
                );
            }
        }
        if !self.filter_wheel && self.auto_order_filter {
            return bad(
                "auto_order_filter".into(),
                "filter_wheel = false: there is no wheel to set order-sorting filters \
                 with; set auto_order_filter = false (and block the second order above \
                 2 × shortest_nm some other way)"
                    .into(),
            );
        }
        if !(1..=MAX_FILTER_POSITION).contains(&self.open_filter) {
            return bad(
                "open_filter".into(),
                format!("{} is not in 1..={MAX_FILTER_POSITION}", self.open_filter),
            );
        }
        for (i, f) in self.filters.iter().enumerate() {
            if !(1..=MAX_FILTER_POSITION).contains(&f.position) {
                return bad(
                    format!("filters[{i}].position"),
                    format!("{} is not in 1..={MAX_FILTER_POSITION}", f.position),
                );
            }
            if f.position == self.open_filter {
                return bad(
                    format!("filters[{i}].position"),
                    format!("{} is the open position", f.position),
                );
            }
            if self.filters[..i].iter().any(|o| o.position == f.position) {
                return bad(
                    format!("filters[{i}].position"),
                    format!("position {} is listed twice", f.position),
                );
            }
            if !(f.cut_on_nm > 0.0 && f.cut_on_nm <= 100_000.0) {
                return bad(
                    format!("filters[{i}].cut_on_nm"),
                    format!("{} is not in (0, 100000]", f.cut_on_nm),
                );
            }
        }
        let checks: [(&str, f64, f64, f64); 4] = [
            ("shortest_nm", self.shortest_nm, f64::MIN_POSITIVE, 10_000.0),
            ("filter_margin_nm", self.filter_margin_nm, 0.0, 500.0),
            ("approach_nm", self.approach_nm, 0.0, 100.0),
            (
                "position_tolerance_nm",
                self.position_tolerance_nm,
                f64::MIN_POSITIVE,
                100.0,
            ),
        ];
        for (field, v, lo, hi) in checks {
            if !(v >= lo && v <= hi) {
                return bad(field.into(), format!("{v} is not in [{lo}, {hi}]"));
            }
        }
        let ints: [(&str, u64, u64, u64); 5] = [
            ("timeout_ms", self.timeout_ms, 1, 60_000),
            ("move_timeout_ms", self.move_timeout_ms, 1, 600_000),
            ("retries", u64::from(self.retries), 0, 10),
            (
                "reconnect_attempts",
                u64::from(self.reconnect_attempts),
                0,
                100,
            ),
            ("reconnect_delay_ms", self.reconnect_delay_ms, 0, 60_000),
        ];
        for (field, v, lo, hi) in ints {
            if !(lo..=hi).contains(&v) {
                return bad(field.into(), format!("{v} is not in {lo}..={hi}"));
            }
        }
        Ok(())
    }

    /// The grating for `nm`: among those whose range holds it, the one with the
    /// shortest `min_nm` (so where two ranges overlap, the crossover is the upper end
    /// of the lower grating's range). Refuses a wavelength no range holds.
    pub fn grating_for(&self, nm: f64) -> Result<&GratingSpec, SelectError> {
        self.gratings
            .iter()
            .filter(|g| nm >= g.min_nm && nm <= g.max_nm)
            .min_by(|a, b| a.min_nm.total_cmp(&b.min_nm))
            .ok_or_else(|| SelectError::OutOfRange {
                nm,
                ranges: self
                    .gratings
                    .iter()
                    .map(|g| format!("{}: {}–{} nm", g.index, g.min_nm, g.max_nm))
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }

    /// The filter wheel position for `nm`: the grating passes λ in first order and
    /// λ/2 in second order at the same angle, and a long-pass filter with cut-on `c`
    /// passes what is longer than `c`. So:
    ///
    /// - when λ < 2 × `shortest_nm`, the beam holds no light at λ/2: the open
    ///   position (`open_filter`), which loses nothing;
    /// - otherwise the filter with the **highest** cut-on `c` such that
    ///   `c ≤ λ − margin` (λ passes, clear of the edge), provided that
    ///   `c ≥ λ/2 + margin` (λ/2 blocked, clear of the edge). The highest cut-on also
    ///   blocks the most stray light below λ; if it does not block λ/2, no lower one
    ///   does, and the wavelength is refused ([`SelectError::NoOrderFilter`]).
    ///
    /// With the defaults (shortest 250 nm, margin 10 nm, cut-ons 335, 590, 1000,
    /// 1500 nm) the crossovers are 500 nm (open → 335), 600 nm (→ 590), 1010 nm
    /// (→ 1000) and 1510 nm (→ 1500).
    pub fn order_filter_for(&self, nm: f64) -> Result<u8, SelectError> {
        if !nm.is_finite() || nm <= 0.0 {
            return Err(SelectError::OutOfRange {
                nm,
                ranges: "a positive wavelength".into(),
            });
        }
        if nm < 2.0 * self.shortest_nm {
            return Ok(self.open_filter);
        }
        let low = nm / 2.0 + self.filter_margin_nm;
        let high = nm - self.filter_margin_nm;
        self.filters
            .iter()
            .filter(|f| f.cut_on_nm <= high)
            .max_by(|a, b| a.cut_on_nm.total_cmp(&b.cut_on_nm))
            .filter(|f| f.cut_on_nm >= low)
            .map(|f| f.position)
            .ok_or(SelectError::NoOrderFilter { nm, low, high })
    }

    /// The cut-on of the filter at `position`; `None` for the open position or an
    /// unlisted one.
    pub fn cut_on_nm(&self, position: u8) -> Option<f64> {
        self.filters
            .iter()
            .find(|f| f.position == position)
            .map(|f| f.cut_on_nm)
    }

    /// `timeout_ms` as a duration.
    pub fn timeout(&self) -> Duration {
        Duration::from_millis(self.timeout_ms)
    }

    /// `move_timeout_ms` as a duration.
    pub fn move_timeout(&self) -> Duration {
        Duration::from_millis(self.move_timeout_ms)
    }

    /// `reconnect_delay_ms` as a duration.
    pub fn reconnect_delay(&self) -> Duration {
        Duration::from_millis(self.reconnect_delay_ms)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate_and_crossovers_fall_where_documented() {
        let c = Cs130Config::default();
        c.validate().unwrap();
        let f = |nm| c.order_filter_for(nm).unwrap();
        assert_eq!(f(250.0), 1);
        assert_eq!(f(499.9), 1);
        assert_eq!(f(500.0), 2);
        assert_eq!(f(599.9), 2);
        assert_eq!(f(600.0), 3);
        assert_eq!(f(1009.9), 3);
        assert_eq!(f(1010.0), 4);
        assert_eq!(f(1509.9), 4);
        assert_eq!(f(1510.0), 5);
        assert_eq!(f(2000.0), 5);
        assert_eq!(c.grating_for(900.0).unwrap().index, 1);
        assert_eq!(c.grating_for(900.1).unwrap().index, 2);
        assert!(matches!(
            c.grating_for(2000.5),
            Err(SelectError::OutOfRange { .. })
        ));
        assert!(matches!(
            c.grating_for(f64::NAN),
            Err(SelectError::OutOfRange { .. })
        ));
    }

    #[test]
    fn every_chosen_filter_blocks_half_lambda_and_passes_lambda() {
        let c = Cs130Config::default();
        let mut nm = 250.0;
        while nm <= 2000.0 {
            let p = c.order_filter_for(nm).unwrap();
            match c.cut_on_nm(p) {
                None => assert!(nm / 2.0 < c.shortest_nm, "{nm}"),
                Some(cut) => {
                    assert!(cut >= nm / 2.0 + c.filter_margin_nm, "{nm}: {cut}");
                    assert!(cut <= nm - c.filter_margin_nm, "{nm}: {cut}");
                }
            }
            nm += 0.5;
        }
    }

    #[test]
    fn a_gap_in_the_filters_is_refused() {
        let c = Cs130Config {
            filters: vec![OrderFilterSpec {
                position: 2,
                cut_on_nm: 335.0,
            }],
            ..Cs130Config::default()
        };
        // 335 blocks λ/2 only up to λ = 650.
        assert_eq!(c.order_filter_for(650.0), Ok(2));
        assert_eq!(
            c.order_filter_for(700.0),
            Err(SelectError::NoOrderFilter {
                nm: 700.0,
                low: 360.0,
                high: 690.0
            })
        );
    }

    #[test]
    fn the_documented_toml_parses_and_unknown_keys_are_refused() {
        let text = "auto_order_filter = false\nshortest_nm = 300.0\n\
                    [[gratings]]\nindex = 1\nlines_per_mm = 1200\nmin_nm = 250.0\nmax_nm = 900.0\n\
                    [[filters]]\nposition = 2\ncut_on_nm = 335.0\n";
        let c: Cs130Config = toml::from_str(text).unwrap();
        c.validate().unwrap();
        assert!(!c.auto_order_filter);
        assert_eq!(c.gratings.len(), 1);
        assert_eq!(c.cut_on_nm(2), Some(335.0));
        assert_eq!(c.timeout_ms, 1000);
        assert!(toml::from_str::<Cs130Config>("speed = 1").is_err());
        assert!(toml::from_str::<Cs130Config>("[[filters]]\nposition = 2\ncut_on = 3.0").is_err());
    }

    #[test]
    fn the_filter_wheel_defaults_to_present_and_without_it_needs_no_auto_filter() {
        // A config written before the field: a wheel, as before.
        let c: Cs130Config = toml::from_str("auto_order_filter = true").unwrap();
        assert!(c.filter_wheel);
        c.validate().unwrap();
        // No wheel: order sorting must be turned off in so many words.
        let c: Cs130Config = toml::from_str("filter_wheel = false").unwrap();
        let e = c.validate().unwrap_err();
        assert_eq!(e.field, "auto_order_filter");
        assert!(e.reason.contains("set auto_order_filter = false"), "{e}");
        let c: Cs130Config =
            toml::from_str("filter_wheel = false\nauto_order_filter = false").unwrap();
        c.validate().unwrap();
    }

    #[test]
    fn validation_names_the_field() {
        let mut c = Cs130Config::default();
        c.gratings[1].max_nm = 800.0;
        assert_eq!(c.validate().unwrap_err().field, "gratings[1].max_nm");
        let mut c = Cs130Config::default();
        c.filters[0].position = 1;
        assert_eq!(c.validate().unwrap_err().field, "filters[0].position");
        let c = Cs130Config {
            timeout_ms: 0,
            ..Cs130Config::default()
        };
        assert_eq!(c.validate().unwrap_err().field, "timeout_ms");
        let c = Cs130Config {
            shortest_nm: f64::NAN,
            ..Cs130Config::default()
        };
        assert_eq!(c.validate().unwrap_err().field, "shortest_nm");
    }
}
