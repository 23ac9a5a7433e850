//! Spectra to colour: CIE XYZ tristimulus values (CIE 015:2018 §7) for the CIE 1931 2°
//! and CIE 1964 10° observers under illuminants D65, D50, A and E, chromaticity, linear
//! and encoded sRGB (IEC 61966-2-1:1999). `docs/colour.md` has the formulas and the
//! table sources.
//!
//! - [`Colorimeter`] holds an [`Observer`], an [`Illuminant`] and the weights
//!   `k·S(λ)·x̄(λ)` (and ȳ, z̄) on the 1 nm grid 360–830 nm of the CIE tables.
//!   [`Colorimeter::xyz`] takes a spectrum sampled uniformly at 1, 5 or 10 nm,
//!   [`Colorimeter::xyz_of_channels`] the wavelength [`Channels`] of a BRDF (any
//!   spacing); [`Colorimeter::colour`] gives everything at once ([`Colour`]).
//! - **Scale.** `k = 1 / Σ S(λ) ȳ(λ) Δλ`, so a perfect reflecting diffuser (reflectance
//!   factor 1 at every wavelength) has Y = 1: Y runs 0–1, not the CIE's 0–100. The same
//!   k applies to BRDF values in 1/sr, whose Y is then a luminance-weighted BRDF in
//!   1/sr (a Lambertian surface of reflectance factor ρ has Y = ρ/π).
//! - **Interpolation.** Uniform 5 and 10 nm spectra are interpolated onto 1 nm by
//!   Sprague (1880) ([`Interpolation::Sprague`], the default) or linearly; channel
//!   wavelengths that are not uniform 1, 5 or 10 nm, linearly. Beyond the spectrum's
//!   ends its end values are used. The spectrum must cover at least
//!   [`REQUIRED_FIRST_NM`]–[`REQUIRED_LAST_NM`] nm.
//! - **sRGB.** XYZ goes to linear sRGB through the IEC 61966-2-1 matrix
//!   ([`srgb::XYZ_TO_SRGB`]), after a Bradford adaptation ([`Adaptation`]) from the
//!   colorimeter's white to the sRGB white (D65, x 0.3127, y 0.3290) unless the
//!   colorimeter is already D65 with the 1931 observer (sRGB's own conditions), so that
//!   a perfect white is (1, 1, 1) under every illuminant. Encoded sRGB clips each
//!   linear channel to [0, 1] and applies the IEC transfer function ([`srgb::encode`]).
//!
//! ```
//! use gonio_core::colour::{Colorimeter, Illuminant, Observer};
//! let c = Colorimeter::new(Observer::Cie1931, Illuminant::D65);
//! let wl: Vec<f64> = (0..=80).map(|i| 380.0 + 5.0 * i as f64).collect();
//! let white = c.xyz(&wl, &vec![1.0; wl.len()]).unwrap();
//! let (x, y) = white.chromaticity().unwrap();
//! assert!((x - 0.31272).abs() < 1e-4 && (y - 0.32903).abs() < 1e-4);
//! assert!((white.y - 1.0).abs() < 1e-12);
//! ```

use std::fmt;
use std::str::FromStr;
use std::sync::Arc;

use crate::Channels;

mod interp;
pub mod srgb;
mod tables;
#[cfg(test)]
mod tests;

pub use interp::Interpolation;
pub use tables::illuminant_a;

use tables::{GRID_FIRST_NM, GRID_LEN};

/// The shortest wavelength a spectrum must reach (nm): below 400 nm and above 700 nm
/// the CIE 1931 ȳ is under 0.5 % of its peak, so the end-value extension there moves a
/// colour little; a spectrum that stops short of this range leaves too much to guess.
pub const REQUIRED_FIRST_NM: f64 = 400.0;
/// The longest wavelength a spectrum must reach (nm).
pub const REQUIRED_LAST_NM: f64 = 700.0;

/// The sample spacings (nm) [`Colorimeter::xyz`] accepts.
pub const SPACINGS_NM: [f64; 3] = [1.0, 5.0, 10.0];

/// How close (nm) two spacings must be to count as the same.
const SPACING_TOLERANCE_NM: f64 = 1e-6;

