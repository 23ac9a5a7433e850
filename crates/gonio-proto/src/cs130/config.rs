//! The CS130's config and the two choices it makes for a wavelength: the grating and
//! the order-sorting filter.

pub use crate::config::ConfigError;
use crate::config::Fields;

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

/// One grating on the turret.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GratingSpec {
    /// Its number on the turret (`GRAT n`), 1..=[`MAX_GRATINGS`].
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

/// How a [`Cs130Session`](super::Cs130Session) drives the monochromator: a TOML table,
/// each field defaulted (see `Default`), unknown fields refused; `[[gratings]]` and
/// `[[filters]]` are arrays of [`GratingSpec`] and [`OrderFilterSpec`].
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
    /// The unit has a filter wheel (default true, so older configs keep their
    /// meaning). With `false` the session never sends `FILTER?` or `FILTER n` (a unit
    /// without a wheel answers `0` and flags an error) and reports
    /// [`NO_FILTER_WHEEL`]; `filters` and `open_filter` are unused, and
    /// `auto_order_filter` must be false: above 2 × `shortest_nm` the second order
    /// must then be blocked some other way. With `true`, `FILTER?` answering `0` is
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

crate::config::line_config!(Cs130Config, move_timeout: move_timeout_ms);

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
    /// Checks every field's range; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let f = Fields::new(Some("cs130"));
        if self.gratings.is_empty() {
            return f.bad("gratings", "at least one grating is needed");
        }
        for (i, g) in self.gratings.iter().enumerate() {
            let at = f.entry("gratings", i);
            let earlier = self.gratings[..i].iter().map(|o| o.index);
            at.int("index", g.index, 1..=MAX_GRATINGS)?;
            at.unique("index", "grating", g.index, earlier)?;
            at.int("lines_per_mm", g.lines_per_mm, 1..=10_000)?;
            let ok = g.min_nm > 0.0 && g.min_nm < g.max_nm && g.max_nm <= 100_000.0;
            at.check(ok, "max_nm", || {
                let (lo, hi) = (g.min_nm, g.max_nm);
                format!("range {lo}..={hi} nm is not 0 < min < max <= 100000")
            })?;
        }
        if !self.filter_wheel && self.auto_order_filter {
            return f.bad(
                "auto_order_filter",
                "filter_wheel = false: there is no wheel to set order-sorting filters \
                 with; set auto_order_filter = false (and block the second order above \
                 2 × shortest_nm some other way)",
            );
        }
        f.int("open_filter", self.open_filter, 1..=MAX_FILTER_POSITION)?;
        for (i, o) in self.filters.iter().enumerate() {
            let at = f.entry("filters", i);
            let earlier = self.filters[..i].iter().map(|o| o.position);
            at.int("position", o.position, 1..=MAX_FILTER_POSITION)?;
            at.check(o.position != self.open_filter, "position", || {
                format!("{} is the open position", o.position)
            })?;
            at.unique("position", "position", o.position, earlier)?;
            at.positive("cut_on_nm", o.cut_on_nm, 100_000.0)?;
        }
        let least = f64::MIN_POSITIVE;
        f.real("shortest_nm", self.shortest_nm, least, 10_000.0)?;
        f.real("filter_margin_nm", self.filter_margin_nm, 0.0, 500.0)?;
        f.real("approach_nm", self.approach_nm, 0.0, 100.0)?;
        f.real(
            "position_tolerance_nm",
            self.position_tolerance_nm,
            least,
            100.0,
        )?;
        let [timeout, retries, attempts, delay] = self.link_checks();
        let move_timeout = ("move_timeout_ms", self.move_timeout_ms, 1..=600_000);
        f.ints([timeout, move_timeout, retries, attempts, delay])
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
}
