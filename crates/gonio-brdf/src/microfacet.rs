//! Microfacet distributions and Smith masking–shadowing (Heitz 2014, "Understanding
//! the Masking-Shadowing Function in Microfacet-Based BRDFs", JCGT 3(2)).
//!
//! Both distributions are anisotropic with roughness `αx` along the sample's x axis and
//! `αy` along y; isotropic when they are equal. All functions take local vectors.

use std::f64::consts::{PI, TAU};

use gonio_core::special::erfcx;
use gonio_core::{Dir, Vec3};

/// The normal distribution function of a microfacet model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Distribution {
    /// Beckmann: `D = exp(−(hx²/αx² + hy²/αy²)/hz²) / (π αx αy hz⁴)`.
    Beckmann,
    /// GGX (Trowbridge–Reitz): `D = 1 / (π αx αy (hx²/αx² + hy²/αy² + hz²)²)`.
    Ggx,
}

impl Distribution {
    /// The name used in model files.
    pub fn name(self) -> &'static str {
        match self {
            Distribution::Beckmann => "beckmann",
            Distribution::Ggx => "ggx",
        }
    }

    /// `D(h)` (1/sr), normalised so that `∫ D(h) cos θh dωh = 1`; zero for `hz ≤ 0`.
    #[inline]
    pub fn d(self, h: Vec3, ax: f64, ay: f64) -> f64 {
        if h.z <= 0.0 {
            return 0.0;
        }
        let sx = h.x / ax;
        let sy = h.y / ay;
        let z2 = h.z * h.z;
        match self {
            Distribution::Beckmann => {
                let e = (sx * sx + sy * sy) / z2;
                (-e).exp() / (PI * ax * ay * z2 * z2)
            }
            Distribution::Ggx => {
                let k = sx * sx + sy * sy + z2;
                1.0 / (PI * ax * ay * k * k)
            }
        }
    }

    /// Smith's `Λ(v)` for the direction `v` (Heitz 2014's closed forms for Beckmann
    /// and GGX, with the anisotropic roughness projected on `v`'s azimuth,
    /// `α(φ)² = cos²φ αx² + sin²φ αy²`). Zero at the normal.
    #[inline]
    pub fn lambda(self, v: Vec3, ax: f64, ay: f64) -> f64 {
        // s = α(φ)² tan²θ = 1/a² in Heitz's notation.
        let num = (v.x * ax).powi(2) + (v.y * ay).powi(2);
        if num == 0.0 {
            return 0.0;
        }
        let s = num / (v.z * v.z);
        match self {
            Distribution::Beckmann => {
                // Λ = (erf(a) − 1)/2 + e^{−a²}/(2a√π) = e^{−a²}/2 · (1/(a√π) − erfcx(a)).
                let a = 1.0 / s.sqrt();
                if a > 26.0 {
                    // e^{−a²} < 1e-293: Λ underflows.
                    return 0.0;
                }
                0.5 * (-a * a).exp() * (1.0 / (a * PI.sqrt()) - erfcx(a))
            }
            // (√(1+s) − 1)/2 without cancellation for small s.
            Distribution::Ggx => 0.5 * s / ((1.0 + s).sqrt() + 1.0),
        }
    }

    /// Smith's monodirectional masking `G1(v) = 1 / (1 + Λ(v))` (for `v·h > 0`).
    #[inline]
    pub fn g1(self, v: Vec3, ax: f64, ay: f64) -> f64 {
        1.0 / (1.0 + self.lambda(v, ax, ay))
    }

    /// The height-correlated masking–shadowing of Heitz 2014:
    /// `G2 = 1 / (1 + Λ(wi) + Λ(wo))`, for directions on the same side as the facet.
    #[inline]
    pub fn g2(self, wi: Vec3, wo: Vec3, ax: f64, ay: f64) -> f64 {
        1.0 / (1.0 + self.lambda(wi, ax, ay) + self.lambda(wo, ax, ay))
    }

    /// Draws a half vector with density `D(h) cos θh` from `u` in [0, 1)².
    ///
    /// φ from `atan2(αy sin 2πu₂, αx cos 2πu₂)`; then `tan²θ = −ln(1−u₁)/A(φ)`
    /// (Beckmann) or `u₁/((1−u₁) A(φ))` (GGX), with `A(φ) = cos²φ/αx² + sin²φ/αy²`.
    #[inline]
    pub fn sample_h(self, u: [f64; 2], ax: f64, ay: f64) -> Dir {
        let (s2, c2) = (TAU * u[1]).sin_cos();
        let phi_y = ay * s2;
        let phi_x = ax * c2;
        let r = phi_x.hypot(phi_y);
        let (sp, cp) = if r > 0.0 {
            (phi_y / r, phi_x / r)
        } else {
            (0.0, 1.0)
        };
        let a = (cp / ax).powi(2) + (sp / ay).powi(2);
        let tan2 = match self {
            Distribution::Beckmann => -(-u[0]).ln_1p() / a,
            Distribution::Ggx => u[0] / ((1.0 - u[0]) * a),
        };
        let cos_t = 1.0 / (1.0 + tan2).sqrt();
        let sin_t = (tan2 / (1.0 + tan2)).sqrt();
        Dir::from_unit(Vec3::new(sin_t * cp, sin_t * sp, cos_t))
    }

    /// The density (1/sr) of [`sample_h`](Self::sample_h): `D(h) cos θh`.
    #[inline]
    pub fn pdf_h(self, h: Vec3, ax: f64, ay: f64) -> f64 {
        self.d(h, ax, ay) * h.z.max(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gonio_core::quad::{Tolerance, integrate_2d};

    /// ∫ D(h) cos θh dωh over the hemisphere, in (θ, φ).
    fn projected_area(d: Distribution, ax: f64, ay: f64) -> f64 {
        integrate_2d(
            |t, p, out| {
                let h = Dir::from_angles(t, p);
                out[0] = d.d(h.vec(), ax, ay) * h.z * t.sin();
            },
            [0.0, 0.5 * PI],
            [0.0, TAU],
            1,
            Tolerance::new(1e-11, 0.0),
        )
        .values[0]
    }

    #[test]
    fn distributions_are_normalised() {
        for d in [Distribution::Beckmann, Distribution::Ggx] {
            for (ax, ay) in [(0.1, 0.1), (0.5, 0.5), (0.2, 0.6), (0.9, 0.3)] {
                let a = projected_area(d, ax, ay);
                assert!((a - 1.0).abs() < 2e-9, "{d:?} {ax} {ay}: {a}");
            }
        }
    }

    /// Heitz 2014's constraint on visible microfacets: the projected area of the visible microfacets equals the
    /// projected area of the macrosurface, `∫ G1(v) ⟨v·h⟩ D(h) dωh = cos θv`. It holds
    /// exactly for Smith's Λ of each distribution, so it checks Λ against D.
    #[test]
    fn smith_lambda_satisfies_the_visible_area_constraint() {
        for d in [Distribution::Beckmann, Distribution::Ggx] {
            for (ax, ay) in [(0.3, 0.3), (0.15, 0.5)] {
                for (tv, pv) in [(0.0, 0.0), (0.7, 0.3), (1.3, 2.0), (1.5, 4.0)] {
                    let v = Dir::from_angles(tv, pv).vec();
                    let g1 = d.g1(v, ax, ay);
                    let lhs = integrate_2d(
                        |t, p, out| {
                            let h = Dir::from_angles(t, p).vec();
                            out[0] = g1 * v.dot(h).max(0.0) * d.d(h, ax, ay) * t.sin();
                        },
                        [0.0, 0.5 * PI],
                        [0.0, TAU],
                        1,
                        Tolerance::new(1e-11, 0.0),
                    )
                    .values[0];
                    assert!((lhs - v.z).abs() < 1e-8, "{d:?} θ={tv}: {lhs} vs {}", v.z);
                }
            }
        }
    }

    #[test]
    fn lambda_known_values() {
        // GGX, α = 0.5, θ = 60°: s = 0.25·3 = 0.75, Λ = (√1.75 − 1)/2.
        let v = Dir::from_angles(PI / 3.0, 0.0).vec();
        let l = Distribution::Ggx.lambda(v, 0.5, 0.5);
        assert!((l - (1.75f64.sqrt() - 1.0) / 2.0).abs() < 1e-15);
        // Beckmann, a = 1: Λ = (erf(1) − 1)/2 + e^{−1}/(2√π).
        let t = (1.0f64 / 0.5).atan(); // tan θ = 2, α = 0.5 → a = 1
        let v = Dir::from_angles(t, 1.0).vec();
        let l = Distribution::Beckmann.lambda(v, 0.5, 0.5);
        let expect =
            (0.842700792949714869341220635083 - 1.0) / 2.0 + (-1.0f64).exp() / (2.0 * PI.sqrt());
        assert!((l - expect).abs() < 1e-15, "{l} vs {expect}");
    }
}
