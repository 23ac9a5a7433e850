//! The real spherical harmonics of DeYoung Eq. 3.4–3.6 and their evaluation: the
//! hemisphere-even basis, the whole-sphere basis, and the degree taper.

use std::f64::consts::{FRAC_1_SQRT_2, PI, TAU};

use gonio_core::Dir;

/// The hemisphere-even basis of degree `l_max`: `(l, m)` for `l = 0..=l_max`,
/// `m = −l..=l` with `l + m` even, in that order; `(l_max + 1)(l_max + 2)/2` entries.
pub fn basis(l_max: usize) -> Vec<(usize, i64)> {
    let mut b = Vec::with_capacity(basis_len(l_max));
    for l in 0..=l_max {
        let li = l as i64;
        b.extend((-li..=li).filter(|m| (li + m) % 2 == 0).map(|m| (l, m)));
    }
    b
}

/// Number of functions in [`basis`]`(l_max)`.
pub fn basis_len(l_max: usize) -> usize {
    (l_max + 1) * (l_max + 2) / 2
}

/// All `Y_lm` of [`basis`]`(l_max)` at `dir`, in basis order, into `out` (cleared
/// first). DeYoung Eq. 3.4–3.6; valid on the whole sphere and accurate up to
/// [`MAX_L_MAX`](super::MAX_L_MAX).
pub fn eval_basis(l_max: usize, dir: Dir, out: &mut Vec<f64>) {
    let (t, s, cp, sp) = polar_parts(dir);
    fill_basis(l_max, t, s, cp, sp, true, out);
}

/// Every real `Y_lm`, `l ≤ l_max`, `m = −l..=l` (the whole-sphere basis, of which
/// [`eval_basis`] keeps the hemisphere-even half), at `dir`, into `out`.
pub fn eval_full_basis(l_max: usize, dir: Dir, out: &mut Vec<f64>) {
    let (t, s, cp, sp) = polar_parts(dir);
    fill_basis(l_max, t, s, cp, sp, false, out);
}

/// The attenuation of degree `l` (Westin et al. Sec. 2.5): 1 for `l ≤ l_filter`, then
/// the cosine taper `½ (1 + cos(π (l − l_filter)/(l_max − l_filter + 1)))`, which
/// falls smoothly and would reach 0 at `l_max + 1`; 0 beyond `l_max`.
pub fn taper(l: usize, l_filter: usize, l_max: usize) -> f64 {
    if l <= l_filter {
        1.0
    } else if l > l_max {
        0.0
    } else {
        let x = (l - l_filter) as f64 / (l_max - l_filter + 1) as f64;
        0.5 * (1.0 + (PI * x).cos())
    }
}

/// cos θ, sin θ, cos φ, sin φ of a direction; φ = 0 at the poles, where every m ≠ 0
/// term vanishes anyway.
fn polar_parts(dir: Dir) -> (f64, f64, f64, f64) {
    let v = dir.vec();
    let s = dir.sin_theta();
    if s > 0.0 {
        (v.z, s, v.x / s, v.y / s)
    } else {
        (v.z, 0.0, 1.0, 0.0)
    }
}

/// Index of (l, m ≥ 0) in the triangle of [`normalized_legendre`].
fn tri(l: usize, m: usize) -> usize {
    l * (l + 1) / 2 + m
}

/// `N_lm P_lm(t)` for `0 ≤ m ≤ l ≤ l_max` at [`tri`]`(l, m)`, with `s = √(1 − t²)`.
///
/// `P_lm` by the recurrence of DeYoung Eq. 3.6, `N_lm` of Eq. 3.5 by running ratios
/// (`N_mm / N_{m−1,m−1}` and `N_lm / N_{l−1,m}`), so no factorial is ever formed.
fn normalized_legendre(l_max: usize, t: f64, s: f64, out: &mut Vec<f64>) {
    out.clear();
    out.resize(tri(l_max + 1, 0), 0.0);
    let mut p_mm = 1.0;
    // N_00 = √(1/2π) (Eq. 3.5).
    let mut n_mm = (1.0 / TAU).sqrt();
    for m in 0..=l_max {
        let mf = m as f64;
        if m > 0 {
            p_mm *= (1.0 - 2.0 * mf) * s;
            // N_mm² / N_{m−1,m−1}² = (2m + 1)/(2m − 1) · 1/((2m)(2m − 1)).
            n_mm *= ((2.0 * mf + 1.0) / ((2.0 * mf - 1.0) * (2.0 * mf) * (2.0 * mf - 1.0))).sqrt();
        }
        out[tri(m, m)] = n_mm * p_mm;
        if m == l_max {
            break;
        }
        let mut p2 = p_mm;
        let mut p1 = t * (2.0 * mf + 1.0) * p_mm;
        // l = m + 1: (2l + 1)/(2l − 1) · (l − m)/(l + m).
        let mut n = n_mm * ((2.0 * mf + 3.0) / ((2.0 * mf + 1.0) * (2.0 * mf + 1.0))).sqrt();
        out[tri(m + 1, m)] = n * p1;
        for l in m + 2..=l_max {
            let lf = l as f64;
            let p = (t * (2.0 * lf - 1.0) * p1 - (lf + mf - 1.0) * p2) / (lf - mf);
            n *= ((2.0 * lf + 1.0) * (lf - mf) / ((2.0 * lf - 1.0) * (lf + mf))).sqrt();
            out[tri(l, m)] = n * p;
            p2 = p1;
            p1 = p;
        }
    }
}