/// Why a spectrum could not be turned into colour.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ColourError {
    /// Wavelengths and values of different lengths.
    #[error("{wavelengths} wavelengths but {values} values")]
    Length {
        /// Number of wavelengths.
        wavelengths: usize,
        /// Number of values.
        values: usize,
    },
    /// Too few samples to interpolate.
    #[error("{got} samples; at least {need} are needed")]
    TooFew {
        /// Samples given.
        got: usize,
        /// Samples needed.
        need: usize,
    },
    /// A wavelength that is not finite, or not above the one before it.
    #[error("wavelength {index} ({wavelength_nm} nm) is not finite and above the one before")]
    BadWavelength {
        /// 0-based position.
        index: usize,
        /// The wavelength.
        wavelength_nm: f64,
    },
    /// Spacing that is not uniform 1, 5 or 10 nm.
    #[error(
        "the spacing must be uniform 1, 5 or 10 nm; found {found_nm} nm between {from_nm} and {to_nm} nm"
    )]
    Spacing {
        /// The spacing found.
        found_nm: f64,
        /// The wavelength where it starts.
        from_nm: f64,
        /// The wavelength where it ends.
        to_nm: f64,
    },
    /// A spectrum that does not reach 400–700 nm.
    #[error(
        "the spectrum covers {first_nm}–{last_nm} nm; at least {REQUIRED_FIRST_NM}–{REQUIRED_LAST_NM} nm is needed"
    )]
    Coverage {
        /// First wavelength.
        first_nm: f64,
        /// Last wavelength.
        last_nm: f64,
    },
    /// A value that is not finite.
    #[error("the value at {wavelength_nm} nm is {value}, not a finite number")]
    NotFinite {
        /// Where.
        wavelength_nm: f64,
        /// The value.
        value: f64,
    },
    /// Channels that are not wavelengths.
    #[error("the channels {0} are not wavelengths: there is no spectrum to turn into colour")]
    NotSpectral(String),
    /// A channel set and values of different lengths.
    #[error(transparent)]
    Channels(#[from] crate::ChannelError),
    /// An observer name that is not `1931` or `1964`.
    #[error("unknown observer {0:?} (expected 1931 or 1964)")]
    UnknownObserver(String),
    /// An illuminant name that is not D65, D50, A or E.
    #[error("unknown illuminant {0:?} (expected D65, D50, A or E)")]
    UnknownIlluminant(String),
    /// An adaptation name that is not `bradford` or `none`.
    #[error("unknown adaptation {0:?} (expected bradford or none)")]
    UnknownAdaptation(String),
}

/// A CIE standard colorimetric observer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Observer {
    /// The CIE 1931 standard colorimetric observer (2°).
    #[default]
    Cie1931,
    /// The CIE 1964 standard colorimetric observer (10°).
    Cie1964,
}

impl Observer {
    /// The name commands take and print: `1931` or `1964`.
    pub fn name(self) -> &'static str {
        match self {
            Observer::Cie1931 => "1931",
            Observer::Cie1964 => "1964",
        }
    }

    /// A longer name for messages.
    pub fn title(self) -> &'static str {
        match self {
            Observer::Cie1931 => "CIE 1931 2°",
            Observer::Cie1964 => "CIE 1964 10°",
        }
    }
}

impl FromStr for Observer {
    type Err = ColourError;
    /// `1931` (or `2`) and `1964` (or `10`).
    fn from_str(s: &str) -> Result<Self, ColourError> {
        match s.trim() {
            "1931" | "2" => Ok(Observer::Cie1931),
            "1964" | "10" => Ok(Observer::Cie1964),
            _ => Err(ColourError::UnknownObserver(s.to_string())),
        }
    }
}

impl fmt::Display for Observer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A CIE illuminant: the light a reflectance is seen under.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Illuminant {
    /// CIE standard illuminant D65 (daylight, about 6504 K): the CIE's 1 nm table.
    #[default]
    D65,
    /// CIE illuminant D50 (daylight, about 5003 K): the CIE's 5 nm table, linearly
    /// interpolated.
    D50,
    /// CIE standard illuminant A (incandescent, Planckian at about 2856 K): from its
    /// definition ([`illuminant_a`]).
    A,
    /// The equal-energy illuminant E: the same power at every wavelength.
    E,
}

impl Illuminant {
    /// Every illuminant.
    pub const ALL: [Illuminant; 4] = [
        Illuminant::D65,
        Illuminant::D50,
        Illuminant::A,
        Illuminant::E,
    ];

