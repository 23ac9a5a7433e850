use gonio_core::{Channels, Dir, Vec3};

use super::{Diffuse, EXPONENT, MAX_LOBE_PEAK, Mirror, ParamError, check, exponent, lobe_weight};
use crate::Brdf;
use crate::lobe::{hemisphere_albedo, sphere_integral};
use crate::proposal::{Proposal, Weighted};

/// A symmetric 3×3 matrix: the `M` of Lafortune et al. 1997, Eq. 3.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sym3 {
    /// M₁₁.
    pub xx: f64,
    /// M₂₂.
    pub yy: f64,
    /// M₃₃.
    pub zz: f64,
    /// M₁₂ = M₂₁.
    pub xy: f64,
    /// M₁₃ = M₃₁.
    pub xz: f64,
    /// M₂₃ = M₃₂.
    pub yz: f64,
}

impl Sym3 {
    /// `diag(cx, cy, cz)`: the coefficients of Eq. 4.
    pub const fn diagonal(cx: f64, cy: f64, cz: f64) -> Self {
        Sym3 {
            xx: cx,
            yy: cy,
            zz: cz,
            xy: 0.0,
            xz: 0.0,
            yz: 0.0,
        }
    }

    /// From a full matrix, which must be symmetric to within 1e-12 relative (Eq. 3
    /// requires `M = Mᵀ` for reciprocity); `None` otherwise.
    pub fn from_rows(m: [[f64; 3]; 3]) -> Option<Self> {
        let scale = m.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
        let tol = 1e-12 * scale;
        let sym = |a: f64, b: f64| (a - b).abs() <= tol;
        (sym(m[0][1], m[1][0]) && sym(m[0][2], m[2][0]) && sym(m[1][2], m[2][1])).then(|| Sym3 {
            xx: m[0][0],
            yy: m[1][1],
            zz: m[2][2],
            xy: 0.5 * (m[0][1] + m[1][0]),
            xz: 0.5 * (m[0][2] + m[2][0]),
            yz: 0.5 * (m[1][2] + m[2][1]),
        })
    }

    /// The matrix as rows.
    pub fn rows(&self) -> [[f64; 3]; 3] {
        [
            [self.xx, self.xy, self.xz],
            [self.xy, self.yy, self.yz],
            [self.xz, self.yz, self.zz],
        ]
    }

    /// True when the off-diagonal entries are zero (Eq. 4).
    pub fn is_diagonal(&self) -> bool {
        self.xy == 0.0 && self.xz == 0.0 && self.yz == 0.0
    }

    /// `M v`.
    #[inline]
    pub fn mul(&self, v: Vec3) -> Vec3 {
        Vec3::new(
            self.xx * v.x + self.xy * v.y + self.xz * v.z,
            self.xy * v.x + self.yy * v.y + self.yz * v.z,
            self.xz * v.x + self.yz * v.y + self.zz * v.z,
        )
    }

    /// `uᵀ M v`, written so that swapping `u` and `v` gives the same bits.
    #[inline]
    pub fn bilinear(&self, u: Vec3, v: Vec3) -> f64 {
        let d = self.xx * (u.x * v.x) + self.yy * (u.y * v.y) + self.zz * (u.z * v.z);
        if self.is_diagonal() {
            d
        } else {
            d + self.xy * (u.x * v.y + u.y * v.x)
                + self.xz * (u.x * v.z + u.z * v.x)
                + self.yz * (u.y * v.z + u.z * v.y)
        }
    }

