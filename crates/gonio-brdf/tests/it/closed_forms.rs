//! Values of `f_r` at directions where the models have closed forms, and the seed
//! model of Table 1 at hand-computed directions.

use crate::common;

use std::f64::consts::PI;

use common::{deg, random_dir, rng};
use gonio_brdf::{
    BlinnPhong, Brdf, CookTorrance, Diffuse, Distribution, Lafortune, LafortuneLobe, Model,
    OrenNayar, OrenNayarVariant, Phong, PhongNormalization, Sym3, Ward,
};
use gonio_core::Channels;

fn eval1(m: &dyn Brdf, wi: gonio_core::Dir, wo: gonio_core::Dir) -> f64 {
    let mut a = vec![0.0; m.channels().len()];
    m.eval(wi, wo, &mut a);
    a[0]
}

/// Eq. 8 at 550 nm with Table 1's coefficients, evaluated independently by mpmath at 30
/// digits (`tests/reference/table1.py`).
#[test]
fn table1_blue_paint_at_hand_computed_directions() {
    let m = Model::from_toml(common::TABLE1, None).expect("valid");
    let cases = [
        ((0.0, 0.0), (0.0, 0.0), 0.13777128125142845398),
        ((35.0, 0.0), (35.0, 180.0), 0.13710368772512167934),
        ((65.0, 0.0), (65.0, 0.0), 0.17258492526298180777),
        ((65.0, 0.0), (80.0, 180.0), 0.35528470225034492222),
        ((30.0, 45.0), (50.0, 200.0), 0.13779297690968638419),
        ((70.0, 0.0), (60.0, 180.0), 0.25469445873563633592),
    ];
    for (i, o, want) in cases {
        let got = eval1(&m, deg(i.0, i.1), deg(o.0, o.1));
        assert!((got - want).abs() < 2e-15, "{i:?} → {o:?}: {got} vs {want}");
    }
    // The retro-reflective lobe I (Cx > 0) makes back-scatter exceed the diffuse level,
    // increasingly towards grazing (Sec. 6.2).
    let back = |t: f64| eval1(&m, deg(t, 0.0), deg(t, 0.0));
    assert!(back(65.0) > back(35.0) && back(35.0) > 0.13);
}

/// Lafortune Eq. 4 reduces to the classical cosine lobe of Eq. 1 for
/// −Cx = −Cy = Cz = C_s^{1/n}.
#[test]
fn eq4_reduces_to_the_cosine_lobe() {
    let ch = Channels::Single;
    let mut r = rng(7);
    for (rho_s, n) in [(1.0, 1.0), (0.2, 20.0), (0.7, 150.0), (0.5, 2.58)] {
        let phong = Phong::new(
            ch.clone(),
            vec![rho_s],
            vec![n],
            PhongNormalization::Albedo,
            false,
        )
        .expect("valid");
        let cs: f64 = rho_s * (n + 2.0) / (2.0 * PI);
        let c = cs.powf(1.0 / n);
        let lobe = LafortuneLobe::diagonal(&ch, &[-c], &[-c], &[c], &[n]).expect("valid");
        let laf = Lafortune::new(ch.clone(), vec![lobe]).expect("one channel");
        for _ in 0..2000 {
            let (wi, wo) = (random_dir(&mut r), random_dir(&mut r));
            let (a, b) = (eval1(&phong, wi, wo), eval1(&laf, wi, wo));
            // Relative to the value, or to a millionth of the peak C_s where the lobe is
            // so small that the rounding of uᵀMv near zero, raised to the n-th power,
            // dominates.
            assert!(
                (a - b).abs() <= 1e-12 * a.max(1e-6 * cs),
                "n={n}: {a} vs {b}"
            );
        }
    }
}

/// Eq. 3 with a diagonal matrix is Eq. 4; a rotated anisotropic lobe `QᵀDQ` (Sec. 4.2)
/// evaluates to the diagonal lobe in the rotated frame.
#[test]
fn eq3_matrix_lobes() {
    let ch = Channels::Single;
    let (cx, cy, cz, n) = (-0.9, -0.5, 0.8, 12.0);
    let diag = LafortuneLobe::diagonal(&ch, &[cx], &[cy], &[cz], &[n]).expect("valid");
    // Rotation by 30° about the normal: M = R D Rᵀ.
    let (s, c) = f64::to_radians(30.0).sin_cos();
    let rot = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]];
    let d = [cx, cy, cz];
    let mut mm = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            mm[i][j] = (0..3).map(|k| rot[i][k] * d[k] * rot[j][k]).sum();
        }
    }
    let full =
        LafortuneLobe::from_matrices(&ch, vec![Sym3::from_rows(mm).expect("symmetric")], vec![n])
            .expect("valid");
    let (a, b) = (
        Lafortune::new(ch.clone(), vec![diag]).expect("one channel"),
        Lafortune::new(ch, vec![full]).expect("one channel"),
    );
    let mut r = rng(8);
    for _ in 0..2000 {
        let (wi, wo) = (random_dir(&mut r), random_dir(&mut r));
        let rotated = |v: gonio_core::Dir| v.rotate_about_normal(-30f64.to_radians());
        let (x, y) = (eval1(&b, wi, wo), eval1(&a, rotated(wi), rotated(wo)));
        assert!((x - y).abs() <= 1e-12 * x.max(1e-12), "{x} vs {y}");
    }
    assert!(Sym3::from_rows([[1.0, 0.1, 0.0], [0.2, 1.0, 0.0], [0.0, 0.0, 1.0]]).is_none());
}

