//! The radiometric quantities of DeYoung 1996, Appendix A, that an instrument needs.
//!
//! Units are in the names: `_sr` for steradians, `_m` for metres, `_w` for watts (any
//! flux unit works where only ratios matter). A BRDF is in 1/sr.

use std::f64::consts::{PI, TAU};

use crate::quad::{Tolerance, integrate_pieces};

/// Solid angle (sr) of a cone of half-angle `half_angle` (radians): `2π (1 − cos a)`,
/// written as `4π sin²(a/2)` to stay accurate for small apertures.
pub fn cone_solid_angle_sr(half_angle: f64) -> f64 {
    let s = (0.5 * half_angle).sin();
    2.0 * TAU * s * s
}

/// A circular aperture (a detector's field stop) facing the sample.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Aperture {
    /// Radius of the aperture, m.
    pub radius_m: f64,
    /// Distance from the illuminated spot to the aperture's centre, m.
    pub distance_m: f64,
}

impl Aperture {
    /// Half-angle (radians) the aperture subtends at the sample: `atan(r / d)`.
    pub fn half_angle(&self) -> f64 {
        self.radius_m.atan2(self.distance_m)
    }

    /// Exact solid angle (sr) of the disc seen from the sample, on its axis:
    /// `2π (1 − d / √(d² + r²))`, in the cancellation-free form
    /// `2π r² / (√(d² + r²) (√(d² + r²) + d))`.
    pub fn solid_angle_sr(&self) -> f64 {
        let (r, d) = (self.radius_m, self.distance_m);
        let l = r.hypot(d);
        TAU * r * r / (l * (l + d))
    }

    /// The small-aperture approximation `A / d²` (sr) that most lab notes use; it
    /// overestimates the exact value by a relative `3 r² / (4 d²)` to first order.
    pub fn solid_angle_small_sr(&self) -> f64 {
        PI * self.radius_m * self.radius_m / (self.distance_m * self.distance_m)
    }
}

/// The azimuthal integral `∫₀^{2π} max(0, w·z) dβ` over the ring of directions `w` at
/// angle `α` (with `cos α = cos_alpha`) from an axis whose polar angle has cosine
/// `cos_theta_axis`: the projected-solid-angle density of that ring, clipped at the
/// horizon. Closed form: with `a = cos α cos θ`, `b = sin α sin θ`, it is `2πa` when the
/// ring is wholly above the horizon, 0 when wholly below, and
/// `2 (a · acos(−a/b) + √(b² − a²))` when the horizon cuts it.
///
/// This is what makes lobe albedos and projected solid angles one-dimensional integrals.
pub fn ring_projected_measure(cos_alpha: f64, cos_theta_axis: f64) -> f64 {
    let x = cos_alpha.clamp(-1.0, 1.0);
    let c = cos_theta_axis.clamp(-1.0, 1.0);
    let a = x * c;
    let b = ((1.0 - x * x) * (1.0 - c * c)).max(0.0).sqrt();
    if a >= b {
        TAU * a
    } else if a <= -b {
        0.0
    } else {
        2.0 * (a * (-a / b).acos() + (b * b - a * a).max(0.0).sqrt())
    }
}

/// The cosine of α at which a ring about an axis at polar angle θ first touches the
/// horizon: `sin θ` (rings with smaller α are wholly on one side). A kink of
/// [`ring_projected_measure`] as a function of `cos α`, so a break point for quadrature.
pub fn ring_horizon_break(cos_theta_axis: f64) -> f64 {
    (1.0 - cos_theta_axis * cos_theta_axis).max(0.0).sqrt()
}

/// Projected solid angle (sr) `∫ cos θ dω` over the part above the horizon of a circular
/// cone of half-angle `half_angle` about a direction at polar angle `theta` (radians).
///
/// When the cone is wholly above the horizon this is exactly `π sin²a cos θ` (the area
/// of the ellipse the cap projects to); otherwise it is integrated ring by ring.
/// Multiplied by a radiance it gives the irradiance the cone delivers (Eq. A.9).
pub fn cone_projected_solid_angle_sr(half_angle: f64, theta: f64) -> f64 {
    if theta + half_angle <= 0.5 * PI {
        let s = half_angle.sin();
        return PI * s * s * theta.cos();
    }
    let c = theta.cos();
    let x0 = half_angle.cos();
    // Kinks where the horizon starts and stops cutting the rings: x = ±sin θ.
    let k = ring_horizon_break(c);
    let mut breaks = vec![x0];
    for b in [-k, k] {
        if b > x0 && b < 1.0 {
            breaks.push(b);
        }
    }
    breaks.push(1.0);
    integrate_pieces(
        |x| ring_projected_measure(x, c),
        &breaks,
        Tolerance::new(1e-15, 1e-13),
    )
    .value
}

