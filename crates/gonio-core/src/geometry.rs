//! Directions and angles in the local sample frame (`docs/CONVENTIONS.md`: z is the normal,
//! both directions point away from the surface, θ from the normal, φ from +x to +y).

use std::f64::consts::TAU;
use std::ops::Deref;

use crate::Vec3;

/// A unit vector: a direction in the local sample frame.
///
/// The unit length is an invariant of the type; every constructor normalises or
/// builds from angles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dir(Vec3);

impl Dir {
    /// The surface normal, θ = 0.
    pub const Z: Dir = Dir(Vec3::Z);

    /// Normalises `v`; `None` for a zero or non-finite vector.
    pub fn new(v: Vec3) -> Option<Dir> {
        v.normalized().map(Dir)
    }

    /// Wraps a vector the caller knows to be of unit length (checked in debug builds).
    ///
    /// Hot paths (samplers, reflection about a unit half vector) produce unit vectors
    /// by construction; renormalising them would only cost time.
    #[inline]
    pub fn from_unit(v: Vec3) -> Dir {
        debug_assert!(
            (v.norm_squared() - 1.0).abs() < 1e-9,
            "not a unit vector: {v:?}"
        );
        Dir(v)
    }

    /// The direction at polar angle `theta` from the normal and azimuth `phi` from +x
    /// towards +y, both in radians.
    #[inline]
    pub fn from_angles(theta: f64, phi: f64) -> Dir {
        let (st, ct) = theta.sin_cos();
        let (sp, cp) = phi.sin_cos();
        Dir(Vec3::new(st * cp, st * sp, ct))
    }

    /// The underlying unit vector.
    #[inline]
    pub fn vec(self) -> Vec3 {
        self.0
    }

    /// cos θ, the z component.
    #[inline]
    pub fn cos_theta(self) -> f64 {
        self.0.z
    }

    /// sin θ, computed from x and y so that it stays accurate near the normal.
    #[inline]
    pub fn sin_theta(self) -> f64 {
        (self.0.x * self.0.x + self.0.y * self.0.y).sqrt()
    }

    /// θ in radians, in [0, π]; accurate near both the normal and the horizon.
    #[inline]
    pub fn theta(self) -> f64 {
        self.sin_theta().atan2(self.0.z)
    }

    /// φ in radians, in [0, 2π); 0 at the normal.
    #[inline]
    pub fn phi(self) -> f64 {
        let p = self.0.y.atan2(self.0.x);
        if p < 0.0 { p + TAU } else { p }
    }

    /// True strictly above the surface (θ < 90°).
    #[inline]
    pub fn is_above(self) -> bool {
        self.0.z > 0.0
    }

    /// The mirror direction about the normal: `(-x, -y, z)` (`docs/CONVENTIONS.md`).
    #[inline]
    pub fn mirror(self) -> Dir {
        Dir(Vec3::new(-self.0.x, -self.0.y, self.0.z))
    }

    /// The reflection of this direction about the unit vector `h`: `2 (v·h) h − v`.
    #[inline]
    pub fn reflect(self, h: Dir) -> Dir {
        let d = self.0.dot(h.0);
        Dir::from_unit(h.0 * (2.0 * d) - self.0)
    }

    /// The same direction mirrored through the surface plane: `(x, y, -z)`.
    #[inline]
    pub fn flip_z(self) -> Dir {
        Dir(Vec3::new(self.0.x, self.0.y, -self.0.z))
    }

    /// This direction rotated by `angle` radians about the normal (counter-clockwise
    /// seen from above, i.e. φ increases by `angle`).
    #[inline]
    pub fn rotate_about_normal(self, angle: f64) -> Dir {
        let (s, c) = angle.sin_cos();
        Dir(Vec3::new(
            c * self.0.x - s * self.0.y,
            s * self.0.x + c * self.0.y,
            self.0.z,
        ))
    }

    /// Right-handed rotation by `angle` radians about the y axis (z turns towards +x).
    #[inline]
    fn rotate_about_y(self, angle: f64) -> Dir {
        let (s, c) = angle.sin_cos();
        Dir(Vec3::new(
            c * self.0.x + s * self.0.z,
            self.0.y,
            -s * self.0.x + c * self.0.z,
        ))
    }

