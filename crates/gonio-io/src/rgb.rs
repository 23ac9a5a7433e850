//! Spectral BRDF data turned into RGB ones: each sample's (or node's) values at the
//! wavelength channels become linear sRGB channels R, G, B through
//! `gonio_core::colour` (CIE XYZ for an observer and illuminant, Bradford adaptation
//! to the sRGB white, the IEC 61966-2-1 matrix; `docs/colour.md`).
//!
//! The conversion is linear in the spectrum (interpolation, summation, adaptation and
//! the matrix all are), so it is one 3 × n matrix ([`rgb_matrix`]) applied to each
//! sample: a BRDF in 1/sr stays a BRDF in 1/sr, and a Lambertian surface of spectral
//! reflectance ρ(λ) (f_r = ρ/π) becomes R, G, B = sRGB_linear(ρ) / π. Standard
//! uncertainties are carried through the same matrix, the channels' errors taken as
//! independent: σ_R² = Σ_λ A_Rλ² σ_λ².

use gonio_core::Channels;
use gonio_core::colour::{Adaptation, Colorimeter, ColourError, Illuminant, Observer};
use gonio_process::{Sample, Samples, Table};

use crate::formats::Data;

/// Why spectral data could not be turned into RGB.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("turning the wavelength channels into sRGB: {0}")]
pub struct RgbError(#[from] pub ColourError);

/// The viewing conditions of the conversion.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Conversion {
    /// The CIE observer (default 1931).
    pub observer: Observer,
    /// The illuminant (default D65).
    pub illuminant: Illuminant,
    /// Chromatic adaptation to the sRGB white (default Bradford).
    pub adaptation: Adaptation,
}

impl Conversion {
    /// The colorimeter of these conditions.
    pub fn colorimeter(&self) -> Colorimeter {
        Colorimeter::new(self.observer, self.illuminant).with_adaptation(self.adaptation)
    }

    /// A short description for reports: `D65, CIE 1931 2° observer`.
    pub fn describe(&self) -> String {
        format!(
            "illuminant {}, {} observer{}",
            self.illuminant,
            self.observer.title(),
            match self.adaptation {
                Adaptation::Bradford => "",
                Adaptation::None => ", no adaptation",
            }
        )
    }
}

/// The linear map from one value per channel to linear sRGB: row `j` is what channel
/// `j` adds to R, G, B per unit. Wavelength channels go through the colorimeter (which
/// refuses spacings or coverage it cannot use, see `gonio_core::colour`); R, G, B are
/// taken as linear sRGB already (the identity); a single channel is grey.
pub fn rgb_matrix(channels: &Channels, conversion: &Conversion) -> Result<Vec<[f64; 3]>, RgbError> {
    match channels {
        Channels::Single => Ok(vec![[1.0; 3]]),
        Channels::Rgb => Ok(vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
        Channels::Wavelengths(w) => {
            let c = conversion.colorimeter();
            let mut unit = vec![0.0; w.len()];
            let mut rows = Vec::with_capacity(w.len());
            for j in 0..w.len() {
                unit[j] = 1.0;
                let xyz = c.xyz_of_channels(channels, &unit)?;
                rows.push(c.srgb_linear(xyz));
                unit[j] = 0.0;
            }
            Ok(rows)
        }
    }
}

/// `Σ_j m[j] · v[j]`.
pub fn apply(m: &[[f64; 3]], v: &[f64]) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (row, x) in m.iter().zip(v) {
        for k in 0..3 {
            out[k] += row[k] * x;
        }
    }
    out
}

/// `sqrt(Σ_j m[j]² · σ[j]²)`, the uncertainty of [`apply`] for independent channels.
fn apply_sigma(m: &[[f64; 3]], s: &[f64]) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (row, x) in m.iter().zip(s) {
        for k in 0..3 {
            out[k] += (row[k] * x).powi(2);
        }
    }
    out.map(f64::sqrt)
}

