//! sRGB (IEC 61966-2-1:1999) and the Bradford chromatic adaptation.

use super::Xyz;

/// A 3 × 3 matrix, rows first.
pub type Mat3 = [[f64; 3]; 3];

/// CIE XYZ (Y = 1 for the white) to linear sRGB: the matrix of IEC 61966-2-1:1999
/// (§5.2, the four-decimal matrix printed in the standard; section **UNCONFIRMED**).
pub const XYZ_TO_SRGB: Mat3 = [
    [3.2406, -1.5372, -0.4986],
    [-0.9689, 1.8758, 0.0415],
    [0.0557, -0.2040, 1.0570],
];

/// The sRGB reference white: CIE D65 as IEC 61966-2-1:1999 gives it, x = 0.3127,
/// y = 0.3290.
pub const SRGB_WHITE_XY: (f64, f64) = (0.3127, 0.3290);

/// The Bradford cone-response matrix (Lam 1985, as ICC.1:2010 Annex E prints it;
/// annex **UNCONFIRMED**): XYZ to the "sharpened" responses ρ, γ, β.
pub const BRADFORD: Mat3 = [
    [0.8951, 0.2664, -0.1614],
    [-0.7502, 1.7135, 0.0367],
    [0.0389, -0.0685, 1.0296],
];

/// The linear-segment breakpoint of the sRGB encoding (linear side): at and below it
/// the encoding is `12.92 · V`.
pub const SRGB_LINEAR_BREAK: f64 = 0.0031308;
/// The breakpoint on the encoded side: `12.92 × 0.0031308 ≈ 0.04045`, as the standard
/// rounds it.
pub const SRGB_ENCODED_BREAK: f64 = 0.04045;

/// `m · v`.
pub fn mul(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

/// `a · b`.
pub fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for (i, row) in c.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

/// The inverse of `m`, `None` when it is singular.
pub fn inverse(m: &Mat3) -> Option<Mat3> {
    let c =
        |r0: usize, r1: usize, c0: usize, c1: usize| m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0];
    let cof = [
        [c(1, 2, 1, 2), -c(1, 2, 0, 2), c(1, 2, 0, 1)],
        [-c(0, 2, 1, 2), c(0, 2, 0, 2), -c(0, 2, 0, 1)],
        [c(0, 1, 1, 2), -c(0, 1, 0, 2), c(0, 1, 0, 1)],
    ];
    let det = m[0][0] * cof[0][0] + m[0][1] * cof[0][1] + m[0][2] * cof[0][2];
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    // The inverse is the transposed cofactor matrix over the determinant.
    let mut inv = [[0.0; 3]; 3];
    for (i, row) in inv.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = cof[j][i] / det;
        }
    }
    Some(inv)
}

/// The XYZ (Y = 1) of chromaticity `(x, y)`.
pub fn xyz_of_xy(x: f64, y: f64) -> Xyz {
    Xyz {
        x: x / y,
        y: 1.0,
        z: (1.0 - x - y) / y,
    }
}

/// The Bradford adaptation from white `from` to white `to` (a von Kries scaling in
/// the Bradford cone space): `M⁻¹ · diag(M·to / M·from) · M`. It maps `from` onto `to`
/// exactly. `None` when a white has a zero cone response.
pub fn bradford(from: Xyz, to: Xyz) -> Option<Mat3> {
    let s = mul(&BRADFORD, from.to_array());
    let d = mul(&BRADFORD, to.to_array());
    if s.iter().any(|v| *v == 0.0 || !v.is_finite()) {
        return None;
    }
    let scale = [
        [d[0] / s[0], 0.0, 0.0],
        [0.0, d[1] / s[1], 0.0],
        [0.0, 0.0, d[2] / s[2]],
    ];
    Some(mat_mul(&inverse(&BRADFORD)?, &mat_mul(&scale, &BRADFORD)))
}

/// The sRGB encoding (IEC 61966-2-1:1999 transfer function) of a linear value,
/// unclipped: `12.92 · V` at and below [`SRGB_LINEAR_BREAK`], `1.055 · V^(1/2.4) − 0.055`
/// above; odd about 0, so a negative value encodes to minus the encoding of its
/// magnitude.
pub fn encode(v: f64) -> f64 {
    if v.abs() <= SRGB_LINEAR_BREAK {
        12.92 * v
    } else {
        v.signum() * (1.055 * v.abs().powf(1.0 / 2.4) - 0.055)
    }
}

/// The inverse of [`encode`]: `V'/12.92` at and below [`SRGB_ENCODED_BREAK`],
/// `((V' + 0.055)/1.055)^2.4` above; odd about 0.
pub fn decode(e: f64) -> f64 {
    if e.abs() <= SRGB_ENCODED_BREAK {
        e / 12.92
    } else {
        e.signum() * ((e.abs() + 0.055) / 1.055).powf(2.4)
    }
}

/// Encoded sRGB of linear sRGB, each channel clipped to [0, 1] first (values outside
/// the sRGB gamut, or brighter than the white, are clipped channel by channel). NaN
/// becomes 0.
pub fn encode_clipped(linear: [f64; 3]) -> [f64; 3] {
    linear.map(|v| {
        if v.is_nan() {
            0.0
        } else {
            encode(v.clamp(0.0, 1.0))
        }
    })
}

/// 8-bit code values of encoded sRGB in [0, 1]: `round(255 · V')`, clipped to 0–255.
pub fn to_8bit(encoded: [f64; 3]) -> [u8; 3] {
    // The clamp keeps the rounded value within 0..=255, so the cast is exact.
    encoded.map(|e| {
        if e.is_nan() {
            0
        } else {
            (255.0 * e.clamp(0.0, 1.0)).round() as u8
        }
    })
}