    /// The largest `|λ|` over the eigenvalues: the largest `‖M u‖` over unit `u`, so
    /// that a lobe `[uᵀ M v]ⁿ` never exceeds its `n`-th power. Closed form for a
    /// symmetric 3×3 matrix (the trigonometric solution of its characteristic cubic).
    pub fn largest_magnitude(&self) -> f64 {
        let p1 = self.xy * self.xy + self.xz * self.xz + self.yz * self.yz;
        if p1 == 0.0 {
            return self.xx.abs().max(self.yy.abs()).max(self.zz.abs());
        }
        let q = (self.xx + self.yy + self.zz) / 3.0;
        let p2 = (self.xx - q).powi(2) + (self.yy - q).powi(2) + (self.zz - q).powi(2) + 2.0 * p1;
        let p = (p2 / 6.0).sqrt();
        let b = Sym3 {
            xx: (self.xx - q) / p,
            yy: (self.yy - q) / p,
            zz: (self.zz - q) / p,
            xy: self.xy / p,
            xz: self.xz / p,
            yz: self.yz / p,
        };
        let det = b.xx * (b.yy * b.zz - b.yz * b.yz) - b.xy * (b.xy * b.zz - b.yz * b.xz)
            + b.xz * (b.xy * b.yz - b.yy * b.xz);
        let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
        let e1 = q + 2.0 * p * phi.cos();
        let e3 = q + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
        e1.abs().max(e3.abs())
    }

    fn is_finite(&self) -> bool {
        [self.xx, self.yy, self.zz, self.xy, self.xz, self.yz]
            .iter()
            .all(|v| v.is_finite())
    }
}

/// One generalized cosine lobe `[uᵀ M v]ⁿ` (Eq. 3; Eq. 4 when `M` is diagonal), with
/// its matrix and exponent per channel. Negative values of the bracket count as 0.
#[derive(Clone, Debug, PartialEq)]
pub struct LafortuneLobe {
    m: Vec<Sym3>,
    n: Vec<f64>,
}

impl LafortuneLobe {
    /// Eq. 4/8 coefficients `Cx, Cy, Cz` and exponent `n`, one value per channel each.
    pub fn diagonal(
        channels: &Channels,
        cx: &[f64],
        cy: &[f64],
        cz: &[f64],
        n: &[f64],
    ) -> Result<Self, ParamError> {
        let any = |_: f64| true;
        check("cx", cx, channels, "must be finite", any)?;
        check("cy", cy, channels, "must be finite", any)?;
        check("cz", cz, channels, "must be finite", any)?;
        let m = (0..channels.len())
            .map(|c| Sym3::diagonal(cx[c], cy[c], cz[c]))
            .collect();
        Self::from_matrices(channels, m, n.to_vec())
    }

    /// Eq. 3: a symmetric matrix and an exponent per channel.
    pub fn from_matrices(
        channels: &Channels,
        m: Vec<Sym3>,
        n: Vec<f64>,
    ) -> Result<Self, ParamError> {
        if m.len() != channels.len() {
            return Err(ParamError::new(
                "m",
                format!(
                    "expected {} matrices (one per channel {}), got {}",
                    channels.len(),
                    channels,
                    m.len()
                ),
            ));
        }
        if let Some(c) = m.iter().position(|m| !m.is_finite()) {
            return Err(ParamError::new(
                "m",
                format!("matrix for channel {} is not finite", channels.name(c)),
            ));
        }
        check("n", &n, channels, EXPONENT, exponent)?;
        for (c, (m, n)) in m.iter().zip(&n).enumerate() {
            let sigma = m.largest_magnitude();
            // σⁿ compared in logarithms, where an absurd peak cannot overflow.
            if sigma > 1.0 && n * sigma.ln() > MAX_LOBE_PEAK.ln() {
                return Err(ParamError::new(
                    "n",
                    format!(
                        "{n} for channel {} makes the lobe peak at {sigma}^{n} = {:e} 1/sr, \
                         more than {MAX_LOBE_PEAK:e}",
                        channels.name(c),
                        sigma.powf(*n)
                    ),
                ));
            }
        }
        Ok(LafortuneLobe { m, n })
    }

    /// The matrix per channel.
    pub fn matrices(&self) -> &[Sym3] {
        &self.m
    }

