//! The instrument's bookkeeping closes: a detector stepped over the whole hemisphere,
//! each position collecting `Φ_r = f_r Φ_i Ω cos θo` (DeYoung Eq. A.15 through
//! `gonio_core::radiometry`), collects in total the albedo times the incident flux; and
//! a finite aperture reports the projected-solid-angle average of the model, which the
//! usual `Ω cos θo` reduction biases by a known factor.

use gonio_brdf::{Brdf, Model};
use gonio_core::quad::{Tolerance, integrate_2d};
use gonio_core::radiometry::{
    Aperture, brdf_from_flux_ratio, cone_projected_solid_angle_sr, reflected_flux,
};
use gonio_core::{Dir, Frame, SphericalDeg, Vec3};

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
    for name in ["minnaert-matte.toml", "blue-paint-550nm.toml"] {
        let m = load(name);
        for t in [0.0, 30.0, 60.0] {
            let wi = Dir::from(SphericalDeg::new(t, 0.0));
            let mut a = vec![0.0; m.channels().len()];
            m.albedo(wi, &mut a);
            let got = collected_fraction(&m, wi);
            assert!(
                (got - a[0]).abs() < 2e-5,
                "{name} θi={t}: scan {got} vs albedo {}",
                a[0]
            );
        }
    }
}

/// The flux a circular aperture of half-angle `a` about `axis` collects, per unit
/// incident flux: `∫_cone f_r cos θ dω`, by cubature over the cone.
fn aperture_flux(m: &Model, wi: Dir, axis: Dir, a: f64) -> f64 {
    let frame = Frame::from_normal(axis);
    let mut f = vec![0.0; m.channels().len()];
    integrate_2d(
        |alpha, beta, out| {
            let (sa, ca) = alpha.sin_cos();
            let local = Vec3::new(sa * beta.cos(), sa * beta.sin(), ca);
            let wo = frame.dir_to_parent(Dir::new(local).expect("unit"));
            m.eval(wi, wo, &mut f);
            out[0] = f[0] * wo.z.max(0.0) * sa;
        },
        [0.0, a],
        [0.0, std::f64::consts::TAU],
        1,
        Tolerance::new(1e-16, 1e-12),
    )
    .values[0]
}

#[test]
fn finite_aperture_reduction() {
    // A 10 mm aperture at 100 mm: a cone of 2.86° half-angle, Ω = 7.8e-3 sr.
    let ap = Aperture {
        radius_m: 0.005,
        distance_m: 0.1,
    };
    let (a, omega) = (ap.half_angle(), ap.solid_angle_sr());
    let wi = Dir::from(SphericalDeg::new(20.0, 0.0));
    let wo = Dir::from(SphericalDeg::new(50.0, 180.0));

    // Lambertian sample: the collected flux is ρ/π times the cone's projected solid
    // angle π sin²a cos θ, so reducing with the projected solid angle gives ρ/π
    // exactly, and the usual Ω cos θo reduction reads low by (1 + cos a)/2.
    let white = load("white-reference.toml");
    let flux = aperture_flux(&white, wi, wo, a);
    let proj = cone_projected_solid_angle_sr(a, wo.theta());
    let rho_pi = 0.99 / std::f64::consts::PI;
    assert!((flux / proj - rho_pi).abs() < 1e-12 * rho_pi);
    let naive = brdf_from_flux_ratio(flux, 1.0, omega, wo.z);
    assert!((naive / rho_pi - (1.0 + a.cos()) / 2.0).abs() < 1e-10);

    // The blue paint near its forward off-specular peak (lobe III, n = 63.8): the
    // aperture average falls below the centre value (a 2.3% bias at this aperture),
    // at second order in a, so it shrinks four-fold when the aperture halves.
    let paint = load("blue-paint-550nm.toml");
    let (wi, wo) = (
        Dir::from(SphericalDeg::new(65.0, 0.0)),
        Dir::from(SphericalDeg::new(70.0, 180.0)),
    );
    let mut centre = [0.0];
    paint.eval(wi, wo, &mut centre);
    let dev = |a: f64| {
        let avg = aperture_flux(&paint, wi, wo, a) / cone_projected_solid_angle_sr(a, wo.theta());
        avg / centre[0] - 1.0
    };
    let (d1, d2) = (dev(a), dev(0.5 * a));
    assert!(d1 < -1e-3 && d1 > -0.05, "{d1}");
    assert!((d1 / d2 - 4.0).abs() < 0.1, "second order: {d1} vs {d2}");
}
