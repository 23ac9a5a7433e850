//! The wheel as an instrument config file describes it: its size, speed, the filters
//! mounted, and the session's timing. The lookups that pick a filter for a band are
//! pure functions of it.

pub use crate::config::ConfigError;
use crate::config::Fields;

use super::{POSITION_COUNTS, Speed};

/// The default tolerance of [`Fw102cConfig::position_for_band`], nm: a band-pass
/// filter serves a channel whose wavelength is within this of its centre. 2 nm is the
/// centre-wavelength tolerance Thorlabs quotes for its 10 nm FWHM band-pass filters
/// (UNCONFIRMED: from the product pages, not a manual in the corpus).
pub const DEFAULT_BAND_TOLERANCE_NM: f64 = 2.0;

/// The standard uncertainty of a band-pass filter's centre wavelength that the
/// reduction assumes when the instrument config states none, nm: a ±2 nm centre
/// tolerance (a common catalogue figure, **UNCONFIRMED** for any one filter) as a
/// rectangular bound.
pub const CENTRE_UNCERTAINTY_NM: f64 = 1.2;

/// One filter mounted in the wheel: a `[[filters]]` entry, its `kind` one of
/// `"bandpass"`, `"longpass"`, `"open"`, `"dark"` (an opaque blank: the wheel as a
/// shutter), with the variant's fields (`position = 2`, `centre_nm = 550`, ...).
/// `peak_transmittance` (0, 1] is optional on band-pass and long-pass filters
/// (default 1); the simulated wheel scales its transmittance by it.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum Filter {
    /// A band-pass filter.
    Bandpass {
        /// Wheel position, 1-based.
        position: u8,
        /// Centre wavelength, nm.
        centre_nm: f64,
        /// Full width at half maximum, nm.
        fwhm_nm: f64,
        /// Transmittance at the centre.
        #[serde(default = "one")]
        peak_transmittance: f64,
    },
    /// A long-pass (order-sorting) filter: passes wavelengths above `cut_on_nm`.
    Longpass {
        /// Wheel position, 1-based.
        position: u8,
        /// The cut-on wavelength (half the pass-band transmittance), nm.
        cut_on_nm: f64,
        /// Transmittance well above the cut-on.
        #[serde(default = "one")]
        peak_transmittance: f64,
    },
    /// An empty aperture.
    Open {
        /// Wheel position, 1-based.
        position: u8,
    },
    /// An opaque blank.
    Dark {
        /// Wheel position, 1-based.
        position: u8,
    },
}

fn one() -> f64 {
    1.0
}

impl Filter {
    /// Its wheel position.
    pub fn position(&self) -> u8 {
        match self {
            Filter::Bandpass { position, .. }
            | Filter::Longpass { position, .. }
            | Filter::Open { position }
            | Filter::Dark { position } => *position,
        }
    }

    /// Its kind, as a config file names it.
    pub fn kind(&self) -> &'static str {
        match self {
            Filter::Bandpass { .. } => "bandpass",
            Filter::Longpass { .. } => "longpass",
            Filter::Open { .. } => "open",
            Filter::Dark { .. } => "dark",
        }
    }
}

/// How a [`Fw102cSession`](super::Fw102cSession) drives the wheel: a table of an
/// instrument config file (TOML), each field defaulted (see `Default`), unknown fields
/// refused; `speed` is `"high"` or `"low"`, `[[filters]]` as [`Filter`] shows.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Fw102cConfig {
    /// The mounted wheel's positions, 6 or 12; set-up refuses a wheel whose `pcount?`
    /// differs (the firmware's count is the operator's to set, with `pcount=`/`save`).
    pub positions: u8,
    /// Rotation speed set at set-up.
    pub speed: Speed,
    /// Set-up sends `sensors=0`, which switches the position sensors off while the
    /// wheel is idle: their light must not reach the detector (UNCONFIRMED that the
    /// sensors emit light; the command's description says "stray light").
    pub sensors_off_when_idle: bool,
    /// The filters mounted; a position not listed is treated as unknown (never
    /// picked by a lookup).
    pub filters: Vec<Filter>,
    /// [`position_for_band`](Self::position_for_band)'s tolerance, nm, in (0, 50].
    pub band_tolerance_nm: f64,
    /// How long to wait for each echo or value line, ms (1..=60000).
    pub timeout_ms: u64,
    /// How long a move may take from `pos=n` until `pos?` reads n, ms (100..=120000).
    /// A `pos?` sent while the wheel turns may be answered only when it stops, so each
    /// poll's reply may take until then.
    pub move_timeout_ms: u64,
    /// Pause between `pos?` polls during a move, ms (1..=10000).
    pub poll_interval_ms: u64,
    /// Re-sends of a command whose echo or value was lost or garbled (0..=10). Every
    /// command Gonio sends is safe to repeat (`pos=n` is absolute).
    pub retries: u32,
    /// Reconnection attempts after the port vanishes, per command (0..=100).
    pub reconnect_attempts: u32,
    /// Wait before each reconnection attempt, ms (0..=60000).
    pub reconnect_delay_ms: u64,
}

