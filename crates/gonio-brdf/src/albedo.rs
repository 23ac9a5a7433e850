//! Numerical directional albedo for any [`Brdf`], by deterministic multiple importance
//! sampling.
//!
//! With the model's proposals `p_k` (weights `w_k`, total `W`) and their mixture
//! `p = Σ (w_k/W) p_k`, the balance heuristic splits the albedo into one integral per
//! proposal, `ρ = ∫ f cos θo dω = Σ_k ∫ (w_k p_k / (W p)) f cos θo dω`, and each is
//! integrated by adaptive 2-D Gauss–Kronrod cubature in that proposal's own sampling
//! coordinates, where `p_k dω` is the flat measure `du`: the integrand is nearly
//! constant however sharp the lobe. The proposals are used unfolded
//! ([`Proposal::raw_sample`](crate::Proposal::raw_sample)), and the part of each
//! coordinate square that maps above the surface is cut out *exactly*:
//! - a cosine lobe about an axis `a`, in coordinates `t = cos^{n+1} α` and the azimuth β
//!   about `a` measured from the plane of `a` and the normal: the ring at angle α is
//!   above the surface for `cos β > −cos α a_z / (sin α √(1 − a_z²))`;
//! - a half-vector density, in its sampling coordinates (u₀ → θh, u₁ → φh): the
//!   reflection stays above the surface for `θh < θmax(φh)` in closed form.
//!
//! So no integrand has a notch cut into its domain by the horizon, and the error
//! estimates of the Gauss–Kronrod rules can be trusted. (One step remains possible: an
//! `n = 0` cosine lobe's density jumps at its rim, which the other proposals' integrands
//! see through the mixture; that costs evaluations, not accuracy.)

use std::f64::consts::{PI, TAU};

use gonio_core::quad::{Tolerance, VecEstimate, integrate_2d};
use gonio_core::{Dir, Frame, Vec3};

use crate::Brdf;
use crate::proposal::{Proposal, Weighted};

/// The tolerance [`Brdf::albedo`] uses by default: 1e-10 absolute, 1e-9 relative.
pub const DEFAULT_TOLERANCE: Tolerance = Tolerance {
    abs: 1e-10,
    rel: 1e-9,
    max_evals: 4_000_000,
};

/// `ρ(wi)` per channel with its error estimate, excluding any mirror term.
pub fn integrate<B: Brdf + ?Sized>(brdf: &B, wi: Dir, tol: Tolerance) -> VecEstimate {
    let m = brdf.channels().len();
    let mut total = VecEstimate {
        values: vec![0.0; m],
        errors: vec![0.0; m],
        evals: 0,
        converged: true,
    };
    if !wi.is_above() {
        return total;
    }
    let mut props: Vec<Weighted> = Vec::new();
    brdf.proposals(wi, &mut props);
    let w_total: f64 = props.iter().map(|p| p.weight).sum();
    if w_total.is_nan() || w_total <= 0.0 {
        return total;
    }
    let pieces = props.len() * 2;
    let per = Tolerance {
        abs: tol.abs / pieces as f64,
        rel: tol.rel,
        max_evals: tol.max_evals / pieces,
    };
    let mut f = vec![0.0; m];
    // (w_k/W) f cos θo / p at `wo`, times the Jacobian `jac` of the cut-out map.
    let mut term = |k: usize, wo: Dir, jac: f64, out: &mut [f64]| {
        out.fill(0.0);
        if wo.z <= 0.0 || jac.is_nan() || jac <= 0.0 {
            return;
        }
        let p: f64 = props
            .iter()
            .map(|q| q.weight * q.proposal.raw_pdf(wi, wo))
            .sum();
        if p > 0.0 {
            brdf.eval(wi, wo, &mut f);
            // p is W times the mixture density.
            let s = props[k].weight * wo.z * jac / p;
            for (o, v) in out.iter_mut().zip(&f) {
                *o = v * s;
            }
        }
    };
    for (k, prop) in props.iter().enumerate() {
        let parts: Vec<VecEstimate> = match prop.proposal {
            Proposal::CosinePower { axis, n } => {
                let az = axis.z.clamp(-1.0, 1.0);
                let kk = (1.0 - az * az).max(0.0).sqrt();
                // t: the unit vector ⟂ axis in the plane of the axis and the normal, up.
                let t = match ((Vec3::Z - axis.vec() * az) / kk).normalized() {
                    Some(t) if kk > 1e-12 => t,
                    _ => Frame::from_normal(axis).x,
                };
                let b = axis.vec().cross(t);
                let t_break = kk.powf(n + 1.0);
                // Each piece runs from the break (where the half-width of the β range
                // has a square-root singularity) to `far`, through σ ∈ [0, 1] with
                // t = t_break + (far − t_break) σ², which makes that singularity smooth.
                let mut piece = |far: f64| {
                    let len = far - t_break;
                    integrate_2d(
                        |sigma, s, out| {
                            let tt = (t_break + len * sigma * sigma).clamp(0.0, 1.0);
                            let dt = 2.0 * sigma * len.abs();
                            let x = tt.powf(1.0 / (n + 1.0));
                            let sa = (1.0 - x * x).max(0.0).sqrt();
                            let bmax = if kk * sa == 0.0 {
                                if x * az > 0.0 { PI } else { 0.0 }
                            } else {
                                let r = -x * az / (sa * kk);
                                if r <= -1.0 {
                                    PI
                                } else if r >= 1.0 {
                                    0.0
                                } else {
                                    r.acos()
                                }
                            };
                            let beta = bmax * (2.0 * s - 1.0);
                            let (sb, cb) = beta.sin_cos();
                            let v = axis.vec() * x + (t * cb + b * sb) * sa;
                            match Dir::new(v) {
                                Some(wo) => term(k, wo, dt * 2.0 * bmax / TAU, out),
                                None => out.fill(0.0),
                            }
                        },
                        [0.0, 1.0],
                        [0.0, 1.0],
                        m,
                        per,
                    )
                };
                let mut v = Vec::with_capacity(2);
                if t_break > 0.0 {
                    v.push(piece(0.0));
                }
                if t_break < 1.0 {
                    v.push(piece(1.0));
                }
                v
            }
            Proposal::HalfVector(hd) => vec![integrate_2d(
                |u1, s, out| {
                    let (lo, hi) = hd.u0_range(wi, u1);
                    let h = hd.sample([lo + (hi - lo) * s, u1]);
                    term(k, wi.reflect(h), hi - lo, out);
                },
                [0.0, 1.0],
                [0.0, 1.0],
                m,
                per,
            )],
        };
        for est in parts {
            for j in 0..m {
                total.values[j] += est.values[j];
                total.errors[j] += est.errors[j];
            }
            total.evals += est.evals;
            total.converged &= est.converged;
        }
    }
    total
}

/// The default numerical albedo, mirror term included, written to `out`.
pub fn numerical_into<B: Brdf + ?Sized>(brdf: &B, wi: Dir, out: &mut [f64]) {
    let est = integrate(brdf, wi, DEFAULT_TOLERANCE);
    for (o, v) in out.iter_mut().zip(&est.values) {
        *o = *v;
    }
    let mut mirror = vec![0.0; out.len()];
    if brdf.mirror(wi, &mut mirror) {
        for (o, m) in out.iter_mut().zip(&mirror) {
            *o += m;
        }
    }
}
