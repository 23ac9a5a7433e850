//! Goniometer kinematics: stage positions ↔ the direction pair `(wi, wo)` in the sample
//! frame of `docs/CONVENTIONS.md` (z the normal, x the mounting reference, y = z × x).
//!
//! Stage positions are in degrees (controller units) at the API; radians inside.
//!
//! # [`Layout::Spherical`]
//!
//! The stages are the spherical angles themselves, `[θi, φi, θo, φo]`.
//!
//! - Forward: `wi = (sin θi cos φi, sin θi sin φi, cos θi)`, `wo` likewise.
//! - Inverse: `θ = acos(z)` (computed as `atan2(√(x²+y²), z)`), `φ = atan2(y, x)`.
//!   φ is only defined modulo 360°: the representative closest to the hint is returned
//!   (a stage never travels the long way), in `[0, 360)` without a hint. At the pole
//!   (θ < 1e-12 rad) φ is undefined and the hint's φ is kept (0 without a hint), so the
//!   φ stage does not move for nothing.
//!
//! # [`Layout::CoplanarArms`]
//!
//! Stages `[source, detector, sample_rot, sample_tilt] = [αs, αd, ρ, τ]`. The source and
//! detector arms turn about the lab's vertical axis Z, so in the lab both directions are
//! horizontal: `s = (cos αs, sin αs, 0)`, `d = (cos αd, sin αd, 0)`. The sample turns by
//! ρ about its own normal, on a stage tilted by τ about the lab's +Y axis
//! (right-handed, `Ry(τ) = [[cos τ, 0, sin τ], [0, 1, 0], [−sin τ, 0, cos τ]]`). The
//! sample axes in the lab are
//!
//! ```text
//! x_s = Ry(τ)(cos ρ Z − sin ρ Y) = ( sin τ cos ρ, −sin ρ, cos τ cos ρ)
//! y_s = Ry(τ)(−sin ρ Z − cos ρ Y) = (−sin τ sin ρ, −cos ρ, −cos τ sin ρ)
//! z_s = Ry(τ) X                   = ( cos τ,        0,     −sin τ     )
//! ```
//!
//! so at ρ = τ = 0 the normal points along X, the reference x_s up along Z, and the arms
//! sweep the sample's y–z plane; at ρ = 90° they sweep its x–z plane.
//!
//! - Forward: `wi = (s·x_s, s·y_s, s·z_s)`, `wo = (d·x_s, d·y_s, d·z_s)`. Never fails;
//!   with `|αs| ≥ 90°` or `|αd| ≥ 90°` (for |τ| < 90°) a direction is at or below the
//!   surface, since `wi.z = cos τ cos αs`.
//! - Inverse. The lab vertical in the sample frame is the third row of the matrix
//!   above, `k = (Z·x_s, Z·y_s, Z·z_s) = (cos τ cos ρ, −cos τ sin ρ, −sin τ)`. Both
//!   directions are horizontal in the lab, so `k ⟂ wi, wo` and
//!   `wi × wo = sin(αd − αs) k`: `k = ±(wi × wo)/|wi × wo|` (computed as
//!   `wi × (wo − wi)`, which stays accurate when the directions are close). Each sign
//!   gives `τ = −asin(k_z)` (as `atan2(−k_z, √(k_x² + k_y²))`, |τ| ≤ 90°) and
//!   `ρ = atan2(−k_y, k_x)`; the sample frame is rebuilt from (ρ, τ), `wi` and `wo` are
//!   taken to the lab, checked to be horizontal, and `α = atan2(Y, X)` of each.
//!   The two signs are the mirror-image set-ups `(αs, αd, ρ, τ)` and
//!   `(−αs, −αd, ρ + 180°, −τ)` (the lab turned 180° about X); with |τ| ≤ 90° these
//!   are the only solutions, up to 360° on each stage. (Allowing |τ| > 90° would add
//!   `(αs + 180°, αd + 180°, ρ + 180°, 180° − τ)` and its twin: the sample hanging
//!   upside down.)
//!
//! Degenerate cases of the arms' inverse:
//! - `wi ∥ wo` (`|wi × (wo − wi)| ≤ 1e-14`: retro-reflection, which real arms cannot
//!   reach as the detector would sit on the source). Any k ⟂ wi works. The candidates
//!   are the horizontal ones (`k_z = 0`, so τ = 0, `k = ±(−wi.y, wi.x, 0)` normalised,
//!   or `k = ±x` at the pole) and, given a hint, the hint's own k projected
//!   perpendicular to wi (the least tilting and turning of the sample).
//! - τ = ±90° would make k the normal and both directions grazing: excluded, since the
//!   inverse rejects directions at or below the horizon ([`KinematicsError::BelowHorizon`]).
//!
//! Choice among candidates: with a hint, each stage angle is moved to its 360°
//! representative closest to the hint's, and the candidate with the least total motion
//! `Σ|Δ|` wins. Without a hint (or on a tie within 1e-9°), the smaller |τ| wins, then
//! the smaller |ρ|, then the larger ρ (so ρ = 90° beats −90°). Since the two signs have
//! the same |τ|, without a hint this returns ρ in [−90°, 90°], and α in (−180°, 180°].

