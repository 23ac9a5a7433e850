use gonio_core::{Channels, Dir};

use super::{ALBEDO, Diffuse, ParamError, ROUGHNESS, albedo, check, roughness, unit_interval};
use crate::Brdf;
use crate::microfacet::Distribution;
use crate::proposal::{HalfDensity, Proposal, Weighted};

/// Cook–Torrance microfacet reflection with a Beckmann or GGX distribution, Heitz's
/// height-correlated Smith masking–shadowing and Schlick's Fresnel approximation:
/// `f_r = ρs F(wi·h) D(h) G2(wi, wo) / (4 cos θi cos θo)` plus an optional `[diffuse]`
/// term, with `F = F0 + (1 − F0)(1 − wi·h)⁵` and `F0` per channel.
///
/// `ρs` (default 1) scales the specular term for fitting; a physical surface has 1.
#[derive(Clone, Debug, PartialEq)]
pub struct CookTorrance {
    channels: Channels,
    dist: Distribution,
    f0: Vec<f64>,
    alpha_x: Vec<f64>,
    alpha_y: Vec<f64>,
    rho_s: Vec<f64>,
    diffuse: Option<Diffuse>,
}

impl CookTorrance {
    /// `f0` in [0, 1], `alpha_x`, `alpha_y` in [1e-4, 10] and `rho_s` in [0, 100] per channel.
    pub fn new(
        channels: Channels,
        dist: Distribution,
        f0: Vec<f64>,
        alpha_x: Vec<f64>,
        alpha_y: Vec<f64>,
        rho_s: Vec<f64>,
    ) -> Result<Self, ParamError> {
        check("f0", &f0, &channels, "must be in [0, 1]", unit_interval)?;
        check("alpha_x", &alpha_x, &channels, ROUGHNESS, roughness)?;
        check("alpha_y", &alpha_y, &channels, ROUGHNESS, roughness)?;
        check("rho_s", &rho_s, &channels, ALBEDO, albedo)?;
        Ok(CookTorrance {
            channels,
            dist,
            f0,
            alpha_x,
            alpha_y,
            rho_s,
            diffuse: None,
        })
    }

    /// Adds a diffuse term, which must have the model's channels.
    pub fn with_diffuse(mut self, d: Diffuse) -> Result<Self, ParamError> {
        super::same_channels("diffuse", &self.channels, d.channels())?;
        self.diffuse = Some(d);
        Ok(self)
    }

    /// The microfacet distribution.
    pub fn distribution(&self) -> Distribution {
        self.dist
    }
    /// Fresnel reflectance at normal incidence per channel.
    pub fn f0(&self) -> &[f64] {
        &self.f0
    }
    /// Roughness along x per channel.
    pub fn alpha_x(&self) -> &[f64] {
        &self.alpha_x
    }
    /// Roughness along y per channel.
    pub fn alpha_y(&self) -> &[f64] {
        &self.alpha_y
    }
    /// Specular scale per channel.
    pub fn rho_s(&self) -> &[f64] {
        &self.rho_s
    }
    /// True when `αx = αy` in every channel.
    pub fn is_isotropic(&self) -> bool {
        self.alpha_x == self.alpha_y
    }
    /// The diffuse term, if any.
    pub fn diffuse(&self) -> Option<&Diffuse> {
        self.diffuse.as_ref()
    }
}

impl Brdf for CookTorrance {
    fn channels(&self) -> &Channels {
        &self.channels
    }

    fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        super::eval_layered(wi, wo, out, self.diffuse.as_ref(), |out| {
            let s = wi.vec() + wo.vec();
            let h = s / s.norm();
            // wi·h = wo·h; their mean keeps the expression bitwise symmetric.
            let cos_d = 0.5 * (wi.dot(h) + wo.dot(h));
            let schlick = (1.0 - cos_d).max(0.0).powi(5);
            let denom = 4.0 * (wi.z * wo.z);
            let mut last: Option<(f64, f64, f64)> = None;
            for (c, o) in out.iter_mut().enumerate() {
                let (ax, ay) = (self.alpha_x[c], self.alpha_y[c]);
                // Channels usually share the roughness: reuse D·G2.
                let dg = match last {
                    Some((lx, ly, v)) if lx == ax && ly == ay => v,
                    _ => {
                        let l =
                            self.dist.lambda(wi.vec(), ax, ay) + self.dist.lambda(wo.vec(), ax, ay);
                        let v = self.dist.d(h, ax, ay) / (1.0 + l);
                        last = Some((ax, ay, v));
                        v
                    }
                };
                let f = self.f0[c] + (1.0 - self.f0[c]) * schlick;
                *o = self.rho_s[c] * f * dg / denom;
            }
        });
    }

    fn proposals(&self, wi: Dir, out: &mut Vec<Weighted>) {
        let schlick = (1.0 - wi.z).powi(5);
        for c in 0..self.f0.len() {
            let f = self.f0[c] + (1.0 - self.f0[c]) * schlick;
            // F ≥ F0 can be 0 at the normal while the term is not (F grows off the
            // normal): the weight keeps a floor so the proposal is never dropped.
            Weighted::push_merged(
                out,
                self.rho_s[c] * f.max(1e-3),
                Proposal::HalfVector(HalfDensity::Microfacet {
                    dist: self.dist,
                    alpha_x: self.alpha_x[c],
                    alpha_y: self.alpha_y[c],
                }),
            );
        }
        if let Some(d) = &self.diffuse {
            d.push_proposals(wi, out);
        }
    }
}
