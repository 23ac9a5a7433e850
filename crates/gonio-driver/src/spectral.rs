//! Wavelength selection: the device that decides which band of light reaches the
//! sample. A monochromator ([`crate::cs130::Cs130`]) or a wheel of band-pass filters
//! ([`crate::fw102c::Fw102c`]) plugs in by implementing [`BandSelector`]; the run
//! engine calls it when a step's channel (a wavelength such as `550nm`) differs from
//! the last, and closes its shutter for dark readings when it has one.

use gonio_core::limits::Range;
use serde::Deserialize;

use crate::clock::Clock;
use crate::cs130::{Cs130, Cs130Error};
use crate::fw102c::{Filter, Fw102c};
use crate::heartbeat::Heartbeat;
use crate::transport::{FlowControl, Framing, SerialSettings, Transport};
use gonio_proto::cs130::Cs130Config;
use gonio_proto::fw102c::Fw102cConfig;

/// Why a band selector failed.
#[derive(Debug, thiserror::Error)]
pub enum SpectralError {
    /// A channel that is not a wavelength (`R`, `value`): a band selector selects
    /// wavelengths only.
    #[error("channel {0:?} is not a wavelength (such as \"550nm\")")]
    NotAWavelength(String),
    /// The device has no band for this wavelength (out of its range, or no filter).
    #[error("{device}: no band at {nm} nm: {reason}")]
    NoBand {
        /// The device family.
        device: &'static str,
        /// The wavelength asked for.
        nm: f64,
        /// Why.
        reason: String,
    },
    /// The device has no shutter.
    #[error("{0}: no shutter")]
    NoShutter(&'static str),
    /// The device failed (its own error, as text).
    #[error("{device}: {message}")]
    Device {
        /// The device family.
        device: &'static str,
        /// Its error.
        message: String,
    },
}

/// What a band selector reports after a selection, for the run log.
#[derive(Clone, Debug, PartialEq)]
pub struct Band {
    /// The wavelength asked for, nm.
    pub nm: f64,
    /// The wavelength the device reports it is at, nm (a monochromator's `WAVE?`; a
    /// filter's centre).
    pub reported_nm: f64,
    /// The rest of its state, in words (`grating 1, order filter 2`).
    pub detail: String,
}

impl std::fmt::Display for Band {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} nm ({})", self.reported_nm, self.detail)
    }
}

/// A device that selects the band of light reaching the sample.
pub trait BandSelector: Send {
    /// The family's name (`cs130`, `fw102c`).
    fn family(&self) -> &'static str;
    /// Sets the device up; returns its identity, for the run log.
    fn setup(&mut self) -> Result<String, SpectralError>;
    /// Selects the band centred on `nm`.
    fn select(&mut self, nm: f64) -> Result<Band, SpectralError>;
    /// True when the device can block the beam (a shutter, an opaque position).
    fn has_shutter(&self) -> bool;
    /// Opens (true) or closes the shutter.
    fn set_shutter(&mut self, open: bool) -> Result<(), SpectralError>;
    /// Exchanges re-sent after a lost, late or garbled reply.
    fn retried(&self) -> u64;
    /// Joins the instrument's heartbeat, which its waits keep going.
    fn set_heartbeat(&mut self, beats: Heartbeat);
}

impl std::fmt::Debug for dyn BandSelector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "BandSelector({})", self.family())
    }
}

/// The wavelength of a channel named like `550nm` (`gonio_core::Channels`' names).
pub fn channel_nm(channel: &str) -> Result<f64, SpectralError> {
    match gonio_core::Channels::from_names(&[channel.to_string()]) {
        Ok(gonio_core::Channels::Wavelengths(w)) if w.len() == 1 => Ok(w[0]),
        _ => Err(SpectralError::NotAWavelength(channel.to_string())),
    }
}

/// The monochromator family.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MonochromatorKind {
    /// A Newport Cornerstone 130 (`[monochromator.cs130]`).
    #[default]
    Cs130,
}