    /// The name commands take and print: `D65`, `D50`, `A`, `E`.
    pub fn name(self) -> &'static str {
        match self {
            Illuminant::D65 => "D65",
            Illuminant::D50 => "D50",
            Illuminant::A => "A",
            Illuminant::E => "E",
        }
    }

    /// The relative spectral power at `wavelength_nm` on the 1 nm grid 360–830 nm as
    /// this module uses it (D65 and D50 tables, A from its definition, E = 1); `None`
    /// off the grid.
    pub fn relative_power(self, wavelength_nm: f64) -> Option<f64> {
        let i = wavelength_nm - GRID_FIRST_NM as f64;
        if i.fract() != 0.0 || i < 0.0 || i >= GRID_LEN as f64 {
            return None;
        }
        Some(tables::spd(self, i as usize))
    }
}

impl FromStr for Illuminant {
    type Err = ColourError;
    /// `D65`, `D50`, `A`, `E` (case-insensitive).
    fn from_str(s: &str) -> Result<Self, ColourError> {
        Illuminant::ALL
            .into_iter()
            .find(|i| i.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| ColourError::UnknownIlluminant(s.to_string()))
    }
}

impl fmt::Display for Illuminant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The chromatic adaptation applied before the sRGB matrix.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Adaptation {
    /// Bradford (von Kries scaling in the Bradford cone space, [`srgb::bradford`]) from
    /// the colorimeter's white to the sRGB white, except under D65 with the 1931
    /// observer, where XYZ goes to the matrix as it is.
    #[default]
    Bradford,
    /// None: XYZ goes to the sRGB matrix as it is, whatever the illuminant (a white
    /// under A then looks orange, as it would to a camera set to daylight).
    None,
}

impl FromStr for Adaptation {
    type Err = ColourError;
    /// `bradford` or `none` (case-insensitive).
    fn from_str(s: &str) -> Result<Self, ColourError> {
        match s.trim().to_ascii_lowercase().as_str() {
            "bradford" => Ok(Adaptation::Bradford),
            "none" => Ok(Adaptation::None),
            _ => Err(ColourError::UnknownAdaptation(s.to_string())),
        }
    }
}

/// CIE XYZ tristimulus values (fields `x`, `y`, `z` are X, Y, Z); Y = 1 for a perfect
/// reflecting diffuser.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Xyz {
    /// X.
    pub x: f64,
    /// Y (luminance factor; or luminance-weighted BRDF in 1/sr for BRDF input).
    pub y: f64,
    /// Z.
    pub z: f64,
}

impl Xyz {
    /// `[X, Y, Z]`.
    pub fn to_array(self) -> [f64; 3] {
        [self.x, self.y, self.z]
    }

    /// From `[X, Y, Z]`.
    pub fn from_array(v: [f64; 3]) -> Xyz {
        Xyz {
            x: v[0],
            y: v[1],
            z: v[2],
        }
    }

    /// The chromaticity `(x, y) = (X, Y) / (X + Y + Z)` (CIE 015:2018 §7.3, section
    /// **UNCONFIRMED**); `None` for black (X + Y + Z = 0) or a non-finite sum.
    pub fn chromaticity(self) -> Option<(f64, f64)> {
        let s = self.x + self.y + self.z;
        (s != 0.0 && s.is_finite()).then(|| (self.x / s, self.y / s))
    }

    /// `self · s`.
    pub fn scale(self, s: f64) -> Xyz {
        Xyz::from_array(self.to_array().map(|v| v * s))
    }
}

/// A spectrum's colour: everything [`Colorimeter::colour`] computes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Colour {
    /// Tristimulus values.
    pub xyz: Xyz,
    /// Chromaticity, `None` for black.
    pub xy: Option<(f64, f64)>,
    /// Linear sRGB (unclipped: out-of-gamut colours have channels below 0 or above 1).
    pub srgb_linear: [f64; 3],
    /// Encoded sRGB in [0, 1] (clipped, then the IEC transfer function).
    pub srgb: [f64; 3],
    /// Encoded sRGB as 8-bit code values.
    pub srgb8: [u8; 3],
}

/// Turns spectra into colour for one observer and illuminant (module docs). Cloning is
/// cheap.
#[derive(Clone, Debug)]
pub struct Colorimeter {
    observer: Observer,
    illuminant: Illuminant,
    interpolation: Interpolation,
    adaptation: Adaptation,
    /// `k·S·x̄, k·S·ȳ, k·S·z̄` (Δλ = 1 nm folded in) at 360, 361, …, 830 nm.
    weights: Arc<[[f64; 3]]>,
    /// XYZ of the perfect reflecting diffuser.
    white: Xyz,
    /// XYZ to linear sRGB, adaptation included.
    to_srgb: srgb::Mat3,
}