    /// The angle between two directions in radians, accurate for small and large angles.
    pub fn angle_to(self, o: Dir) -> f64 {
        let s = self.0.cross(o.0).norm();
        s.atan2(self.0.dot(o.0))
    }
}

impl Deref for Dir {
    type Target = Vec3;
    #[inline]
    fn deref(&self) -> &Vec3 {
        &self.0
    }
}

/// Spherical angles in radians (code works in radians; see [`SphericalDeg`] for files).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spherical {
    /// Polar angle from the normal, radians.
    pub theta: f64,
    /// Azimuth from +x towards +y, radians.
    pub phi: f64,
}

impl Spherical {
    /// Angles in radians.
    pub fn new(theta: f64, phi: f64) -> Self {
        Spherical { theta, phi }
    }
}

impl From<Spherical> for Dir {
    fn from(s: Spherical) -> Dir {
        Dir::from_angles(s.theta, s.phi)
    }
}

impl From<Dir> for Spherical {
    fn from(d: Dir) -> Spherical {
        Spherical {
            theta: d.theta(),
            phi: d.phi(),
        }
    }
}

/// Spherical angles in degrees: what every user-facing file and command speaks.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SphericalDeg {
    /// Polar angle from the normal, degrees.
    pub theta_deg: f64,
    /// Azimuth from +x towards +y, degrees.
    pub phi_deg: f64,
}

impl SphericalDeg {
    /// Angles in degrees.
    pub fn new(theta_deg: f64, phi_deg: f64) -> Self {
        SphericalDeg { theta_deg, phi_deg }
    }

    /// The same angles in radians.
    pub fn to_radians(self) -> Spherical {
        Spherical {
            theta: self.theta_deg.to_radians(),
            phi: self.phi_deg.to_radians(),
        }
    }

    /// `n` directions of the upper hemisphere on a spherical Fibonacci lattice turned
    /// by `turn` (a fraction of a full turn): direction k at cos θ = 1 − (k + ½)/n and
    /// φ = 360° · frac(k/Φ + turn), Φ the golden ratio. Equal-area (each direction
    /// stands for 2π/n sr) and without a cluster at the pole.
    pub fn fibonacci_hemisphere(n: usize, turn: f64) -> Vec<SphericalDeg> {
        let golden = (1.0 + 5f64.sqrt()) / 2.0;
        (0..n)
            .map(|k| {
                let z = 1.0 - (k as f64 + 0.5) / n as f64;
                let phi = (k as f64 / golden + turn).fract() * 360.0;
                SphericalDeg::new(z.clamp(-1.0, 1.0).acos().to_degrees(), phi)
            })
            .collect()
    }
}

impl From<SphericalDeg> for Dir {
    /// Exact at multiples of 90°: θ = 90° lies exactly on the horizon (z = 0), and
    /// φ = 90° exactly on the y axis.
    fn from(s: SphericalDeg) -> Dir {
        let (st, ct) = sin_cos_deg(s.theta_deg);
        let (sp, cp) = sin_cos_deg(s.phi_deg);
        Dir(Vec3::new(st * cp, st * sp, ct))
    }
}

/// `(sin x, cos x)` for `x` in degrees, reduced to a quadrant first so that multiples
/// of 90° give exact zeros and ones (`cos(π/2)` in radians is 6e-17, not 0).
pub fn sin_cos_deg(x: f64) -> (f64, f64) {
    let r = x.rem_euclid(360.0);
    let q = (r / 90.0).floor();
    let (s, c) = (r - 90.0 * q).to_radians().sin_cos();
    match q as i64 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

impl From<Dir> for SphericalDeg {
    fn from(d: Dir) -> SphericalDeg {
        let s = Spherical::from(d);
        SphericalDeg {
            theta_deg: s.theta.to_degrees(),
            phi_deg: s.phi.to_degrees(),
        }
    }
}

/// An incident and an outgoing direction: one point of a BRDF's domain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirPair {
    /// Towards the light source.
    pub wi: Dir,
    /// Towards the detector.
    pub wo: Dir,
}