/// The monochromator's serial line and settings (`[monochromator]`): the device that
/// selects each wavelength channel, sets its order-sorting filter, and closes its
/// shutter for dark readings.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MonochromatorConfig {
    /// The family (default `cs130`).
    #[serde(default)]
    pub kind: MonochromatorKind,
    /// Port path, or `usb:SERIAL`.
    pub port: String,
    /// Baud rate (default 9600: the Cornerstone 130's fixed RS-232 rate, see
    /// `docs/instruments/cs130.md`).
    #[serde(default = "default_mono_baud")]
    pub baud: u32,
    /// Flow control (none on the Cornerstone 130's three-wire RS-232).
    #[serde(default = "default_flow")]
    pub flow: FlowControl,
    /// The gratings, order-sorting filters and link policy (`[monochromator.cs130]`).
    #[serde(default)]
    pub cs130: Cs130Config,
    /// How long its moves take, for planning (`[monochromator.timing]`).
    #[serde(default)]
    pub timing: MonochromatorTimingConfig,
    /// The standard uncertainty of its wavelength scale, nm, for the reduction's
    /// wavelength term (default [`gonio_proto::cs130::WAVELENGTH_UNCERTAINTY_NM`]).
    #[serde(default)]
    pub wavelength_uncertainty_nm: Option<f64>,
    /// Its bandpass (the FWHM of the slit function with the slits installed), nm
    /// (default [`gonio_proto::cs130::BANDWIDTH_NM`]).
    #[serde(default)]
    pub bandwidth_nm: Option<f64>,
}

/// A monochromator's move times, as the planner estimates them. The defaults are the
/// simulated Cornerstone 130's (`simulator/src/monochromator.rs`); measure yours with
/// `gonio instrument check --connect` and a stopwatch, or from the run log's times.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MonochromatorTimingConfig {
    /// Grating slew rate, nm/s.
    pub slew_nm_per_s: f64,
    /// Settling after every move, s.
    pub settle_s: f64,
    /// An order-sorting filter change, s.
    pub filter_change_s: f64,
    /// A grating change, s.
    pub grating_change_s: f64,
}

impl Default for MonochromatorTimingConfig {
    fn default() -> Self {
        MonochromatorTimingConfig {
            slew_nm_per_s: 100.0,
            settle_s: 0.1,
            filter_change_s: 1.5,
            grating_change_s: 4.0,
        }
    }
}

/// The filter wheel family.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FilterWheelKind {
    /// A Thorlabs FW102C (`[filter_wheel.fw102c]`).
    #[default]
    Fw102c,
}

/// A wheel of band-pass filters that selects each wavelength channel
/// (`[filter_wheel]`); an opaque position, when it has one, is its shutter.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FilterWheelConfig {
    /// The family (default `fw102c`).
    #[serde(default)]
    pub kind: FilterWheelKind,
    /// Port path, or `usb:SERIAL`.
    pub port: String,
    /// Baud rate: the FW102C's is 115200 (`gonio_proto::fw102c::BAUD`).
    #[serde(default = "default_wheel_baud")]
    pub baud: u32,
    /// Flow control (none).
    #[serde(default = "default_flow")]
    pub flow: FlowControl,
    /// The filters mounted and the link policy (`[filter_wheel.fw102c]`).
    #[serde(default)]
    pub fw102c: Fw102cConfig,
    /// One change of position, s, for planning (the wheel's longest move).
    #[serde(default = "default_wheel_change_s")]
    pub change_s: f64,
    /// The standard uncertainty of the filters' centre wavelengths, nm, for the
    /// reduction's wavelength term (default
    /// [`gonio_proto::fw102c::CENTRE_UNCERTAINTY_NM`]).
    #[serde(default)]
    pub wavelength_uncertainty_nm: Option<f64>,
}

