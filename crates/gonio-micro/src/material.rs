//! What a facet does to a ray: the microscale reflection models (Westin et al. Sec. 4:
//! each ray carries an energy, attenuated at every bounce; here one energy per
//! channel).
//!
//! - [`Material::Mirror`]: ideal specular reflection with a fixed reflectance per
//!   channel (`F = 1` for the validation against microfacet theory).
//! - [`Material::Conductor`]: ideal specular reflection weighted by the exact Fresnel
//!   reflectance of a conductor of complex index `n + ik`, unpolarised
//!   ([`fresnel_conductor`]).
//! - [`Material::Dielectric`]: ideal specular reflection weighted by the dielectric
//!   Fresnel reflectance from air ([`fresnel_dielectric`]); the transmitted part is
//!   absorbed (no subsurface or transmission through the facet is modelled).
//! - [`Material::Lambert`]: a new direction drawn with density `cos θ/π` about the
//!   facet normal, the energy multiplied by the albedo (`f cos θ / pdf = ρ`).
//! - [`Material::Model`]: any gonio-brdf model in the facet's frame (z along the facet
//!   normal, x along the macro-surface's x projected onto the facet): a direction
//!   drawn with the model's own sampler, the energy multiplied by `f cos θ / pdf`
//!   (or by the mirror reflectance over its probability for a delta sample).

use std::f64::consts::TAU;

use gonio_brdf::{Brdf, Model};
use gonio_core::{Dir, Frame, Vec3};
use rand::Rng;

/// A facet's reflection model. Every per-channel list has one value a channel.
#[derive(Clone, Debug, PartialEq)]
pub enum Material {
    /// Ideal mirror with reflectance per channel.
    Mirror {
        /// Reflectance per channel, in [0, 1].
        reflectance: Vec<f64>,
    },
    /// Ideal mirror with the Fresnel reflectance of a conductor.
    Conductor {
        /// Real part of the index per channel.
        n: Vec<f64>,
        /// Extinction coefficient per channel.
        k: Vec<f64>,
    },
    /// Ideal mirror with the Fresnel reflectance of a dielectric (transmission
    /// absorbed).
    Dielectric {
        /// Relative index per channel.
        eta: Vec<f64>,
    },
    /// Lambertian reflection.
    Lambert {
        /// Albedo per channel, in [0, 1].
        albedo: Vec<f64>,
    },
    /// A gonio-brdf model at the microscale.
    Model(Box<Model>),
}

/// The exact unpolarised Fresnel reflectance of a conductor of complex index
/// `eta + i·k` in air, for the cosine `cos_i` of the angle of incidence (Born & Wolf
/// Sec. 14.4; the form of pbrt-v3's `FrConductor`): with `a² + b² =
/// √((η² − k² − sin²θ)² + 4η²k²)` and `a = √((a² + b² + η² − k² − sin²θ)/2)`,
/// `Rs = (a²+b² + cos²θ − 2a cosθ)/(a²+b² + cos²θ + 2a cosθ)` and
/// `Rp = Rs (cos²θ (a²+b²) + sin⁴θ − 2a cosθ sin²θ)/(cos²θ (a²+b²) + sin⁴θ + 2a cosθ sin²θ)`.
pub fn fresnel_conductor(cos_i: f64, eta: f64, k: f64) -> f64 {
    let c = cos_i.clamp(0.0, 1.0);
    let c2 = c * c;
    let s2 = 1.0 - c2;
    let t0 = eta * eta - k * k - s2;
    let a2b2 = (t0 * t0 + 4.0 * eta * eta * k * k).sqrt();
    let t1 = a2b2 + c2;
    let a = (0.5 * (a2b2 + t0)).max(0.0).sqrt();
    let t2 = 2.0 * a * c;
    let t3 = c2 * a2b2 + s2 * s2;
    let t4 = t2 * s2;
    // (Rs + Rp)/2 = Rs (1 + (t3 − t4)/(t3 + t4))/2 = Rs t3/(t3 + t4): one division,
    // not three (this runs at every bounce on a conductor).
    ((t1 - t2) * t3 / ((t1 + t2) * (t3 + t4))).clamp(0.0, 1.0)
}

/// The unpolarised Fresnel reflectance from air onto a dielectric of relative index
/// `eta`, for the cosine `cos_i` of the angle of incidence (Fresnel's equations:
/// `rs = (cos θi − η cos θt)/(cos θi + η cos θt)`, `rp = (η cos θi − cos θt)/(η cos θi
/// + cos θt)`, `R = (rs² + rp²)/2`); 1 under total internal reflection (`eta < 1`).
pub fn fresnel_dielectric(cos_i: f64, eta: f64) -> f64 {
    let c = cos_i.clamp(0.0, 1.0);
    let s2t = (1.0 - c * c) / (eta * eta);
    if s2t >= 1.0 {
        return 1.0;
    }
    let ct = (1.0 - s2t).sqrt();
    let rs = (c - eta * ct) / (c + eta * ct);
    let rp = (eta * c - ct) / (eta * c + ct);
    0.5 * (rs * rs + rp * rp)
}

