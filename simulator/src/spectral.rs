//! The light a monochromator passes: a tungsten-halogen lamp, a blazed grating's
//! efficiency in the first and second orders, the triangular slit function, and the
//! filters in the beam.
//!
//! A monochromator set to `λ` passes, through its exit slit, first-order light near
//! `λ` and second-order light near `λ/2` (the grating equation `m λ = d (sin α + sin β)`
//! sends `λ/2` in order 2 to the same angle as `λ` in order 1). An order-sorting
//! long-pass filter with cut-on between `λ/2` and `λ` removes the second order. This
//! module turns those facts into a list of `(wavelength, weight)` pairs: the spectral
//! power reaching the sample, relative to the lamp's power per nm at 560 nm through a
//! perfect 1 nm passband. The optics multiply the sample's `f_r(λ)` by it and sum.
//!
//! Models, with their sources:
//! - Lamp: Planck's law at the lamp's colour temperature (a tungsten filament is close
//!   to a grey body over 350–1000 nm; its colour temperature is what a lamp's data
//!   sheet gives). `c2 = 1.438 776 877e-2 m·K` (CODATA 2018).
//! - Grating: the scalar approximation of a blazed grating's efficiency in order `m`,
//!   `η_m(λ) = sinc²(π (m − λ_B/λ))` with `λ_B` the first-order blaze wavelength
//!   (Littrow mounting; scalar theory, valid for `λ/d` well below 1). A real grating's
//!   curve differs by polarisation and anomalies; the simulator needs only the shape
//!   that makes the second order matter.
//! - Slit: with equal entrance and exit slits the instrument's slit function is a
//!   triangle whose full width at half maximum is the bandpass (the Cornerstone 130
//!   manual's bandpass is this FWHM).

use std::f64::consts::PI;

/// Second radiation constant, m·K (CODATA 2018).
pub const C2_M_K: f64 = 1.438_776_877e-2;
/// The wavelength the lamp's spectrum is normalised at, nm.
const REFERENCE_NM: f64 = 560.0;
/// Nodes per FWHM of the slit function in each order's sum.
const NODES_PER_FWHM: usize = 16;

/// Planck's spectral radiance at `nm` and temperature `kelvin`, relative to its value
/// at 560 nm.
pub fn planck_relative(nm: f64, kelvin: f64) -> f64 {
    let b = |nm: f64| {
        let l = nm * 1e-9;
        1.0 / (l.powi(5) * ((C2_M_K / (l * kelvin)).exp_m1()))
    };
    b(nm) / b(REFERENCE_NM)
}

/// A blazed grating's efficiency in order `order` at `nm` (scalar theory, Littrow),
/// for a first-order blaze wavelength `blaze_nm`; 1 at `λ = λ_B / m`.
pub fn blaze_efficiency(nm: f64, blaze_nm: f64, order: u32) -> f64 {
    let x = PI * (f64::from(order) - blaze_nm / nm);
    if x.abs() < 1e-12 {
        1.0
    } else {
        (x.sin() / x).powi(2)
    }
}

/// The triangular slit function of full width at half maximum `fwhm_nm`, at `delta_nm`
/// from its centre; unit area (1/nm).
pub fn slit(delta_nm: f64, fwhm_nm: f64) -> f64 {
    (1.0 - delta_nm.abs() / fwhm_nm).max(0.0) / fwhm_nm
}

/// A long-pass filter's transmittance: `peak` well above the cut-on (50 % point)
/// `cut_on_nm`, a logistic edge of 10–90 % width `edge_nm`.
pub fn longpass(nm: f64, cut_on_nm: f64, edge_nm: f64, peak: f64) -> f64 {
    // 10 %–90 % of a logistic spans 2 ln 9 scale lengths.
    let s = edge_nm / (2.0 * 9f64.ln());
    peak / (1.0 + (-(nm - cut_on_nm) / s).exp())
}

/// What the monochromator is doing, as the light model needs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Setting {
    /// The wavelength the grating really sends to the exit slit's centre, nm (the set
    /// wavelength plus the instrument's accuracy error and backlash).
    pub actual_nm: f64,
    /// The bandpass (FWHM of the slit function), nm.
    pub fwhm_nm: f64,
    /// The grating's first-order blaze wavelength, nm.
    pub blaze_nm: f64,
    /// The lamp's colour temperature, K.
    pub lamp_k: f64,
    /// False with the shutter closed: no light at all.
    pub shutter_open: bool,
}