impl Colorimeter {
    /// A colorimeter for `observer` under `illuminant`, with Sprague interpolation and
    /// Bradford adaptation.
    pub fn new(observer: Observer, illuminant: Illuminant) -> Colorimeter {
        let cmf = tables::cmf(observer);
        let s: Vec<f64> = (0..GRID_LEN).map(|i| tables::spd(illuminant, i)).collect();
        // CIE 015:2018 §7 (equation numbers UNCONFIRMED): k = 100 / Σ S ȳ Δλ for a
        // 0–100 scale; here 1 / Σ S ȳ Δλ, Δλ = 1 nm.
        let norm: f64 = s.iter().zip(cmf).map(|(s, c)| s * c[1]).sum();
        let k = 1.0 / norm;
        let weights: Arc<[[f64; 3]]> = s
            .iter()
            .zip(cmf)
            .map(|(s, c)| c.map(|c| k * s * c))
            .collect();
        let white = Xyz::from_array(
            weights
                .iter()
                .fold([0.0; 3], |a, w| [a[0] + w[0], a[1] + w[1], a[2] + w[2]]),
        );
        let mut c = Colorimeter {
            observer,
            illuminant,
            interpolation: Interpolation::default(),
            adaptation: Adaptation::default(),
            weights,
            white,
            to_srgb: srgb::XYZ_TO_SRGB,
        };
        c.to_srgb = c.srgb_matrix();
        c
    }

    /// The same colorimeter reading uniform spectra with `interpolation`.
    pub fn with_interpolation(mut self, interpolation: Interpolation) -> Colorimeter {
        self.interpolation = interpolation;
        self
    }

    /// The same colorimeter with `adaptation` before the sRGB matrix.
    pub fn with_adaptation(mut self, adaptation: Adaptation) -> Colorimeter {
        self.adaptation = adaptation;
        self.to_srgb = self.srgb_matrix();
        self
    }

    fn srgb_matrix(&self) -> srgb::Mat3 {
        let native = self.illuminant == Illuminant::D65 && self.observer == Observer::Cie1931;
        if self.adaptation == Adaptation::None || native {
            return srgb::XYZ_TO_SRGB;
        }
        let (x, y) = srgb::SRGB_WHITE_XY;
        // Every white of the tables has positive cone responses (a unit test checks
        // all eight); the identity is the fallback should one not.
        match srgb::bradford(self.white, srgb::xyz_of_xy(x, y)) {
            Some(cat) => srgb::mat_mul(&srgb::XYZ_TO_SRGB, &cat),
            None => srgb::XYZ_TO_SRGB,
        }
    }

    /// The observer.
    pub fn observer(&self) -> Observer {
        self.observer
    }

    /// The illuminant.
    pub fn illuminant(&self) -> Illuminant {
        self.illuminant
    }

    /// The interpolation of uniform spectra.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// The adaptation before the sRGB matrix.
    pub fn adaptation(&self) -> Adaptation {
        self.adaptation
    }

    /// XYZ of the perfect reflecting diffuser (Y = 1): the illuminant's white point.
    pub fn white(&self) -> Xyz {
        self.white
    }

    /// The XYZ of a spectrum sampled at `wavelengths_nm` (uniform spacing of 1, 5 or
    /// 10 nm, covering at least 400–700 nm): reflectance factors, or BRDF values in 1/sr.
    /// `X = Σ k S(λ) x̄(λ) φ(λ) Δλ` over 360–830 nm at 1 nm, φ interpolated as
    /// [`Colorimeter::interpolation`] says and extended by its end values.
    pub fn xyz(&self, wavelengths_nm: &[f64], values: &[f64]) -> Result<Xyz, ColourError> {
        let step = check_spectrum(wavelengths_nm, values)?;
        let step = uniform_step(wavelengths_nm, step)?;
        let need = match self.interpolation {
            Interpolation::Sprague => interp::SPRAGUE_MIN_POINTS,
            Interpolation::Linear => 2,
        };
        if values.len() < need {
            return Err(ColourError::TooFew {
                got: values.len(),
                need,
            });
        }
        let mut acc = [0.0; 3];
        let w = &self.weights;
        interp::uniform_onto_grid(
            wavelengths_nm[0],
            step,
            values,
            self.interpolation,
            |g, v| {
                acc[0] += w[g][0] * v;
                acc[1] += w[g][1] * v;
                acc[2] += w[g][2] * v;
            },
        );
        Ok(Xyz::from_array(acc))
    }

