//! The simulated light path: the detector equation, aperture and divergence averaging,
//! shadowing by the detector arm, overfilling at grazing incidence, drift.

use gonio_brdf::{Brdf, Model};
use gonio_core::radiometry::Aperture;
use gonio_core::{Dir, DirPair, SphericalDeg};
use gonio_sim::optics::{Geometry, LightPath, Optics, OpticsConfig};

fn deg(t: f64, p: f64) -> Dir {
    Dir::from(SphericalDeg::new(t, p))
}

fn lambert() -> Box<dyn Brdf> {
    Box::new(
        Model::from_toml(
            "kind = \"lambert\"\nchannels = [\"value\"]\nrho = [0.8]\n",
            None,
        )
        .expect("valid"),
    )
}

/// A sharp glossy sample: a cosine lobe of exponent 2000 (about 1.8° wide).
fn glossy() -> Box<dyn Brdf> {
    Box::new(
        Model::from_toml(
            "kind = \"phong\"\nchannels = [\"value\"]\nrho_s = [0.5]\nn = [2000]\n",
            None,
        )
        .expect("valid"),
    )
}

#[test]
fn detector_equation() {
    let cfg = OpticsConfig::default();
    let o = Optics::new(cfg.clone(), lambert(), 0);
    let pair = DirPair::new(deg(30.0, 0.0), deg(45.0, 180.0));
    let omega = Aperture {
        radius_m: 0.005,
        distance_m: 0.3,
    }
    .solid_angle_sr();
    assert!((o.solid_angle_sr() - omega).abs() < 1e-18);
    // V = R_v · P · f · cos θo · Ω with f = 0.8/π.
    let want = 1e4 * 1e-3 * (0.8 / std::f64::consts::PI) * 45f64.to_radians().cos() * omega;
    assert!((o.signal(0.0, pair) - want).abs() < 1e-15 * want);
    assert_eq!(o.geometry(pair), Geometry::Clear);
}

#[test]
fn aperture_averaging_smooths_a_specular_peak() {
    let sharp = Optics::new(OpticsConfig::default(), glossy(), 0);
    let avg = Optics::new(
        OpticsConfig {
            integrate_aperture: true,
            beam_divergence_deg: 0.5,
            ..OpticsConfig::default()
        },
        glossy(),
        0,
    );
    let wi = deg(30.0, 0.0);
    let peak = DirPair::new(wi, wi.mirror());
    // At the peak the average over a 0.95° aperture and a 0.5° beam is lower…
    let (p, a) = (sharp.signal(0.0, peak), avg.signal(0.0, peak));
    assert!(a < 0.9 * p && a > 0.3 * p, "{a} vs {p}");
    // …and 2.5° off the peak higher: the peak is spread out, not lost.
    let off = DirPair::new(wi, deg(32.5, 180.0));
    assert!(avg.signal(0.0, off) > sharp.signal(0.0, off));
    // For a Lambertian sample averaging changes nothing but the cos θo variation.
    let l1 = Optics::new(OpticsConfig::default(), lambert(), 0);
    let l2 = Optics::new(
        OpticsConfig {
            integrate_aperture: true,
            ..OpticsConfig::default()
        },
        lambert(),
        0,
    );
    let pair = DirPair::new(deg(20.0, 0.0), deg(40.0, 180.0));
    assert!((l2.signal(0.0, pair) / l1.signal(0.0, pair) - 1.0).abs() < 1e-4);
}

#[test]
fn detector_arm_shadows_the_source() {
    let o = Optics::new(OpticsConfig::default(), lambert(), 0);
    // Retro-reflection: the detector would sit in the beam.
    let wi = deg(40.0, 0.0);
    for (wo, g) in [
        (deg(40.0, 0.0), Geometry::Shadowed),
        (deg(47.0, 0.0), Geometry::Shadowed),
        (deg(49.0, 0.0), Geometry::Clear),
    ] {
        let pair = DirPair::new(wi, wo);
        assert_eq!(o.geometry(pair), g, "{wo:?}");
        assert_eq!(o.signal(0.0, pair) == 0.0, g == Geometry::Shadowed);
    }
    assert_eq!(
        o.geometry(DirPair::new(wi, deg(95.0, 0.0))),
        Geometry::BelowHorizon
    );
}