    /// The exponent per channel.
    pub fn n(&self) -> &[f64] {
        &self.n
    }

    /// True when every channel's matrix is diagonal (an Eq. 4 lobe).
    pub fn is_diagonal(&self) -> bool {
        self.m.iter().all(Sym3::is_diagonal)
    }

    /// Eq. 5 for channel `c`: `(C_s(u), u')` with `C_s(u) = ‖M u‖ⁿ` and
    /// `u' = M u / ‖M u‖`; `None` when `M u = 0` (the lobe vanishes).
    #[inline]
    fn as_cosine_lobe(&self, c: usize, wi: Dir) -> Option<(f64, Dir)> {
        let mu = self.m[c].mul(wi.vec());
        let s = mu.norm();
        let axis = Dir::new(mu)?;
        Some((s.powf(self.n[c]), axis))
    }
}

/// Lafortune et al. 1997's sum of generalized cosine lobes (Eq. 8, or Eq. 3 lobes),
/// with an optional Lambert/Minnaert `[diffuse]` term (Eq. 6) and the Eq. 7 `[mirror]`:
/// `f_r(u, v) = Σ_i [uᵀ M_i v]^{n_i} + f_d`.
///
/// No normalisation is hidden in the lobes: the coefficients are exactly those of Eq. 8
/// (`docs/CONVENTIONS.md`). Reciprocal by construction (each `M_i` is symmetric). The
/// albedo is exact (see [`crate::lobe`]): each lobe is a cosine lobe of scale `C_s(u)`
/// about `u'` (Eq. 5); sampling is the mixture of those lobes (Sec. 4.3 and 7).
#[derive(Clone, Debug, PartialEq)]
pub struct Lafortune {
    channels: Channels,
    lobes: Vec<LafortuneLobe>,
    diffuse: Option<Diffuse>,
    mirror: Option<Mirror>,
    /// Boxed: the model is copied and held in enums where its size counts.
    fit: Option<Box<FitNote>>,
}

/// How a model's parameters were fitted, as `gonio fit` records it in the model file's
/// optional `[fit]` table. Informational: nothing evaluates it, and files without it
/// load as before.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FitNote {
    /// The objective's name (`cosine`, `chi2`, `relative`).
    pub objective: String,
    /// The sum minimised, in words.
    pub minimised: String,
    /// The energy constraint the fit was held to, in words, when there was one.
    pub constraint: Option<String>,
}

impl Lafortune {
    /// A sum of `lobes` (any number, including none), each with the model's channels.
    pub fn new(channels: Channels, lobes: Vec<LafortuneLobe>) -> Result<Self, ParamError> {
        for (i, l) in lobes.iter().enumerate() {
            if l.n.len() != channels.len() {
                return Err(ParamError::new(
                    format!("lobes[{i}]"),
                    format!(
                        "has {} channels but the model has {} ({channels})",
                        l.n.len(),
                        channels.len()
                    ),
                ));
            }
        }
        Ok(Lafortune {
            channels,
            lobes,
            diffuse: None,
            mirror: None,
            fit: None,
        })
    }

    /// Records how the parameters were fitted (the `[fit]` table).
    pub fn with_fit_note(mut self, note: FitNote) -> Self {
        self.fit = Some(Box::new(note));
        self
    }

    /// How the parameters were fitted, when the model file says.
    pub fn fit_note(&self) -> Option<&FitNote> {
        self.fit.as_deref()
    }

    /// Adds a diffuse term, which must have the model's channels.
    pub fn with_diffuse(mut self, d: Diffuse) -> Result<Self, ParamError> {
        super::same_channels("diffuse", &self.channels, d.channels())?;
        self.diffuse = Some(d);
        Ok(self)
    }

