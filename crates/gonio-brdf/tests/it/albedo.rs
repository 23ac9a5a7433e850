//! Directional albedo: closed forms, the semi-analytic lobe integral against the
//! generic cubature, published values, and Lafortune et al.'s observations.

use crate::common;

use std::f64::consts::PI;

use common::{deg, zoo};
use gonio_brdf::albedo::{DEFAULT_TOLERANCE, integrate};
use gonio_brdf::{
    BlinnPhong, Brdf, CookTorrance, Diffuse, Distribution, Lafortune, LafortuneLobe, Mirror, Model,
    Phong, PhongNormalization,
};
use gonio_core::Channels;

const THETAS: [f64; 7] = [0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 89.0];

fn albedo1(m: &dyn Brdf, theta: f64) -> f64 {
    let mut a = vec![0.0; m.channels().len()];
    m.albedo(deg(theta, 0.0), &mut a);
    a[0]
}

fn numeric1(m: &dyn Brdf, theta: f64) -> f64 {
    let e = integrate(m, deg(theta, 0.0), DEFAULT_TOLERANCE);
    assert!(e.converged, "cubature did not converge: {e:?}");
    e.values[0]
}

fn single() -> Channels {
    Channels::Single
}

/// A classical cosine lobe as an Eq. 4 lobe: −Cx = −Cy = Cz = C_s^{1/n}.
fn cosine_as_lafortune(rho_s: f64, n: f64) -> Lafortune {
    let c = (rho_s * (n + 2.0) / (2.0 * PI)).powf(1.0 / n);
    let lobe = LafortuneLobe::diagonal(&single(), &[-c], &[-c], &[c], &[n]).expect("valid");
    Lafortune::new(single(), vec![lobe]).expect("one channel")
}

#[test]
fn lambert_albedo_is_rho_at_every_angle() {
    let m = Diffuse::lambert(Channels::Rgb, vec![0.2, 0.5, 0.8]).expect("valid");
    for t in THETAS {
        let mut a = [0.0; 3];
        m.albedo(deg(t, 0.0), &mut a);
        assert_eq!(a, [0.2, 0.5, 0.8]);
        let e = integrate(&m, deg(t, 0.0), DEFAULT_TOLERANCE);
        for (got, want) in e.values.iter().zip([0.2, 0.5, 0.8]) {
            assert!((got - want).abs() < 1e-12, "θ={t}: {got}");
        }
    }
}

#[test]
fn minnaert_albedo_is_rho_cos_to_the_n() {
    let m = Diffuse::minnaert(single(), vec![0.8], vec![0.5]).expect("valid");
    for t in THETAS {
        let want = 0.8 * f64::to_radians(t).cos().powf(0.5);
        assert!((albedo1(&m, t) - want).abs() < 1e-15);
        assert!((numeric1(&m, t) - want).abs() < 1e-9, "θ={t}");
    }
}

/// Eq. 1 with `C_s = (n+2)/(2π)`: ρs is the albedo at normal incidence, exactly.
#[test]
fn normalised_cosine_lobe_has_albedo_one_at_normal_incidence() {
    for n in [0.5, 1.0, 10.0, 100.0, 1000.0] {
        let m = Phong::new(
            single(),
            vec![1.0],
            vec![n],
            PhongNormalization::Albedo,
            false,
        )
        .expect("valid");
        assert!((albedo1(&m, 0.0) - 1.0).abs() < 1e-13, "n={n}");
        assert!((numeric1(&m, 0.0) - 1.0).abs() < 1e-8, "n={n}");
        let l = cosine_as_lafortune(1.0, n);
        assert!((albedo1(&l, 0.0) - 1.0).abs() < 1e-12, "lafortune n={n}");
    }
}

/// The exact lobe integral and the generic cubature are independent computations; they
/// agree far inside the 1e-4 the albedo must reach, up to exponent 1000.
#[test]
fn lobe_albedo_agrees_with_cubature_up_to_exponent_1000() {
    for n in [1.0, 10.0, 100.0, 1000.0] {
        for ratio in [1.0, 0.95, 0.8] {
            // Off-specular lobes too (Cz/Cx < 1, Sec. 5.3).
            let c = (n + 2.0) / (2.0 * PI);
            let cx = c.powf(1.0 / n);
            let lobe = LafortuneLobe::diagonal(&single(), &[-cx], &[-cx], &[ratio * cx], &[n])
                .expect("valid");
            let m = Lafortune::new(single(), vec![lobe]).expect("one channel");
            for t in THETAS {
                let exact = albedo1(&m, t);
                let cub = numeric1(&m, t);
                assert!(
                    (exact - cub).abs() < 5e-9 * exact.max(1.0),
                    "n={n} Cz/Cx={ratio} θ={t}: exact {exact} vs cubature {cub}"
                );
            }
        }
    }
}

