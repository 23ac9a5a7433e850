//! The light model of the band selectors (`gonio_sim::spectral`): the lamp, the
//! grating's orders, the slit, white light through a filter, interpolation.

use std::f64::consts::PI;

use gonio_sim::spectral::{
    C2_M_K, Setting, blaze_efficiency, interpolate, longpass, passband, planck_relative, slit,
    white,
};

#[test]
fn planck_matches_wiens_displacement_and_its_own_ratio() {
    // Wien: λ_max T = 2.897 771 955e-3 m·K (CODATA 2018).
    let t = 3000.0;
    let peak = 2.897_771_955e-3 / t * 1e9;
    let at = |d: f64| planck_relative(peak + d, t);
    assert!(at(0.0) > at(1.0) && at(0.0) > at(-1.0));
    assert!((planck_relative(560.0, t) - 1.0).abs() < 1e-15);
    // The ratio at 700 and 350 nm from Planck's law written out.
    let x = |nm: f64| C2_M_K / (nm * 1e-9 * t);
    let want = (700.0f64 / 350.0).powi(5) * x(700.0).exp_m1() / x(350.0).exp_m1();
    let got = planck_relative(350.0, t) / planck_relative(700.0, t);
    assert!((got / want - 1.0).abs() < 1e-12, "{got} vs {want}");
}

#[test]
fn blaze_efficiency_peaks_at_the_blaze_in_each_order() {
    assert_eq!(blaze_efficiency(500.0, 500.0, 1), 1.0);
    assert!((blaze_efficiency(250.0, 500.0, 2) - 1.0).abs() < 1e-12);
    // A zero of sinc²: m − λB/λ = ±1 → λ = λB/2 in order 1 (second order's peak).
    assert!(blaze_efficiency(250.0, 500.0, 1) < 1e-24);
    // At λ = λB/1.5, m − λB/λ = −1/2 and sinc²(−π/2) = 4/π².
    let v = blaze_efficiency(500.0 / 1.5, 500.0, 1);
    assert!((v - 4.0 / (PI * PI)).abs() < 1e-12, "{v}");
}

#[test]
fn slit_function_has_unit_area_and_its_fwhm() {
    let f = 4.0;
    let n = 100_000;
    let h = 2.0 * f / n as f64;
    let area: f64 = (0..n).map(|k| slit(-f + (k as f64 + 0.5) * h, f) * h).sum();
    assert!((area - 1.0).abs() < 1e-9, "{area}");
    assert!((slit(f / 2.0, f) / slit(0.0, f) - 0.5).abs() < 1e-15);
    assert_eq!(slit(f, f), 0.0);
}

#[test]
fn passband_integrates_to_lamp_times_grating_and_holds_second_order_at_half() {
    let s = Setting {
        actual_nm: 700.0,
        fwhm_nm: 4.0,
        blaze_nm: 500.0,
        lamp_k: 3100.0,
        shutter_open: true,
    };
    let open = passband(&s, &|_| 1.0);
    let (first, second): (Vec<_>, Vec<_>) = open.iter().partition(|(nm, _)| *nm > 500.0);
    let sum = |v: &[&(f64, f64)]| v.iter().map(|(_, w)| *w).sum::<f64>();
    // Over a 4 nm passband the lamp and grating are nearly linear: the sum is
    // their product at the centre to well under 0.1 %.
    let want1 = planck_relative(700.0, 3100.0) * blaze_efficiency(700.0, 500.0, 1);
    assert!(
        (sum(&first) / want1 - 1.0).abs() < 1e-3,
        "{} {want1}",
        sum(&first)
    );
    // The second order spans λ/2 ± FWHM/2: half the first order's bandwidth, so
    // it carries L(350) η₂(350) / 2.
    let want2 = planck_relative(350.0, 3100.0) * blaze_efficiency(350.0, 500.0, 2) / 2.0;
    assert!(
        (sum(&second) / want2 - 1.0).abs() < 2e-3,
        "{} {want2}",
        sum(&second)
    );
    assert!(second.iter().all(|(nm, _)| (nm - 350.0).abs() <= 2.0));
    // A long-pass at 495 nm takes the second order out and leaves the first.
    let sorted = passband(&s, &|nm| longpass(nm, 495.0, 10.0, 1.0));
    let leak: f64 = sorted
        .iter()
        .filter(|(nm, _)| *nm < 500.0)
        .map(|p| p.1)
        .sum();
    assert!(leak < 1e-12 * want2, "{leak}");
    let closed = Setting {
        shutter_open: false,
        ..s
    };
    assert!(passband(&closed, &|_| 1.0).is_empty());
}

#[test]
fn white_light_through_a_gaussian_band_pass_has_its_equivalent_width() {
    // A Gaussian of FWHM w has equivalent width w √(π / (4 ln 2)); through a flat
    // lamp (a very hot one is nearly flat over a few nm) the weights sum to it.
    let (c, w) = (550.0, 10.0);
    let s = w / (8.0 * 2f64.ln()).sqrt();
    let g = |nm: f64| (-0.5 * ((nm - c) / s).powi(2)).exp();
    let sum: f64 = white(2.897_771_955e-3 / 560e-9, &g)
        .iter()
        .map(|p| p.1)
        .sum();
    let want = w * (PI / (4.0 * 2f64.ln())).sqrt();
    assert!((sum / want - 1.0).abs() < 2e-3, "{sum} vs {want}");
    assert!(white(3000.0, &|_| 0.0).is_empty());
}

#[test]
fn interpolation_is_smooth_exact_for_quadratics_and_holds_outside() {
    let w = [400.0, 430.0, 500.0, 520.0, 600.0];
    let q = |x: f64| 0.3 + 2e-3 * (x - 450.0) - 3e-5 * (x - 450.0).powi(2);
    let v: Vec<f64> = w.iter().map(|x| q(*x)).collect();
    // Between interior points both slopes are the parabola's: exact.
    for x in [431.0, 467.5, 499.0, 505.0, 519.9] {
        assert!((interpolate(&w, &v, x) - q(x)).abs() < 1e-14, "{x}");
    }
    for (x, y) in w.iter().zip(&v) {
        assert_eq!(interpolate(&w, &v, *x), *y);
    }
    assert_eq!(interpolate(&w, &v, 350.0), v[0]);
    assert_eq!(interpolate(&w, &v, 650.0), v[4]);
    // A straight line stays straight.
    let l: Vec<f64> = w.iter().map(|x| 1.0 - 1e-3 * x).collect();
    assert!((interpolate(&w, &l, 555.0) - (1.0 - 0.555)).abs() < 1e-14);
    // No kink: the one-sided slopes at a tabulated wavelength agree.
    let d = 1e-6;
    let left = (interpolate(&w, &v, 500.0) - interpolate(&w, &v, 500.0 - d)) / d;
    let right = (interpolate(&w, &v, 500.0 + d) - interpolate(&w, &v, 500.0)) / d;
    assert!((left - right).abs() < 1e-6, "{left} {right}");
}