impl DirPair {
    /// The pair `(wi, wo)`.
    pub fn new(wi: Dir, wo: Dir) -> Self {
        DirPair { wi, wo }
    }

    /// The reciprocal pair `(wo, wi)`.
    pub fn swapped(self) -> Self {
        DirPair {
            wi: self.wo,
            wo: self.wi,
        }
    }
}

/// The half vector `normalize(wi + wo)`; `None` when the directions are opposite
/// (to within rounding: `|wi + wo| < 1e-12`).
#[inline]
pub fn half_vector(wi: Dir, wo: Dir) -> Option<Dir> {
    let s = wi.vec() + wo.vec();
    let n = s.norm();
    (n >= 1e-12).then(|| Dir::from_unit(s / n))
}

/// Rusinkiewicz's half/difference angles (radians) of a direction pair.
///
/// `θh, φh` are the spherical angles of the half vector; `θd, φd` those of `wi` in the
/// frame where the half vector is the pole. Isotropic BRDFs do not depend on φh, and
/// reciprocity maps φd to φd + π: the parametrisation of tabulated formats like MERL.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfDiff {
    /// Polar angle of the half vector.
    pub theta_h: f64,
    /// Azimuth of the half vector.
    pub phi_h: f64,
    /// Polar angle of `wi` about the half vector.
    pub theta_d: f64,
    /// Azimuth of `wi` about the half vector.
    pub phi_d: f64,
}

impl HalfDiff {
    /// The half/difference angles of `(wi, wo)`; `None` when `wi = -wo`.
    pub fn from_pair(wi: Dir, wo: Dir) -> Option<HalfDiff> {
        let h = half_vector(wi, wo)?;
        let theta_h = h.theta();
        let phi_h = h.phi();
        let d = wi.rotate_about_normal(-phi_h).rotate_about_y(-theta_h);
        Some(HalfDiff {
            theta_h,
            phi_h,
            theta_d: d.theta(),
            phi_d: d.phi(),
        })
    }

    /// The direction pair these angles describe.
    pub fn to_pair(self) -> DirPair {
        let h = Dir::from_angles(self.theta_h, self.phi_h);
        let wi = Dir::from_angles(self.theta_d, self.phi_d)
            .rotate_about_y(self.theta_h)
            .rotate_about_normal(self.phi_h);
        DirPair::new(wi, wi.reflect(h))
    }
}