use crate::{Dir, DirPair, Frame, SphericalDeg, Vec3, sin_cos_deg};

/// θ (radians) under which a direction counts as the pole, where φ is undefined.
const POLE_RAD: f64 = 1e-12;
/// `|wi × (wo − wi)|` under which the two directions count as parallel.
const PARALLEL: f64 = 1e-14;
/// Largest lab vertical component a direction may keep once taken back to the lab.
const OUT_OF_PLANE: f64 = 1e-9;
/// Total motions (degrees) closer than this count as a tie.
const TIE_DEG: f64 = 1e-9;

/// The mechanical layout of a goniometer: how its four stages make a direction pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Layout {
    /// Four stages that are the spherical angles `θi, φi, θo, φo` themselves.
    Spherical,
    /// Source and detector arms turning in one horizontal plane, and a sample on a
    /// rotation stage (about its normal) mounted on a tilt stage (about the lab's Y).
    CoplanarArms,
}

impl Layout {
    /// The four stage roles, in the order of the angle arrays.
    pub fn roles(self) -> [&'static str; 4] {
        match self {
            Layout::Spherical => ["theta_i", "phi_i", "theta_o", "phi_o"],
            Layout::CoplanarArms => ["source", "detector", "sample_rot", "sample_tilt"],
        }
    }

    /// Stage positions (degrees, controller units) → directions in the sample frame.
    ///
    /// Never fails: the directions may be below the surface (check with
    /// [`Dir::is_above`]); non-finite positions give non-finite directions.
    pub fn forward(self, stages_deg: [f64; 4]) -> DirPair {
        let [a, b, c, d] = stages_deg;
        match self {
            Layout::Spherical => DirPair::new(
                Dir::from(SphericalDeg::new(a, b)),
                Dir::from(SphericalDeg::new(c, d)),
            ),
            Layout::CoplanarArms => {
                let f = sample_frame(c, d);
                DirPair::new(unit(f.to_local(arm(a))), unit(f.to_local(arm(b))))
            }
        }
    }

    /// Directions → stage positions in degrees.
    ///
    /// `hint` is the current position: among equivalent solutions (φ at the pole, 360°
    /// turns, the two mirror-image set-ups of the arms) the one needing the least motion
    /// from it is returned. Fails for directions at or below the horizon, which no
    /// reflectometer measures, and for non-finite input.
    pub fn inverse(
        self,
        pair: DirPair,
        hint: Option<[f64; 4]>,
    ) -> Result<[f64; 4], KinematicsError> {
        check_dir("wi", pair.wi)?;
        check_dir("wo", pair.wo)?;
        if let Some(h) = hint
            && let Some(index) = h.iter().position(|v| !v.is_finite())
        {
            return Err(KinematicsError::NonFiniteHint {
                index,
                value: h[index],
            });
        }
        match self {
            Layout::Spherical => {
                let (ti, pi) = spherical_inverse(pair.wi, hint.map(|h| h[1]));
                let (to, po) = spherical_inverse(pair.wo, hint.map(|h| h[3]));
                Ok([ti, pi, to, po])
            }
            Layout::CoplanarArms => arms_inverse(pair, hint),
        }
    }
}

