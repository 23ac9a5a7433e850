use gonio_core::{Channels, Dir, Spectrum};

use crate::proposal::{Weighted, mixture_pdf, mixture_sample};

/// A direction drawn by [`Brdf::sample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrdfSample {
    /// The outgoing direction, strictly above the surface.
    pub wo: Dir,
    /// For a continuous sample, the density (1/sr) it was drawn with, equal to
    /// [`Brdf::pdf`]; for a `delta` sample, the probability of choosing the mirror term.
    pub pdf: f64,
    /// True when the sample is the ideal mirror direction of a delta term.
    pub delta: bool,
}

/// A bidirectional reflectance distribution function with named channels.
///
/// Directions are unit vectors in the local sample frame, both pointing away from the
/// surface (`docs/CONVENTIONS.md`). The domain is the open upper hemisphere: a direction at
/// or below the horizon gives `f_r = 0`, no sample and zero albedo.
///
/// Implementors provide [`eval`](Brdf::eval) and [`proposals`](Brdf::proposals); the
/// sampler, pdf and a numerical albedo follow from them. Models with a closed-form
/// albedo override [`albedo`](Brdf::albedo).
pub trait Brdf: Send + Sync {
    /// The channels every value has one entry for.
    fn channels(&self) -> &Channels;

    /// `f_r(wi, wo)` in 1/sr for every channel, written to `out`, which must have
    /// exactly `channels().len()` entries. Excludes any delta (mirror) term, which
    /// [`mirror`](Brdf::mirror) reports.
    fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]);

    /// The weighted mixture of densities that sampling and numerical integration use
    /// for this `wi`, appended to `out`. Weights are estimates of each part's share of
    /// the albedo (any positive weights give a correct sampler; good ones give a
    /// low-variance one). Together the proposals must cover the support of `f_r`.
    fn proposals(&self, wi: Dir, out: &mut Vec<Weighted>);

    /// The reflectance of an ideal mirror (delta) term towards `wi.mirror()`, per
    /// channel, in `out`; false (and `out` untouched) when the model has none.
    fn mirror(&self, _wi: Dir, _out: &mut [f64]) -> bool {
        false
    }

    /// True when `f_r(wi, wo) = f_r(wo, wi)` holds by construction.
    fn is_reciprocal(&self) -> bool {
        true
    }

    /// Directional–hemispherical reflectance `ρ(wi) = ∫ f_r cos θo dωo` per channel,
    /// including any mirror term.
    fn albedo(&self, wi: Dir, out: &mut [f64]) {
        crate::albedo::numerical_into(self, wi, out);
    }

    /// Draws `wo` for `wi` from the model's mixture, using `uc` in [0, 1) to choose a
    /// component and `u` in [0, 1)² for the direction. `None` only when `wi` is not
    /// above the surface or the model reflects nothing. To draw many samples for one
    /// `wi`, build an [`IncidentSampler`] once instead.
    fn sample(&self, wi: Dir, uc: f64, u: [f64; 2]) -> Option<BrdfSample> {
        IncidentSampler::new(self, wi).sample(uc, u)
    }

    /// The density (1/sr, solid-angle measure on the upper hemisphere) with which
    /// [`sample`](Brdf::sample) draws a continuous `wo`. It integrates to one minus the
    /// probability of the mirror term.
    fn pdf(&self, wi: Dir, wo: Dir) -> f64 {
        IncidentSampler::new(self, wi).pdf(wo)
    }

    /// `f_r(wi, wo)` as a [`Spectrum`] that names its channels.
    fn eval_spectrum(&self, wi: Dir, wo: Dir) -> Spectrum {
        let mut s = Spectrum::zeros(self.channels().clone());
        self.eval(wi, wo, s.values_mut());
        s
    }

    /// `ρ(wi)` as a [`Spectrum`] that names its channels.
    fn albedo_spectrum(&self, wi: Dir) -> Spectrum {
        let mut s = Spectrum::zeros(self.channels().clone());
        self.albedo(wi, s.values_mut());
        s
    }
}

/// Sampling for one incident direction, prepared once: the model's proposals and the
/// probability of its mirror term. What [`Brdf::sample`] and [`Brdf::pdf`] build on
/// every call; a renderer or a test that draws many directions for one `wi` keeps one.
#[derive(Clone, Debug, PartialEq)]
pub struct IncidentSampler {
    wi: Dir,
    props: Vec<Weighted>,
    p_delta: f64,
}

impl IncidentSampler {
    /// Prepares sampling of `brdf` for the incident direction `wi`.
    pub fn new<B: Brdf + ?Sized>(brdf: &B, wi: Dir) -> Self {
        let mut props = Vec::new();
        let mut p_delta = 0.0;
        if wi.is_above() {
            brdf.proposals(wi, &mut props);
            let mut m = vec![0.0; brdf.channels().len()];
            if brdf.mirror(wi, &mut m) {
                // The mirror's mean reflectance over channels against the proposals'
                // total weight, which estimates the rest of the albedo.
                let pm = m.iter().sum::<f64>() / m.len() as f64;
                let w: f64 = props.iter().map(|p| p.weight).sum();
                if pm > 0.0 {
                    p_delta = pm / (pm + w);
                }
            }
        }
        IncidentSampler { wi, props, p_delta }
    }

    /// The incident direction.
    pub fn wi(&self) -> Dir {
        self.wi
    }

    /// The weighted proposals.
    pub fn proposals(&self) -> &[Weighted] {
        &self.props
    }

    /// The probability that a sample is the mirror direction.
    pub fn mirror_probability(&self) -> f64 {
        self.p_delta
    }

    /// See [`Brdf::sample`].
    pub fn sample(&self, uc: f64, u: [f64; 2]) -> Option<BrdfSample> {
        if !self.wi.is_above() {
            return None;
        }
        if uc < self.p_delta {
            return Some(BrdfSample {
                wo: self.wi.mirror(),
                pdf: self.p_delta,
                delta: true,
            });
        }
        let uc = ((uc - self.p_delta) / (1.0 - self.p_delta)).min(1.0 - f64::EPSILON);
        let (wo, pdf) = mixture_sample(&self.props, self.wi, uc, u)?;
        Some(BrdfSample {
            wo,
            pdf: (1.0 - self.p_delta) * pdf,
            delta: false,
        })
    }

    /// See [`Brdf::pdf`].
    pub fn pdf(&self, wo: Dir) -> f64 {
        if !self.wi.is_above() || !wo.is_above() {
            return 0.0;
        }
        (1.0 - self.p_delta) * mixture_pdf(&self.props, self.wi, wo)
    }
}
