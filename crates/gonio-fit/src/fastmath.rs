//! `ln x` and `x^n = exp(n ln x)` over slices, written so the compiler vectorises them.
//!
//! A lobe fit spends most of its arithmetic on one power per lobe and pair, and the
//! logarithm is needed anyway for ∂/∂ln n. glibc's scalar `log` and `exp` cost ~20
//! cycles each; these branch-free versions (range reduction by bit manipulation,
//! polynomials whose coefficients are Taylor's) run four lanes at a time where the
//! CPU has AVX2, two with the baseline SSE2. Accuracy: a few ulp (the tests compare
//! with the standard library over the range a fit uses).
//!
//! The AVX2 copy is chosen at run time, so the binary stays portable; calling a
//! `#[target_feature]` function is the one `unsafe` of the crate.
#![allow(unsafe_code)]

/// ln 2 split so that `k * LN2_HI` is exact for |k| < 2²⁰ (its low mantissa bits
/// are zero) and `LN2_HI + LN2_LO` = ln 2 to ~1e-27.
const LN2_HI: f64 = 0.693_147_180_369_123_816_490;
const LN2_LO: f64 = 1.908_214_929_270_587_700_02e-10;
const LOG2_E: f64 = std::f64::consts::LOG2_E;
/// 1.5 · 2⁵²: adding it rounds to an integer, which then sits in the low mantissa
/// bits.
const ROUND: f64 = 6_755_399_441_055_744.0;
/// Its bit pattern.
const ROUND_BITS: u64 = 0x4338_0000_0000_0000;
/// √½'s bit pattern: mantissas are reduced into [√½, √2).
const SQRT_HALF_BITS: u64 = 0x3fe6_a09e_667f_3bcd;
const ONE_BITS: u64 = 0x3ff0_0000_0000_0000;
const MANTISSA: u64 = 0x000f_ffff_ffff_ffff;

/// Lanes processed together (the generic code is unrolled over them).
const LANES: usize = 8;

/// a·b + c, fused where the caller was compiled for FMA (`F`), else two operations:
/// `f64::mul_add` without the instruction is a slow library call.
#[inline(always)]
fn madd<const F: bool>(a: f64, b: f64, c: f64) -> f64 {
    if F { a.mul_add(b, c) } else { a * b + c }
}

/// e^y for −708 ≤ y ≤ 709; 0 below, ∞ above (giving up the last 0.1% of the range
/// keeps 2^k a normal number).
#[inline(always)]
fn exp_lane<const F: bool>(y: f64) -> f64 {
    let yc = y.clamp(-708.0, 709.0);
    let shifted = madd::<F>(yc, LOG2_E, ROUND);
    let kf = shifted - ROUND;
    let r = madd::<F>(-kf, LN2_LO, madd::<F>(-kf, LN2_HI, yc));
    // e^r, |r| ≤ ln2/2: Taylor to r¹³ (remainder < 5e-18), summed by Estrin's
    // scheme — a shallow tree instead of Horner's 13-deep chain of dependent steps.
    let r2 = r * r;
    let r4 = r2 * r2;
    let r8 = r4 * r4;
    let p01 = madd::<F>(r, 1.0, 1.0);
    let p23 = madd::<F>(r, 1.0 / 6.0, 0.5);
    let p45 = madd::<F>(r, 1.0 / 120.0, 1.0 / 24.0);
    let p67 = madd::<F>(r, 1.0 / 5_040.0, 1.0 / 720.0);
    let p89 = madd::<F>(r, 1.0 / 362_880.0, 1.0 / 40_320.0);
    let p1011 = madd::<F>(r, 1.0 / 39_916_800.0, 1.0 / 3_628_800.0);
    let p1213 = madd::<F>(r, 1.0 / 6_227_020_800.0, 1.0 / 479_001_600.0);
    let p03 = madd::<F>(p23, r2, p01);
    let p47 = madd::<F>(p67, r2, p45);
    let p811 = madd::<F>(p1011, r2, p89);
    let p07 = madd::<F>(p47, r4, p03);
    let p813 = madd::<F>(p1213, r4, p811);
    let p = madd::<F>(p813, r8, p07);
    // 2^k from k's bits: k = bits(shifted) − bits(ROUND), in [−1021, 1023].
    let k = shifted.to_bits().wrapping_sub(ROUND_BITS);
    let scale = f64::from_bits(k.wrapping_add(1023) << 52);
    if y < -708.0 {
        0.0
    } else if y > 709.0 {
        f64::INFINITY
    } else {
        p * scale
    }
}