/// The blue paint of Table 1: albedo by mpmath's tanh-sinh quadrature of Eq. 8 over the
/// hemisphere at 20 digits (`tests/reference/table1.py`).
#[test]
fn table1_albedo_matches_reference_quadrature() {
    let m = Model::from_toml(common::TABLE1, None).expect("valid");
    for (t, want) in [(0.0, 0.410810984534), (30.0, 0.418024770928)] {
        let got = albedo1(&m, t);
        assert!((got - want).abs() < 2e-12, "θ={t}: {got} vs {want}");
    }
}

/// Eq. 7 with `C_s = (n+1)/(2π)`: the mirror reflects `R_m (ρs − ρs(u))`. At normal
/// incidence the lobe's albedo is `ρs (n+1)/(n+2)`, so the mirror adds `R_m ρs/(n+2)`.
#[test]
fn mirror_term_takes_the_power_the_lobe_loses() {
    let (rho_s, n, rm) = (0.2, 20.0, 0.4);
    let m = Phong::new(
        single(),
        vec![rho_s],
        vec![n],
        PhongNormalization::Power,
        false,
    )
    .expect("valid")
    .with_mirror(Mirror::new(&single(), vec![rm]).expect("valid"))
    .expect("one channel");
    let mut mir = [0.0];
    assert!(m.mirror(deg(0.0, 0.0), &mut mir));
    assert!((mir[0] - rm * rho_s / (n + 2.0)).abs() < 1e-15);
    assert!((albedo1(&m, 0.0) - rho_s * ((n + 1.0) / (n + 2.0) + rm / (n + 2.0))).abs() < 1e-14);
    // Towards grazing the lobe loses more and the mirror takes over (Fig. 7b).
    let mut prev = mir[0];
    for t in [30.0, 60.0, 80.0, 89.0] {
        m.mirror(deg(t, 0.0), &mut mir);
        assert!(mir[0] > prev, "θ={t}");
        prev = mir[0];
    }
    // Total albedo never exceeds ρs: lobe + R_m·(ρs − lobe) ≤ ρs.
    for t in THETAS {
        assert!(albedo1(&m, t) <= rho_s + 1e-15);
    }
}

/// Fig. 4b: the classical lobe (ρs = 0.2, n = 20) loses albedo towards grazing incidence,
/// as cos θ while the horizon does not cut it.
#[test]
fn classical_lobe_albedo_falls_towards_grazing() {
    let m = cosine_as_lafortune(0.2, 20.0);
    let a0 = albedo1(&m, 0.0);
    let mut prev = a0;
    for t in (5..=89).step_by(5) {
        let a = albedo1(&m, t as f64);
        assert!(a < prev, "θ={t}");
        prev = a;
    }
    for t in [15.0, 30.0, 45.0] {
        let r = albedo1(&m, t) / a0;
        assert!((r - f64::to_radians(t).cos()).abs() < 1e-3, "θ={t}: {r}");
    }
    assert!((albedo1(&m, 60.0) / a0 - 0.5005).abs() < 1e-3);
    assert!(albedo1(&m, 85.0) / a0 < 0.15);
}

/// Fig. 9: with Cz/Cx = 0.95 the lobe is off-specular and grows towards grazing, so its
/// albedo rises first and falls only late.
#[test]
fn off_specular_lobe_albedo_falls_only_late() {
    let classic = cosine_as_lafortune(0.2, 20.0);
    let c = (0.2 * 22.0 / (2.0 * PI)).powf(1.0 / 20.0);
    let lobe =
        LafortuneLobe::diagonal(&single(), &[-c], &[-c], &[0.95 * c], &[20.0]).expect("valid");
    let m = Lafortune::new(single(), vec![lobe]).expect("one channel");
    let a0 = albedo1(&m, 0.0);
    let r = |t: f64| albedo1(&m, t) / a0;
    let rc = |t: f64| albedo1(&classic, t) / albedo1(&classic, 0.0);
    for t in [15.0, 30.0, 45.0, 60.0] {
        assert!(r(t) > 1.0, "θ={t}: {}", r(t));
    }
    assert!(r(45.0) > 1.15 && r(45.0) < 1.18, "{}", r(45.0));
    assert!(r(70.0) > 2.0 * rc(70.0));
    let mut prev = r(60.0);
    for t in [65.0, 70.0, 75.0, 80.0, 85.0, 89.0] {
        assert!(r(t) < prev, "θ={t}");
        prev = r(t);
    }
}