    /// Adds the Eq. 7 mirror term. Refused when a lobe's matrix couples z with x or y
    /// (`xz` or `yz` ≠ 0): mirroring `u` then changes `|M u|`, and the mirror term
    /// would not be reciprocal.
    pub fn with_mirror(mut self, m: Mirror) -> Result<Self, ParamError> {
        m.check_channels(&self.channels)?;
        if let Some(i) = self
            .lobes
            .iter()
            .position(|l| l.m.iter().any(|m| m.xz != 0.0 || m.yz != 0.0))
        {
            return Err(ParamError::new(
                "mirror",
                format!(
                    "the Eq. 7 mirror term is reciprocal only for lobes whose matrix has no xz or yz terms, and lobes[{i}] has them"
                ),
            ));
        }
        self.mirror = Some(m);
        Ok(self)
    }

    /// The lobes.
    pub fn lobes(&self) -> &[LafortuneLobe] {
        &self.lobes
    }
    /// The diffuse term, if any.
    pub fn diffuse(&self) -> Option<&Diffuse> {
        self.diffuse.as_ref()
    }
    /// The mirror term, if any.
    pub fn mirror_term(&self) -> Option<&Mirror> {
        self.mirror.as_ref()
    }

    /// Per channel: the summed albedo of the lobes and their summed power over the
    /// sphere (what the mirror term draws on).
    fn lobe_albedo(&self, wi: Dir, out_albedo: &mut [f64], out_full: &mut [f64]) {
        out_albedo.fill(0.0);
        out_full.fill(0.0);
        for lobe in &self.lobes {
            for c in 0..self.channels.len() {
                if let Some((cs, axis)) = lobe.as_cosine_lobe(c, wi) {
                    let n = lobe.n[c];
                    out_albedo[c] += cs * hemisphere_albedo(n, axis.z);
                    out_full[c] += cs * sphere_integral(n);
                }
            }
        }
    }
}

impl Brdf for Lafortune {
    fn channels(&self) -> &Channels {
        &self.channels
    }

    fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        super::eval_layered(wi, wo, out, self.diffuse.as_ref(), |out| {
            let (u, v) = (wi.vec(), wo.vec());
            for lobe in &self.lobes {
                for (c, o) in out.iter_mut().enumerate() {
                    let d = lobe.m[c].bilinear(u, v);
                    if d > 0.0 {
                        *o += d.powf(lobe.n[c]);
                    }
                }
            }
        });
    }

    fn proposals(&self, wi: Dir, out: &mut Vec<Weighted>) {
        for lobe in &self.lobes {
            for c in 0..self.channels.len() {
                if let Some((cs, axis)) = lobe.as_cosine_lobe(c, wi) {
                    let n = lobe.n[c];
                    Weighted::push_merged(
                        out,
                        lobe_weight(cs, n, axis.z),
                        Proposal::CosinePower { axis, n },
                    );
                }
            }
        }
        if let Some(d) = &self.diffuse {
            d.push_proposals(wi, out);
        }
    }

    fn mirror(&self, wi: Dir, out: &mut [f64]) -> bool {
        let Some(m) = &self.mirror else {
            return false;
        };
        out.fill(0.0);
        if wi.is_above() {
            let k = self.channels.len();
            let (mut a, mut f) = (vec![0.0; k], vec![0.0; k]);
            self.lobe_albedo(wi, &mut a, &mut f);
            for c in 0..k {
                out[c] = m.reflectance(c, f[c], a[c]);
            }
        }
        true
    }

    fn albedo(&self, wi: Dir, out: &mut [f64]) {
        out.fill(0.0);
        if !wi.is_above() {
            return;
        }
        let k = self.channels.len();
        let mut full = vec![0.0; k];
        self.lobe_albedo(wi, out, &mut full);
        if let Some(m) = &self.mirror {
            for c in 0..k {
                out[c] += m.reflectance(c, full[c], out[c]);
            }
        }
        if let Some(d) = &self.diffuse {
            d.add_albedo(wi, out);
        }
    }
}
