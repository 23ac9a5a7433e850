use std::fmt;
use std::sync::Arc;

/// Why a list of channel names or values was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ChannelError {
    /// No channel names at all.
    #[error("no channels given")]
    Empty,
    /// A name that is neither `value`, `R`/`G`/`B` nor a wavelength like `550nm`.
    #[error(
        "unknown channel name {0:?} (expected \"value\", \"R\",\"G\",\"B\" or wavelengths like \"550nm\")"
    )]
    UnknownName(String),
    /// Names of different kinds mixed, or R/G/B incomplete or out of order.
    #[error(
        "channels must be [\"value\"], [\"R\",\"G\",\"B\"] in that order, or wavelengths; got {0:?}"
    )]
    BadSet(Vec<String>),
    /// Wavelengths must be positive, finite and strictly increasing.
    #[error("wavelengths must be positive and strictly increasing; got {0:?}")]
    BadWavelengths(Vec<f64>),
    /// A list of values whose length is not the number of channels.
    #[error("expected {expected} values (one per channel), got {got}")]
    Length {
        /// Number of channels.
        expected: usize,
        /// Number of values given.
        got: usize,
    },
}

/// The spectral channels of a BRDF: one band, R/G/B, or wavelengths in nm.
///
/// Every BRDF value in Gonio carries one number per channel, and every file and
/// result names its channels (`docs/CONVENTIONS.md`). Cloning is cheap.
#[derive(Clone, Debug, PartialEq)]
pub enum Channels {
    /// One band, named `value`.
    Single,
    /// Red, green, blue, named `R`, `G`, `B`.
    Rgb,
    /// Wavelengths in nm, strictly increasing, named like `550nm`.
    Wavelengths(Arc<[f64]>),
}

impl Channels {
    /// Wavelength channels; `wavelengths_nm` must be positive and strictly increasing.
    pub fn wavelengths(wavelengths_nm: &[f64]) -> Result<Channels, ChannelError> {
        let ok = !wavelengths_nm.is_empty()
            && wavelengths_nm.iter().all(|w| w.is_finite() && *w > 0.0)
            && wavelengths_nm.windows(2).all(|p| p[0] < p[1]);
        if ok {
            Ok(Channels::Wavelengths(wavelengths_nm.into()))
        } else {
            Err(ChannelError::BadWavelengths(wavelengths_nm.to_vec()))
        }
    }

    /// Number of channels.
    pub fn len(&self) -> usize {
        match self {
            Channels::Single => 1,
            Channels::Rgb => 3,
            Channels::Wavelengths(w) => w.len(),
        }
    }

    /// Always false: a channel set has at least one channel.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The name of channel `i` as files and commands write it.
    ///
    /// # Panics
    /// If `i >= self.len()`.
    pub fn name(&self, i: usize) -> String {
        match self {
            Channels::Single => {
                assert!(i == 0, "channel {i} of a single-band set");
                "value".to_string()
            }
            Channels::Rgb => ["R", "G", "B"][i].to_string(),
            Channels::Wavelengths(w) => format!("{}nm", w[i]),
        }
    }

    /// All channel names, in order.
    pub fn names(&self) -> Vec<String> {
        (0..self.len()).map(|i| self.name(i)).collect()
    }

    /// The index of the channel named `name`.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        (0..self.len()).find(|&i| self.name(i) == name)
    }

    /// The channel set that these names describe.
    pub fn from_names<S: AsRef<str>>(names: &[S]) -> Result<Channels, ChannelError> {
        let names: Vec<&str> = names.iter().map(|s| s.as_ref().trim()).collect();
        let owned = || names.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        match names.as_slice() {
            [] => Err(ChannelError::Empty),
            ["value"] => Ok(Channels::Single),
            ["R", "G", "B"] => Ok(Channels::Rgb),
            _ => {
                let mut wl = Vec::with_capacity(names.len());
                for n in &names {
                    match parse_wavelength(n) {
                        Some(w) => wl.push(w),
                        None if ["value", "R", "G", "B"].contains(n) => {
                            return Err(ChannelError::BadSet(owned()));
                        }
                        None => return Err(ChannelError::UnknownName(n.to_string())),
                    }
                }
                Channels::wavelengths(&wl)
            }
        }
    }

    /// Checks that `values` has one entry per channel.
    pub fn check_len(&self, got: usize) -> Result<(), ChannelError> {
        if got == self.len() {
            Ok(())
        } else {
            Err(ChannelError::Length {
                expected: self.len(),
                got,
            })
        }
    }
}

