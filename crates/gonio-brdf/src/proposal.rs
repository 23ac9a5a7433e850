//! The sampling densities models are built from, folded onto the upper hemisphere.

use std::f64::consts::TAU;

use gonio_core::{Dir, Frame, Vec3, half_vector};

use crate::microfacet::Distribution;

/// A density of half vectors about the normal, from which `wo` is the reflection of
/// `wi` (the `dωo/dωh = 4 (wi·h)` Jacobian is accounted for in [`Proposal::pdf`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HalfDensity {
    /// `(n+1)/(2π) cosⁿθh` (Blinn-Phong).
    CosinePower {
        /// Exponent.
        n: f64,
    },
    /// `D(h) cos θh` of a microfacet distribution (Ward's model uses Beckmann's).
    Microfacet {
        /// The distribution.
        dist: Distribution,
        /// Roughness along x.
        alpha_x: f64,
        /// Roughness along y.
        alpha_y: f64,
    },
}

impl HalfDensity {
    /// The half vector for `u` in [0, 1)²: the sampling map, which the albedo
    /// integrator also uses as its coordinates.
    #[inline]
    pub(crate) fn sample(&self, u: [f64; 2]) -> Dir {
        match *self {
            HalfDensity::CosinePower { n } => sample_cosine_power_local(n, u),
            HalfDensity::Microfacet {
                dist,
                alpha_x,
                alpha_y,
            } => dist.sample_h(u, alpha_x, alpha_y),
        }
    }

    /// The range of `u₀` that, with this `u₁`, draws half vectors whose reflection of
    /// `wi` stays above the surface (then `wi·h > 0` too). In the sampling map, `u₁`
    /// fixes the azimuth φ and `u₀` the polar angle θ monotonically; reflection stays
    /// above the surface for `θ < θmax(φ) = (π/2 + δ)/2` with
    /// `δ = atan2(sin θi cos(φ − φi), cos θi)`, because
    /// `wo_z = cos θi cos 2θ + sin θi cos(φ − φi) sin 2θ`.
    pub(crate) fn u0_range(&self, wi: Dir, u1: f64) -> (f64, f64) {
        let phi_dir = self.sample([0.5, u1]);
        let (sp, cp) = (phi_dir.y, phi_dir.x);
        let norm = sp.hypot(cp);
        let (sp, cp) = if norm > 0.0 {
            (sp / norm, cp / norm)
        } else {
            (0.0, 1.0)
        };
        let delta = (wi.x * cp + wi.y * sp).atan2(wi.z);
        let theta_max = 0.5 * (std::f64::consts::FRAC_PI_2 + delta);
        let tan2 = theta_max.tan().powi(2);
        match *self {
            HalfDensity::CosinePower { n } => (theta_max.cos().powf(n + 1.0), 1.0),
            HalfDensity::Microfacet {
                dist,
                alpha_x,
                alpha_y,
            } => {
                let a = (cp / alpha_x).powi(2) + (sp / alpha_y).powi(2);
                let hi = match dist {
                    Distribution::Beckmann => -(-a * tan2).exp_m1(),
                    Distribution::Ggx => a * tan2 / (1.0 + a * tan2),
                };
                (0.0, hi)
            }
        }
    }

    #[inline]
    fn pdf(&self, h: Vec3) -> f64 {
        match *self {
            HalfDensity::CosinePower { n } => cosine_power_density(n, h.z),
            HalfDensity::Microfacet {
                dist,
                alpha_x,
                alpha_y,
            } => dist.pdf_h(h, alpha_x, alpha_y),
        }
    }
}

