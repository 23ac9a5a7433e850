use std::f64::consts::{FRAC_1_PI, FRAC_2_PI};

use gonio_core::{Channels, Dir};

use super::{ALBEDO, ParamError, albedo, check};
use crate::Brdf;
use crate::proposal::{Proposal, Weighted};

/// Which of Oren and Nayar's two approximations to evaluate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OrenNayarVariant {
    /// The functional approximation with the `C1, C2, C3` coefficients and the
    /// interreflection term `L2` (Oren & Nayar 1994, Sec. 4).
    Full,
    /// The simplified "qualitative" model `ρ/π (A + B max(0, cos Δφ) sin α tan β)`.
    Qualitative,
}

impl OrenNayarVariant {
    /// The name used in model files.
    pub fn name(self) -> &'static str {
        match self {
            OrenNayarVariant::Full => "full",
            OrenNayarVariant::Qualitative => "qualitative",
        }
    }
}

/// Oren–Nayar reflection from rough diffuse surfaces of V-cavities whose facet slope
/// angles have standard deviation σ (Oren & Nayar 1994, "Generalization of Lambert's
/// reflectance model"). With `α = max(θi, θo)`, `β = min(θi, θo)` and Δφ the azimuth
/// difference, the full model is
/// `L1 = ρ/π [C1 + cos Δφ C2 tan β + (1 − |cos Δφ|) C3 tan((α+β)/2)]`,
/// `L2 = 0.17 ρ²/π σ²/(σ²+0.13) [1 − cos Δφ (2β/π)²]`, `f_r = L1 + L2`, where
/// `C1 = 1 − 0.5 σ²/(σ²+0.33)`, `C2 = 0.45 σ²/(σ²+0.09) sin α` when `cos Δφ ≥ 0` and
/// `0.45 σ²/(σ²+0.09) (sin α − (2β/π)³)` otherwise, `C3 = 0.125 σ²/(σ²+0.09) (4αβ/π²)²`.
/// σ = 0 gives Lambert. Reciprocal: everything depends on `α, β, Δφ` symmetrically.
#[derive(Clone, Debug, PartialEq)]
pub struct OrenNayar {
    channels: Channels,
    rho: Vec<f64>,
    sigma_deg: Vec<f64>,
    /// σ in radians, as the formulas use it.
    sigma: Vec<f64>,
    variant: OrenNayarVariant,
}

impl OrenNayar {
    /// `rho` ≥ 0 and the slope-angle deviation `sigma_deg` in [0, 90) degrees (as model
    /// files give it) per channel.
    pub fn new(
        channels: Channels,
        rho: Vec<f64>,
        sigma_deg: Vec<f64>,
        variant: OrenNayarVariant,
    ) -> Result<Self, ParamError> {
        check("rho", &rho, &channels, ALBEDO, albedo)?;
        check(
            "sigma_deg",
            &sigma_deg,
            &channels,
            "must be in [0, 90) degrees",
            |s| (0.0..90.0).contains(&s),
        )?;
        let sigma = sigma_deg.iter().map(|d| d.to_radians()).collect();
        Ok(OrenNayar {
            channels,
            rho,
            sigma_deg,
            sigma,
            variant,
        })
    }

    /// Albedo scale per channel.
    pub fn rho(&self) -> &[f64] {
        &self.rho
    }
    /// Slope-angle deviation per channel, degrees.
    pub fn sigma_deg(&self) -> &[f64] {
        &self.sigma_deg
    }
    /// The approximation evaluated.
    pub fn variant(&self) -> OrenNayarVariant {
        self.variant
    }
}

impl Brdf for OrenNayar {
    fn channels(&self) -> &Channels {
        &self.channels
    }

    fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        super::eval_layered(wi, wo, out, None, |out| {
            let (ti, to) = (wi.theta(), wo.theta());
            let (alpha, beta) = (ti.max(to), ti.min(to));
            let ss = wi.sin_theta() * wo.sin_theta();
            // At the normal the azimuth is undefined, and every term it multiplies is 0.
            let cos_dphi = if ss > 0.0 {
                ((wi.x * wo.x + wi.y * wo.y) / ss).clamp(-1.0, 1.0)
            } else {
                0.0
            };
            let (sin_a, tan_b) = (alpha.sin(), beta.tan());
            let b2 = FRAC_2_PI * beta;
            for (c, o) in out.iter_mut().enumerate() {
                let s2 = self.sigma[c] * self.sigma[c];
                let rho = self.rho[c];
                let c1 = 1.0 - 0.5 * s2 / (s2 + 0.33);
                let b = 0.45 * s2 / (s2 + 0.09);
                *o = match self.variant {
                    OrenNayarVariant::Qualitative => {
                        rho * FRAC_1_PI * (c1 + b * cos_dphi.max(0.0) * sin_a * tan_b)
                    }
                    OrenNayarVariant::Full => {
                        let c2 = if cos_dphi >= 0.0 {
                            b * sin_a
                        } else {
                            b * (sin_a - b2 * b2 * b2)
                        };
                        let k = 4.0 * alpha * beta * FRAC_1_PI * FRAC_1_PI;
                        let c3 = 0.125 * s2 / (s2 + 0.09) * k * k;
                        let l1 = rho
                            * FRAC_1_PI
                            * (c1
                                + cos_dphi * c2 * tan_b
                                + (1.0 - cos_dphi.abs()) * c3 * (0.5 * (alpha + beta)).tan());
                        let l2 = 0.17 * rho * rho * FRAC_1_PI * s2 / (s2 + 0.13)
                            * (1.0 - cos_dphi * b2 * b2);
                        l1 + l2
                    }
                };
            }
        });
    }

    fn proposals(&self, _wi: Dir, out: &mut Vec<Weighted>) {
        let w = self.rho.iter().sum::<f64>() / self.rho.len() as f64;
        Weighted::push_merged(
            out,
            w.max(1e-6),
            Proposal::CosinePower {
                axis: Dir::Z,
                n: 1.0,
            },
        );
    }
}