/// The light through the exit slit at `setting`, as `(wavelength nm, weight)` pairs:
/// first order around `actual_nm`, second order around `actual_nm / 2`, each through
/// `filter` (the transmittance of everything else in the beam: order-sorting filter,
/// filter wheel). Weights are relative to the lamp at 560 nm through a perfect grating
/// and a unit-area passband, so they sum to about `η(λ) T(λ) L(λ)/L(560)` (plus the
/// second order's share). Empty with the shutter closed.
pub fn passband(setting: &Setting, filter: &dyn Fn(f64) -> f64) -> Vec<(f64, f64)> {
    let positive = |x: f64| x.is_finite() && x > 0.0;
    if !setting.shutter_open || !positive(setting.fwhm_nm) || !positive(setting.actual_nm) {
        return Vec::new();
    }
    let mut out = Vec::with_capacity(4 * NODES_PER_FWHM + 2);
    for order in 1..=2u32 {
        let m = f64::from(order);
        // Order m sends λ/m to the slit's centre; a wavelength λ' of it sits at m λ'
        // on the first-order scale, so its slit width in λ' is FWHM/m.
        let centre = setting.actual_nm / m;
        let half = setting.fwhm_nm / m;
        let n = 2 * NODES_PER_FWHM;
        let h = 2.0 * half / n as f64;
        // Composite midpoint rule over the triangle's support: exact for the
        // piecewise-linear slit function at these nodes, up to the kink at the centre.
        for k in 0..n {
            let nm = centre - half + (k as f64 + 0.5) * h;
            // The slit passes the dimensionless triangle in λ'; over λ' it is FWHM/m
            // wide, so order m carries 1/m of the first order's bandwidth.
            let w = slit(m * nm - setting.actual_nm, setting.fwhm_nm)
                * h
                * planck_relative(nm, setting.lamp_k)
                * blaze_efficiency(nm, setting.blaze_nm, order)
                * filter(nm);
            if w > 0.0 {
                out.push((nm, w));
            }
        }
    }
    out
}

/// The lamp's light through `filter` (a filter wheel's band-pass, and the lamp's
/// cut-on), as `(wavelength nm, weight)` pairs over 250–1200 nm at 0.5 nm: the lamp
/// at `lamp_k` relative to its value at 560 nm, times the transmittance, times the
/// step (so the weights sum to the filter's equivalent width in nm, seen through the
/// lamp's shape). Nodes below 1e-9 of the largest are left out.
pub fn white(lamp_k: f64, filter: &dyn Fn(f64) -> f64) -> Vec<(f64, f64)> {
    const FROM_NM: f64 = 250.0;
    const TO_NM: f64 = 1200.0;
    const STEP_NM: f64 = 0.5;
    let n = ((TO_NM - FROM_NM) / STEP_NM) as usize;
    let all: Vec<(f64, f64)> = (0..=n)
        .map(|k| {
            let nm = FROM_NM + k as f64 * STEP_NM;
            (nm, planck_relative(nm, lamp_k) * filter(nm) * STEP_NM)
        })
        .collect();
    let top = all.iter().map(|p| p.1).fold(0.0, f64::max);
    all.into_iter().filter(|p| p.1 > 1e-9 * top).collect()
}

/// `values` (one per wavelength of `wavelengths_nm`, strictly increasing) at `nm`:
/// a cubic Hermite curve through them whose slope at each wavelength is that of the
/// parabola through it and its two neighbours (the chord's at the ends), held at the
/// end values outside. Smooth (no kink at a tabulated wavelength, which a finite
/// passband would turn into a bias a real spectrum does not have) and exact for
/// quadratics between interior points.
pub fn interpolate(wavelengths_nm: &[f64], values: &[f64], nm: f64) -> f64 {
    let n = wavelengths_nm.len().min(values.len());
    if n == 0 {
        return 0.0;
    }
    let (w, v) = (&wavelengths_nm[..n], &values[..n]);
    if nm <= w[0] {
        return v[0];
    }
    if nm >= w[n - 1] {
        return v[n - 1];
    }
    let k = w.partition_point(|x| *x <= nm);
    // w[k-1] <= nm < w[k], with 1 <= k <= n-1 from the checks above.
    let chord = |a: usize| (v[a + 1] - v[a]) / (w[a + 1] - w[a]);
    let slope = |i: usize| {
        if i == 0 {
            chord(0)
        } else if i == n - 1 {
            chord(n - 2)
        } else {
            let (hl, hr) = (w[i] - w[i - 1], w[i + 1] - w[i]);
            (chord(i - 1) * hr + chord(i) * hl) / (hl + hr)
        }
    };
    let (x0, x1) = (w[k - 1], w[k]);
    let h = x1 - x0;
    let t = (nm - x0) / h;
    let (t2, t3) = (t * t, t * t * t);
    (2.0 * t3 - 3.0 * t2 + 1.0) * v[k - 1]
        + (t3 - 2.0 * t2 + t) * h * slope(k - 1)
        + (-2.0 * t3 + 3.0 * t2) * v[k]
        + (t3 - t2) * h * slope(k)
}
