use std::f64::consts::TAU;

use gonio_core::{Channels, Dir};

use super::{ALBEDO, EXPONENT, ParamError, albedo, check, exponent};
use crate::Brdf;
use crate::proposal::{Proposal, Weighted};

/// Lambertian or Minnaert diffuse reflection (Lafortune et al. 1997, Eq. 6):
/// `f_r = ρd (n+2)/(2π) (u_z v_z)ⁿ`, which for `n = 0` is Lambert's `ρd/π`.
///
/// `ρd` is the albedo at normal incidence; the albedo at `u` is exactly `ρd u_zⁿ`.
/// Used on its own (`kind = "lambert"` / `"minnaert"`) and as the `[diffuse]` term of
/// other models.
#[derive(Clone, Debug, PartialEq)]
pub struct Diffuse {
    channels: Channels,
    rho: Vec<f64>,
    n: Vec<f64>,
    /// `ρd (n+2)/(2π)` per channel.
    coef: Vec<f64>,
}

impl Diffuse {
    /// Lambert: `f_r = ρ/π`, with `rho` ≥ 0 per channel.
    pub fn lambert(channels: Channels, rho: Vec<f64>) -> Result<Self, ParamError> {
        let n = vec![0.0; rho.len()];
        Self::minnaert(channels, rho, n)
    }

    /// Minnaert (Eq. 6): `rho` ≥ 0 and exponent `n` ≥ 0 per channel.
    pub fn minnaert(channels: Channels, rho: Vec<f64>, n: Vec<f64>) -> Result<Self, ParamError> {
        check("rho", &rho, &channels, ALBEDO, albedo)?;
        check("n", &n, &channels, EXPONENT, exponent)?;
        let coef = rho
            .iter()
            .zip(&n)
            .map(|(r, n)| r * (n + 2.0) / TAU)
            .collect();
        Ok(Diffuse {
            channels,
            rho,
            n,
            coef,
        })
    }

    /// Albedo at normal incidence per channel.
    pub fn rho(&self) -> &[f64] {
        &self.rho
    }

    /// Minnaert exponent per channel (all zero for Lambert).
    pub fn n(&self) -> &[f64] {
        &self.n
    }

    /// True when every exponent is zero.
    pub fn is_lambert(&self) -> bool {
        self.n.iter().all(|n| *n == 0.0)
    }

    #[inline]
    pub(crate) fn add_eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        let p = wi.z * wo.z;
        for ((o, c), n) in out.iter_mut().zip(&self.coef).zip(&self.n) {
            *o += if *n == 0.0 { *c } else { c * p.powf(*n) };
        }
    }

    pub(crate) fn add_albedo(&self, wi: Dir, out: &mut [f64]) {
        for ((o, r), n) in out.iter_mut().zip(&self.rho).zip(&self.n) {
            *o += r * wi.z.powf(*n);
        }
    }

    pub(crate) fn push_proposals(&self, wi: Dir, out: &mut Vec<Weighted>) {
        for (r, n) in self.rho.iter().zip(&self.n) {
            // Density ∝ v_z^{n+1}: the cosine-weighted Minnaert lobe.
            Weighted::push_merged(
                out,
                r * wi.z.powf(*n),
                Proposal::CosinePower {
                    axis: Dir::Z,
                    n: n + 1.0,
                },
            );
        }
    }
}

impl Brdf for Diffuse {
    fn channels(&self) -> &Channels {
        &self.channels
    }

    fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        out.fill(0.0);
        if wi.is_above() && wo.is_above() {
            self.add_eval(wi, wo, out);
        }
    }

    fn proposals(&self, wi: Dir, out: &mut Vec<Weighted>) {
        self.push_proposals(wi, out);
    }

    fn albedo(&self, wi: Dir, out: &mut [f64]) {
        out.fill(0.0);
        if wi.is_above() {
            self.add_albedo(wi, out);
        }
    }
}
