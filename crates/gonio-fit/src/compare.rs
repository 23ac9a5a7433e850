//! Other analytic models fitted to the same data with the same metric, so that a user
//! sees whether lobes are the right choice (the comparison of Ngan et al. 2005).
//!
//! Each is a Lambertian term plus a specular term that is linear in its strength:
//! Ward (isotropic) and Blinn-Phong with ρs as the coefficient, Cook–Torrance with
//! Schlick's Fresnel split into two columns, ρs f0 · [F = 1] + ρs (1 − f0) · [F =
//! (1 − cos)⁵], so that both coefficients ≥ 0 means 0 ≤ f0 ≤ 1. Their one non-linear
//! parameter (roughness α or exponent n, searched as its logarithm) is started from a
//! log-spaced scan scored by the projected cost. The columns are the `gonio-brdf`
//! models themselves (the same code that renders and simulates them), so their
//! derivatives are central differences in the logarithm, step 1e-6.

use std::sync::RwLock;

use gonio_brdf::{Brdf, Model};
use serde::Serialize;

use crate::FitError;
use crate::data::FitData;
use crate::varpro::{self, Basis};

/// A comparison model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Kind {
    /// Ward 1992, isotropic.
    Ward,
    /// Blinn-Phong, exactly normalised.
    BlinnPhong,
    /// Cook–Torrance with the Beckmann distribution.
    CookTorranceBeckmann,
    /// Cook–Torrance with the GGX distribution.
    CookTorranceGgx,
}

impl Kind {
    /// All of them, in the order the table lists them.
    pub const ALL: [Kind; 4] = [
        Kind::Ward,
        Kind::BlinnPhong,
        Kind::CookTorranceBeckmann,
        Kind::CookTorranceGgx,
    ];

    /// The name the table prints.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Ward => "Ward",
            Kind::BlinnPhong => "Blinn-Phong",
            Kind::CookTorranceBeckmann => "Cook-Torrance (Beckmann)",
            Kind::CookTorranceGgx => "Cook-Torrance (GGX)",
        }
    }

    /// The specular columns' model files at parameter p (α or n): one per column.
    fn specular(self, p: f64) -> Vec<String> {
        let head = "channels = [\"value\"]\n";
        match self {
            Kind::Ward => vec![format!(
                "kind = \"ward\"\n{head}rho_s = [1.0]\nalpha = [{p:?}]\n"
            )],
            Kind::BlinnPhong => {
                vec![format!(
                    "kind = \"blinn-phong\"\n{head}rho_s = [1.0]\nn = [{p:?}]\n"
                )]
            }
            Kind::CookTorranceBeckmann | Kind::CookTorranceGgx => {
                let d = if self == Kind::CookTorranceGgx {
                    "ggx"
                } else {
                    "beckmann"
                };
                [1.0, 0.0]
                    .iter()
                    .map(|f0| {
                        format!(
                            "kind = \"cook-torrance\"\n{head}distribution = \"{d}\"\nf0 = [{f0:?}]\nalpha = [{p:?}]\n"
                        )
                    })
                    .collect()
            }
        }
    }

    /// The scan of the non-linear parameter's start.
    fn scan(self) -> Vec<f64> {
        match self {
            Kind::BlinnPhong => [1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0].to_vec(),
            _ => [0.03, 0.06, 0.1, 0.15, 0.2, 0.3, 0.45, 0.7].to_vec(),
        }
    }
}

/// Models at θ and at θ ± h (for the derivative), rebuilt when θ changes.
struct Cache {
    theta: f64,
    at: Vec<Model>,
    plus: Vec<Model>,
    minus: Vec<Model>,
}

const H: f64 = 1e-6;

/// The separable basis of a comparison model: [1/π, specular columns…], θ = [ln p].
pub struct ModelBasis {
    kind: Kind,
    cache: RwLock<Option<Cache>>,
}

impl ModelBasis {
    /// The basis of `kind`.
    pub fn new(kind: Kind) -> ModelBasis {
        ModelBasis {
            kind,
            cache: RwLock::new(None),
        }
    }

    fn build(&self, ln_p: f64) -> Option<Vec<Model>> {
        self.kind
            .specular(ln_p.exp())
            .iter()
            .map(|t| Model::from_toml(t, None).ok())
            .collect()
    }

    fn ensure(&self, ln_p: f64) {
        let fresh = self
            .cache
            .read()
            .map(|c| c.as_ref().is_some_and(|c| c.theta == ln_p))
            .unwrap_or(false);
        if fresh {
            return;
        }
        let built = (self.build(ln_p), self.build(ln_p + H), self.build(ln_p - H));
        if let (Some(at), Some(plus), Some(minus)) = built
            && let Ok(mut w) = self.cache.write()
        {
            *w = Some(Cache {
                theta: ln_p,
                at,
                plus,
                minus,
            });
        }
    }
}

