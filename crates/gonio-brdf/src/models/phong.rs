use std::f64::consts::TAU;

use gonio_core::{Channels, Dir};

use super::{
    ALBEDO, Diffuse, EXPONENT, ParamError, albedo, check, exponent, lobe_weight, unit_interval,
};
use crate::Brdf;
use crate::lobe::{hemisphere_albedo, sphere_integral};
use crate::proposal::{Proposal, Weighted};

/// The ideal mirror term of Lafortune et al. 1997, Eq. 7: `(ρs − ρs(u)) R_m δ(u_m − v)`.
///
/// It reflects the fraction `R_m` of the power that a lobe loses to the horizon and to
/// foreshortening: the lobe's integral over the whole sphere (without the cosine)
/// minus its albedo. For a cosine lobe normalised with `C_s = (n+1)/(2π)` that is
/// exactly Eq. 7's `ρs − ρs(u)`; for generalized lobes it is the same quantity for the
/// scaled lobe of Eq. 5. It is reciprocal when both terms are the same for `u` and its
/// mirror `u_m`, i.e. when `|M u|` and the tilt of `M u` are: true for every diagonal
/// (Eq. 4) lobe and any lobe whose `M` does not couple z with x or y
/// ([`Lafortune::with_mirror`](crate::Lafortune::with_mirror) refuses the others).
#[derive(Clone, Debug, PartialEq)]
pub struct Mirror {
    rm: Vec<f64>,
}

impl Mirror {
    /// `rm` in [0, 1] per channel.
    pub fn new(channels: &Channels, rm: Vec<f64>) -> Result<Self, ParamError> {
        check("rm", &rm, channels, "must be in [0, 1]", unit_interval)?;
        Ok(Mirror { rm })
    }

    /// `R_m` per channel.
    pub fn rm(&self) -> &[f64] {
        &self.rm
    }

    pub(crate) fn check_channels(&self, channels: &Channels) -> Result<(), ParamError> {
        check("rm", &self.rm, channels, "must be in [0, 1]", unit_interval)
            .map_err(|e| e.within("mirror"))
    }

    /// Channel `c`'s mirror reflectance for a lobe with sphere power `full` and albedo
    /// `albedo`.
    #[inline]
    pub(crate) fn reflectance(&self, c: usize, full: f64, albedo: f64) -> f64 {
        self.rm[c] * (full - albedo).max(0.0)
    }
}

/// How a cosine lobe's scale `ρs` is normalised.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PhongNormalization {
    /// `C_s = (n+2)/(2π)` (Eq. 1): `ρs` is the albedo at normal incidence.
    Albedo,
    /// `C_s = (n+1)/(2π)` (with Eq. 7): `ρs` is the lobe's power over the whole sphere.
    Power,
}

impl PhongNormalization {
    /// The name used in model files.
    pub fn name(self) -> &'static str {
        match self {
            PhongNormalization::Albedo => "albedo",
            PhongNormalization::Power => "power",
        }
    }

    fn factor(self, n: f64) -> f64 {
        match self {
            PhongNormalization::Albedo => (n + 2.0) / TAU,
            PhongNormalization::Power => (n + 1.0) / TAU,
        }
    }
}

/// The classical cosine lobe (Lafortune et al. 1997, Eq. 1–2):
/// `f_r = ρs C_s [u_m · v]ⁿ` about the mirror direction `u_m`, with an optional
/// Lambert/Minnaert `[diffuse]` term and the Eq. 7 `[mirror]` term.
///
/// With `shading = true` it is the *Phong shading* variant whose specular term is
/// divided by `cos θi` (the shading formula `k_s (r·v)ⁿ` read as a BRDF), which is not
/// reciprocal (Lewis 1993; DeYoung 1996 measures its `P_r`).
#[derive(Clone, Debug, PartialEq)]
pub struct Phong {
    channels: Channels,
    rho_s: Vec<f64>,
    n: Vec<f64>,
    normalization: PhongNormalization,
    shading: bool,
    diffuse: Option<Diffuse>,
    mirror: Option<Mirror>,
    coef: Vec<f64>,
}