#[test]
fn beam_overfills_the_sample_at_grazing_incidence() {
    let o = Optics::new(OpticsConfig::default(), lambert(), 0);
    // A 5 mm beam on a 50 mm sample overfills beyond cos θi = 0.1 (84.26°).
    assert_eq!(o.overfill_fraction(deg(84.0, 0.0)), 1.0);
    let f = o.overfill_fraction(deg(87.0, 0.0));
    assert!((f - 10.0 * 87f64.to_radians().cos()).abs() < 1e-15, "{f}");
    let pair = DirPair::new(deg(87.0, 0.0), deg(30.0, 180.0));
    assert_eq!(o.geometry(pair), Geometry::Overfilled);
    let full = Optics::new(
        OpticsConfig {
            sample_length_m: 1.0,
            ..OpticsConfig::default()
        },
        lambert(),
        0,
    );
    assert!((o.signal(0.0, pair) / full.signal(0.0, pair) - f).abs() < 1e-12);
}

#[test]
fn source_drifts() {
    let o = Optics::new(
        OpticsConfig {
            drift_per_hour: 0.01,
            drift_amplitude: 0.002,
            drift_period_s: 600.0,
            ..OpticsConfig::default()
        },
        lambert(),
        0,
    );
    assert_eq!(o.source_power(0.0), 1e-3);
    // After an hour: +1 % linear, and the periodic term back at zero (6 periods).
    assert!((o.source_power(3600.0) - 1.01e-3).abs() < 1e-15);
    // A quarter period in: the periodic term at its peak.
    assert!((o.source_power(150.0) - 1e-3 * (1.0 + 0.01 * 150.0 / 3600.0 + 0.002)).abs() < 1e-15);
}

/// The light paths of the calibrations: dark leaves only pickup; the incident beam
/// through its filter reaches the detector only when it faces the source, and then
/// all of it (the 10 mm aperture takes the whole 5 mm beam).
#[test]
fn calibration_light_paths() {
    let cfg = OpticsConfig {
        pickup_v: 2e-6,
        ..OpticsConfig::default()
    };
    let mut o = Optics::new(cfg, lambert(), 0);
    let pair = DirPair::new(deg(30.0, 0.0), deg(45.0, 180.0));
    let sample = o.signal(0.0, pair);
    assert!(sample > 1e-4, "pickup and reflection: {sample}");
    o.set_light_path(LightPath::Dark);
    assert_eq!(o.signal(0.0, pair), 2e-6);
    o.set_light_path(LightPath::Incident {
        transmittance: 1e-3,
    });
    // Sample removed: reflection is gone, the beam misses this detector position.
    assert_eq!(o.signal(0.0, pair), 2e-6);
    // Detector opposite the source (wo = −wi, below the sample plane).
    let wi = deg(60.0, 0.0);
    let opposite = Dir::new(-wi.vec()).expect("unit");
    let direct = o.signal(0.0, DirPair::new(wi, opposite));
    assert!(
        (direct - (2e-6 + 1e4 * 1e-3 * 1e-3)).abs() < 1e-15,
        "{direct}"
    );
    // 1° off the beam's axis is outside the 0.95° half-angle of the aperture.
    let off = Dir::from(SphericalDeg::new(121.0, 180.0));
    assert_eq!(o.signal(0.0, DirPair::new(wi, off)), 2e-6);
    o.set_light_path(LightPath::Sample);
    assert_eq!(o.signal(0.0, pair), sample);
}

/// A reference standard swapped in is measured, and the sample comes back.
#[test]
fn swapping_the_sample() {
    let mut o = Optics::new(OpticsConfig::default(), glossy(), 0);
    let pair = DirPair::new(deg(30.0, 0.0), deg(30.0, 180.0));
    let glossy_v = o.signal(0.0, pair);
    let (old, ch) = o.swap_sample(lambert(), 0);
    let omega = o.solid_angle_sr();
    let want = 1e4 * 1e-3 * (0.8 / std::f64::consts::PI) * 30f64.to_radians().cos() * omega;
    assert!((o.signal(0.0, pair) - want).abs() < 1e-15);
    o.swap_sample(old, ch);
    assert_eq!(o.signal(0.0, pair), glossy_v);
}