impl Basis for ModelBasis {
    fn n_params(&self) -> usize {
        1
    }

    fn n_cols(&self) -> usize {
        1 + self.kind.specular(0.1).len()
    }

    fn eval(
        &self,
        theta: &[f64],
        _ch: usize,
        wi: [f64; 3],
        wo: [f64; 3],
        cols: &mut [f64],
        d: Option<&mut [f64]>,
    ) {
        self.ensure(theta[0]);
        cols[0] = 1.0 / std::f64::consts::PI;
        let (wi, wo) = (
            gonio_core::Dir::from_unit(gonio_core::Vec3::new(wi[0], wi[1], wi[2])),
            gonio_core::Dir::from_unit(gonio_core::Vec3::new(wo[0], wo[1], wo[2])),
        );
        let Ok(guard) = self.cache.read() else {
            cols.fill(f64::NAN);
            return;
        };
        let Some(c) = guard.as_ref() else {
            // The parameter left the models' domain: an infinite cost steers the
            // search back.
            cols.fill(f64::NAN);
            return;
        };
        let mut out = [0.0];
        let mut one = |m: &Model| {
            m.eval(wi, wo, &mut out);
            out[0]
        };
        for (k, m) in c.at.iter().enumerate() {
            cols[1 + k] = one(m);
        }
        if let Some(d) = d {
            d[0] = 0.0;
            for k in 0..c.at.len() {
                d[1 + k] = (one(&c.plus[k]) - one(&c.minus[k])) / (2.0 * H);
            }
        }
    }
}

/// One comparison model's fit of one channel.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Compared {
    /// The model.
    pub model: &'static str,
    /// The channel.
    pub channel: String,
    /// Diffuse albedo ρd.
    pub rho_d: f64,
    /// Specular strength ρs.
    pub rho_s: f64,
    /// Fresnel f0 (Cook–Torrance), else none.
    pub f0: Option<f64>,
    /// Roughness α, or Blinn-Phong's exponent n.
    pub shape: f64,
    /// RMS of f_model − f_data, 1/sr (unweighted).
    pub rms: f64,
    /// RMS of the weighted residuals relative to the weighted data's.
    pub relative_rms: f64,
}

/// Fits one comparison model to every channel of `data`.
pub fn fit_model(kind: Kind, data: &FitData) -> Result<Vec<Compared>, FitError> {
    (0..data.channels.len())
        .map(|ch| {
            let one = FitData {
                channels: gonio_core::Channels::Single,
                wi: data.wi.clone(),
                wo: data.wo.clone(),
                y: vec![data.y[ch].clone()],
                weight: vec![data.weight[ch].clone()],
                ..data.clone()
            };
            let basis = ModelBasis::new(kind);
            let start = kind
                .scan()
                .into_iter()
                .map(|p| {
                    let t = [p.ln()];
                    let c = varpro::evaluate(&basis, &one, &t, false).cost;
                    (if c.is_finite() { c } else { f64::INFINITY }, t)
                })
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .map(|x| x.1)
                .ok_or_else(|| FitError::Numerics("no start".into()))?;
            let s = varpro::solve(&basis, &one, &start, 100);
            let (coef, residuals) = varpro::residuals(&basis, &one, &s.theta);
            let m = one.len() as f64;
            let wrms = (residuals.iter().map(|r| r * r).sum::<f64>() / m).sqrt();
            let rms = (residuals
                .iter()
                .zip(one.weight[0].iter())
                .map(|(r, w)| if *w != 0.0 { (r / w).powi(2) } else { 0.0 })
                .sum::<f64>()
                / m)
                .sqrt();
            let scale = (one.y[0]
                .iter()
                .zip(one.weight[0].iter())
                .map(|(y, w)| (y * w).powi(2))
                .sum::<f64>()
                / m)
                .sqrt();
            let c = &coef[0];
            let (rho_s, f0) = if c.len() == 3 {
                let s = c[1] + c[2];
                (s, Some(if s > 0.0 { c[1] / s } else { 0.0 }))
            } else {
                (c[1], None)
            };
            Ok(Compared {
                model: kind.name(),
                channel: data.channels.name(ch),
                rho_d: c[0],
                rho_s,
                f0,
                shape: s.theta[0].exp(),
                rms,
                relative_rms: if scale > 0.0 { wrms / scale } else { 0.0 },
            })
        })
        .collect()
}