impl Phong {
    /// A cosine lobe with `rho_s` ≥ 0 and `n` ≥ 0 per channel.
    pub fn new(
        channels: Channels,
        rho_s: Vec<f64>,
        n: Vec<f64>,
        normalization: PhongNormalization,
        shading: bool,
    ) -> Result<Self, ParamError> {
        check("rho_s", &rho_s, &channels, ALBEDO, albedo)?;
        check("n", &n, &channels, EXPONENT, exponent)?;
        let coef = rho_s
            .iter()
            .zip(&n)
            .map(|(r, n)| r * normalization.factor(*n))
            .collect();
        Ok(Phong {
            channels,
            rho_s,
            n,
            normalization,
            shading,
            diffuse: None,
            mirror: None,
            coef,
        })
    }

    /// Adds a diffuse term, which must have the model's channels.
    pub fn with_diffuse(mut self, d: Diffuse) -> Result<Self, ParamError> {
        super::same_channels("diffuse", &self.channels, d.channels())?;
        self.diffuse = Some(d);
        Ok(self)
    }

    /// Adds the Eq. 7 mirror term, which must have one `rm` per channel.
    pub fn with_mirror(mut self, m: Mirror) -> Result<Self, ParamError> {
        m.check_channels(&self.channels)?;
        self.mirror = Some(m);
        Ok(self)
    }

    /// Lobe scale per channel.
    pub fn rho_s(&self) -> &[f64] {
        &self.rho_s
    }
    /// Exponent per channel.
    pub fn n(&self) -> &[f64] {
        &self.n
    }
    /// The normalisation of `ρs`.
    pub fn normalization(&self) -> PhongNormalization {
        self.normalization
    }
    /// True for the non-reciprocal shading variant.
    pub fn shading(&self) -> bool {
        self.shading
    }
    /// The diffuse term, if any.
    pub fn diffuse(&self) -> Option<&Diffuse> {
        self.diffuse.as_ref()
    }
    /// The mirror term, if any.
    pub fn mirror_term(&self) -> Option<&Mirror> {
        self.mirror.as_ref()
    }

    /// `1/cos θi` for the shading variant, else 1.
    #[inline]
    fn shading_factor(&self, wi: Dir) -> f64 {
        if self.shading { 1.0 / wi.z } else { 1.0 }
    }

    /// Lobe albedo and sphere power of channel `c` for `wi`.
    fn lobe_albedo(&self, wi: Dir, c: usize) -> (f64, f64) {
        let s = self.coef[c] * self.shading_factor(wi);
        let n = self.n[c];
        // The mirror direction has the same polar angle as wi.
        (s * hemisphere_albedo(n, wi.z), s * sphere_integral(n))
    }
}

impl Brdf for Phong {
    fn channels(&self) -> &Channels {
        &self.channels
    }

    fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        super::eval_layered(wi, wo, out, self.diffuse.as_ref(), |out| {
            // u_m · v, written symmetrically in u and v.
            let d = wi.z * wo.z - wi.x * wo.x - wi.y * wo.y;
            if d > 0.0 {
                let k = self.shading_factor(wi);
                for ((o, c), n) in out.iter_mut().zip(&self.coef).zip(&self.n) {
                    *o = c * d.powf(*n) * k;
                }
            }
        });
    }

    fn proposals(&self, wi: Dir, out: &mut Vec<Weighted>) {
        let k = self.shading_factor(wi);
        for (c, n) in self.coef.iter().zip(&self.n) {
            Weighted::push_merged(
                out,
                lobe_weight(c * k, *n, wi.z),
                Proposal::CosinePower {
                    axis: wi.mirror(),
                    n: *n,
                },
            );
        }
        if let Some(d) = &self.diffuse {
            d.push_proposals(wi, out);
        }
    }

    fn mirror(&self, wi: Dir, out: &mut [f64]) -> bool {
        let Some(m) = &self.mirror else {
            return false;
        };
        for (c, o) in out.iter_mut().enumerate() {
            let (albedo, full) = self.lobe_albedo(wi, c);
            *o = if wi.is_above() {
                m.reflectance(c, full, albedo)
            } else {
                0.0
            };
        }
        true
    }

    fn is_reciprocal(&self) -> bool {
        !self.shading
    }

    fn albedo(&self, wi: Dir, out: &mut [f64]) {
        out.fill(0.0);
        if !wi.is_above() {
            return;
        }
        for (c, o) in out.iter_mut().enumerate() {
            let (albedo, full) = self.lobe_albedo(wi, c);
            *o = albedo
                + self
                    .mirror
                    .as_ref()
                    .map_or(0.0, |m| m.reflectance(c, full, albedo));
        }
        if let Some(d) = &self.diffuse {
            d.add_albedo(wi, out);
        }
    }
}