/// One sampling density over outgoing directions.
///
/// Both kinds are *folded*: a direction that would fall below the surface is mirrored
/// through it (`z → −z`), and a half vector facing away from `wi` is turned by 180°
/// about the normal. So sampling never fails, and the density on the upper hemisphere
/// is `q(v) = p(v) + p(v̄)` — still closed-form, and integrating to exactly 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Proposal {
    /// `p(v) = (n+1)/(2π) max(0, axis·v)ⁿ` over the sphere: a cosine lobe about `axis`
    /// (Lambert is `axis = z, n = 1`; a Lafortune lobe has `axis = u'` of Eq. 5).
    CosinePower {
        /// Lobe axis.
        axis: Dir,
        /// Exponent.
        n: f64,
    },
    /// A half-vector density about the normal, reflected about `wi`.
    HalfVector(HalfDensity),
}

/// A proposal with its mixture weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Weighted {
    /// Non-negative weight (an estimate of this part's albedo).
    pub weight: f64,
    /// The density.
    pub proposal: Proposal,
}

impl Weighted {
    /// Cosine-weighted about the normal, all the weight: what tabulated and measured
    /// BRDFs sample with (their shape is unknown in advance; it covers the
    /// hemisphere).
    pub const COSINE: Weighted = Weighted {
        weight: 1.0,
        proposal: Proposal::CosinePower {
            axis: Dir::Z,
            n: 1.0,
        },
    };

    /// Appends `proposal` with `weight` to `out`, merging it into an identical one
    /// already there (models with per-channel parameters often repeat themselves).
    pub fn push_merged(out: &mut Vec<Weighted>, weight: f64, proposal: Proposal) {
        if !weight.is_finite() || weight <= 0.0 {
            return;
        }
        if let Some(w) = out.iter_mut().find(|w| w.proposal == proposal) {
            w.weight += weight;
        } else {
            out.push(Weighted { weight, proposal });
        }
    }
}

/// `(n+1)/(2π) cⁿ` for `c > 0`, else 0.
#[inline]
pub(crate) fn cosine_power_density(n: f64, c: f64) -> f64 {
    if c <= 0.0 {
        0.0
    } else {
        (n + 1.0) / TAU * c.powf(n)
    }
}

/// A direction about +z with density `(n+1)/(2π) cosⁿα`: `cos α = u₀^{1/(n+1)}`,
/// `φ = 2π u₁` (monotone in `u₀`, which the albedo integrator relies on).
#[inline]
pub(crate) fn sample_cosine_power_local(n: f64, u: [f64; 2]) -> Dir {
    if n == 1.0 {
        // The same map without ln/exp: cos α = √u₀.
        let r = (1.0 - u[0]).max(0.0).sqrt();
        let (s, c) = (TAU * u[1]).sin_cos();
        return Dir::from_unit(Vec3::new(r * c, r * s, u[0].sqrt()));
    }
    let ln_c = u[0].ln() / (n + 1.0);
    let cos_a = ln_c.exp();
    // 1 − cos α without cancellation when the lobe is sharp.
    let one_minus = -ln_c.exp_m1();
    let sin_a = (one_minus * (1.0 + cos_a)).max(0.0).sqrt();
    let (s, c) = (TAU * u[1]).sin_cos();
    Dir::from_unit(Vec3::new(sin_a * c, sin_a * s, cos_a))
}

impl Proposal {
    /// Draws a direction strictly above the surface, or `None` on a set of measure zero
    /// (a sample exactly on the horizon).
    #[inline]
    pub fn sample(&self, wi: Dir, u: [f64; 2]) -> Option<Dir> {
        let v = match *self {
            Proposal::CosinePower { axis, n } => cosine_power_about(axis, n, u),
            Proposal::HalfVector(hd) => {
                let mut h = hd.sample(u);
                if wi.dot(*h) <= 0.0 {
                    h = Dir::from_unit(Vec3::new(-h.x, -h.y, h.z));
                    if wi.dot(*h) <= 0.0 {
                        return None;
                    }
                }
                wi.reflect(h)
            }
        };
        let v = if v.z < 0.0 { v.flip_z() } else { v };
        (v.z > 0.0).then_some(v)
    }

    /// The folded density (1/sr) of [`sample`](Self::sample) at `wo` (above the surface).
    #[inline]
    pub fn pdf(&self, wi: Dir, wo: Dir) -> f64 {
        self.folded_sphere_pdf(wi, wo) + self.folded_sphere_pdf(wi, wo.flip_z())
    }

