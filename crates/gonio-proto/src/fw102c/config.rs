//! The wheel as an instrument config file describes it: its size, speed, the filters
//! mounted, and the session's timing. The lookups that pick a filter for a band are
//! pure functions of it.

use std::time::Duration;

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

/// One filter mounted in the wheel, as a config file writes it (`[[filters]]`):
///
/// ```toml
/// [[filters]]
/// position = 2
/// kind = "bandpass"
/// centre_nm = 550
/// fwhm_nm = 10
///
/// [[filters]]
/// position = 3
/// kind = "longpass"
/// cut_on_nm = 495
///
/// [[filters]]
/// position = 6
/// kind = "dark"     # an opaque blank: the wheel as a shutter
/// ```
///
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

/// How a [`Fw102cSession`](super::Fw102cSession) drives the wheel. Embeddable in an
/// instrument config file (TOML); every field has a default, unknown fields are
/// refused:
///
/// ```toml
/// positions = 6             # 6 (FW102C) or 12 (FW212C): what pcount? must answer
/// speed = "high"            # or "low"
/// sensors_off_when_idle = true
/// band_tolerance_nm = 2.0
/// timeout_ms = 1000
/// move_timeout_ms = 15000
/// poll_interval_ms = 100
/// retries = 2
/// reconnect_attempts = 3
/// reconnect_delay_ms = 1000
/// # [[filters]] ... (see Filter)
/// ```
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

/// A config value out of its range, naming the field as a config file writes it.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("fw102c config {field}: {reason}")]
pub struct ConfigError {
    /// The field (`filters[2].fwhm_nm` for a filter's).
    pub field: String,
    /// What is wrong with it.
    pub reason: String,
}

fn positive(v: f64) -> bool {
    v.is_finite() && v > 0.0
}

