//! The wavelength term of a spectral run's budget: what the band selector's
//! wavelength scale and bandwidth do to each f_r(λ).
//!
//! A reading at a set wavelength λ measures the slit- (or filter-) weighted mean of
//! f_r about the wavelength the selector really passes. Two effects follow, each
//! scaled by how fast the sample's spectrum changes there:
//! - the wavelength scale's standard uncertainty `u_λ` moves the reading by
//!   `u_λ · ∂f/∂λ`;
//! - a passband of variance `s²` averages `f` to `f + (s²/2) ∂²f/∂λ²` (a Taylor
//!   expansion of the weighted mean); a triangular slit function of FWHM `b` has
//!   `s² = b²/6`, a Gaussian filter of FWHM `b` has `s² = b²/(8 ln 2)`.
//!
//! Both derivatives are estimated from the run's own values at the neighbouring
//! wavelengths of the same direction pair. The term is their quadrature sum. It is
//! shared by every sample of a wavelength (one scale error), in proportion to each
//! sample's slope.

/// The budget term's name.
pub const TERM: &str = "wavelength";
/// How it is shared between samples.
pub const CORRELATION: &str = "wavelength";
/// A monochromator's wavelength standard uncertainty when its config states none,
/// nm (the driver's config documents the same constant).
pub const MONOCHROMATOR_UNCERTAINTY_NM: f64 = gonio_proto::cs130::WAVELENGTH_UNCERTAINTY_NM;
/// A monochromator's bandpass (FWHM) when its config states none, nm.
pub const MONOCHROMATOR_BANDWIDTH_NM: f64 = gonio_proto::cs130::BANDWIDTH_NM;
/// A band-pass filter's centre-wavelength standard uncertainty when the config
/// states none, nm.
pub const FILTER_UNCERTAINTY_NM: f64 = gonio_proto::fw102c::CENTRE_UNCERTAINTY_NM;

/// The band selector of a run, as the instrument config gives it.
#[derive(Clone, Debug, PartialEq)]
pub struct Bandpass {
    /// `monochromator` or `filter wheel`.
    pub device: &'static str,
    /// The wavelength scale's standard uncertainty, nm.
    pub uncertainty_nm: f64,
    /// The passband's variance about its centre, nm², per channel wavelength.
    variance: Variance,
}

#[derive(Clone, Debug, PartialEq)]
enum Variance {
    /// A triangular slit function of this FWHM, nm.
    Slit(f64),
    /// Gaussian filters: (centre, FWHM) of each band-pass filter, nm.
    Filters(Vec<(f64, f64)>),
}

impl Bandpass {
    /// The band selector of an instrument config's text (`[monochromator]`,
    /// `[filter_wheel]`), if it has one; unreadable text has none.
    pub fn of_instrument(text: &str) -> Option<Bandpass> {
        let t = toml::from_str::<toml::Table>(text).ok()?;
        let num = |v: Option<&toml::Value>| {
            v.and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
        };
        if let Some(m) = t.get("monochromator") {
            return Some(Bandpass {
                device: "monochromator",
                uncertainty_nm: num(m.get("wavelength_uncertainty_nm"))
                    .unwrap_or(MONOCHROMATOR_UNCERTAINTY_NM),
                variance: Variance::Slit(
                    num(m.get("bandwidth_nm")).unwrap_or(MONOCHROMATOR_BANDWIDTH_NM),
                ),
            });
        }
        let w = t.get("filter_wheel")?;
        let filters = w
            .get("fw102c")
            .and_then(|f| f.get("filters"))
            .and_then(|f| f.as_array())
            .map(|a| {
                a.iter()
                    .filter(|f| f.get("kind").and_then(|k| k.as_str()) == Some("bandpass"))
                    .filter_map(|f| Some((num(f.get("centre_nm"))?, num(f.get("fwhm_nm"))?)))
                    .collect()
            })
            .unwrap_or_default();
        Some(Bandpass {
            device: "filter wheel",
            uncertainty_nm: num(w.get("wavelength_uncertainty_nm"))
                .unwrap_or(FILTER_UNCERTAINTY_NM),
            variance: Variance::Filters(filters),
        })
    }

    /// The passband's variance at `nm`, nm².
    fn variance(&self, nm: f64) -> f64 {
        match &self.variance {
            Variance::Slit(b) => b * b / 6.0,
            Variance::Filters(f) => f
                .iter()
                .min_by(|a, b| (a.0 - nm).abs().total_cmp(&(b.0 - nm).abs()))
                .map_or(0.0, |(_, b)| b * b / (8.0 * 2f64.ln())),
        }
    }

    /// What the source text of the budget says.
    pub fn source(&self) -> String {
        let passband = match &self.variance {
            Variance::Slit(b) => format!("a triangular slit function of FWHM {b} nm"),
            Variance::Filters(_) => "each band-pass filter's FWHM (a Gaussian)".into(),
        };
        format!(
            "the {}'s wavelength scale (u = {} nm) times ∂f/∂λ, and its passband ({passband}) as (s²/2)·∂²f/∂λ², both from the neighbouring wavelengths",
            self.device, self.uncertainty_nm
        )
    }