    /// Draws from the *unfolded* density over the whole sphere: no mirroring through
    /// the surface, and `None` for a half vector facing away from `wi`. Its density,
    /// [`raw_pdf`](Self::raw_pdf), may integrate to less than 1; integrals weighted by
    /// it are continuous where the folded ones have steps, which is what quadrature
    /// wants.
    #[inline]
    pub fn raw_sample(&self, wi: Dir, u: [f64; 2]) -> Option<Dir> {
        match *self {
            Proposal::CosinePower { axis, n } => Some(cosine_power_about(axis, n, u)),
            Proposal::HalfVector(hd) => {
                let h = hd.sample(u);
                (wi.dot(*h) > 0.0).then(|| wi.reflect(h))
            }
        }
    }

    /// The density (1/sr) of [`raw_sample`](Self::raw_sample) at any `w` on the sphere.
    #[inline]
    pub fn raw_pdf(&self, wi: Dir, w: Dir) -> f64 {
        match *self {
            Proposal::CosinePower { axis, n } => cosine_power_density(n, axis.dot(*w)),
            Proposal::HalfVector(hd) => {
                let Some(h) = half_vector(wi, w) else {
                    return 0.0;
                };
                let d = wi.dot(*h);
                if h.z <= 0.0 || d <= 0.0 {
                    0.0
                } else {
                    hd.pdf(*h) / (4.0 * d)
                }
            }
        }
    }

    /// The density of [`sample`](Self::sample) before folding through the surface
    /// plane, over the whole sphere.
    #[inline]
    fn folded_sphere_pdf(&self, wi: Dir, w: Dir) -> f64 {
        match *self {
            Proposal::CosinePower { .. } => self.raw_pdf(wi, w),
            Proposal::HalfVector(hd) => {
                let Some(h) = half_vector(wi, w) else {
                    return 0.0;
                };
                let d = wi.dot(*h);
                if h.z <= 0.0 || d <= 0.0 {
                    return 0.0;
                }
                let mut ph = hd.pdf(*h);
                let rh = Vec3::new(-h.x, -h.y, h.z);
                if wi.dot(rh) <= 0.0 {
                    // Half vectors drawn at `rh` were turned to `h`.
                    ph += hd.pdf(rh);
                }
                ph / (4.0 * d)
            }
        }
    }
}

#[inline]
fn cosine_power_about(axis: Dir, n: f64, u: [f64; 2]) -> Dir {
    let local = sample_cosine_power_local(n, u);
    if axis.vec() == Vec3::Z {
        local
    } else {
        Frame::from_normal(axis).dir_to_parent(local)
    }
}

/// Draws from a weighted mixture: `uc` chooses the component, `u` the direction.
/// Returns the direction and the mixture density there.
pub fn mixture_sample(props: &[Weighted], wi: Dir, uc: f64, u: [f64; 2]) -> Option<(Dir, f64)> {
    let total: f64 = props.iter().map(|p| p.weight).sum();
    if total.is_nan() || total <= 0.0 {
        return None;
    }
    let mut target = uc * total;
    let mut chosen = &props[props.len() - 1];
    for p in props {
        if target < p.weight {
            chosen = p;
            break;
        }
        target -= p.weight;
    }
    let wo = chosen.proposal.sample(wi, u)?;
    Some((wo, mixture_pdf(props, wi, wo)))
}

/// The density (1/sr) of the weighted mixture at `wo`.
pub fn mixture_pdf(props: &[Weighted], wi: Dir, wo: Dir) -> f64 {
    let total: f64 = props.iter().map(|p| p.weight).sum();
    if total.is_nan() || total <= 0.0 || !wo.is_above() {
        return 0.0;
    }
    props
        .iter()
        .map(|p| p.weight * p.proposal.pdf(wi, wo))
        .sum::<f64>()
        / total
}
