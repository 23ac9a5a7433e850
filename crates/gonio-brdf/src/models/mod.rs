//! The analytic models. Each stores one parameter value per channel.

mod blinn_phong;
mod cook_torrance;
mod diffuse;
mod lafortune;
mod oren_nayar;
mod phong;
mod ward;

pub use crate::microfacet::Distribution;
pub use blinn_phong::BlinnPhong;
pub use cook_torrance::CookTorrance;
pub use diffuse::Diffuse;
pub use lafortune::{FitNote, Lafortune, LafortuneLobe, Sym3};
pub use oren_nayar::{OrenNayar, OrenNayarVariant};
pub use phong::{Mirror, Phong, PhongNormalization};
pub use ward::Ward;

use gonio_core::{Channels, Dir};
use std::f64::consts::TAU;

/// A model parameter that is out of range or has the wrong number of channel values.
/// `field` names it as a model file does (`rho`, `lobes[2].cz`, `diffuse.n`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field}: {message}")]
pub struct ParamError {
    /// The parameter's path in a model file.
    pub field: String,
    /// What is wrong with it.
    pub message: String,
}

impl ParamError {
    pub(crate) fn new(field: impl Into<String>, message: impl Into<String>) -> Self {
        ParamError {
            field: field.into(),
            message: message.into(),
        }
    }

    /// The same error with `prefix.` in front of the field (for nested tables).
    pub fn within(mut self, prefix: &str) -> Self {
        self.field = format!("{prefix}.{}", self.field);
        self
    }
}

/// Checks that `values` has one entry per channel and that each satisfies `ok`, whose
/// failure is described by `what` (e.g. "must be ≥ 0").
pub(crate) fn check(
    field: &str,
    values: &[f64],
    channels: &Channels,
    what: &str,
    ok: impl Fn(f64) -> bool,
) -> Result<(), ParamError> {
    if values.len() != channels.len() {
        return Err(ParamError::new(
            field,
            format!(
                "expected {} values (one per channel {}), got {}",
                channels.len(),
                channels,
                values.len()
            ),
        ));
    }
    for (i, v) in values.iter().enumerate() {
        if !v.is_finite() || !ok(*v) {
            return Err(ParamError::new(
                field,
                format!(
                    "{} for channel {} {what}",
                    gonio_core::limits::num(*v),
                    channels.name(i)
                ),
            ));
        }
    }
    Ok(())
}

/// The frame of every model's `eval`: `out` is zero outside the open hemisphere;
/// inside, `specular` writes the model's own term and the optional diffuse term adds.
#[inline]
pub(crate) fn eval_layered(
    wi: Dir,
    wo: Dir,
    out: &mut [f64],
    diffuse: Option<&Diffuse>,
    specular: impl FnOnce(&mut [f64]),
) {
    out.fill(0.0);
    if !(wi.is_above() && wo.is_above()) {
        return;
    }
    specular(out);
    if let Some(d) = diffuse {
        d.add_eval(wi, wo, out);
    }
}

/// Checks that an added term has the model's channels.
pub(crate) fn same_channels(
    field: &str,
    ours: &Channels,
    theirs: &Channels,
) -> Result<(), ParamError> {
    if ours == theirs {
        Ok(())
    } else {
        Err(ParamError::new(
            field,
            format!("has channels {theirs} but the model has {ours}"),
        ))
    }
}

/// The smallest roughness accepted: below it `π αx αy` and `tan²θ/α²` leave the range
/// of `f64` in places that matter, and no real surface is that smooth.
pub const MIN_ALPHA: f64 = 1e-4;

/// The largest roughness accepted (Ward's and Cook–Torrance's `alpha`): an RMS facet
/// slope of 10, facets at 84° on average; rougher is no longer a surface these models
/// describe, and `α²` of an absurd value overflows.
pub const MAX_ALPHA: f64 = 10.0;

/// The largest exponent accepted (Phong, Blinn-Phong, Lafortune lobes, Minnaert):
/// a lobe of half-width about 0.1°, far narrower than any instrument resolves;
/// beyond it normalisations like `(n + 2)/(2π)` stop meaning anything.
pub const MAX_EXPONENT: f64 = 1e6;

/// The largest albedo-like scale accepted (`rho`, `rho_s`): a surface reflects at most
/// 1; the margin admits fitted models that do not conserve energy.
pub const MAX_ALBEDO: f64 = 100.0;

/// The largest peak a Lafortune lobe may reach, `σⁿ` with `σ` the largest magnitude
/// of `Cᵀ u` over unit `u` (the largest `|C|` of an Eq. 4 lobe), in 1/sr: a mirror-like
/// lobe of exponent 10⁴ peaks near 10³; 10¹² is far beyond any surface and keeps every
/// value, albedo and sampling weight finite.
pub const MAX_LOBE_PEAK: f64 = 1e12;

pub(crate) fn roughness(v: f64) -> bool {
    (MIN_ALPHA..=MAX_ALPHA).contains(&v)
}

/// The message of [`roughness`].
pub(crate) const ROUGHNESS: &str = "must be in [1e-4, 10]";

pub(crate) fn albedo(v: f64) -> bool {
    (0.0..=MAX_ALBEDO).contains(&v)
}

/// The message of [`albedo`].
pub(crate) const ALBEDO: &str = "must be in [0, 100]";

pub(crate) fn exponent(v: f64) -> bool {
    (0.0..=MAX_EXPONENT).contains(&v)
}

/// The message of [`exponent`].
pub(crate) const EXPONENT: &str = "must be in [0, 1e6]";

pub(crate) fn unit_interval(v: f64) -> bool {
    (0.0..=1.0).contains(&v)
}

/// A sampling weight for a cosine lobe of scale `scale` and exponent `n` whose axis has
/// z component `axis_z`: its power over the sphere, `scale · 2π/(n+1)`, discounted for
/// how far the axis leans towards the horizon. Only a mixture weight: any positive
/// value keeps sampling correct.
pub(crate) fn lobe_weight(scale: f64, n: f64, axis_z: f64) -> f64 {
    scale * TAU / (n + 1.0) * (0.1 + 0.9 * axis_z.max(0.0))
}