impl MonochromatorConfig {
    /// The serial settings of its line: CR LF lines, framed on LF.
    pub fn serial(&self) -> SerialSettings {
        SerialSettings {
            path: self.port.clone(),
            baud: self.baud,
            flow: self.flow,
            framing: Framing::Lines {
                terminator: gonio_proto::cs130::REPLY_TERMINATOR,
                max_line: gonio_proto::cs130::MAX_LINE,
            },
        }
    }
}

impl FilterWheelConfig {
    /// The serial settings of its line: CR-terminated lines (the prompt that ends
    /// each answer arrives at the start of the next line, where the session strips
    /// it).
    pub fn serial(&self) -> SerialSettings {
        SerialSettings {
            path: self.port.clone(),
            baud: self.baud,
            flow: self.flow,
            framing: Framing::Lines {
                terminator: gonio_proto::fw102c::TERMINATOR,
                max_line: gonio_proto::fw102c::MAX_LINE,
            },
        }
    }
}

/// A wavelength uncertainty or bandpass, nm.
pub const BANDWIDTH: Range = Range::closed(0.0, 1000.0, "nm");

/// A slew rate, nm/s.
pub const SLEW: Range = Range::positive(1e6, "nm/s");
/// A settling, filter or grating change time, s.
pub const CHANGE_TIME: Range = Range::closed(0.0, 3600.0, "s");

impl MonochromatorTimingConfig {
    /// Checks each time against its range; `prefix` names the section.
    pub fn validate(&self, prefix: &str) -> Result<(), (String, String)> {
        let at = |f: &str, r: Range, v: f64| {
            r.check(v)
                .map(|_| ())
                .map_err(|m| (format!("{prefix}.{f}"), m))
        };
        at("slew_nm_per_s", SLEW, self.slew_nm_per_s)?;
        at("settle_s", CHANGE_TIME, self.settle_s)?;
        at("filter_change_s", CHANGE_TIME, self.filter_change_s)?;
        at("grating_change_s", CHANGE_TIME, self.grating_change_s)
    }
}

fn default_mono_baud() -> u32 {
    9_600
}
fn default_wheel_baud() -> u32 {
    gonio_proto::fw102c::BAUD
}
fn default_flow() -> FlowControl {
    FlowControl::None
}
fn default_wheel_change_s() -> f64 {
    2.0
}

fn device(device: &'static str) -> impl Fn(&dyn std::fmt::Display) -> SpectralError {
    move |e| SpectralError::Device {
        device,
        message: e.to_string(),
    }
}

impl<T: Transport, C: Clock> BandSelector for Cs130<T, C> {
    fn set_heartbeat(&mut self, beats: Heartbeat) {
        Cs130::set_heartbeat(self, beats);
    }
    fn family(&self) -> &'static str {
        "cs130"
    }

    fn setup(&mut self) -> Result<String, SpectralError> {
        let st = self.init().map_err(|e| device("cs130")(&e))?;
        Ok(format!(
            "{} (at {} nm, grating {}, filter {}, shutter {})",
            self.info().unwrap_or("Cornerstone 130"),
            st.wavelength_nm,
            st.grating,
            st.filter,
            if st.shutter_open { "open" } else { "closed" }
        ))
    }

    fn select(&mut self, nm: f64) -> Result<Band, SpectralError> {
        let st = self.go_to(nm).map_err(|e| match &e {
            Cs130Error::Select(reason) => SpectralError::NoBand {
                device: "cs130",
                nm,
                reason: reason.to_string(),
            },
            _ => device("cs130")(&e),
        })?;
        Ok(Band {
            nm,
            reported_nm: st.wavelength_nm,
            detail: if st.filter == gonio_proto::cs130::NO_FILTER_WHEEL {
                format!("grating {}, no order filter wheel", st.grating)
            } else {
                format!("grating {}, order filter {}", st.grating, st.filter)
            },
        })
    }

    fn has_shutter(&self) -> bool {
        true
    }

    fn set_shutter(&mut self, open: bool) -> Result<(), SpectralError> {
        self.shutter(open)
            .map(|_| ())
            .map_err(|e| device("cs130")(&e))
    }

    fn retried(&self) -> u64 {
        Cs130::retried(self)
    }
}