/// The specular term's albedo at normal incidence is ρs exactly, for every exponent.
#[test]
fn blinn_phong_normalisation_is_exact() {
    for n in [0.0, 1.0, 10.0, 100.0, 1000.0] {
        let m = BlinnPhong::new(single(), vec![1.0], vec![n]).expect("valid");
        let a = numeric1(&m, 0.0);
        assert!((a - 1.0).abs() < 1e-7, "n={n}: {a}");
    }
}

/// A microfacet model with F ≤ 1 cannot create energy: G2 ≤ G1 and
/// ∫ G1(wi) ⟨wi·h⟩ D(h)/cos θi dωh = 1. Near α → 0 it approaches 1.
#[test]
fn cook_torrance_conserves_energy() {
    for dist in [Distribution::Beckmann, Distribution::Ggx] {
        for alpha in [0.05, 0.3, 0.8] {
            let m = CookTorrance::new(
                single(),
                dist,
                vec![1.0],
                vec![alpha],
                vec![alpha],
                vec![1.0],
            )
            .expect("valid");
            for t in THETAS {
                let a = numeric1(&m, t);
                assert!(a <= 1.0 + 1e-7 && a > 0.3, "{dist:?} α={alpha} θ={t}: {a}");
            }
            if alpha == 0.05 {
                assert!(numeric1(&m, 0.0) > 0.995);
            }
        }
    }
}

/// The models whose albedo has its own closed or semi-analytic form (Lambert,
/// Minnaert, the cosine lobes, Lafortune lobes, and their mirror terms) agree with the
/// generic cubature, which shares none of that code; and no model except Ward's and
/// the shading variant creates energy for these parameters.
#[test]
fn zoo_albedos_are_consistent() {
    let closed_form = [
        "lambert",
        "minnaert",
        "phong",
        "phong-mirror",
        "phong-shading",
    ];
    for (name, m) in zoo() {
        let k = m.channels().len();
        let mut a = vec![0.0; k];
        let mut mirror = vec![0.0; k];
        for t in [0.0, 40.0, 80.0] {
            let wi = deg(t, 20.0);
            m.albedo(wi, &mut a);
            if closed_form.contains(&name) || name.starts_with("lafortune") {
                let e = integrate(&m, wi, DEFAULT_TOLERANCE);
                let has = m.mirror(wi, &mut mirror);
                for c in 0..k {
                    let cub = e.values[c] + if has { mirror[c] } else { 0.0 };
                    assert!((a[c] - cub).abs() < 1e-8, "{name} θ={t}: {} vs {cub}", a[c]);
                }
            }
            if !name.starts_with("ward") && name != "phong-shading" {
                assert!(a.iter().all(|v| *v <= 1.0), "{name} θ={t}: albedo {a:?}");
            }
        }
    }
}

/// With F0 = 0 the Fresnel factor vanishes only for facets facing the light head-on;
/// at normal incidence the model still reflects, samples and integrates.
#[test]
fn cook_torrance_with_zero_f0_still_reflects_at_normal_incidence() {
    let m = CookTorrance::new(
        single(),
        Distribution::Ggx,
        vec![0.0],
        vec![0.5],
        vec![0.5],
        vec![1.0],
    )
    .expect("valid");
    let wi = deg(0.0, 0.0);
    let a = numeric1(&m, 0.0);
    assert!(a > 1e-5, "albedo {a}");
    assert!(m.sample(wi, 0.5, [0.3, 0.7]).is_some());
    // Brute force in (θo, φo) agrees.
    let brute = gonio_core::quad::integrate_2d(
        |t, p, out| {
            let wo = gonio_core::Dir::from_angles(t, p);
            let mut f = [0.0];
            m.eval(wi, wo, &mut f);
            out[0] = f[0] * wo.z * t.sin();
        },
        [0.0, 0.5 * PI],
        [0.0, 2.0 * PI],
        1,
        gonio_core::quad::Tolerance::new(1e-12, 1e-10),
    );
    assert!(
        (a - brute.values[0]).abs() < 1e-8,
        "{a} vs {}",
        brute.values[0]
    );
}