/// The data with wavelength channels turned into linear sRGB R, G, B (module docs);
/// data with other channels is returned as it is.
pub fn to_rgb(data: &Data, conversion: &Conversion) -> Result<Data, RgbError> {
    if !matches!(data.channels(), Channels::Wavelengths(_)) {
        return Ok(data.clone());
    }
    let m = rgb_matrix(data.channels(), conversion)?;
    Ok(match data {
        Data::Samples(s) => Data::Samples(Samples {
            channels: Channels::Rgb,
            samples: s
                .samples
                .iter()
                .map(|x| Sample {
                    pair: x.pair,
                    value: apply(&m, &x.value).to_vec(),
                    sigma: x.sigma.as_ref().map(|s| apply_sigma(&m, s).to_vec()),
                    flags: x.flags,
                })
                .collect(),
            isotropic: s.isotropic,
        }),
        Data::Table(t) => {
            let n = t.grid.len();
            let nc = t.channels.len();
            let convert = |src: &[f64], sigma: bool| {
                let mut out = vec![0.0; 3 * n];
                let mut v = vec![0.0; nc];
                for i in 0..n {
                    for (ch, x) in v.iter_mut().enumerate() {
                        *x = src[ch * n + i];
                    }
                    let rgb = if sigma {
                        apply_sigma(&m, &v)
                    } else {
                        apply(&m, &v)
                    };
                    for k in 0..3 {
                        out[k * n + i] = rgb[k];
                    }
                }
                out
            };
            Data::Table(Table {
                channels: Channels::Rgb,
                grid: t.grid,
                values: convert(&t.values, false),
                sigma: t.sigma.as_ref().map(|s| convert(s, true)),
            })
        }
        // A MERL table's channels are R, G, B: handled above.
        Data::Merl(_) => data.clone(),
        // Spectral RGL: its values on the 10° grid, converted.
        Data::Rgl(r) => return to_rgb(&Data::Samples(crate::formats::rgl_samples(r)), conversion),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use gonio_core::SphericalDeg;
    use gonio_core::dirfile::PairDeg;

    fn spectral_samples(w: &[f64], v: &[f64]) -> Samples {
        Samples {
            channels: Channels::wavelengths(w).unwrap(),
            samples: vec![Sample {
                pair: PairDeg {
                    incident: SphericalDeg::new(30.0, 0.0),
                    outgoing: SphericalDeg::new(20.0, 180.0),
                },
                value: v.to_vec(),
                sigma: Some(v.iter().map(|x| 0.1 * x).collect()),
                flags: 0,
            }],
            isotropic: true,
        }
    }

    #[test]
    fn samples_become_the_srgb_of_their_spectrum() {
        let w: Vec<f64> = (0..31).map(|i| 400.0 + 10.0 * i as f64).collect();
        let v: Vec<f64> = w
            .iter()
            .map(|l| 0.1 + 0.5 * ((l - 400.0) / 300.0))
            .collect();
        let conv = Conversion::default();
        let Data::Samples(out) = to_rgb(&Data::Samples(spectral_samples(&w, &v)), &conv).unwrap()
        else {
            panic!()
        };
        assert_eq!(out.channels, Channels::Rgb);
        let c = conv.colorimeter();
        let expect = c.srgb_linear(c.xyz(&w, &v).unwrap());
        for (got, e) in out.samples[0].value.iter().zip(expect) {
            assert!((got - e).abs() < 1e-12);
        }
        // A reddish ramp: R above B.
        assert!(expect[0] > expect[2]);
        // σ of 10 % on every channel, independent: σ_R² = Σ_λ (A_Rλ · 0.1 v_λ)², A the
        // response of R to one unit in channel λ alone.
        let s = out.samples[0].sigma.as_ref().unwrap();
        let ch = Channels::wavelengths(&w).unwrap();
        let mut var = [0.0; 3];
        for j in 0..w.len() {
            let mut unit = vec![0.0; w.len()];
            unit[j] = 1.0;
            let a = c.srgb_linear(c.xyz_of_channels(&ch, &unit).unwrap());
            for (vk, ak) in var.iter_mut().zip(a) {
                *vk += (ak * 0.1 * v[j]).powi(2);
            }
        }
        for (got, e) in s.iter().zip(var) {
            assert!(
                *got > 0.0 && (got - e.sqrt()).abs() < 1e-12,
                "{got} {}",
                e.sqrt()
            );
        }
    }

    #[test]
    fn rgb_and_single_channels_pass_through() {
        let rgb = rgb_matrix(&Channels::Rgb, &Conversion::default()).unwrap();
        assert_eq!(apply(&rgb, &[0.1, 0.2, 0.3]), [0.1, 0.2, 0.3]);
        let grey = rgb_matrix(&Channels::Single, &Conversion::default()).unwrap();
        assert_eq!(apply(&grey, &[0.25]), [0.25; 3]);
        let w = [450.0, 550.0, 650.0];
        let e = to_rgb(
            &Data::Samples(spectral_samples(&w, &[0.1, 0.2, 0.3])),
            &Conversion::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("450–650 nm"), "{e}");
    }
}