/// A filter wheel as a band selector: the band-pass filter of each channel, and its
/// opaque position as the shutter. Band and shutter share the one wheel, so while
/// the shutter is closed a new band is only remembered (the wheel stays opaque: a
/// dark reading at the next wavelength is still dark), and opening the shutter turns
/// the wheel to the band.
#[derive(Debug)]
pub struct WheelBands<T: Transport, C: Clock> {
    wheel: Fw102c<T, C>,
    band: Option<f64>,
    closed: bool,
}

impl<T: Transport, C: Clock> WheelBands<T, C> {
    /// The wheel, no band selected yet.
    pub fn new(wheel: Fw102c<T, C>) -> Self {
        WheelBands {
            wheel,
            band: None,
            closed: false,
        }
    }

    /// The wheel.
    pub fn wheel(&mut self) -> &mut Fw102c<T, C> {
        &mut self.wheel
    }
}

impl<T: Transport, C: Clock> BandSelector for WheelBands<T, C> {
    fn set_heartbeat(&mut self, beats: Heartbeat) {
        self.wheel.set_heartbeat(beats);
    }
    fn family(&self) -> &'static str {
        "fw102c"
    }

    fn setup(&mut self) -> Result<String, SpectralError> {
        let id = self.wheel.init().map_err(|e| device("fw102c")(&e))?;
        Ok(id)
    }

    fn select(&mut self, nm: f64) -> Result<Band, SpectralError> {
        if self.wheel.config().position_for_band(nm).is_none() {
            return Err(SpectralError::NoBand {
                device: "fw102c",
                nm,
                reason: "no band-pass filter on the wheel is centred there".into(),
            });
        }
        self.band = Some(nm);
        if self.closed {
            let position = self.wheel.config().position_for_band(nm).unwrap_or(0);
            return Ok(Band {
                nm,
                reported_nm: nm,
                detail: format!("position {position} once the shutter opens"),
            });
        }
        let position = self
            .wheel
            .select_band(nm)
            .map_err(|e| device("fw102c")(&e))?;
        let (centre, detail) = match self.wheel.config().filter_at(position) {
            Some(Filter::Bandpass {
                centre_nm, fwhm_nm, ..
            }) => (
                *centre_nm,
                format!("position {position}, FWHM {fwhm_nm} nm"),
            ),
            _ => (nm, format!("position {position}")),
        };
        Ok(Band {
            nm,
            reported_nm: centre,
            detail,
        })
    }

    fn has_shutter(&self) -> bool {
        self.wheel.config().dark_position().is_some()
    }

    fn set_shutter(&mut self, open: bool) -> Result<(), SpectralError> {
        self.closed = !open;
        if open {
            match self.band {
                Some(nm) => self.select(nm).map(|_| ()),
                None => match self.wheel.config().open_position() {
                    Some(p) => self.wheel.select(p).map_err(|e| device("fw102c")(&e)),
                    None => Ok(()),
                },
            }
        } else {
            match self.wheel.select_dark() {
                Ok(_) => Ok(()),
                Err(e) => Err(device("fw102c")(&e)),
            }
        }
    }

    fn retried(&self) -> u64 {
        self.wheel.retried()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn channel_names_give_their_wavelengths() {
        assert_eq!(channel_nm("550nm").unwrap(), 550.0);
        assert_eq!(channel_nm("632.8nm").unwrap(), 632.8);
        assert!(matches!(
            channel_nm("R"),
            Err(SpectralError::NotAWavelength(c)) if c == "R"
        ));
        assert!(channel_nm("value").is_err());
    }
}
