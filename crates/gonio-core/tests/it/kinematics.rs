//! Forward and inverse goniometer kinematics against hand-computed configurations and
//! round-trip properties.

use gonio_core::kinematics::{KinematicsError, Layout, arm_separation_deg};
use gonio_core::{Dir, DirPair, SphericalDeg, Vec3};
use proptest::prelude::*;

const ARMS: Layout = Layout::CoplanarArms;
const SPH: Layout = Layout::Spherical;

fn close_vec(a: Vec3, b: Vec3, tol: f64) -> bool {
    (a - b).norm() <= tol
}

fn assert_vec(a: Vec3, b: Vec3, tol: f64) {
    assert!(close_vec(a, b, tol), "{a:?} != {b:?} (tol {tol})");
}

fn assert_stages(got: [f64; 4], want: [f64; 4], tol: f64) {
    for i in 0..4 {
        assert!((got[i] - want[i]).abs() <= tol, "{got:?} != {want:?}");
    }
}

fn deg(d: Dir) -> SphericalDeg {
    SphericalDeg::from(d)
}

fn sd(t: f64, p: f64) -> Dir {
    Dir::from(SphericalDeg::new(t, p))
}

fn rad(x: f64) -> f64 {
    x.to_radians()
}

#[test]
fn roles_name_the_stages_in_order() {
    assert_eq!(SPH.roles(), ["theta_i", "phi_i", "theta_o", "phi_o"]);
    assert_eq!(
        ARMS.roles(),
        ["source", "detector", "sample_rot", "sample_tilt"]
    );
}

#[test]
fn arms_untilted_sweep_the_sample_y_z_plane() {
    // ρ = τ = 0: normal = lab X, reference x_s = lab Z, y_s = −Y. A source at 30°
    // from X towards +Y is 30° from the normal on the −y side: φ = 270°.
    let p = ARMS.forward([30.0, -45.0, 0.0, 0.0]);
    assert_vec(p.wi.vec(), Vec3::new(0.0, -0.5, rad(30.0).cos()), 1e-15);
    assert_eq!(p.wi.x, 0.0);
    let s = deg(p.wi);
    assert!((s.theta_deg - 30.0).abs() < 1e-12);
    assert!((s.phi_deg - 270.0).abs() < 1e-12);
    // The detector at −45° lands on the +y side, 45° from the normal: φ = 90°.
    let h = 0.5f64.sqrt();
    assert_vec(p.wo.vec(), Vec3::new(0.0, h, h), 1e-15);
    let s = deg(p.wo);
    assert!((s.theta_deg - 45.0).abs() < 1e-12);
    assert!((s.phi_deg - 90.0).abs() < 1e-12);
    assert!((arm_separation_deg(p) - 75.0).abs() < 1e-12);

    // The inverse without a hint returns these stages (|ρ| ≤ 90° is preferred) ...
    let st = ARMS.inverse(p, None).expect("above the horizon");
    assert_stages(st, [30.0, -45.0, 0.0, 0.0], 1e-12);
    // ... and the mirror-image set-up when the hint is near it.
    let twin = ARMS
        .inverse(p, Some([-29.0, 44.0, 179.0, 1.0]))
        .expect("above the horizon");
    assert_stages(twin, [-30.0, 45.0, 180.0, 0.0], 1e-12);
    let q = ARMS.forward(twin);
    assert_vec(q.wi.vec(), p.wi.vec(), 1e-15);
    assert_vec(q.wo.vec(), p.wo.vec(), 1e-15);
}

#[test]
fn symmetric_arms_at_zero_tilt_are_specular() {
    for rho in [0.0, 17.0, 90.0, -123.0, 180.0] {
        let p = ARMS.forward([30.0, -30.0, rho, 0.0]);
        assert_vec(p.wo.vec(), p.wi.mirror().vec(), 1e-15);
        assert!((deg(p.wi).theta_deg - 30.0).abs() < 1e-12);
        assert!((arm_separation_deg(p) - 60.0).abs() < 1e-12);
    }
}