/// The real harmonics of DeYoung Eq. 3.4 from cos θ, sin θ, cos φ, sin φ.
pub(super) fn fill_basis(
    l_max: usize,
    t: f64,
    s: f64,
    cp: f64,
    sp: f64,
    even_only: bool,
    out: &mut Vec<f64>,
) {
    let mut leg = Vec::new();
    normalized_legendre(l_max, t, s, &mut leg);
    // cos mφ, sin mφ by angle addition.
    let mut trig = Vec::with_capacity(l_max + 1);
    let (mut c, mut sn) = (1.0, 0.0);
    for _ in 0..=l_max {
        trig.push((c, sn));
        (c, sn) = (c * cp - sn * sp, sn * cp + c * sp);
    }
    out.clear();
    out.reserve(if even_only {
        basis_len(l_max)
    } else {
        (l_max + 1) * (l_max + 1)
    });
    for l in 0..=l_max {
        let li = l as i64;
        for m in -li..=li {
            if even_only && (li + m) % 2 != 0 {
                continue;
            }
            let am = m.unsigned_abs() as usize;
            let np = leg[tri(l, am)];
            out.push(match m {
                0 => np * FRAC_1_SQRT_2,
                m if m > 0 => np * trig[am].0,
                _ => np * trig[am].1,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use gonio_core::Vec3;

    use super::super::MAX_L_MAX;
    use super::super::project::gauss_legendre;
    use super::*;

    /// Product rule on the sphere (or the upper hemisphere): `n` Gauss nodes in cos θ,
    /// `2n` azimuths; exact for products of harmonics of degree < n.
    fn sphere_rule(n: usize, upper_only: bool) -> Vec<(Dir, f64)> {
        let (x, w) = gauss_legendre(n);
        let n_phi = 2 * n;
        let dphi = TAU / n_phi as f64;
        let mut out = Vec::new();
        for (xi, wi) in x.iter().zip(&w) {
            let (t, wt) = if upper_only {
                (0.5 * (xi + 1.0), 0.5 * wi)
            } else {
                (*xi, *wi)
            };
            let s = ((1.0 - t) * (1.0 + t)).sqrt();
            for c in 0..n_phi {
                let (sp, cp) = (c as f64 * dphi).sin_cos();
                out.push((Dir::from_unit(Vec3::new(s * cp, s * sp, t)), wt * dphi));
            }
        }
        out
    }

    /// `Σ w Y_j Y_k` over a rule, as a dense matrix.
    fn gram(rule: &[(Dir, f64)], l_max: usize, full: bool) -> (usize, Vec<f64>) {
        let mut y = Vec::new();
        let mut g: Vec<f64> = Vec::new();
        let mut k = 0;
        for &(d, w) in rule {
            if full {
                eval_full_basis(l_max, d, &mut y);
            } else {
                eval_basis(l_max, d, &mut y);
            }
            if g.is_empty() {
                k = y.len();
                g = vec![0.0; k * k];
            }
            for i in 0..k {
                for j in 0..k {
                    g[i * k + j] += w * y[i] * y[j];
                }
            }
        }
        (k, g)
    }
    #[test]
    fn full_basis_is_orthonormal_over_the_sphere() {
        let l_max = 16;
        let rule = sphere_rule(l_max + 1, false);
        let (k, g) = gram(&rule, l_max, true);
        assert_eq!(k, (l_max + 1) * (l_max + 1));
        let mut worst: f64 = 0.0;
        for i in 0..k {
            for j in 0..k {
                let want = if i == j { 1.0 } else { 0.0 };
                worst = worst.max((g[i * k + j] - want).abs());
            }
        }
        assert!(worst < 1e-12, "worst deviation {worst:e}");
    }

    #[test]
    fn even_basis_has_norm_one_half_over_the_upper_hemisphere() {
        let l_max = 16;
        let rule = sphere_rule(l_max + 1, true);
        let (k, g) = gram(&rule, l_max, false);
        assert_eq!(k, basis_len(l_max));
        let mut worst: f64 = 0.0;
        for i in 0..k {
            for j in 0..k {
                let want = if i == j { 0.5 } else { 0.0 };
                worst = worst.max((g[i * k + j] - want).abs());
            }
        }
        assert!(worst < 1e-12, "worst deviation {worst:e}");
    }

    #[test]
    fn low_degree_harmonics_match_closed_forms() {
        let d = Dir::from_angles(0.7, 2.1);
        let v = d.vec();
        let mut y = Vec::new();
        eval_full_basis(2, d, &mut y);
        let c0 = (1.0 / (4.0 * PI)).sqrt();
        let c1 = (3.0 / (4.0 * PI)).sqrt();
        let c2 = (15.0 / (4.0 * PI)).sqrt();
        let c20 = (5.0 / (16.0 * PI)).sqrt();
        // Order l = 0; l = 1: m = −1, 0, 1; l = 2: m = −2..=2. Eq. 3.6 carries the
        // Condon–Shortley sign (1 − 2m), so the odd-m terms are negated.
        let want = [
            c0,
            -c1 * v.y,
            c1 * v.z,
            -c1 * v.x,
            c2 * v.x * v.y,
            -c2 * v.y * v.z,
            c20 * (3.0 * v.z * v.z - 1.0),
            -c2 * v.x * v.z,
            0.5 * c2 * (v.x * v.x - v.y * v.y),
        ];
        for (i, (a, b)) in y.iter().zip(want).enumerate() {
            assert!((a - b).abs() < 1e-14, "Y[{i}] = {a}, want {b}");
        }
        // The even basis keeps exactly the l + m even ones.
        eval_basis(2, d, &mut y);
        assert_eq!(
            basis(2),
            vec![(0, 0), (1, -1), (1, 1), (2, -2), (2, 0), (2, 2)]
        );
        let want_even = [want[0], want[1], want[3], want[4], want[6], want[8]];
        for (a, b) in y.iter().zip(want_even) {
            assert!((a - b).abs() < 1e-14);
        }
    }

    #[test]
    fn parity_under_reflection_through_the_surface() {
        let l_max = 12;
        let d = Dir::from_angles(0.4, 1.3);
        let (mut a, mut b) = (Vec::new(), Vec::new());
        eval_full_basis(l_max, d, &mut a);
        eval_full_basis(l_max, d.flip_z(), &mut b);
        let mut i = 0;
        for l in 0..=l_max as i64 {
            for m in -l..=l {
                let sign = if (l + m) % 2 == 0 { 1.0 } else { -1.0 };
                assert!((b[i] - sign * a[i]).abs() < 1e-12, "l = {l}, m = {m}");
                i += 1;
            }
        }
    }

    #[test]
    fn high_degrees_stay_finite_and_bounded() {
        // |Y_lm| ≤ √((2l + 1)/2π) for the real harmonics.
        let mut y = Vec::new();
        for theta in [1e-9, 0.3, 1.2, PI / 2.0] {
            eval_full_basis(MAX_L_MAX, Dir::from_angles(theta, 0.9), &mut y);
            let bound = ((2.0 * MAX_L_MAX as f64 + 1.0) / TAU).sqrt();
            assert!(y.iter().all(|v| v.is_finite() && v.abs() <= bound + 1e-9));
        }
    }

    #[test]
    fn taper_is_one_then_falls_smoothly() {
        assert_eq!(taper(3, 3, 3), 1.0);
        assert_eq!(taper(2, 4, 8), 1.0);
        assert!((taper(5, 4, 7) - 0.5 * (1.0 + (PI / 4.0).cos())).abs() < 1e-15);
        assert!((taper(6, 4, 7) - 0.5).abs() < 1e-15);
        assert_eq!(taper(9, 4, 8), 0.0);
        let t: Vec<f64> = (4..=8).map(|l| taper(l, 4, 8)).collect();
        assert!(t.windows(2).all(|p| p[1] < p[0]) && t[4] > 0.0);
    }
}