fn parse_wavelength(s: &str) -> Option<f64> {
    let num = s.strip_suffix("nm")?.trim();
    let w: f64 = num.parse().ok()?;
    (w.is_finite() && w > 0.0).then_some(w)
}

impl fmt::Display for Channels {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.names().join(","))
    }
}

impl serde::Serialize for Channels {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeSeq;
        let mut seq = s.serialize_seq(Some(self.len()))?;
        for n in self.names() {
            seq.serialize_element(&n)?;
        }
        seq.end()
    }
}

impl<'de> serde::Deserialize<'de> for Channels {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let names = Vec::<String>::deserialize(d)?;
        Channels::from_names(&names).map_err(serde::de::Error::custom)
    }
}

/// One value per channel, tagged with its channels: a BRDF value, an albedo.
#[derive(Clone, Debug, PartialEq)]
pub struct Spectrum {
    channels: Channels,
    values: Vec<f64>,
}

impl Spectrum {
    /// A value per channel; the lengths must agree.
    pub fn new(channels: Channels, values: Vec<f64>) -> Result<Spectrum, ChannelError> {
        channels.check_len(values.len())?;
        Ok(Spectrum { channels, values })
    }

    /// Zero in every channel.
    pub fn zeros(channels: Channels) -> Spectrum {
        let values = vec![0.0; channels.len()];
        Spectrum { channels, values }
    }

    /// The channels.
    pub fn channels(&self) -> &Channels {
        &self.channels
    }

    /// The values, one per channel in channel order.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// Mutable access to the values (the length cannot change).
    pub fn values_mut(&mut self) -> &mut [f64] {
        &mut self.values
    }

    /// The value of the channel named `name`.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.channels.index_of(name).map(|i| self.values[i])
    }

    /// `(name, value)` for each channel.
    pub fn iter(&self) -> impl Iterator<Item = (String, f64)> + '_ {
        self.values
            .iter()
            .enumerate()
            .map(|(i, v)| (self.channels.name(i), *v))
    }

    /// The mean over channels (a scalar summary, e.g. for a sampling weight).
    pub fn mean(&self) -> f64 {
        self.values.iter().sum::<f64>() / self.values.len() as f64
    }
}

impl fmt::Display for Spectrum {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, (n, v)) in self.iter().enumerate() {
            if i > 0 {
                f.write_str(" ")?;
            }
            write!(f, "{n}={v}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for c in [
            Channels::Single,
            Channels::Rgb,
            Channels::wavelengths(&[450.0, 532.5, 700.0]).expect("valid"),
        ] {
            assert_eq!(Channels::from_names(&c.names()).expect("round trip"), c);
        }
        assert_eq!(
            Channels::wavelengths(&[532.5]).expect("valid").names(),
            vec!["532.5nm"]
        );
    }

    #[test]
    fn bad_sets_are_refused_with_reasons() {
        let e = Channels::from_names(&["R", "B", "G"]).unwrap_err();
        assert!(matches!(e, ChannelError::BadSet(_)), "{e}");
        let e = Channels::from_names(&["green"]).unwrap_err();
        assert_eq!(e, ChannelError::UnknownName("green".into()));
        let e = Channels::from_names(&["600nm", "500nm"]).unwrap_err();
        assert!(matches!(e, ChannelError::BadWavelengths(_)));
        let e = Channels::from_names::<&str>(&[]).unwrap_err();
        assert_eq!(e, ChannelError::Empty);
        let e = Channels::from_names(&["-5nm"]).unwrap_err();
        assert!(matches!(e, ChannelError::UnknownName(_)));
    }

    #[test]
    fn spectrum_checks_length_and_looks_up_by_name() {
        assert!(Spectrum::new(Channels::Rgb, vec![1.0, 2.0]).is_err());
        let s = Spectrum::new(Channels::Rgb, vec![1.0, 2.0, 4.0]).expect("3 values");
        assert_eq!(s.get("G"), Some(2.0));
        assert_eq!(s.get("value"), None);
        assert!((s.mean() - 7.0 / 3.0).abs() < 1e-15);
        assert_eq!(s.to_string(), "R=1 G=2 B=4");
    }
}