/// Scratch space for [`Material::scatter`], reused across rays.
#[derive(Clone, Debug, Default)]
pub(crate) struct Scratch {
    f: Vec<f64>,
}

impl Scratch {
    pub(crate) fn new(nc: usize) -> Scratch {
        Scratch { f: vec![0.0; nc] }
    }
}

/// A uniform number in [0, 1).
#[inline]
pub(crate) fn uniform<R: Rng>(rng: &mut R) -> f64 {
    rng.random::<f64>()
}

impl Material {
    /// Reflects a ray travelling along `d` off a facet of unit normal `n` (with
    /// `d·n < 0`), multiplying `weight` (one entry a channel) by the reflectance; the
    /// new direction, or `None` when the ray is absorbed.
    pub(crate) fn scatter<R: Rng>(
        &self,
        d: Vec3,
        n: Vec3,
        rng: &mut R,
        weight: &mut [f64],
        scratch: &mut Scratch,
    ) -> Option<Vec3> {
        let cos_i = -d.dot(n);
        let mirror = || d + n * (2.0 * cos_i);
        match self {
            Material::Mirror { reflectance } => {
                weight
                    .iter_mut()
                    .zip(reflectance)
                    .for_each(|(w, r)| *w *= r);
                Some(mirror())
            }
            Material::Conductor { n: eta, k } => {
                for (c, w) in weight.iter_mut().enumerate() {
                    *w *= fresnel_conductor(cos_i, eta[c], k[c]);
                }
                Some(mirror())
            }
            Material::Dielectric { eta } => {
                for (c, w) in weight.iter_mut().enumerate() {
                    *w *= fresnel_dielectric(cos_i, eta[c]);
                }
                Some(mirror())
            }
            Material::Lambert { albedo } => {
                weight.iter_mut().zip(albedo).for_each(|(w, a)| *w *= a);
                let (u0, u1) = (uniform(rng), uniform(rng));
                let r = u0.sqrt();
                let (s, c) = (TAU * u1).sin_cos();
                let local = Vec3::new(r * c, r * s, (1.0 - u0).max(0.0).sqrt());
                let frame = Frame::from_normal(Dir::from_unit(n));
                Some(frame.to_parent(local))
            }
            Material::Model(m) => {
                let nd = Dir::from_unit(n);
                let frame = Frame::from_normal_and_reference(nd, Vec3::X)
                    .unwrap_or_else(|| Frame::from_normal(nd));
                let wi = Dir::new(frame.to_local(-d))?;
                let (uc, u0, u1) = (uniform(rng), uniform(rng), uniform(rng));
                let s = m.sample(wi, uc, [u0, u1])?;
                let f = &mut scratch.f;
                if s.delta {
                    if !m.mirror(wi, f) || s.pdf <= 0.0 {
                        return None;
                    }
                    for (w, r) in weight.iter_mut().zip(f.iter()) {
                        *w *= r / s.pdf;
                    }
                } else {
                    if s.pdf <= 0.0 {
                        return None;
                    }
                    m.eval(wi, s.wo, f);
                    let k = s.wo.z / s.pdf;
                    for (w, v) in weight.iter_mut().zip(f.iter()) {
                        *w *= v * k;
                    }
                }
                Some(frame.to_parent(s.wo.vec()))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conductor_reduces_to_dielectric_and_normal_incidence() {
        for &c in &[1.0, 0.9, 0.5, 0.2, 0.01] {
            for &eta in &[1.33, 1.5, 2.4] {
                let a = fresnel_conductor(c, eta, 0.0);
                let b = fresnel_dielectric(c, eta);
                assert!((a - b).abs() < 1e-13, "cos {c} η {eta}: {a} vs {b}");
            }
        }
        // ((n−1)² + k²)/((n+1)² + k²) at normal incidence: gold at 550 nm-ish.
        let (n, k) = (0.43, 2.45);
        let r0 = ((n - 1.0f64).powi(2) + k * k) / ((n + 1.0f64).powi(2) + k * k);
        assert!((fresnel_conductor(1.0, n, k) - r0).abs() < 1e-14);
        // Grazing: 1.
        assert!((fresnel_conductor(0.0, n, k) - 1.0).abs() < 1e-12);
        assert!((fresnel_dielectric(0.0, 1.5) - 1.0).abs() < 1e-12);
        // Brewster's angle: Rp = 0, so R = Rs²/2.
        let tb = 1.5f64.atan();
        let ct = (1.0 - (tb.sin() / 1.5).powi(2)).sqrt();
        let rs = (tb.cos() - 1.5 * ct) / (tb.cos() + 1.5 * ct);
        assert!((fresnel_dielectric(tb.cos(), 1.5) - 0.5 * rs * rs).abs() < 1e-15);
    }
}
