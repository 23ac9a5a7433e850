//! Integrals of a cosine lobe `max(0, a·v)ⁿ` about a unit axis `a`, in closed form where
//! one exists and semi-analytically where the horizon cuts the lobe.
//!
//! They give the exact albedo of every lobe-based model (the cosine lobe of
//! Lafortune et al. Eq. 1–2, the generalized lobes of Eq. 3–8, whose Eq. 5 writes each
//! as a scaled cosine lobe about `u'`) and the power of the Eq. 7 mirror term.

use std::f64::consts::{FRAC_PI_2, TAU};

use gonio_core::quad::{Tolerance, integrate_pieces};
use gonio_core::radiometry::{ring_horizon_break, ring_projected_measure};

/// `∫ max(0, a·v)ⁿ dω` over the whole sphere: `2π/(n+1)`.
#[inline]
pub fn sphere_integral(n: f64) -> f64 {
    TAU / (n + 1.0)
}

/// `∫_{v_z>0} max(0, a·v)ⁿ v_z dω`, the albedo of a unit cosine lobe whose axis `a` has
/// `a_z = axis_z`.
///
/// Writing `x = cos α` for the angle from the axis, the integral over the ring of
/// directions at angle α is the closed form `ring(x) = ring_projected_measure(x, a_z)`,
/// so `I = ∫₀¹ xⁿ ring(x) dx`. Rings with `x > k = √(1 − a_z²)` lie wholly on one side
/// of the horizon, where `ring(x) = 2π x a_z` (or 0), which integrates in closed form
/// to `2π a_z (1 − k^{n+2})/(n+2)`. The rings the horizon cuts, `x < k`, make the
/// integrand singular at `x = k` (like `(k − x)^{3/2}`); the substitution `x = k sin ψ`
/// removes that, leaving a
/// smooth integrand on [0, π/2] for adaptive Gauss–Kronrod. Relative accuracy ~1e-12
/// for any `n ≥ 0`, in a few dozen evaluations.
pub fn hemisphere_albedo(n: f64, axis_z: f64) -> f64 {
    let c = axis_z.clamp(-1.0, 1.0);
    let k = ring_horizon_break(c);
    let whole = if c > 0.0 {
        TAU * c * (1.0 - k.powf(n + 2.0)) / (n + 2.0)
    } else {
        0.0
    };
    if k == 0.0 {
        return whole;
    }
    let cut = integrate_pieces(
        |psi| {
            let (s, co) = psi.sin_cos();
            let x = k * s;
            let w = if n == 0.0 { 1.0 } else { x.powf(n) };
            w * ring_projected_measure(x, c) * k * co
        },
        &[0.0, FRAC_PI_2],
        Tolerance::new(1e-16, 1e-13),
    );
    whole + cut.value
}

/// The albedo of the *clipped* cosine lobe centred at the normal: `2π/(n+2)`.
#[inline]
pub fn normal_albedo(n: f64) -> f64 {
    TAU / (n + 2.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use gonio_core::Dir;
    use gonio_core::quad::integrate_2d;
    use std::f64::consts::PI;

    /// Brute force in the sample's own (θ, φ) coordinates, with the lobe axis at polar
    /// angle `theta_a`: no use of the ring formula.
    fn brute(n: f64, theta_a: f64) -> f64 {
        let a = Dir::from_angles(theta_a, 0.0);
        integrate_2d(
            |t, p, out| {
                let v = Dir::from_angles(t, p);
                let d = a.dot(*v);
                // Negative values count as 0 (and 0⁰ must not become 1).
                out[0] = if d > 0.0 {
                    d.powf(n) * v.z * t.sin()
                } else {
                    0.0
                };
            },
            [0.0, 0.5 * PI],
            [0.0, 2.0 * PI],
            1,
            Tolerance::new(1e-13, 1e-11),
        )
        .values[0]
    }

    #[test]
    fn matches_brute_force_for_moderate_exponents() {
        // (For n < 1 the lobe's edge is a step or a square-root cusp along a curve, which
        // the brute-force cubature resolves only to ~1e-8; those exponents are checked
        // against closed forms and the mpmath reference instead.)
        for n in [1.0, 2.58, 18.6, 63.8] {
            for deg in [0.0, 10.0, 45.0, 80.0, 89.0, 90.0, 100.0, 135.0] {
                let t: f64 = f64::to_radians(deg);
                let fast = hemisphere_albedo(n, t.cos());
                let slow = brute(n, t);
                // The brute-force rule is the less accurate of the two (the lobe's edge is
                // a kink it must chase); see `matches_high_precision_reference`.
                assert!(
                    (fast - slow).abs() < 1e-9 * slow.max(1e-3),
                    "n={n} θa={deg}: {fast} vs {slow}"
                );
            }
        }
    }

    /// `∫₀¹ xⁿ ring(x) dx` by mpmath's tanh-sinh quadrature at 30 digits, split at the
    /// horizon break (`tests/reference/lobe_albedo.py`). It uses the same closed form for
    /// the ring, so it checks the quadrature and the substitutions; the ring formula
    /// itself is checked against brute force above and the closed forms below.
    #[test]
    fn matches_high_precision_reference() {
        let cases = [
            (0.5, 10.0, 2.47995869400730383559687830416),
            (18.6, 80.0, 0.0618144367313816921039907867961),
            (63.8, 89.0, 0.00562998259076636249734229106913),
            (1000.0, 60.0, 0.00313532200957065193459345647034),
            (1000.0, 89.5, 0.000109441517494563224453668604998),
        ];
        for (n, deg, want) in cases {
            let got = hemisphere_albedo(n, f64::to_radians(deg).cos());
            assert!(
                (got - want).abs() < 1e-12 * want,
                "n={n} θ={deg}: {got} vs {want}"
            );
        }
    }

    #[test]
    fn closed_forms() {
        // Axis at the normal: 2π/(n+2).
        assert!((hemisphere_albedo(20.0, 1.0) - TAU / 22.0).abs() < 1e-15);
        // Axis along +x on the horizon, n = 0: ∫ v_z over the quarter sphere
        // {v_z > 0, v_x > 0} = π/2.
        assert!((hemisphere_albedo(0.0, 0.0) - PI / 2.0).abs() < 1e-12);
        // n = 1: ∫ v_x v_z over the same quarter = (∫cos φ dφ)(∫sin²θ cos θ dθ) = 2 · 1/3.
        assert!((hemisphere_albedo(1.0, 0.0) - 2.0 / 3.0).abs() < 1e-12);
        // n = 0: ∫ v_z over {v_z > 0, a·v > 0} = π (1 + a_z)/2, from ∫_{a·v>0} v_z dω = π a_z
        // and ∫_{v_z>0} v_z dω = π split along a·v = 0.
        for deg in [0.0f64, 10.0, 50.0, 89.0, 120.0] {
            let az = deg.to_radians().cos();
            let exact = PI * (1.0 + az) / 2.0;
            assert!((hemisphere_albedo(0.0, az) - exact).abs() < 1e-12, "{deg}");
        }
        // A lobe pointing straight down reflects nothing above the surface.
        assert_eq!(hemisphere_albedo(5.0, -1.0), 0.0);
    }
}