/// Angle in degrees between the source and the detector as seen from the sample, the
/// same in any frame: what decides whether the detector arm shadows the source.
pub fn arm_separation_deg(pair: DirPair) -> f64 {
    pair.wi.angle_to(pair.wo).to_degrees()
}

/// Why stage positions cannot be found for a direction pair.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KinematicsError {
    /// A direction has a non-finite component.
    #[error("direction {which} is not finite")]
    NonFiniteDirection {
        /// `wi` or `wo`.
        which: &'static str,
    },
    /// A direction is at or below the surface: neither a source nor a detector
    /// measures reflection from there.
    #[error("direction {which} at θ = {theta_deg}° is at or below the horizon")]
    BelowHorizon {
        /// `wi` or `wo`.
        which: &'static str,
        /// Its polar angle in degrees (≥ 90).
        theta_deg: f64,
    },
    /// A stage position of the hint is not finite.
    #[error("hint position {index} is not finite ({value})")]
    NonFiniteHint {
        /// Index of the stage in the angle array.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// The arms cannot reach the pair: a direction stays out of the arms' plane once
    /// taken back to the lab. A safeguard: the construction of k makes it unreachable.
    #[error("direction {which} is {residual:e} out of the arms' plane")]
    OutOfArmPlane {
        /// `wi` or `wo`.
        which: &'static str,
        /// Its lab vertical component.
        residual: f64,
    },
}

fn check_dir(which: &'static str, d: Dir) -> Result<(), KinematicsError> {
    if !d.vec().is_finite() {
        return Err(KinematicsError::NonFiniteDirection { which });
    }
    if d.z <= 0.0 {
        return Err(KinematicsError::BelowHorizon {
            which,
            theta_deg: d.theta().to_degrees(),
        });
    }
    Ok(())
}

/// `Dir::from_unit` for finite vectors; a NaN direction (without the debug assertion
/// firing) for non-finite stage input, since `forward` never fails.
fn unit(v: Vec3) -> Dir {
    if v.is_finite() {
        Dir::from_unit(v)
    } else {
        Dir::from_angles(f64::NAN, f64::NAN)
    }
}

/// The lab direction of an arm at `alpha_deg` from lab X towards lab Y.
fn arm(alpha_deg: f64) -> Vec3 {
    let (s, c) = sin_cos_deg(alpha_deg);
    Vec3::new(c, s, 0.0)
}

/// The sample axes in the lab for rotation `rho_deg` and tilt `tau_deg`.
fn sample_frame(rho_deg: f64, tau_deg: f64) -> Frame {
    let (sr, cr) = sin_cos_deg(rho_deg);
    let (st, ct) = sin_cos_deg(tau_deg);
    Frame {
        x: Vec3::new(st * cr, -sr, ct * cr),
        y: Vec3::new(-st * sr, -cr, -ct * sr),
        z: Vec3::new(ct, 0.0, -st),
    }
}

/// The representative `a + 360 k` closest to `h`.
fn nearest(a: f64, h: f64) -> f64 {
    a + 360.0 * ((h - a) / 360.0).round()
}

/// Wraps degrees into (−180, 180].
fn wrap180(a: f64) -> f64 {
    let r = a.rem_euclid(360.0);
    if r > 180.0 { r - 360.0 } else { r }
}