#[test]
fn sample_rotated_by_90_puts_the_arms_in_its_x_z_plane() {
    // ρ = 90°: x_s = −Y, y_s = −Z, z_s = X. A source at 30° towards +Y lies towards −x.
    let p = ARMS.forward([30.0, -45.0, 90.0, 0.0]);
    assert_eq!(p.wi.y, 0.0);
    assert_eq!(p.wo.y, 0.0);
    assert_vec(p.wi.vec(), Vec3::new(-0.5, 0.0, rad(30.0).cos()), 1e-15);
    let h = 0.5f64.sqrt();
    assert_vec(p.wo.vec(), Vec3::new(h, 0.0, h), 1e-15);
    assert!((deg(p.wi).phi_deg - 180.0).abs() < 1e-12);
    assert!(deg(p.wo).phi_deg.abs() < 1e-12);
    let st = ARMS.inverse(p, None).expect("above the horizon");
    assert_stages(st, [30.0, -45.0, 90.0, 0.0], 1e-12);
}

#[test]
fn tilted_sample() {
    // τ = 20°, ρ = 0: z_s = (cos20, 0, −sin20), x_s = (sin20, 0, cos20), y_s = −Y.
    // The source along lab X is 20° from the normal towards +x_s.
    let p = ARMS.forward([0.0, 60.0, 0.0, 20.0]);
    let (s20, c20) = rad(20.0).sin_cos();
    assert_vec(p.wi.vec(), Vec3::new(s20, 0.0, c20), 1e-15);
    let s = deg(p.wi);
    assert!((s.theta_deg - 20.0).abs() < 1e-12 && s.phi_deg.abs() < 1e-12);
    // Detector d = (cos60, sin60, 0): wo = (d·x_s, d·y_s, d·z_s).
    let s60 = rad(60.0).sin();
    assert_vec(p.wo.vec(), Vec3::new(0.5 * s20, -s60, 0.5 * c20), 1e-15);
    // The lab vertical in the sample frame, k = (cos τ cos ρ, −cos τ sin ρ, −sin τ),
    // is perpendicular to both.
    let k = Vec3::new(c20, 0.0, -s20);
    assert!(k.dot(p.wi.vec()).abs() < 1e-15 && k.dot(p.wo.vec()).abs() < 1e-15);
    assert!((arm_separation_deg(p) - 60.0).abs() < 1e-12);
    let st = ARMS.inverse(p, None).expect("above the horizon");
    assert_stages(st, [0.0, 60.0, 0.0, 20.0], 1e-12);
}

#[test]
fn lab_vertical_in_sample_frame_matches_the_derivation() {
    // wi × wo = sin(αd − αs) k for every set-up.
    for (r, t) in [(0.0, 0.0), (35.0, 20.0), (-120.0, -60.0), (170.0, 80.0)] {
        let (sr, cr) = rad(r).sin_cos();
        let (stau, ctau) = rad(t).sin_cos();
        let k = Vec3::new(ctau * cr, -ctau * sr, -stau);
        let p = ARMS.forward([10.0, 50.0, r, t]);
        let c = p.wi.vec().cross(p.wo.vec());
        assert_vec(c, k * rad(40.0).sin(), 1e-15);
    }
}

#[test]
fn retro_reflection_picks_an_untilted_sample_or_follows_the_hint() {
    let x = [40.0, 40.0, 25.0, 15.0];
    let p = ARMS.forward(x);
    assert_vec(p.wi.vec(), p.wo.vec(), 0.0);
    let st = ARMS.inverse(p, None).expect("above the horizon");
    assert_eq!(st[3], 0.0, "untilted without a hint: {st:?}");
    assert!(st[2].abs() <= 90.0);
    let q = ARMS.forward(st);
    assert_vec(q.wi.vec(), p.wi.vec(), 1e-15);
    assert_vec(q.wo.vec(), p.wo.vec(), 1e-15);
    // With the hint, no motion at all.
    let st = ARMS.inverse(p, Some(x)).expect("above the horizon");
    assert_stages(st, x, 1e-12);

    // Both at the normal: τ = 0 and ρ = 0, or the hint's ρ.
    let n = DirPair::new(Dir::Z, Dir::Z);
    assert_stages(ARMS.inverse(n, None).expect("ok"), [0.0; 4], 1e-12);
    let st = ARMS
        .inverse(n, Some([0.0, 0.0, 33.0, 0.0]))
        .expect("above the horizon");
    assert_stages(st, [0.0, 0.0, 33.0, 0.0], 1e-12);
}

#[test]
fn spherical_forward_is_the_spherical_angles() {
    let p = SPH.forward([30.0, 45.0, 60.0, 200.0]);
    assert_eq!(p.wi, sd(30.0, 45.0));
    assert_eq!(p.wo, sd(60.0, 200.0));
    let st = SPH.inverse(p, None).expect("above the horizon");
    assert_stages(st, [30.0, 45.0, 60.0, 200.0], 1e-12);
}

