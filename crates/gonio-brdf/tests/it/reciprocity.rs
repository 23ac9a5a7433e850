//! Reciprocity, positivity and the domain, for every model.

use crate::common;

use common::{random_dir, rng, zoo};
use gonio_brdf::Brdf;

#[test]
fn reciprocal_models_are_reciprocal_to_1e12() {
    let mut r = rng(1);
    for (name, m) in zoo() {
        if !m.is_reciprocal() {
            continue;
        }
        let k = m.channels().len();
        let (mut a, mut b) = (vec![0.0; k], vec![0.0; k]);
        for _ in 0..20_000 {
            let (wi, wo) = (random_dir(&mut r), random_dir(&mut r));
            m.eval(wi, wo, &mut a);
            m.eval(wo, wi, &mut b);
            for c in 0..k {
                let scale = a[c].abs().max(b[c].abs()).max(1e-300);
                assert!(
                    (a[c] - b[c]).abs() <= 1e-12 * scale,
                    "{name}: f({wi:?},{wo:?}) = {} but f(wo,wi) = {}",
                    a[c],
                    b[c]
                );
            }
        }
    }
}

/// Lewis 1993 showed Phong shading is never reciprocal; DeYoung's P_r measures by
/// how much. The shading variant must show it, by a factor of cos θo / cos θi.
#[test]
fn phong_shading_violates_reciprocity_by_the_cosine_ratio() {
    let (_, m) = zoo()
        .into_iter()
        .find(|(n, _)| *n == "phong-shading")
        .expect("in the zoo");
    assert!(!m.is_reciprocal());
    let wi = common::deg(60.0, 0.0);
    let wo = common::deg(40.0, 180.0);
    let (mut a, mut b) = ([0.0], [0.0]);
    m.eval(wi, wo, &mut a);
    m.eval(wo, wi, &mut b);
    // The diffuse part (0.5/π) is reciprocal; the specular parts differ by cos θo/cos θi.
    let d = 0.5 / std::f64::consts::PI;
    let ratio = (a[0] - d) / (b[0] - d);
    let expect = 40f64.to_radians().cos() / 60f64.to_radians().cos();
    assert!((ratio - expect).abs() < 1e-12, "{ratio} vs {expect}");
    assert!((a[0] - b[0]).abs() > 0.1 * a[0]);
}

#[test]
fn values_are_finite_and_non_negative() {
    let mut r = rng(2);
    for (name, m) in zoo() {
        let k = m.channels().len();
        let mut a = vec![0.0; k];
        for _ in 0..20_000 {
            let (wi, wo) = (random_dir(&mut r), random_dir(&mut r));
            m.eval(wi, wo, &mut a);
            assert!(
                a.iter().all(|v| v.is_finite() && *v >= 0.0),
                "{name}: f({wi:?}, {wo:?}) = {a:?}"
            );
        }
    }
}

#[test]
fn zero_below_the_horizon() {
    for (name, m) in zoo() {
        let k = m.channels().len();
        let mut a = vec![1.0; k];
        let up = common::deg(30.0, 10.0);
        for below in [common::deg(90.0, 0.0), common::deg(120.0, 40.0)] {
            m.eval(up, below, &mut a);
            assert!(a.iter().all(|v| *v == 0.0), "{name}");
            m.eval(below, up, &mut a);
            assert!(a.iter().all(|v| *v == 0.0), "{name}");
            assert!(m.sample(below, 0.5, [0.5, 0.5]).is_none(), "{name}");
        }
    }
}

/// The Eq. 7 mirror term `g(u) δ(u_m − v)` is reciprocal when `g(u) = g(u_m)`.
#[test]
fn mirror_terms_are_reciprocal() {
    let mut r = rng(3);
    let mut seen = 0;
    for (name, m) in zoo() {
        let k = m.channels().len();
        let (mut a, mut b) = (vec![0.0; k], vec![0.0; k]);
        if !m.mirror(common::deg(30.0, 0.0), &mut a) {
            continue;
        }
        seen += 1;
        for _ in 0..2000 {
            let u = random_dir(&mut r);
            m.mirror(u, &mut a);
            m.mirror(u.mirror(), &mut b);
            for c in 0..k {
                assert!(
                    (a[c] - b[c]).abs() <= 1e-12 * a[c].max(1e-300),
                    "{name}: g(u) = {} but g(u_m) = {}",
                    a[c],
                    b[c]
                );
            }
        }
    }
    assert_eq!(seen, 2, "the zoo has two models with a mirror term");
}