/// (θ, φ) in degrees of an above-horizon direction, φ following the hint.
fn spherical_inverse(d: Dir, phi_hint: Option<f64>) -> (f64, f64) {
    let theta = d.theta();
    let phi = if theta < POLE_RAD {
        phi_hint.unwrap_or(0.0)
    } else {
        let p = d.phi().to_degrees();
        match phi_hint {
            Some(h) => nearest(p, h),
            // `phi()` < 2π can still round to 360° in degrees.
            None if p >= 360.0 => p - 360.0,
            None => p,
        }
    };
    (theta.to_degrees(), phi)
}

/// The stage positions that put the lab vertical at `k` (a unit vector ⟂ both
/// directions) in the sample frame, canonically wrapped.
fn arms_candidate(k: Vec3, pair: DirPair) -> Result<[f64; 4], KinematicsError> {
    let tau = (-k.z).atan2(k.x.hypot(k.y)).to_degrees();
    let rho = (-k.y).atan2(k.x).to_degrees();
    let f = sample_frame(rho, tau);
    let mut alpha = [0.0; 2];
    for (a, (which, d)) in alpha.iter_mut().zip([("wi", pair.wi), ("wo", pair.wo)]) {
        let lab = f.to_parent(d.vec());
        if lab.z.abs() > OUT_OF_PLANE {
            return Err(KinematicsError::OutOfArmPlane {
                which,
                residual: lab.z,
            });
        }
        *a = wrap180(lab.y.atan2(lab.x).to_degrees());
    }
    Ok([alpha[0], alpha[1], wrap180(rho), tau])
}

fn arms_inverse(pair: DirPair, hint: Option<[f64; 4]>) -> Result<[f64; 4], KinematicsError> {
    let wi = pair.wi.vec();
    // wi × wo, but from the difference, which is exact for close directions.
    let c = wi.cross(pair.wo.vec() - wi);
    let n = c.norm();
    let mut ks: Vec<Vec3> = Vec::with_capacity(2);
    if n > PARALLEL {
        ks.push(c / n);
    } else {
        // Parallel: any k ⟂ wi. The horizontal one keeps the sample untilted.
        ks.push(Vec3::new(-wi.y, wi.x, 0.0).normalized().unwrap_or(Vec3::X));
        if let Some(h) = hint {
            // The hint's own lab vertical, made ⟂ wi: the least motion of the sample.
            let kh = sample_frame(h[2], h[3]).to_local(Vec3::Z);
            let p = kh - wi * kh.dot(wi);
            let pn = p.norm();
            if pn > 1e-6 {
                ks.push(p / pn);
            }
        }
    }
    let mut best: Option<([f64; 4], f64)> = None;
    for k in ks {
        for k in [k, -k] {
            let cand = arms_candidate(k, pair)?;
            let (cand, cost) = match hint {
                Some(h) => {
                    let mut moved = [0.0; 4];
                    let mut cost = 0.0;
                    for i in 0..4 {
                        moved[i] = nearest(cand[i], h[i]);
                        cost += (moved[i] - h[i]).abs();
                    }
                    (moved, cost)
                }
                None => (cand, 0.0),
            };
            if best.is_none_or(|(b, bc)| better(cand, cost, b, bc)) {
                best = Some((cand, cost));
            }
        }
    }
    // `ks` is never empty, so `best` is set; the fallback is unreachable.
    Ok(best.map_or([0.0; 4], |(b, _)| b))
}

/// Whether candidate `a` (total motion `ac`) beats `b`: less motion, then smaller
/// |τ|, then smaller |ρ|, then larger ρ (compared canonically wrapped).
fn better(a: [f64; 4], ac: f64, b: [f64; 4], bc: f64) -> bool {
    if (ac - bc).abs() > TIE_DEG {
        return ac < bc;
    }
    let (ta, tb) = (wrap180(a[3]).abs(), wrap180(b[3]).abs());
    if (ta - tb).abs() > TIE_DEG {
        return ta < tb;
    }
    let (ra, rb) = (wrap180(a[2]), wrap180(b[2]));
    if (ra.abs() - rb.abs()).abs() > TIE_DEG {
        return ra.abs() < rb.abs();
    }
    ra > rb + TIE_DEG
}
