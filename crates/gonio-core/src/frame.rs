use crate::{Dir, Vec3};

/// An orthonormal right-handed frame `(x, y, z)`: converts between a parent frame
/// (e.g. the laboratory) and the local frame whose z axis is `z`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Local x axis expressed in the parent frame.
    pub x: Vec3,
    /// Local y axis expressed in the parent frame.
    pub y: Vec3,
    /// Local z axis (the normal) expressed in the parent frame.
    pub z: Vec3,
}

impl Frame {
    /// The identity frame.
    pub const IDENTITY: Frame = Frame {
        x: Vec3::X,
        y: Vec3::Y,
        z: Vec3::Z,
    };

    /// A frame with z along `n` and some x perpendicular to it.
    ///
    /// Uses the branch-free construction of Duff et al. (JCGT 2017), continuous except
    /// across `n.z = 0`, so nearby normals get nearby frames.
    pub fn from_normal(n: Dir) -> Frame {
        let n = n.vec();
        let sign = 1f64.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let x = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let y = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { x, y, z: n }
    }

    /// The frame with z along `n` and x along the part of `reference` perpendicular to
    /// `n` (a sample's mounting direction); `None` if `reference` is parallel to `n`.
    pub fn from_normal_and_reference(n: Dir, reference: Vec3) -> Option<Frame> {
        let z = n.vec();
        let x = (reference - z * reference.dot(z)).normalized()?;
        Some(Frame {
            x,
            y: z.cross(x),
            z,
        })
    }

    /// Parent-frame vector → local coordinates.
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.x), v.dot(self.y), v.dot(self.z))
    }

    /// Local coordinates → parent-frame vector.
    #[inline]
    pub fn to_parent(&self, v: Vec3) -> Vec3 {
        self.x * v.x + self.y * v.y + self.z * v.z
    }

    /// A parent-frame direction in local coordinates.
    #[inline]
    pub fn dir_to_local(&self, d: Dir) -> Dir {
        Dir::from_unit(self.to_local(d.vec()))
    }

    /// A local direction in parent-frame coordinates.
    #[inline]
    pub fn dir_to_parent(&self, d: Dir) -> Dir {
        Dir::from_unit(self.to_parent(d.vec()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::SphericalDeg;
    use proptest::prelude::*;

    fn assert_orthonormal(f: &Frame) {
        for (a, b) in [(f.x, f.y), (f.y, f.z), (f.z, f.x)] {
            assert!(a.dot(b).abs() < 1e-14);
        }
        for v in [f.x, f.y, f.z] {
            assert!((v.norm() - 1.0).abs() < 1e-14);
        }
        // Right-handed.
        assert!((f.x.cross(f.y) - f.z).norm() < 1e-14);
    }

    proptest! {
        #[test]
        fn from_normal_is_orthonormal_and_round_trips(t in 0.0..180.0f64, p in 0.0..360.0f64,
                                                      vt in 0.0..180.0f64, vp in 0.0..360.0f64) {
            let n = Dir::from(SphericalDeg::new(t, p));
            let f = Frame::from_normal(n);
            assert_orthonormal(&f);
            let v = Dir::from(SphericalDeg::new(vt, vp));
            let back = f.to_parent(f.to_local(v.vec()));
            prop_assert!((back - v.vec()).norm() < 1e-14);
            // The normal itself is the local z axis.
            prop_assert!((f.to_local(n.vec()) - Vec3::Z).norm() < 1e-14);
        }
    }

    #[test]
    fn reference_direction_becomes_local_x() {
        let n = Dir::from(SphericalDeg::new(20.0, 30.0));
        let f = Frame::from_normal_and_reference(n, Vec3::X).expect("not parallel");
        assert_orthonormal(&f);
        let lx = f.to_local(Vec3::X);
        // The reference lies in the local x-z plane, on the +x side.
        assert!(lx.y.abs() < 1e-15 && lx.x > 0.0);
        assert!(Frame::from_normal_and_reference(Dir::Z, Vec3::Z * 2.0).is_none());
    }
}