#[test]
fn spherical_phi_follows_the_hint() {
    let p = SPH.forward([30.0, 10.0, 60.0, 200.0]);
    // φ = 10 near 350 → 370; φ = 200 near −170 → −160.
    let st = SPH
        .inverse(p, Some([0.0, 350.0, 0.0, -170.0]))
        .expect("above the horizon");
    assert_stages(st, [30.0, 370.0, 60.0, -160.0], 1e-12);
    // Without a hint φ is in [0, 360).
    let p = SPH.forward([30.0, -10.0, 60.0, 720.0]);
    let st = SPH.inverse(p, None).expect("above the horizon");
    assert_stages(st, [30.0, 350.0, 60.0, 0.0], 1e-12);
}

#[test]
fn spherical_pole_keeps_the_hint_phi() {
    let p = DirPair::new(Dir::Z, sd(40.0, 70.0));
    let st = SPH
        .inverse(p, Some([5.0, 123.0, 40.0, 60.0]))
        .expect("above the horizon");
    assert_stages(st, [0.0, 123.0, 40.0, 70.0], 1e-12);
    let st = SPH.inverse(p, None).expect("above the horizon");
    assert_stages(st, [0.0, 0.0, 40.0, 70.0], 1e-12);
}

#[test]
fn directions_at_or_below_the_horizon_are_rejected() {
    for layout in [SPH, ARMS] {
        let grazing = DirPair::new(sd(30.0, 0.0), sd(90.0, 180.0));
        assert!(matches!(
            layout.inverse(grazing, None),
            Err(KinematicsError::BelowHorizon { which: "wo", theta_deg }) if theta_deg == 90.0
        ));
        let below = DirPair::new(sd(120.0, 0.0), sd(30.0, 180.0));
        assert!(matches!(
            layout.inverse(below, None),
            Err(KinematicsError::BelowHorizon { which: "wi", .. })
        ));
        let ok = DirPair::new(sd(30.0, 0.0), sd(30.0, 180.0));
        assert!(matches!(
            layout.inverse(ok, Some([0.0, f64::NAN, 0.0, 0.0])),
            Err(KinematicsError::NonFiniteHint { index: 1, value }) if value.is_nan()
        ));
        let bad = DirPair::new(Dir::from_angles(f64::NAN, 0.0), sd(30.0, 0.0));
        assert_eq!(
            layout.inverse(bad, None),
            Err(KinematicsError::NonFiniteDirection { which: "wi" })
        );
    }
}

#[test]
fn forward_never_fails_even_below_the_surface() {
    let p = ARMS.forward([120.0, 0.0, 0.0, 0.0]);
    assert!(!p.wi.is_above());
    assert!((deg(p.wi).theta_deg - 120.0).abs() < 1e-12);
}

/// The separation of the arms `|αs − αd|`, wrapped into [0, 180].
fn arm_gap(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}

fn dir_strategy() -> impl Strategy<Value = Dir> {
    (0.0..89.9f64, 0.0..360.0f64).prop_map(|(t, p)| sd(t, p))
}

/// Above-the-surface pairs, including (nearly) parallel ones.
fn pair_strategy() -> impl Strategy<Value = DirPair> {
    prop_oneof![
        4 => (dir_strategy(), dir_strategy()).prop_map(|(a, b)| DirPair::new(a, b)),
        1 => (0.01..89.0f64, 0.0..360.0f64, -12.0..-3.0f64, 0.0..360.0f64).prop_map(
            |(t, p, e, dir)| {
                // wo within 10^e radians of wi.
                let wi = sd(t, p);
                let eps = 10f64.powf(e);
                let (s, c) = dir.to_radians().sin_cos();
                let wo = Dir::from_angles(wi.theta() + eps * c, wi.phi() + eps * s);
                DirPair::new(wi, wo)
            }
        ),
        1 => dir_strategy().prop_map(|d| DirPair::new(d, d)),
    ]
}

fn hint_strategy() -> impl Strategy<Value = Option<[f64; 4]>> {
    proptest::option::of(proptest::array::uniform4(-400.0..400.0f64))
}

