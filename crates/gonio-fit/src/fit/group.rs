//! One channel group's fit (one channel, or all with shared exponents): the search
//! from no start values, the final joint refinement on all the data (under the
//! energy constraint when asked), and the natural parameters' standard errors.

use nalgebra::DMatrix;

use crate::data::FitData;
use crate::lobes::{Diffuse, LobeBasis, Natural, Shape};
use crate::varpro;

use super::FitOptions;
use super::search::{search, thin};

/// A fitted channel group (one channel, or all with shared exponents).
pub(super) struct Group {
    pub(super) basis: LobeBasis,
    pub(super) data: FitData,
    pub(super) solved: varpro::Solved,
    /// Under `conserve_energy`: the limit directions, the unconstrained solution's
    /// per-channel cost and constraint state, and whether the result is constrained.
    pub(super) energy: Option<GroupEnergy>,
}

pub(super) struct GroupEnergy {
    pub(super) limits: Vec<[f64; 3]>,
    pub(super) unconstrained_cost: Vec<f64>,
    pub(super) unconstrained: Vec<varpro::ChannelConstraint>,
    pub(super) constrained: bool,
}

/// The distinct incident directions of the data: for an isotropic model (whose albedo
/// does not depend on φi) one a distinct θi, at φi = 0.
fn incident_directions(d: &FitData, anisotropic: bool) -> Vec<[f64; 3]> {
    let key = |w: &[f64; 3]| -> [i64; 3] {
        if anisotropic {
            w.map(|x| (x * 1e9).round() as i64)
        } else {
            [0, 0, (w[2] * 1e9).round() as i64]
        }
    };
    let mut seen = std::collections::BTreeMap::new();
    let mut last = None;
    for w in d.wi.iter() {
        // Pairs come in runs of one incident direction.
        if last == Some(*w) {
            continue;
        }
        last = Some(*w);
        seen.entry(key(w)).or_insert_with(|| {
            if anisotropic {
                *w
            } else {
                let z = w[2].clamp(-1.0, 1.0);
                [(1.0 - z * z).max(0.0).sqrt(), 0.0, z]
            }
        });
    }
    seen.into_values().collect()
}

/// Σr² of each channel of a group from its residuals.
fn channel_costs(full: &varpro::Full, channels: usize) -> Vec<f64> {
    let m = full.residuals.len() / channels.max(1);
    (0..channels)
        .map(|ch| {
            full.residuals[ch * m..(ch + 1) * m]
                .iter()
                .map(|r| r * r)
                .sum()
        })
        .collect()
}

/// Fits one channel group: the start searched on the thinned data, then the joint
/// refinement on all of it (under albedo ≤ 1 at the data's incident directions
/// when `conserve_energy` asks and the unconstrained optimum breaks it).
pub(super) fn fit_group(d: FitData, shape: Shape, shared: bool, opts: &FitOptions) -> Group {
    let sub = thin(&d, opts.search_samples);
    let theta0 = search(&sub, shape, shared);
    let basis = LobeBasis {
        shape,
        channels: d.channels.len(),
        shared,
    };
    let solved = varpro::solve(&basis, &d, &theta0, 200);
    let mut energy = None;
    let mut solved = solved;
    if opts.conserve_energy {
        let limits = incident_directions(&d, shape.anisotropic);
        // The unconstrained optimum's albedos: the constrained problem at the same θ
        // with no row active reproduces them, so evaluate them directly.
        let nl = limits.len();
        let k = varpro::Basis::n_cols(&basis);
        let unconstrained: Vec<varpro::ChannelConstraint> = (0..d.channels.len())
            .map(|ch| {
                let mut b = vec![0.0; nl * k];
                varpro::Basis::albedo_rows(&basis, &solved.theta, ch, &limits, &mut b, None);
                varpro::ChannelConstraint {
                    albedo: (0..nl)
                        .map(|l| (0..k).map(|u| b[l * k + u] * solved.coef[ch][u]).sum())
                        .collect(),
                    multiplier: vec![0.0; nl],
                }
            })
            .collect();
        let unconstrained_cost = channel_costs(&solved.full, d.channels.len());
        let exceeds = unconstrained
            .iter()
            .any(|c| c.albedo.iter().any(|a| *a > 1.0));
        if exceeds {
            solved =
                varpro::solve_with(&basis, &d, &solved.theta, 200, 1e-10, Some(limits.clone()));
        }
        energy = Some(GroupEnergy {
            limits,
            unconstrained_cost,
            unconstrained,
            constrained: exceeds,
        });
    }
    Group {
        basis,
        data: d,
        solved,
        energy,
    }
}

/// Standard errors of channel `ch`'s natural parameters by the delta method from the
/// covariance of (θ, c): the same as from the Jacobian in the natural parameters,
/// without another pass over the data.
pub(super) fn std_errors(
    basis: &LobeBasis,
    theta: &[f64],
    coef: &[f64],
    cov: &DMatrix<f64>,
    ch: usize,
) -> Natural {
    let se: Vec<f64> = basis
        .natural_jacobian(theta, ch, coef)
        .iter()
        .map(|d| {
            let mut v = 0.0;
            for (a, da) in d.iter().enumerate() {
                if *da != 0.0 {
                    for (b, db) in d.iter().enumerate() {
                        v += da * cov[(a, b)] * db;
                    }
                }
            }
            v.max(0.0).sqrt()
        })
        .collect();
    let shape = &basis.shape;
    let mut it = se.into_iter();
    let mut next = || it.next().unwrap_or(f64::NAN);
    let rho_d = next();
    let m = if shape.diffuse == Diffuse::Minnaert {
        next()
    } else {
        0.0
    };
    let lobes = (0..shape.lobes)
        .map(|_| {
            if shape.anisotropic {
                let (cx, cy, cz, n) = (next(), next(), next(), next());
                [cx, cy, cz, n]
            } else {
                let (c, cz, n) = (next(), next(), next());
                [c, c, cz, n]
            }
        })
        .collect();
    Natural { rho_d, m, lobes }
}

/// A group's constrained directions and whether the constraint changed it.
pub(super) fn energy_of(g: &Group) -> (usize, bool) {
    g.energy
        .as_ref()
        .map_or((0, false), |e| (e.limits.len(), e.constrained))
}
