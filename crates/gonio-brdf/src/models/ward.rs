use std::f64::consts::PI;

use gonio_core::{Channels, Dir};

use super::{ALBEDO, Diffuse, ParamError, ROUGHNESS, albedo, check, roughness};
use crate::Brdf;
use crate::microfacet::Distribution;
use crate::proposal::{HalfDensity, Proposal, Weighted};

/// Ward's anisotropic Gaussian model (Ward 1992, "Measuring and modeling anisotropic
/// reflection"; the isotropic model when `αx = αy`):
/// `f_r = ρd/π + ρs exp(−tan²θh (cos²φh/αx² + sin²φh/αy²)) / (4π αx αy √(cos θi cos θo))`.
///
/// `αx` is the slope deviation along the sample's x axis. The diffuse part is the
/// optional `[diffuse]` term. Sampling draws half vectors with Ward's own formulas,
/// which are those of a Beckmann distribution.
#[derive(Clone, Debug, PartialEq)]
pub struct Ward {
    channels: Channels,
    rho_s: Vec<f64>,
    alpha_x: Vec<f64>,
    alpha_y: Vec<f64>,
    diffuse: Option<Diffuse>,
}

impl Ward {
    /// `rho_s` in [0, 100], `alpha_x`, `alpha_y` in [1e-4, 10] per channel.
    pub fn new(
        channels: Channels,
        rho_s: Vec<f64>,
        alpha_x: Vec<f64>,
        alpha_y: Vec<f64>,
    ) -> Result<Self, ParamError> {
        check("rho_s", &rho_s, &channels, ALBEDO, albedo)?;
        check("alpha_x", &alpha_x, &channels, ROUGHNESS, roughness)?;
        check("alpha_y", &alpha_y, &channels, ROUGHNESS, roughness)?;
        Ok(Ward {
            channels,
            rho_s,
            alpha_x,
            alpha_y,
            diffuse: None,
        })
    }

    /// Adds a diffuse term, which must have the model's channels.
    pub fn with_diffuse(mut self, d: Diffuse) -> Result<Self, ParamError> {
        super::same_channels("diffuse", &self.channels, d.channels())?;
        self.diffuse = Some(d);
        Ok(self)
    }

    /// Specular scale per channel.
    pub fn rho_s(&self) -> &[f64] {
        &self.rho_s
    }
    /// Roughness along x per channel.
    pub fn alpha_x(&self) -> &[f64] {
        &self.alpha_x
    }
    /// Roughness along y per channel.
    pub fn alpha_y(&self) -> &[f64] {
        &self.alpha_y
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

impl Brdf for Ward {
    fn channels(&self) -> &Channels {
        &self.channels
    }

    fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        super::eval_layered(wi, wo, out, self.diffuse.as_ref(), |out| {
            // tan²θh cos²φh = hx²/hz²: the unnormalised half vector will do.
            let h = wi.vec() + wo.vec();
            let root = (wi.z * wo.z).sqrt();
            let (tx, ty) = (h.x / h.z, h.y / h.z);
            for (c, o) in out.iter_mut().enumerate() {
                let (ax, ay) = (self.alpha_x[c], self.alpha_y[c]);
                let e = (tx / ax).powi(2) + (ty / ay).powi(2);
                *o = self.rho_s[c] * (-e).exp() / (4.0 * PI * ax * ay * root);
            }
        });
    }

    fn proposals(&self, wi: Dir, out: &mut Vec<Weighted>) {
        for c in 0..self.rho_s.len() {
            Weighted::push_merged(
                out,
                self.rho_s[c],
                Proposal::HalfVector(HalfDensity::Microfacet {
                    dist: Distribution::Beckmann,
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