/// Wraps an angle in radians into [0, 2π).
#[cfg(test)]
fn wrap_tau(a: f64) -> f64 {
    let r = a.rem_euclid(TAU);
    if r >= TAU { 0.0 } else { r }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::PI;

    fn close(a: Vec3, b: Vec3, tol: f64) -> bool {
        (a - b).norm() < tol
    }

    #[test]
    fn angles_follow_the_conventions() {
        // θ from the normal, φ from +x towards +y.
        let d = Dir::from(SphericalDeg::new(90.0, 90.0));
        assert!(close(d.vec(), Vec3::Y, 1e-15));
        let d = Dir::from(SphericalDeg::new(90.0, 0.0));
        assert!(close(d.vec(), Vec3::X, 1e-15));
        let d = Dir::from(SphericalDeg::new(0.0, 123.0));
        assert!(close(d.vec(), Vec3::Z, 1e-15));
        assert_eq!(Dir::Z.phi(), 0.0);
        let d = Dir::from(SphericalDeg::new(45.0, 270.0));
        assert!((d.phi() - 1.5 * PI).abs() < 1e-15);
    }

    #[test]
    fn degrees_are_exact_at_quadrants() {
        let d = Dir::from(SphericalDeg::new(90.0, 90.0));
        assert_eq!(d.vec(), Vec3::new(0.0, 1.0, 0.0));
        assert!(!d.is_above());
        let d = Dir::from(SphericalDeg::new(90.0, -90.0));
        assert_eq!(d.vec(), Vec3::new(0.0, -1.0, 0.0));
        let d = Dir::from(SphericalDeg::new(180.0, 0.0));
        assert_eq!(d.vec(), Vec3::new(0.0, 0.0, -1.0));
        for x in [-725.0, -30.0, 0.0, 12.5, 135.0, 200.0, 271.0, 359.9] {
            let (s, c) = sin_cos_deg(x);
            let (es, ec) = f64::to_radians(x).sin_cos();
            assert!((s - es).abs() < 1e-15 && (c - ec).abs() < 1e-15, "{x}");
        }
    }

    #[test]
    fn mirror_is_minus_x_minus_y() {
        let d = Dir::from(SphericalDeg::new(30.0, 40.0));
        let m = d.mirror();
        assert_eq!(m.vec(), Vec3::new(-d.x, -d.y, d.z));
        // The mirror is the reflection about the normal.
        assert!(close(d.reflect(Dir::Z).vec(), m.vec(), 1e-15));
        let s = SphericalDeg::from(m);
        assert!((s.theta_deg - 30.0).abs() < 1e-12);
        assert!((s.phi_deg - 220.0).abs() < 1e-12);
    }

    #[test]
    fn half_vector_of_mirror_pair_is_normal() {
        let wi = Dir::from(SphericalDeg::new(63.0, 11.0));
        let h = half_vector(wi, wi.mirror()).expect("not opposite");
        assert!(close(h.vec(), Vec3::Z, 1e-15));
        assert!(half_vector(wi, Dir::new(-wi.vec()).expect("unit")).is_none());
    }

    #[test]
    fn rotation_about_normal_adds_to_phi() {
        let d = Dir::from(SphericalDeg::new(50.0, 10.0));
        let r = SphericalDeg::from(d.rotate_about_normal(35f64.to_radians()));
        assert!((r.theta_deg - 50.0).abs() < 1e-12);
        assert!((r.phi_deg - 45.0).abs() < 1e-12);
    }

    #[test]
    fn theta_is_accurate_near_the_normal_and_the_horizon() {
        for t in [1e-9, 1e-6, 0.3, PI / 2.0 - 1e-9] {
            let d = Dir::from_angles(t, 0.7);
            assert!((d.theta() - t).abs() < 1e-15 * t.max(1.0), "{t}");
        }
    }

    #[test]
    fn half_diff_of_in_plane_specular_pair() {
        // wi at 30°, wo at its mirror: h is the normal and the difference angle is 30°.
        let wi = Dir::from(SphericalDeg::new(30.0, 0.0));
        let hd = HalfDiff::from_pair(wi, wi.mirror()).expect("defined");
        assert!(hd.theta_h.abs() < 1e-15);
        assert!((hd.theta_d - 30f64.to_radians()).abs() < 1e-15);
    }

    proptest! {
        #[test]
        fn spherical_round_trip(t in 0.0..90.0f64, p in 0.0..359.999f64) {
            let d = Dir::from(SphericalDeg::new(t, p));
            let s = SphericalDeg::from(d);
            prop_assert!((s.theta_deg - t).abs() < 1e-9);
            if t > 1e-6 {
                let dp = (s.phi_deg - p).abs();
                prop_assert!(dp < 1e-8 || (360.0 - dp) < 1e-8);
            }
        }

        #[test]
        fn half_diff_round_trip(ti in 0.0..89.0f64, pi in 0.0..360.0f64,
                                to in 0.0..89.0f64, po in 0.0..360.0f64) {
            let wi = Dir::from(SphericalDeg::new(ti, pi));
            let wo = Dir::from(SphericalDeg::new(to, po));
            let hd = HalfDiff::from_pair(wi, wo).expect("upper hemisphere pairs are never opposite");
            let back = hd.to_pair();
            prop_assert!(close(back.wi.vec(), wi.vec(), 1e-12));
            prop_assert!(close(back.wo.vec(), wo.vec(), 1e-12));
            // Reciprocity in half/difference angles: swapping moves φd by π.
            let sw = HalfDiff::from_pair(wo, wi).expect("defined");
            prop_assert!((sw.theta_h - hd.theta_h).abs() < 1e-12);
            prop_assert!((sw.theta_d - hd.theta_d).abs() < 1e-12);
            if hd.theta_d > 1e-6 {
                let dphi = wrap_tau(sw.phi_d - hd.phi_d);
                prop_assert!((dphi - PI).abs() < 1e-9);
            }
        }
    }
}