    /// The XYZ of one BRDF (or reflectance) value per wavelength channel. Channels at a
    /// uniform 1, 5 or 10 nm go through [`Colorimeter::xyz`]; any other strictly
    /// increasing wavelengths are interpolated linearly onto 1 nm (end values beyond
    /// the ends). Refused for channels that are not wavelengths.
    pub fn xyz_of_channels(&self, channels: &Channels, values: &[f64]) -> Result<Xyz, ColourError> {
        let Channels::Wavelengths(w) = channels else {
            return Err(ColourError::NotSpectral(channels.to_string()));
        };
        channels.check_len(values.len())?;
        let step = check_spectrum(w, values)?;
        if uniform_step(w, step).is_ok() && values.len() >= interp::SPRAGUE_MIN_POINTS {
            return self.xyz(w, values);
        }
        let mut acc = [0.0; 3];
        let wt = &self.weights;
        interp::scattered_onto_grid(w, values, |g, v| {
            acc[0] += wt[g][0] * v;
            acc[1] += wt[g][1] * v;
            acc[2] += wt[g][2] * v;
        });
        Ok(Xyz::from_array(acc))
    }

    /// Linear sRGB of XYZ: the adaptation ([`Adaptation`]) then the IEC 61966-2-1
    /// matrix. Unclipped.
    pub fn srgb_linear(&self, xyz: Xyz) -> [f64; 3] {
        srgb::mul(&self.to_srgb, xyz.to_array())
    }

    /// The matrix [`Colorimeter::srgb_linear`] applies (adaptation included).
    pub fn srgb_matrix_used(&self) -> srgb::Mat3 {
        self.to_srgb
    }

    /// Everything about one colour: XYZ, xy, linear, encoded and 8-bit sRGB.
    pub fn colour_of_xyz(&self, xyz: Xyz) -> Colour {
        let srgb_linear = self.srgb_linear(xyz);
        let encoded = srgb::encode_clipped(srgb_linear);
        Colour {
            xyz,
            xy: xyz.chromaticity(),
            srgb_linear,
            srgb: encoded,
            srgb8: srgb::to_8bit(encoded),
        }
    }

    /// [`Colorimeter::colour_of_xyz`] of [`Colorimeter::xyz`].
    pub fn colour(&self, wavelengths_nm: &[f64], values: &[f64]) -> Result<Colour, ColourError> {
        Ok(self.colour_of_xyz(self.xyz(wavelengths_nm, values)?))
    }
}

/// Checks lengths, finiteness, order and coverage; returns the first spacing.
fn check_spectrum(w: &[f64], v: &[f64]) -> Result<f64, ColourError> {
    if w.len() != v.len() {
        return Err(ColourError::Length {
            wavelengths: w.len(),
            values: v.len(),
        });
    }
    if w.len() < 2 {
        return Err(ColourError::TooFew {
            got: w.len(),
            need: 2,
        });
    }
    for (i, &x) in w.iter().enumerate() {
        if !x.is_finite() || (i > 0 && x <= w[i - 1]) {
            return Err(ColourError::BadWavelength {
                index: i,
                wavelength_nm: x,
            });
        }
    }
    if let Some((wl, val)) = w.iter().zip(v).find(|(_, v)| !v.is_finite()) {
        return Err(ColourError::NotFinite {
            wavelength_nm: *wl,
            value: *val,
        });
    }
    let (first, last) = (w[0], w[w.len() - 1]);
    if first > REQUIRED_FIRST_NM || last < REQUIRED_LAST_NM {
        return Err(ColourError::Coverage {
            first_nm: first,
            last_nm: last,
        });
    }
    Ok(w[1] - w[0])
}

/// The spacing when it is uniform and one of [`SPACINGS_NM`].
fn uniform_step(w: &[f64], first_step: f64) -> Result<f64, ColourError> {
    let bad = |i: usize| ColourError::Spacing {
        found_nm: w[i + 1] - w[i],
        from_nm: w[i],
        to_nm: w[i + 1],
    };
    let Some(step) = SPACINGS_NM
        .into_iter()
        .find(|s| (first_step - s).abs() <= SPACING_TOLERANCE_NM)
    else {
        return Err(bad(0));
    };
    // Each wavelength against first + i·step, so that rounding cannot accumulate.
    for i in 1..w.len() {
        if (w[i] - (w[0] + step * i as f64)).abs() > SPACING_TOLERANCE_NM {
            return Err(bad(i - 1));
        }
    }
    Ok(step)
}
