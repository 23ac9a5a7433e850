use std::f64::consts::PI;

use gonio_core::{Channels, Dir};

use super::{ALBEDO, Diffuse, EXPONENT, ParamError, albedo, check, exponent};
use crate::Brdf;
use crate::proposal::{HalfDensity, Proposal, Weighted};

/// Normalised Blinn-Phong: `f_r = ρs C(n) cosⁿθh` with the half vector `h`, plus an
/// optional `[diffuse]` term.
///
/// The normalisation is exact, not the usual `(n+8)/(8π)` approximation: at normal
/// incidence `θo = 2θh`, and `∫ cosⁿθh cos θo dωo = 8π (n + 2^{−n/2}) / ((n+2)(n+4))`,
/// so `C(n) = (n+2)(n+4) / (8π (n + 2^{−n/2}))` makes `ρs` the albedo of the specular
/// term at normal incidence. `n = 0` gives Lambert (`C = 1/π`).
#[derive(Clone, Debug, PartialEq)]
pub struct BlinnPhong {
    channels: Channels,
    rho_s: Vec<f64>,
    n: Vec<f64>,
    diffuse: Option<Diffuse>,
    coef: Vec<f64>,
}

/// `C(n)` of [`BlinnPhong`].
pub(crate) fn blinn_phong_normalization(n: f64) -> f64 {
    (n + 2.0) * (n + 4.0) / (8.0 * PI * (n + (-0.5 * n).exp2()))
}

impl BlinnPhong {
    /// `rho_s` ≥ 0 and `n` ≥ 0 per channel.
    pub fn new(channels: Channels, rho_s: Vec<f64>, n: Vec<f64>) -> Result<Self, ParamError> {
        check("rho_s", &rho_s, &channels, ALBEDO, albedo)?;
        check("n", &n, &channels, EXPONENT, exponent)?;
        let coef: Vec<f64> = rho_s
            .iter()
            .zip(&n)
            .map(|(r, n)| r * blinn_phong_normalization(*n))
            .collect();
        // (n+2)(n+4) overflows past n ≈ 1e154 and C(n) becomes inf/inf (found by
        // fuzzing `n = 1e308`): such an exponent is refused rather than evaluated as NaN.
        if let Some(c) = coef.iter().position(|x| !x.is_finite()) {
            return Err(ParamError::new(
                "n",
                format!(
                    "{:?} for channel {} is too large: its normalisation overflows",
                    n[c],
                    channels.name(c)
                ),
            ));
        }
        Ok(BlinnPhong {
            channels,
            rho_s,
            n,
            diffuse: None,
            coef,
        })
    }

    /// Adds a diffuse term, which must have the model's channels.
    pub fn with_diffuse(mut self, d: Diffuse) -> Result<Self, ParamError> {
        super::same_channels("diffuse", &self.channels, d.channels())?;
        self.diffuse = Some(d);
        Ok(self)
    }

    /// Specular albedo at normal incidence per channel.
    pub fn rho_s(&self) -> &[f64] {
        &self.rho_s
    }
    /// Exponent per channel.
    pub fn n(&self) -> &[f64] {
        &self.n
    }
    /// The diffuse term, if any.
    pub fn diffuse(&self) -> Option<&Diffuse> {
        self.diffuse.as_ref()
    }
}

impl Brdf for BlinnPhong {
    fn channels(&self) -> &Channels {
        &self.channels
    }

    fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        super::eval_layered(wi, wo, out, self.diffuse.as_ref(), |out| {
            let s = wi.vec() + wo.vec();
            let hz = s.z / s.norm();
            for ((o, c), n) in out.iter_mut().zip(&self.coef).zip(&self.n) {
                *o = c * hz.powf(*n);
            }
        });
    }

    fn proposals(&self, wi: Dir, out: &mut Vec<Weighted>) {
        for (r, n) in self.rho_s.iter().zip(&self.n) {
            Weighted::push_merged(
                out,
                *r,
                Proposal::HalfVector(HalfDensity::CosinePower { n: *n }),
            );
        }
        if let Some(d) = &self.diffuse {
            d.push_proposals(wi, out);
        }
    }
}
