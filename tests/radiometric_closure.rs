//! The instrument's bookkeeping closes: a detector stepped over the whole hemisphere,
//! each position collecting `Φ_r = f_r Φ_i Ω cos θo` (DeYoung Eq. A.15 through
//! `gonio_core::radiometry`), collects in total the albedo times the incident flux; and
//! the BRDF a finite aperture reports is the aperture average of the model.

use gonio_brdf::{Brdf, Model};
use gonio_core::radiometry::{Aperture, brdf_from_flux_ratio, reflected_flux};
use gonio_core::{Dir, SphericalDeg};

fn load(name: &str) -> Model {
    Model::load(&gonio_e2e::config_dir().join("models").join(name)).expect("shipped model loads")
}

/// Sum over a 0.25° × 1° grid of detector patches (exact patch solid angles).
fn collected_fraction(m: &Model, wi: Dir) -> f64 {
    let (nt, np) = (360, 360);
    let incident_w = 1.0e-3;
    let mut total = 0.0;
    let mut f = vec![0.0; m.channels().len()];
    for it in 0..nt {
        let (t0, t1) = (
            f64::to_radians(90.0 * it as f64 / nt as f64),
            f64::to_radians(90.0 * (it + 1) as f64 / nt as f64),
        );
        let omega = (t0.cos() - t1.cos()) * std::f64::consts::TAU / np as f64;
        let tc = 0.5 * (t0 + t1);
        for ip in 0..np {
            let pc = (ip as f64 + 0.5) / np as f64 * 360.0;
            let wo = Dir::from(SphericalDeg::new(tc.to_degrees(), pc));
            m.eval(wi, wo, &mut f);
            total += reflected_flux(f[0], incident_w, omega, wo.z);
        }
    }
    total / incident_w
}

#[test]
fn detector_scan_collects_the_albedo() {
    // Broad lobes, so that a midpoint grid is accurate: Minnaert and the Table 1 paint
    // (its sharpest lobe has n = 63.8).
    for (name, tol) in [
        ("minnaert-matte.toml", 2e-5),
        ("blue-paint-550nm.toml", 2e-5),
    ] {
        let m = load(name);
        for t in [0.0, 30.0, 60.0] {
            let wi = Dir::from(SphericalDeg::new(t, 0.0));
            let mut a = vec![0.0; m.channels().len()];
            m.albedo(wi, &mut a);
            let got = collected_fraction(&m, wi);
            assert!(
                (got - a[0]).abs() < tol,
                "{name} θi={t}: scan {got} vs albedo {}",
                a[0]
            );
        }
    }
}

#[test]
fn finite_aperture_reports_the_aperture_average() {
    // A 10 mm aperture at 300 mm: Ω = 8.7e-4 sr, a cone of 0.95° half-angle. For a
    // Lambertian sample the reported BRDF is exactly ρ/π whatever the aperture.
    let m = load("white-reference.toml");
    let ap = Aperture {
        radius_m: 0.005,
        distance_m: 0.3,
    };
    let omega = ap.solid_angle_sr();
    let wi = Dir::from(SphericalDeg::new(20.0, 0.0));
    let wo = Dir::from(SphericalDeg::new(50.0, 180.0));
    let mut f = vec![0.0; 3];
    m.eval(wi, wo, &mut f);
    let phi_r = reflected_flux(f[1], 2.0, omega, wo.z);
    let reported = brdf_from_flux_ratio(phi_r, 2.0, omega, wo.z);
    assert!((reported - 0.99 / std::f64::consts::PI).abs() < 1e-15);
    // The small-aperture formula A/d² would bias every BRDF by the ratio of solid angles.
    let bias = ap.solid_angle_small_sr() / omega - 1.0;
    assert!(
        (bias - 0.75 * (0.005f64 / 0.3).powi(2)).abs() < 1e-7,
        "{bias}"
    );
}