    /// The slope ∂f/∂λ at each of `wavelengths` (as [`Bandpass::terms`] estimates
    /// it), 1/(sr nm): which way a wavelength scale error moves each value.
    pub fn slopes(&self, wavelengths: &[f64], values: &[f64]) -> Vec<f64> {
        let n = wavelengths.len().min(values.len());
        if n < 2 {
            return vec![0.0; n];
        }
        let slope =
            |a: usize, b: usize| (values[b] - values[a]) / (wavelengths[b] - wavelengths[a]);
        (0..n)
            .map(|c| match c {
                0 => slope(0, 1),
                c if c == n - 1 => slope(n - 2, n - 1),
                c => {
                    let (hl, hr) = (
                        wavelengths[c] - wavelengths[c - 1],
                        wavelengths[c + 1] - wavelengths[c],
                    );
                    (slope(c - 1, c) * hr + slope(c, c + 1) * hl) / (hl + hr)
                }
            })
            .collect()
    }

    /// The term, 1/sr, at each of `wavelengths` (strictly increasing, nm) for one
    /// direction pair's `values` there. Fewer than two wavelengths: all zero.
    pub fn terms(&self, wavelengths: &[f64], values: &[f64]) -> Vec<f64> {
        let n = wavelengths.len().min(values.len());
        if n < 2 {
            return vec![0.0; n];
        }
        let slope =
            |a: usize, b: usize| (values[b] - values[a]) / (wavelengths[b] - wavelengths[a]);
        let (first, second): (Vec<f64>, Vec<f64>) = (0..n)
            .map(|c| {
                if c == 0 || c == n - 1 {
                    let (a, b) = if c == 0 { (0, 1) } else { (n - 2, n - 1) };
                    (slope(a, b), 0.0)
                } else {
                    let (hl, hr) = (
                        wavelengths[c] - wavelengths[c - 1],
                        wavelengths[c + 1] - wavelengths[c],
                    );
                    let (sl, sr) = (slope(c - 1, c), slope(c, c + 1));
                    // The derivative of the parabola through the three points.
                    ((sl * hr + sr * hl) / (hl + hr), 2.0 * (sr - sl) / (hl + hr))
                }
            })
            .unzip();
        (0..n)
            .map(|c| {
                // At the ends the curvature is the nearest interior one's.
                let curv = if n < 3 {
                    0.0
                } else {
                    second[c.clamp(1, n - 2)]
                };
                let shift = self.uncertainty_nm * first[c].abs();
                let blur = 0.5 * self.variance(wavelengths[c]) * curv.abs();
                shift.hypot(blur)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quadratic_spectrum_gives_its_exact_derivatives() {
        // f = 1 + 0.01 (λ − 500) + 1e-4 (λ − 500)², on uneven wavelengths: the
        // three-point derivatives of a parabola are exact.
        let w = [400.0, 450.0, 520.0, 600.0];
        let f: Vec<f64> = w
            .iter()
            .map(|l| 1.0 + 0.01 * (l - 500.0) + 1e-4 * (l - 500.0) * (l - 500.0))
            .collect();
        let b = Bandpass {
            device: "monochromator",
            uncertainty_nm: 0.5,
            variance: Variance::Slit(3.0),
        };
        let t = b.terms(&w, &f);
        for (c, l) in [(1, 450.0), (2, 520.0)] {
            let d1: f64 = 0.01 + 2e-4 * (l - 500.0);
            let want = (0.5 * d1.abs()).hypot(0.5 * 9.0 / 6.0 * 2e-4);
            assert!((t[c] - want).abs() < 1e-12, "{c}: {} vs {want}", t[c]);
        }
        // A flat spectrum carries no term; two wavelengths give the chord's slope.
        assert!(b.terms(&w, &[0.3; 4]).iter().all(|x| *x == 0.0));
        let two = b.terms(&[500.0, 600.0], &[1.0, 2.0]);
        assert!((two[0] - 0.5 * 0.01).abs() < 1e-15 && (two[1] - 0.005).abs() < 1e-15);
    }

    #[test]
    fn the_instrument_text_names_the_selector() {
        let m = Bandpass::of_instrument(
            "[monochromator]\nport = \"sim\"\nwavelength_uncertainty_nm = 0.1\nbandwidth_nm = 4\n",
        )
        .expect("monochromator");
        assert_eq!(m.uncertainty_nm, 0.1);
        assert_eq!(m.variance(500.0), 16.0 / 6.0);
        let w = Bandpass::of_instrument(
            "[filter_wheel]\nport = \"x\"\n[[filter_wheel.fw102c.filters]]\nkind = \"bandpass\"\nposition = 1\ncentre_nm = 550\nfwhm_nm = 10\n",
        )
        .expect("wheel");
        assert_eq!(w.uncertainty_nm, FILTER_UNCERTAINTY_NM);
        assert!((w.variance(551.0) - 100.0 / (8.0 * 2f64.ln())).abs() < 1e-12);
        assert_eq!(Bandpass::of_instrument("[detector]\nport = \"x\"\n"), None);
        assert_eq!(Bandpass::of_instrument("not toml ["), None);
    }
}
