//! Wavelength selection: the device that decides which band of light reaches the
//! sample. A monochromator ([`crate::cs130::Cs130`]) or a wheel of band-pass filters
//! ([`crate::fw102c::Fw102c`]) plugs in by implementing [`BandSelector`]; the run
//! engine calls it when a step's channel (a wavelength such as `550nm`) differs from
//! the last, and closes its shutter for dark readings when it has one.

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