/// BRDF (1/sr) from a measurement of reflected and incident flux: DeYoung Eq. A.15,
/// `f_r = dL_r / dE`, with the irradiance `E = Φ_i / A` of a beam that lights area `A`
/// and the reflected radiance `L_r = Φ_r / (A cos θ_o Ω)` seen by a detector of solid
/// angle `Ω`, so that `f_r = Φ_r / (Φ_i Ω cos θ_o)`.
pub fn brdf_from_flux_ratio(
    reflected_w: f64,
    incident_w: f64,
    detector_solid_angle_sr: f64,
    cos_theta_o: f64,
) -> f64 {
    reflected_w / (incident_w * detector_solid_angle_sr * cos_theta_o)
}

/// The reflected flux (same unit as `incident_w`) a detector of solid angle `Ω`
/// collects from a sample of BRDF `f_r`: the inverse of [`brdf_from_flux_ratio`].
pub fn reflected_flux(
    brdf_per_sr: f64,
    incident_w: f64,
    detector_solid_angle_sr: f64,
    cos_theta_o: f64,
) -> f64 {
    brdf_per_sr * incident_w * detector_solid_angle_sr * cos_theta_o
}

/// Reflectance factor `R = π f_r` (Eq. A.17): the ratio to a perfectly diffuse
/// reflector, for which `f_r = 1/π`.
pub fn reflectance_factor(brdf_per_sr: f64) -> f64 {
    PI * brdf_per_sr
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quad::integrate_2d;

    #[test]
    fn whole_hemisphere_cone_has_projected_solid_angle_pi() {
        assert!((cone_projected_solid_angle_sr(0.5 * PI, 0.0) - PI).abs() < 1e-14);
        assert!((cone_solid_angle_sr(0.5 * PI) - TAU).abs() < 1e-14);
        assert!((cone_solid_angle_sr(PI) - 2.0 * TAU).abs() < 1e-14);
    }

    #[test]
    fn aperture_solid_angle_exact_and_small() {
        // r = 5 mm at 0.5 m: Ω = 2π(1 − 0.5/√(0.25 + 2.5e-5)).
        let a = Aperture {
            radius_m: 0.005,
            distance_m: 0.5,
        };
        let exact = TAU * (1.0 - 0.5 / (0.25f64 + 2.5e-5).sqrt());
        assert!((a.solid_angle_sr() - exact).abs() < 1e-15);
        assert!((a.solid_angle_sr() - cone_solid_angle_sr(a.half_angle())).abs() < 1e-17);
        let rel = a.solid_angle_small_sr() / a.solid_angle_sr() - 1.0;
        assert!((rel - 0.75 * 1e-4).abs() < 1e-8, "{rel}");
    }

    /// Brute force: ∫∫ max(0, w_z) over the cap by 2-D cubature in (α, β).
    fn projected_by_cubature(half_angle: f64, theta: f64) -> f64 {
        let (st, ct) = theta.sin_cos();
        integrate_2d(
            |alpha, beta, out| {
                let (sa, ca) = alpha.sin_cos();
                // w = cos α · axis + sin α (cos β · t) with t the axis' tangent in the x-z plane
                let wz = ca * ct - sa * beta.cos() * st;
                out[0] = wz.max(0.0) * sa;
            },
            [0.0, half_angle],
            [0.0, TAU],
            1,
            Tolerance::new(1e-12, 0.0),
        )
        .values[0]
    }

    #[test]
    fn projected_solid_angle_matches_cubature_across_the_horizon() {
        for (a, t) in [
            (0.1, 0.3),
            (0.2, 1.45),
            (0.3, 1.5),
            (0.05, 1.55),
            (1.0, 1.0),
            (1.8, 0.4),
        ] {
            let fast = cone_projected_solid_angle_sr(a, t);
            let slow = projected_by_cubature(a, t);
            assert!((fast - slow).abs() < 1e-9, "a={a} θ={t}: {fast} vs {slow}");
        }
    }

    #[test]
    fn cone_containing_the_hemisphere_projects_to_pi() {
        // Half-angle 2 rad = 114.6° about an axis at 22.9°: every upper direction is
        // within 112.9° of the axis.
        assert!((cone_projected_solid_angle_sr(2.0, 0.4) - PI).abs() < 1e-13);
    }

    #[test]
    fn ring_measure_limits() {
        // Axis at the normal: every ring is above (for α < 90°) and contributes 2π cos α.
        assert!((ring_projected_measure(0.6, 1.0) - TAU * 0.6).abs() < 1e-15);
        // Axis on the horizon: the ring of α = 90° is the meridian, half above the horizon.
        assert!((ring_projected_measure(0.0, 0.0) - 2.0).abs() < 1e-15);
        assert_eq!(ring_projected_measure(-0.9, 0.9), 0.0);
    }

    #[test]
    fn perfect_diffuser_has_reflectance_factor_one() {
        assert!((reflectance_factor(1.0 / PI) - 1.0).abs() < 1e-15);
    }
}