/// ln x for positive normal x.
#[inline(always)]
fn ln_lane<const F: bool>(x: f64) -> f64 {
    // Move mantissas ≥ √2 into the next binade, so m = x / 2^e lies in [√½, √2).
    let adj = x.to_bits().wrapping_add(ONE_BITS - SQRT_HALF_BITS);
    let e = adj >> 52;
    let m = f64::from_bits((adj & MANTISSA).wrapping_add(SQRT_HALF_BITS));
    let ef = f64::from_bits(0x4330_0000_0000_0000 | e) - (4_503_599_627_370_496.0 + 1023.0);
    // ln m = 2 atanh s, s = (m − 1)/(m + 1), |s| ≤ 0.1716: 2s Σ s^{2j}/(2j + 1),
    // eleven terms (remainder < 1e-18); p = Σ_{j≥1} z^{j−1}/(2j + 1) by Estrin.
    let f = m - 1.0;
    let s = f / (2.0 + f);
    let z = s * s;
    let z2 = z * z;
    let z4 = z2 * z2;
    let z8 = z4 * z4;
    let q01 = madd::<F>(z, 1.0 / 5.0, 1.0 / 3.0);
    let q23 = madd::<F>(z, 1.0 / 9.0, 1.0 / 7.0);
    let q45 = madd::<F>(z, 1.0 / 13.0, 1.0 / 11.0);
    let q67 = madd::<F>(z, 1.0 / 17.0, 1.0 / 15.0);
    let q89 = madd::<F>(z, 1.0 / 21.0, 1.0 / 19.0);
    let q03 = madd::<F>(q23, z2, q01);
    let q47 = madd::<F>(q67, z2, q45);
    let q07 = madd::<F>(q47, z4, q03);
    let p = madd::<F>(q89, z8, q07);
    // f − (f − 2s(1 + z p)) keeps the leading term exact: 2s = f − s f.
    let hf = s * f;
    let lnm = f - madd::<F>(-2.0 * s * z, p, hf);
    madd::<F>(ef, LN2_HI, madd::<F>(ef, LN2_LO, lnm))
}

/// (ln x, xⁿ), or (0, 0) where x ≤ 0 (NaN stays NaN). Arithmetic rather than
/// selects on the results: a select becomes a masked store, which is microcoded and
/// slow on AMD cores; ln 1 = 0 exactly, so the clamped lanes need no select.
#[inline(always)]
fn ln_pow_lane<const F: bool>(x: f64, n: f64) -> (f64, f64) {
    let pos = x > 0.0;
    let keep = if pos { 1.0 } else { 0.0 };
    let l = ln_lane::<F>(if pos { x } else { 1.0 });
    let h = exp_lane::<F>(n * l);
    // x · 0 is 0 for finite x and NaN for NaN, so a NaN argument stays visible.
    (l, madd::<F>(h, keep, x * 0.0))
}