proptest! {
    #[test]
    fn forward_of_inverse_is_identity(pair in pair_strategy(), hint in hint_strategy()) {
        for layout in [SPH, ARMS] {
            let st = layout.inverse(pair, hint).expect("above the horizon");
            let back = layout.forward(st);
            prop_assert!(close_vec(back.wi.vec(), pair.wi.vec(), 1e-12), "{layout:?} {st:?}");
            prop_assert!(close_vec(back.wo.vec(), pair.wo.vec(), 1e-12), "{layout:?} {st:?}");
            match hint {
                // No stage travels the long way (θ of the spherical layout is not
                // periodic in practice: it is always acos(z)).
                Some(h) => for i in if layout == ARMS { 0..4 } else { 1..2 }.chain([3]) {
                    prop_assert!((st[i] - h[i]).abs() <= 180.0 + 1e-9, "{layout:?} {st:?} {h:?}");
                },
                None => if layout == ARMS {
                    prop_assert!(st[0] > -180.0 && st[0] <= 180.0);
                    prop_assert!(st[1] > -180.0 && st[1] <= 180.0);
                    prop_assert!(st[2].abs() <= 90.0 + 1e-9, "{st:?}");
                    prop_assert!(st[3].abs() <= 90.0);
                } else {
                    prop_assert!(st[1] >= 0.0 && st[1] < 360.0);
                    prop_assert!(st[3] >= 0.0 && st[3] < 360.0);
                },
            }
        }
    }

    #[test]
    fn arms_inverse_of_forward_without_hint(a in -89.0..89.0f64, b in -89.0..89.0f64,
                                            rho in -179.9..179.9f64, tau in -85.0..85.0f64) {
        prop_assume!((a - b).abs() > 1.0 && (rho.abs() - 90.0).abs() > 1e-6);
        let p = ARMS.forward([a, b, rho, tau]);
        prop_assert!(p.wi.is_above() && p.wo.is_above());
        let st = ARMS.inverse(p, None).expect("above the horizon");
        // |ρ| ≤ 90° is canonical; otherwise the mirror-image twin comes back.
        let want = if rho.abs() < 90.0 {
            [a, b, rho, tau]
        } else {
            [-a, -b, if rho > 0.0 { rho - 180.0 } else { rho + 180.0 }, -tau]
        };
        for i in 0..4 {
            prop_assert!((st[i] - want[i]).abs() < 1e-9, "{st:?} != {want:?}");
        }
    }

    #[test]
    fn arms_hint_is_honoured(a in -89.0..89.0f64, b in -89.0..89.0f64,
                             rho in -720.0..720.0f64, tau in -89.0..89.0f64,
                             turns in (-1i32..=1, -1i32..=1), retro in any::<bool>()) {
        let b = if retro { a } else { b };
        let x = [a + 360.0 * f64::from(turns.0), b + 360.0 * f64::from(turns.1), rho, tau];
        let st = ARMS.inverse(ARMS.forward(x), Some(x)).expect("above the horizon");
        for i in 0..4 {
            prop_assert!((st[i] - x[i]).abs() < 1e-9, "{st:?} != {x:?}");
        }
    }

    #[test]
    fn spherical_inverse_of_forward(ti in 0.001..89.9f64, pi in -720.0..720.0f64,
                                    to in 0.001..89.9f64, po in -720.0..720.0f64) {
        let x = [ti, pi, to, po];
        let p = SPH.forward(x);
        // With the hint: exactly x.
        let st = SPH.inverse(p, Some(x)).expect("above the horizon");
        for i in 0..4 {
            prop_assert!((st[i] - x[i]).abs() < 1e-9, "{st:?} != {x:?}");
        }
        // Without: the same angles with φ in [0, 360).
        let st = SPH.inverse(p, None).expect("above the horizon");
        prop_assert!((st[0] - ti).abs() < 1e-9 && (st[2] - to).abs() < 1e-9);
        for (got, want) in [(st[1], pi), (st[3], po)] {
            let d = (got - want).rem_euclid(360.0);
            prop_assert!(d.min(360.0 - d) < 1e-9, "{got} vs {want}");
        }
    }

    #[test]
    fn arm_separation_is_the_angle_between_the_arms(a in -400.0..400.0f64, b in -400.0..400.0f64,
                                                   rho in -400.0..400.0f64, tau in -400.0..400.0f64) {
        let p = ARMS.forward([a, b, rho, tau]);
        prop_assert!((arm_separation_deg(p) - arm_gap(a, b)).abs() < 1e-9);
        prop_assert!((arm_separation_deg(p.swapped()) - arm_separation_deg(p)).abs() < 1e-12);
    }
}