impl Fw102cConfig {
    /// Checks every field's range; the first bad field is named in the error.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |field: String, reason: String| Err(ConfigError { field, reason });
        if !POSITION_COUNTS.contains(&self.positions) {
            return bad(
                "positions".into(),
                format!("{} is not 6 or 12", self.positions),
            );
        }
        if !(positive(self.band_tolerance_nm) && self.band_tolerance_nm <= 50.0) {
            return bad(
                "band_tolerance_nm".into(),
                format!("{} is not in (0, 50]", self.band_tolerance_nm),
            );
        }
        for (field, v, lo, hi) in [
            ("timeout_ms", self.timeout_ms, 1, 60_000),
            ("move_timeout_ms", self.move_timeout_ms, 100, 120_000),
            ("poll_interval_ms", self.poll_interval_ms, 1, 10_000),
            ("reconnect_delay_ms", self.reconnect_delay_ms, 0, 60_000),
            ("retries", u64::from(self.retries), 0, 10),
            (
                "reconnect_attempts",
                u64::from(self.reconnect_attempts),
                0,
                100,
            ),
        ] {
            if !(lo..=hi).contains(&v) {
                return bad(field.into(), format!("{v} is not in {lo}..={hi}"));
            }
        }
        let mut seen = Vec::new();
        for (i, f) in self.filters.iter().enumerate() {
            let name = |k: &str| format!("filters[{i}].{k}");
            let p = f.position();
            if !(1..=self.positions).contains(&p) {
                return bad(
                    name("position"),
                    format!("{p} is not in 1..={}", self.positions),
                );
            }
            if seen.contains(&p) {
                return bad(name("position"), format!("position {p} is listed twice"));
            }
            seen.push(p);
            match f {
                Filter::Bandpass {
                    centre_nm,
                    fwhm_nm,
                    peak_transmittance,
                    ..
                } => {
                    if !(positive(*centre_nm) && *centre_nm <= 20_000.0) {
                        return bad(
                            name("centre_nm"),
                            format!("{centre_nm} is not in (0, 20000]"),
                        );
                    }
                    if !(positive(*fwhm_nm) && *fwhm_nm <= 1000.0) {
                        return bad(name("fwhm_nm"), format!("{fwhm_nm} is not in (0, 1000]"));
                    }
                    if !(positive(*peak_transmittance) && *peak_transmittance <= 1.0) {
                        return bad(
                            name("peak_transmittance"),
                            format!("{peak_transmittance} is not in (0, 1]"),
                        );
                    }
                }
                Filter::Longpass {
                    cut_on_nm,
                    peak_transmittance,
                    ..
                } => {
                    if !(positive(*cut_on_nm) && *cut_on_nm <= 20_000.0) {
                        return bad(
                            name("cut_on_nm"),
                            format!("{cut_on_nm} is not in (0, 20000]"),
                        );
                    }
                    if !(positive(*peak_transmittance) && *peak_transmittance <= 1.0) {
                        return bad(
                            name("peak_transmittance"),
                            format!("{peak_transmittance} is not in (0, 1]"),
                        );
                    }
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
        self.filters
            .iter()
            .filter(|f| matches!(f, Filter::Dark { .. }))
            .map(Filter::position)
            .min()
    }

    /// The first (lowest) position holding an empty aperture.
    pub fn open_position(&self) -> Option<u8> {
        self.filters
            .iter()
            .filter(|f| matches!(f, Filter::Open { .. }))
            .map(Filter::position)
            .min()
    }

    pub(crate) fn timeout(&self) -> Duration {
        Duration::from_millis(self.timeout_ms)
    }
    pub(crate) fn move_timeout(&self) -> Duration {
        Duration::from_millis(self.move_timeout_ms)
    }
    pub(crate) fn poll_interval(&self) -> Duration {
        Duration::from_millis(self.poll_interval_ms)
    }
    pub(crate) fn reconnect_delay(&self) -> Duration {
        Duration::from_millis(self.reconnect_delay_ms)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Fw102cConfig, String> {
        toml::from_str::<Fw102cConfig>(text).map_err(|e| e.to_string())
    }

    const WHEEL: &str = r#"
        positions = 6
        [[filters]]
        position = 1
        kind = "open"
        [[filters]]
        position = 2
        kind = "bandpass"
        centre_nm = 550
        fwhm_nm = 10
        [[filters]]
        position = 3
        kind = "bandpass"
        centre_nm = 553.5
        fwhm_nm = 10
        peak_transmittance = 0.5
        [[filters]]
        position = 4
        kind = "longpass"
        cut_on_nm = 495
        [[filters]]
        position = 5
        kind = "longpass"
        cut_on_nm = 695
        [[filters]]
        position = 6
        kind = "dark"
    "#;

    #[test]
    fn a_wheel_parses_with_defaults_and_validates() {
        let c = parse(WHEEL).unwrap();
        c.validate().unwrap();
        assert_eq!(c.speed, Speed::High);
        assert_eq!(c.filters.len(), 6);
        assert_eq!(
            c.filter_at(3),
            Some(&Filter::Bandpass {
                position: 3,
                centre_nm: 553.5,
                fwhm_nm: 10.0,
                peak_transmittance: 0.5
            })
        );
        assert_eq!(
            c.filter_at(4),
            Some(&Filter::Longpass {
                position: 4,
                cut_on_nm: 495.0,
                peak_transmittance: 1.0
            })
        );
    }

    #[test]
    fn lookups_pick_by_the_documented_rules() {
        let c = parse(WHEEL).unwrap();
        assert_eq!(c.position_for_band(550.0), Some(2));
        assert_eq!(c.position_for_band(551.0), Some(2));
        // 552.0 is 2.0 from 550 and 1.5 from 553.5: the nearer wins.
        assert_eq!(c.position_for_band(552.0), Some(3));
        assert_eq!(c.position_for_band(555.5), Some(3));
        assert_eq!(c.position_for_band(555.6), None);
        assert_eq!(c.position_for_band(600.0), None);
        // 495 lies in (λ/2, λ) for λ in (495, 990); 695 for λ in (695, 1390).
        assert_eq!(c.position_for_order_sorting(600.0), Some(4));
        assert_eq!(c.position_for_order_sorting(495.0), None);
        assert_eq!(c.position_for_order_sorting(989.0), Some(5));
        // At 800: 495 has margin min(305, 95) = 95, 695 has min(105, 295) = 105.
        assert_eq!(c.position_for_order_sorting(800.0), Some(5));
        assert_eq!(c.position_for_order_sorting(700.0), Some(4));
        assert_eq!(c.position_for_order_sorting(400.0), None);
        assert_eq!(c.dark_position(), Some(6));
        assert_eq!(c.open_position(), Some(1));
        assert_eq!(Fw102cConfig::default().dark_position(), None);
    }

    #[test]
    fn bad_values_name_their_field() {
        let field = |text: &str| match parse(text) {
            Ok(c) => c.validate().unwrap_err().field,
            Err(e) => format!("parse: {e}"),
        };
        assert_eq!(field("positions = 8"), "positions");
        assert_eq!(field("band_tolerance_nm = 0"), "band_tolerance_nm");
        assert_eq!(field("move_timeout_ms = 50"), "move_timeout_ms");
        assert_eq!(field("retries = 11"), "retries");
        assert_eq!(
            field("[[filters]]\nposition = 7\nkind = \"open\""),
            "filters[0].position"
        );
        assert_eq!(
            field(
                "[[filters]]\nposition = 1\nkind = \"open\"\n[[filters]]\nposition = 1\nkind = \"dark\""
            ),
            "filters[1].position"
        );
        assert_eq!(
            field("[[filters]]\nposition = 1\nkind = \"bandpass\"\ncentre_nm = 550\nfwhm_nm = -1"),
            "filters[0].fwhm_nm"
        );
        assert_eq!(
            field(
                "[[filters]]\nposition = 1\nkind = \"longpass\"\ncut_on_nm = 495\npeak_transmittance = 1.5"
            ),
            "filters[0].peak_transmittance"
        );
    }

    #[test]
    fn unknown_keys_and_kinds_are_refused() {
        assert!(parse("position = 6").is_err());
        assert!(parse("[[filters]]\nposition = 1\nkind = \"open\"\ncentre_nm = 3").is_err());
        assert!(parse("[[filters]]\nposition = 1\nkind = \"notch\"").is_err());
        assert!(parse("[[filters]]\nposition = 1\nkind = \"bandpass\"\ncentre_nm = 550").is_err());
    }
}