/// For each `x[i]`: `lx[i] = ln x[i]` and `h[i] = x[i]^n`, or both 0 where
/// `x[i] ≤ 0` (a lobe that is clamped to 0).
#[inline(always)]
fn ln_pow_generic<const F: bool>(x: &[f64], n: f64, lx: &mut [f64], h: &mut [f64]) {
    // One straight-line body an element: the loop vectoriser turns the branches of
    // `exp_lane` and the selects below into masks.
    for ((x, l), p) in x.iter().zip(lx.iter_mut()).zip(h.iter_mut()) {
        (*l, *p) = ln_pow_lane::<F>(*x, n);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn ln_pow_avx2(x: &[f64], n: f64, lx: &mut [f64], h: &mut [f64]) {
    ln_pow_generic::<true>(x, n, lx, h)
}

/// Whether the AVX2 + FMA kernels can run (detected once, then cached by std).
#[inline]
fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// For each `x[i]`: `lx[i] = ln x[i]` and `h[i] = x[i]^n` (n finite), or both 0 where
/// `x[i] ≤ 0`. Slices are truncated to the shortest.
pub fn ln_pow(x: &[f64], n: f64, lx: &mut [f64], h: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    if avx2() {
        // SAFETY: the CPU has just been found to support AVX2 and FMA, the features
        // the function is compiled for.
        return unsafe { ln_pow_avx2(x, n, lx, h) };
    }
    ln_pow_generic::<false>(x, n, lx, h)
}

/// The products wi ∘ wo of a chunk, by component.
pub type Uv<'a> = [&'a [f64]; 3];

/// One lobe's column: `x = c · uv`, `lx = ln x`, `col = w xⁿ` (both 0 where x ≤ 0).
#[inline(always)]
fn lobe_column_generic<const F: bool>(
    c: [f64; 3],
    n: f64,
    uv: Uv,
    w: &[f64],
    lx: &mut [f64],
    col: &mut [f64],
) {
    let len = w
        .len()
        .min(lx.len())
        .min(col.len())
        .min(uv[0].len())
        .min(uv[1].len())
        .min(uv[2].len());
    let (ux, uy, uz, w) = (&uv[0][..len], &uv[1][..len], &uv[2][..len], &w[..len]);
    let (lx, col) = (&mut lx[..len], &mut col[..len]);
    for i in 0..len {
        let x = madd::<F>(c[0], ux[i], madd::<F>(c[1], uy[i], c[2] * uz[i]));
        let (l, h) = ln_pow_lane::<F>(x, n);
        lx[i] = l;
        col[i] = w[i] * h;
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn lobe_column_avx2(c: [f64; 3], n: f64, uv: Uv, w: &[f64], lx: &mut [f64], col: &mut [f64]) {
    lobe_column_generic::<true>(c, n, uv, w, lx, col)
}

/// The weighted column `col = w (c·uv)ⁿ` of a lobe and `lx = ln(c·uv)` (both 0 where
/// c·uv ≤ 0), over the common length.
pub fn lobe_column(c: [f64; 3], n: f64, uv: Uv, w: &[f64], lx: &mut [f64], col: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    if avx2() {
        // SAFETY: as in `ln_pow`.
        return unsafe { lobe_column_avx2(c, n, uv, w, lx, col) };
    }
    lobe_column_generic::<false>(c, n, uv, w, lx, col)
}

/// Where one lobe's derivative columns go.
pub struct LobeDerivatives<'a> {
    /// ∂/∂β.
    pub beta: &'a mut [f64],
    /// ∂/∂γ with ∂ĉ/∂γ (anisotropic lobes).
    pub gamma: Option<(&'a mut [f64], [f64; 3])>,
    /// ∂/∂η (η = ln n).
    pub eta: &'a mut [f64],
}

#[inline(always)]
fn lobe_derivatives_generic<const F: bool>(
    c: [f64; 3],
    dc_db: [f64; 3],
    sn: f64,
    uv: Uv,
    col: &[f64],
    lx: &[f64],
    out: LobeDerivatives,
) {
    let len = col
        .len()
        .min(lx.len())
        .min(out.beta.len())
        .min(out.eta.len());
    let (ux, uy, uz) = (&uv[0][..len], &uv[1][..len], &uv[2][..len]);
    let (col, lx) = (&col[..len], &lx[..len]);
    let (beta, eta) = (&mut out.beta[..len], &mut out.eta[..len]);
    let dx = |i: usize| {
        let x = madd::<F>(c[0], ux[i], madd::<F>(c[1], uy[i], c[2] * uz[i]));
        // ∂(s w xⁿ)/∂x = s n w xⁿ / x, 0 where the lobe is clamped.
        if x > 0.0 { sn * col[i] / x } else { 0.0 }
    };
    match out.gamma {
        None => {
            for i in 0..len {
                let d = dx(i);
                beta[i] = d * madd::<F>(
                    dc_db[0],
                    ux[i],
                    madd::<F>(dc_db[1], uy[i], dc_db[2] * uz[i]),
                );
                eta[i] = sn * col[i] * lx[i];
            }
        }
        Some((gamma, dg)) => {
            let gamma = &mut gamma[..len];
            for i in 0..len {
                let d = dx(i);
                beta[i] = d * madd::<F>(
                    dc_db[0],
                    ux[i],
                    madd::<F>(dc_db[1], uy[i], dc_db[2] * uz[i]),
                );
                gamma[i] = d * madd::<F>(dg[0], ux[i], dg[1] * uy[i]);
                eta[i] = sn * col[i] * lx[i];
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn lobe_derivatives_avx2(
    c: [f64; 3],
    dc_db: [f64; 3],
    sn: f64,
    uv: Uv,
    col: &[f64],
    lx: &[f64],
    out: LobeDerivatives,
) {
    lobe_derivatives_generic::<true>(c, dc_db, sn, uv, col, lx, out)
}

/// The derivative columns of a lobe of strength s and exponent n (`sn` = s n) with
/// direction ĉ = `c` from its weighted column `col` = w (ĉ·uv)ⁿ and `lx` = ln(ĉ·uv):
/// ∂/∂β = s n w xⁿ⁻¹ (∂ĉ/∂β · uv), likewise γ, and ∂/∂η = s n w xⁿ ln x.
pub fn lobe_derivatives(
    c: [f64; 3],
    dc_db: [f64; 3],
    sn: f64,
    uv: Uv,
    col: &[f64],
    lx: &[f64],
    out: LobeDerivatives,
) {
    #[cfg(target_arch = "x86_64")]
    if avx2() {
        // SAFETY: as in `ln_pow`.
        return unsafe { lobe_derivatives_avx2(c, dc_db, sn, uv, col, lx, out) };
    }
    lobe_derivatives_generic::<false>(c, dc_db, sn, uv, col, lx, out)
}

/// Σ aᵢbᵢ with eight partial sums (which lets the compiler vectorise it; the order
/// of the additions is fixed, so the result is deterministic on a given CPU).
#[inline(always)]
fn dot_generic<const F: bool>(a: &[f64], b: &[f64]) -> f64 {
    let len = a.len().min(b.len());
    let (a, b) = (&a[..len], &b[..len]);
    let mut acc = [0.0; LANES];
    let mut ac = a.chunks_exact(LANES);
    let mut bc = b.chunks_exact(LANES);
    for (x, y) in (&mut ac).zip(&mut bc) {
        for j in 0..LANES {
            acc[j] = madd::<F>(x[j], y[j], acc[j]);
        }
    }
    let mut tail = 0.0;
    for (x, y) in ac.remainder().iter().zip(bc.remainder()) {
        tail += x * y;
    }
    ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7])) + tail
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn dot_avx2(a: &[f64], b: &[f64]) -> f64 {
    dot_generic::<true>(a, b)
}

/// Σ aᵢbᵢ over the common length.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if avx2() {
        // SAFETY: as in `ln_pow`.
        return unsafe { dot_avx2(a, b) };
    }
    dot_generic::<false>(a, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ulps(a: f64, b: f64) -> f64 {
        if a == b {
            return 0.0;
        }
        ((a - b) / b).abs() / f64::EPSILON
    }

    #[test]
    fn ln_and_pow_agree_with_the_standard_library() {
        // x over the lobes' range (0, 1] and beyond, n over the exponents a fit meets.
        let mut x = Vec::new();
        let mut v = 1e-300f64;
        while v < 4.0 {
            x.push(v);
            v *= 1.000_37;
        }
        x.extend([1.0, 0.5, 0.999_999_999, 1.000_000_001, f64::MIN_POSITIVE]);
        let mut lx = vec![0.0; x.len()];
        let mut h = vec![0.0; x.len()];
        let mut worst_ln = 0.0f64;
        let mut worst_pow = 0.0f64;
        for n in [0.0, 0.3, 1.0, 2.5, 21.8, 66.9, 250.0, 1000.0] {
            ln_pow(&x, n, &mut lx, &mut h);
            for i in 0..x.len() {
                let want = x[i].ln();
                // Near x = 1 compare absolutely (ln → 0).
                let err = if want.abs() < 1e-3 {
                    (lx[i] - want).abs() / f64::EPSILON
                } else {
                    ulps(lx[i], want)
                };
                worst_ln = worst_ln.max(err);
                let want = (n * x[i].ln()).exp();
                if want > 1e-300 {
                    // exp amplifies ln's error by |n ln x|, as the standard library does.
                    let scale = 1.0 + (n * x[i].ln()).abs();
                    let e = ulps(h[i], want) / scale;
                    if want < 1e307 {
                        worst_pow = worst_pow.max(e);
                    } else {
                        assert!(h[i] > 1e307, "x {} n {n}: {} vs {want}", x[i], h[i]);
                    }
                } else {
                    assert!(h[i] < 1e-290, "x {} n {n}: {} vs {want}", x[i], h[i]);
                }
            }
        }
        assert!(worst_ln < 4.0, "ln: {worst_ln} ulp");
        assert!(worst_pow < 4.0, "pow: {worst_pow} ulp per unit of |n ln x|");
    }

    #[test]
    fn dot_is_the_sum_of_products() {
        let a: Vec<f64> = (0..1037).map(|i| (i as f64 * 0.37).sin()).collect();
        let b: Vec<f64> = (0..1037).map(|i| (i as f64 * 0.11).cos()).collect();
        let want: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
        assert!(
            (dot(&a, &b) - want).abs() < 1e-12,
            "{} vs {want}",
            dot(&a, &b)
        );
        assert_eq!(
            dot(&a[..5], &b[..3]),
            a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
        );
    }

    #[test]
    fn non_positive_arguments_give_zero() {
        let x = [0.0, -1.0, -1e-300, 0.25, -0.0, 0.0, 0.0, 0.0, 0.0, -2.0];
        let mut lx = [9.0; 10];
        let mut h = [9.0; 10];
        ln_pow(&x, 3.0, &mut lx, &mut h);
        for i in 0..10 {
            if x[i] > 0.0 {
                assert!((h[i] - 0.015_625).abs() < 1e-17 && (lx[i] + 4f64.ln()).abs() < 1e-15);
            } else {
                assert_eq!((lx[i], h[i]), (0.0, 0.0), "x = {}", x[i]);
            }
        }
    }

    #[test]
    fn exp_covers_the_exponent_range() {
        for y in [
            -708.0, -700.5, -30.2, -1.0, -1e-12, 0.0, 1e-9, 0.7, 10.0, 300.0, 709.0,
        ] {
            assert!(
                ulps(exp_lane::<false>(y), y.exp()) < 3.0,
                "e^{y}: {} vs {}",
                exp_lane::<false>(y),
                y.exp()
            );
        }
        assert_eq!(exp_lane::<false>(-709.0), 0.0);
        assert_eq!(exp_lane::<false>(-1e6), 0.0);
        // The split of ln 2 (value from its decimal expansion 0.6931471805599453094172…).
        assert_eq!(LN2_HI.to_bits() & 0x1f_ffff, 0);
        assert!((LN2_HI + LN2_LO - std::f64::consts::LN_2).abs() < 1e-17);
    }
}
