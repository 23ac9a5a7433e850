//! Evaluating a [`Source`]: BRDFs directly, samples through the nearest-j kernel.

use std::f64::consts::{PI, TAU};

use gonio_brdf::{Brdf, Weighted};
use gonio_core::dirfile::PairDeg;
use gonio_core::{Channels, Dir, SphericalDeg};
use gonio_process::Samples;
use gonio_process::samples::{Interpolator, Kernel};

use super::{PlotErrorKind, Source};

/// Scattered samples seen as a BRDF through the nearest-j Gaussian kernel.
pub(crate) struct SampledBrdf<'a> {
    samples: &'a Samples,
    interp: Interpolator<'a>,
}

impl SampledBrdf<'_> {
    /// The kernel's distance (over both directions, radians for small separations)
    /// from a pair to the nearest sample.
    pub(crate) fn gap(&self, wi: Dir, wo: Dir) -> f64 {
        self.interp.nearest_distance(&PairDeg {
            incident: SphericalDeg::from(wi),
            outgoing: SphericalDeg::from(wo),
        })
    }
}

/// Polar nodes of the fixed albedo quadrature of sampled data.
const ALBEDO_N_THETA: usize = 24;
/// Azimuth nodes of the same.
const ALBEDO_N_PHI: usize = 48;

impl Brdf for SampledBrdf<'_> {
    fn channels(&self) -> &Channels {
        &self.samples.channels
    }

    fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        if !wi.is_above() || !wo.is_above() {
            out.fill(0.0);
            return;
        }
        let v = self.interp.eval_dirs(wi, wo);
        out.copy_from_slice(&v);
    }

    fn proposals(&self, _wi: Dir, out: &mut Vec<Weighted>) {
        out.push(Weighted::COSINE);
    }

    fn is_reciprocal(&self) -> bool {
        false
    }

    /// A fixed midpoint rule in the cosine-weighted coordinates (sin²θo, φo), which
    /// is all an interpolated sample set warrants: ρ = π · mean of f_r over the disk.
    fn albedo(&self, wi: Dir, out: &mut [f64]) {
        out.fill(0.0);
        if !wi.is_above() {
            return;
        }
        let mut f = vec![0.0; out.len()];
        for a in 0..ALBEDO_N_THETA {
            let s2 = (a as f64 + 0.5) / ALBEDO_N_THETA as f64;
            let theta = s2.sqrt().asin();
            for b in 0..ALBEDO_N_PHI {
                let phi = TAU * (b as f64 + 0.5) / ALBEDO_N_PHI as f64;
                self.eval(wi, Dir::from_angles(theta, phi), &mut f);
                for (o, v) in out.iter_mut().zip(&f) {
                    *o += v;
                }
            }
        }
        let w = PI / (ALBEDO_N_THETA * ALBEDO_N_PHI) as f64;
        for o in out.iter_mut() {
            *o *= w;
        }
    }
}

/// A source made ready for evaluation.
pub(crate) enum Evaluator<'a> {
    /// A BRDF evaluated directly.
    Direct(&'a dyn Brdf),
    /// Samples through the kernel.
    Sampled(SampledBrdf<'a>),
}

impl<'a> Evaluator<'a> {
    pub(crate) fn new(src: &Source<'a>, kernel: Kernel) -> Result<Self, PlotErrorKind> {
        Ok(match *src {
            Source::Brdf(b) => Evaluator::Direct(b),
            Source::Model(m) => Evaluator::Direct(m.as_brdf()),
            Source::Samples(s) => Evaluator::Sampled(SampledBrdf {
                samples: s,
                interp: s.interpolator(kernel)?,
            }),
        })
    }

    /// The source as a BRDF.
    pub(crate) fn brdf(&self) -> &dyn Brdf {
        match self {
            Evaluator::Direct(b) => *b,
            Evaluator::Sampled(s) => s,
        }
    }

    /// The sampled form, for the kernel's coverage.
    pub(crate) fn sampled(&self) -> Option<&SampledBrdf<'a>> {
        match self {
            Evaluator::Direct(_) => None,
            Evaluator::Sampled(s) => Some(s),
        }
    }
}

/// `d` wrapped to (−180°, 180°].
pub(crate) fn wrap180(d: f64) -> f64 {
    let r = (d + 180.0).rem_euclid(360.0) - 180.0;
    if r <= -180.0 { r + 360.0 } else { r }
}

/// The samples of channel `ch` at `theta_i_deg` (within `tol`) that lie in the plane
/// of incidence at azimuth `phi_i_deg` (within `tol` in azimuth, or within `tol` of
/// the normal): (signed θo, f_r), with θo negative towards the light, sorted.
///
/// For isotropic samples the plane is each sample's own (φo − φi is what counts);
/// otherwise a sample's φi must also match `phi_i_deg` unless its θi is within `tol`
/// of the normal.
pub(crate) fn in_plane(
    s: &Samples,
    theta_i_deg: f64,
    phi_i_deg: f64,
    tol: f64,
    ch: usize,
) -> Vec<(f64, f64)> {
    let mut pts: Vec<(f64, f64)> = s
        .samples
        .iter()
        .filter_map(|smp| {
            let (inc, out) = (smp.pair.incident, smp.pair.outgoing);
            if (inc.theta_deg - theta_i_deg).abs() > tol {
                return None;
            }
            let phi_ref = if s.isotropic {
                inc.phi_deg
            } else {
                if inc.theta_deg > tol && wrap180(inc.phi_deg - phi_i_deg).abs() > tol {
                    return None;
                }
                phi_i_deg
            };
            let d = wrap180(out.phi_deg - phi_ref);
            let t = out.theta_deg;
            let signed = if t <= tol || (d.abs() - 180.0).abs() <= tol {
                t
            } else if d.abs() <= tol {
                -t
            } else {
                return None;
            };
            Some((signed, *smp.value.get(ch)?))
        })
        .collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    pts
}

/// The pair of directions for the incident direction (θi, φi) and the in-plane
/// outgoing angle `signed_deg` (negative towards the light), all in degrees.
pub(crate) fn in_plane_dirs(theta_i_deg: f64, phi_i_deg: f64, signed_deg: f64) -> (Dir, Dir) {
    let wi = Dir::from_angles(theta_i_deg.to_radians(), phi_i_deg.to_radians());
    let phi_o = if signed_deg >= 0.0 {
        phi_i_deg + 180.0
    } else {
        phi_i_deg
    };
    let wo = Dir::from_angles(signed_deg.abs().to_radians(), phi_o.to_radians());
    (wi, wo)
}