impl Default for Fw102cConfig {
    fn default() -> Self {
        Fw102cConfig {
            positions: 6,
            speed: Speed::High,
            sensors_off_when_idle: true,
            filters: Vec::new(),
            band_tolerance_nm: DEFAULT_BAND_TOLERANCE_NM,
            timeout_ms: 1000,
            move_timeout_ms: 15_000,
            poll_interval_ms: 100,
            retries: 2,
            reconnect_attempts: 3,
            reconnect_delay_ms: 1000,
        }
    }
}

crate::config::line_config!(
    Fw102cConfig,
    move_timeout: move_timeout_ms,
    poll_interval: poll_interval_ms
);

impl Fw102cConfig {
    /// Checks every field's range; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let f = Fields::new(Some("fw102c"));
        f.check(
            POSITION_COUNTS.contains(&self.positions),
            "positions",
            || format!("{} is not 6 or 12", self.positions),
        )?;
        f.positive("band_tolerance_nm", self.band_tolerance_nm, 50.0)?;
        let [timeout, retries, attempts, delay] = self.link_checks();
        f.ints([
            timeout,
            ("move_timeout_ms", self.move_timeout_ms, 100..=120_000),
            ("poll_interval_ms", self.poll_interval_ms, 1..=10_000),
            delay,
            retries,
            attempts,
        ])?;
        for (i, filter) in self.filters.iter().enumerate() {
            let at = f.entry("filters", i);
            let p = filter.position();
            at.int("position", p, 1..=self.positions)?;
            let earlier = self.filters[..i].iter().map(Filter::position);
            at.unique("position", "position", p, earlier)?;
            match filter {
                Filter::Bandpass {
                    centre_nm,
                    fwhm_nm,
                    peak_transmittance,
                    ..
                } => {
                    at.positive("centre_nm", *centre_nm, 20_000.0)?;
                    at.positive("fwhm_nm", *fwhm_nm, 1000.0)?;
                    at.positive("peak_transmittance", *peak_transmittance, 1.0)?;
                }
                Filter::Longpass {
                    cut_on_nm,
                    peak_transmittance,
                    ..
                } => {
                    at.positive("cut_on_nm", *cut_on_nm, 20_000.0)?;
                    at.positive("peak_transmittance", *peak_transmittance, 1.0)?;
                }
                Filter::Open { .. } | Filter::Dark { .. } => {}
            }
        }
        Ok(())
    }

    /// The filter at `position`, if one is listed.
    pub fn filter_at(&self, position: u8) -> Option<&Filter> {
        self.filters.iter().find(|f| f.position() == position)
    }

    /// The band-pass filter for a channel at `nm`: the one whose centre is nearest
    /// `nm`, if within [`band_tolerance_nm`](Self::band_tolerance_nm) (a tie goes to the
    /// lower position).
    pub fn position_for_band(&self, nm: f64) -> Option<u8> {
        self.filters
            .iter()
            .filter_map(|f| match f {
                Filter::Bandpass {
                    position,
                    centre_nm,
                    ..
                } => Some((*position, (centre_nm - nm).abs())),
                _ => None,
            })
            .filter(|(_, d)| *d <= self.band_tolerance_nm)
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
            .map(|(p, _)| p)
    }

    /// The long-pass filter that sorts orders for a channel at `nm`: its cut-on lies
    /// strictly between `nm`/2 (a grating's second order of `nm`/2 lands on `nm`) and
    /// `nm`. Of several, the one whose cut-on is farthest from both ends (largest
    /// min(`nm` − cut-on, cut-on − `nm`/2)) blocks the second order and passes the first
    /// best; a tie goes to the lower position.
    pub fn position_for_order_sorting(&self, nm: f64) -> Option<u8> {
        self.filters
            .iter()
            .filter_map(|f| match f {
                Filter::Longpass {
                    position,
                    cut_on_nm,
                    ..
                } if *cut_on_nm > nm / 2.0 && *cut_on_nm < nm => {
                    Some((*position, (nm - cut_on_nm).min(cut_on_nm - nm / 2.0)))
                }
                _ => None,
            })
            .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
            .map(|(p, _)| p)
    }

    /// The first (lowest) position holding an opaque blank.
    pub fn dark_position(&self) -> Option<u8> {
        self.lowest("dark")
    }

    /// The first (lowest) position holding an empty aperture.
    pub fn open_position(&self) -> Option<u8> {
        self.lowest("open")
    }

    /// The lowest position of the filters of `kind`.
    fn lowest(&self, kind: &str) -> Option<u8> {
        let of_kind = self.filters.iter().filter(|f| f.kind() == kind);
        of_kind.map(Filter::position).min()
    }
}