/// Cook–Torrance at normal incidence and normal view: `h = n`, `D(n) = 1/(π α²)` for
/// both distributions, `Λ(n) = 0` so `G2 = 1`, and `F = F0`: `f = F0 / (4π α²)`.
#[test]
fn cook_torrance_at_the_normal() {
    for dist in [Distribution::Beckmann, Distribution::Ggx] {
        for (f0, a) in [(0.04, 0.1), (0.9, 0.5)] {
            let m = CookTorrance::new(
                Channels::Single,
                dist,
                vec![f0],
                vec![a],
                vec![a],
                vec![1.0],
            )
            .expect("valid");
            let got = eval1(&m, deg(0.0, 0.0), deg(0.0, 0.0));
            let want = f0 / (4.0 * PI * a * a);
            assert!(
                (got - want).abs() < 1e-15 * want,
                "{dist:?}: {got} vs {want}"
            );
        }
    }
    // Off the normal, in the mirror configuration at 60°: h = n still, F from cos 60° = ½,
    // and G2 = 1/(1 + 2Λ(60°)) with GGX's Λ = (√(1 + α² tan²θ) − 1)/2.
    let (f0, a) = (0.04, 0.3);
    let m = CookTorrance::new(
        Channels::Single,
        Distribution::Ggx,
        vec![f0],
        vec![a],
        vec![a],
        vec![1.0],
    )
    .expect("valid");
    let got = eval1(&m, deg(60.0, 0.0), deg(60.0, 180.0));
    let lam = ((1.0 + a * a * 3.0f64).sqrt() - 1.0) / 2.0;
    let f = f0 + (1.0 - f0) * 0.5f64.powi(5);
    let want = f / (PI * a * a) / (1.0 + 2.0 * lam) / (4.0 * 0.25);
    assert!((got - want).abs() < 1e-14 * want, "{got} vs {want}");
}

/// Ward at the mirror configuration: `θh = 0`, so `f = ρs / (4π αx αy cos θi)`.
#[test]
fn ward_at_the_mirror_direction() {
    let m = Ward::new(Channels::Single, vec![0.05], vec![0.1], vec![0.3]).expect("valid");
    for t in [0.0, 30.0, 70.0] {
        let got = eval1(&m, deg(t, 10.0), deg(t, 190.0));
        let want = 0.05 / (4.0 * PI * 0.1 * 0.3 * f64::to_radians(t).cos());
        assert!((got - want).abs() < 1e-14 * want);
    }
}

/// Oren–Nayar with β = 0 (normal incidence): `f = ρ/π C1 + 0.17 ρ²/π σ²/(σ²+0.13)`;
/// σ = 0 is Lambert.
#[test]
fn oren_nayar_limits() {
    let (rho, sdeg) = (0.8, 30.0);
    let m = OrenNayar::new(
        Channels::Single,
        vec![rho],
        vec![sdeg],
        OrenNayarVariant::Full,
    )
    .expect("valid");
    let s2 = f64::to_radians(sdeg).powi(2);
    let want = rho / PI * (1.0 - 0.5 * s2 / (s2 + 0.33)) + 0.17 * rho * rho / PI * s2 / (s2 + 0.13);
    for to in [0.0, 40.0, 80.0] {
        let got = eval1(&m, deg(0.0, 0.0), deg(to, 123.0));
        assert!((got - want).abs() < 1e-15, "θo={to}: {got} vs {want}");
    }
    let smooth = OrenNayar::new(
        Channels::Single,
        vec![rho],
        vec![0.0],
        OrenNayarVariant::Full,
    )
    .expect("valid");
    let lambert = Diffuse::lambert(Channels::Single, vec![rho]).expect("valid");
    let mut r = rng(9);
    for _ in 0..500 {
        let (wi, wo) = (random_dir(&mut r), random_dir(&mut r));
        assert!((eval1(&smooth, wi, wo) - eval1(&lambert, wi, wo)).abs() < 1e-16);
    }
    // The qualitative model brightens back-scatter: at θi = θo = 60°, Δφ = 0,
    // f = ρ/π (A + B sin 60° tan 60°).
    let q = OrenNayar::new(
        Channels::Single,
        vec![rho],
        vec![sdeg],
        OrenNayarVariant::Qualitative,
    )
    .expect("valid");
    let (a, b) = (1.0 - 0.5 * s2 / (s2 + 0.33), 0.45 * s2 / (s2 + 0.09));
    let want = rho / PI * (a + b * f64::to_radians(60.0).sin() * f64::to_radians(60.0).tan());
    let got = eval1(&q, deg(60.0, 0.0), deg(60.0, 0.0));
    assert!((got - want).abs() < 1e-14, "{got} vs {want}");
}

/// Blinn-Phong with n = 0 is Lambert (its normalisation for other n is checked by its
/// albedo in `albedo.rs`).
#[test]
fn blinn_phong_closed_forms() {
    let m = BlinnPhong::new(Channels::Single, vec![0.6], vec![0.0]).expect("valid");
    let got = eval1(&m, deg(20.0, 0.0), deg(70.0, 50.0));
    assert!((got - 0.6 / PI).abs() < 1e-16);
}

/// Minnaert (Eq. 6): `ρd (n+2)/(2π) (cos θi cos θo)ⁿ`.
#[test]
fn minnaert_value() {
    let m = Diffuse::minnaert(Channels::Single, vec![0.8], vec![0.5]).expect("valid");
    let got = eval1(&m, deg(60.0, 0.0), deg(0.0, 0.0));
    let want = 0.8 * 2.5 / (2.0 * PI) * 0.5f64.sqrt();
    assert!((got - want).abs() < 1e-16);
}
