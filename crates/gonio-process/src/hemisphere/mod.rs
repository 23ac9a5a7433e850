//! Measured samples over the hemisphere: the symmetry an isotropic half-turn plan
//! assumes, the grid a run's own plan forms, and the directional albedo of samples
//! that lie on no complete grid.
//!
//! **Symmetry.** An isotropic material measured over Δφ = φo − φi ∈ [0°, 180°] (the
//! usual half turn) is bilaterally symmetric as well: f(θi, θo, Δφ) = f(θi, θo, −Δφ),
//! the mirror image of the scattering plane. [`unfold`] adds the mirror image of each
//! sample off that plane, so that measures and transforms that need the whole
//! hemisphere get it; anisotropic samples, and isotropic ones that already span more
//! than a half turn, are never unfolded. What was assumed is returned as a
//! [`Symmetry`] for outputs to record.
//!
//! **The run's own grid.** [`own_table`] tabulates samples on the grid their own
//! angles form (each axis the distinct values of that angle, uniformly spaced). A
//! node measured is taken as it is; a node the plan could not measure (the detector
//! shadowing the source near retro-reflection) is interpolated with the nearest-j
//! kernel of DeYoung Sec. 3.2.1 only when a sample lies within one and a half polar
//! steps of it, and reported in [`Fill`]; a node farther from the data refuses the
//! grid rather than be invented.
//!
//! The directional albedo of samples on no complete grid, and its quadrature
//! uncertainty, are in the `albedo` module (re-exported here).

mod albedo;

pub use albedo::{IncidentAlbedo, albedos, albedos_of_table};
pub(crate) use albedo::{albedos_of_table_with, albedos_with, incidence_key};

use std::collections::BTreeMap;

use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use serde::Serialize;

use crate::samples::Kernel;
use crate::{Axis, Grid, ProcessError, Sample, Samples, Table};

/// Angles keyed in micro-degrees (exact for any grid a plan or file writes).
fn q(x: f64) -> i64 {
    (x * 1e6).round() as i64
}

/// An azimuth keyed in micro-degrees within [0°, 360°).
fn wrap(x: f64) -> i64 {
    q(x.rem_euclid(360.0)) % 360_000_000
}

/// The symmetry assumed of the data before it was measured or transformed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Symmetry {
    /// None: the samples are taken as measured (anisotropic data).
    None,
    /// Isotropic: f depends on φo − φi only (the plan fixed φi).
    Isotropic,
    /// Isotropic and bilaterally symmetric: a half turn of Δφ mirrored to −Δφ.
    IsotropicBilateral,
}

impl Symmetry {
    /// The symmetry of samples as they are (before any unfolding).
    pub fn of(s: &Samples) -> Symmetry {
        if s.isotropic {
            Symmetry::Isotropic
        } else {
            Symmetry::None
        }
    }

    /// How outputs name it.
    pub fn name(self) -> &'static str {
        match self {
            Symmetry::None => "none",
            Symmetry::Isotropic => "isotropic",
            Symmetry::IsotropicBilateral => "isotropic-bilateral",
        }
    }

    /// A sentence for text output.
    pub fn describe(self) -> &'static str {
        match self {
            Symmetry::None => "none assumed (anisotropic data, taken as measured)",
            Symmetry::Isotropic => "isotropic: f depends on φo − φi only",
            Symmetry::IsotropicBilateral => {
                "isotropic and bilateral: Δφ measured over a half turn, \
                 f(θi, θo, −Δφ) = f(θi, θo, Δφ) supplies the other half"
            }
        }
    }
}

/// Unfolds isotropic samples measured over a half turn of Δφ = φo − φi (all within
/// [0°, 180°] or all within [180°, 360°], some strictly inside) by their mirror image
/// f(θi, θo, −Δφ) = f(θi, θo, Δφ); samples on the mirror plane (Δφ = 0°, 180°) and at
/// θo = 0 are not repeated. Anything else is returned as it is.
pub fn unfold(s: &Samples) -> (Samples, Symmetry) {
    if !s.isotropic {
        return (s.clone(), Symmetry::None);
    }
    let half = 180_000_000;
    let dphi = |p: &PairDeg| wrap(p.outgoing.phi_deg - p.incident.phi_deg);
    let on_plane = |d: i64| d == 0 || d == half;
    let lower = s.samples.iter().all(|x| dphi(&x.pair) <= half);
    let upper = s
        .samples
        .iter()
        .all(|x| on_plane(dphi(&x.pair)) || dphi(&x.pair) >= half);
    let inside = s
        .samples
        .iter()
        .any(|x| !on_plane(dphi(&x.pair)) && x.pair.outgoing.theta_deg > 0.0);
    if !(inside && (lower || upper)) {
        return (s.clone(), Symmetry::Isotropic);
    }
    let mut out = s.samples.clone();
    for x in &s.samples {
        let p = &x.pair;
        if on_plane(dphi(p)) || q(p.outgoing.theta_deg) == 0 {
            continue;
        }
        let mirrored = PairDeg {
            incident: p.incident,
            outgoing: SphericalDeg::new(
                p.outgoing.theta_deg,
                2.0 * p.incident.phi_deg - p.outgoing.phi_deg,
            ),
        };
        out.push(Sample {
            pair: mirrored,
            ..x.clone()
        });
    }
    tracing::debug!(
        measured = s.samples.len(),
        unfolded = out.len(),
        "isotropic half turn unfolded by bilateral symmetry"
    );
    (
        Samples {
            channels: s.channels.clone(),
            samples: out,
            isotropic: true,
        },
        Symmetry::IsotropicBilateral,
    )
}

/// Whether a grid is the isotropic form over a half turn of φ+ (all nodes within
/// [0°, 180°] or all within [180°, 360°], some off the plane of incidence, some θo
/// above 0): what [`unfold`] would mirror, told from the axes alone.
pub fn half_turn(g: &Grid) -> bool {
    let p = &g.phi_o;
    let deg = |c: usize| p.node(c).to_degrees();
    let (lo, hi) = (deg(0), deg(p.n - 1));
    let within = |a: f64, b: f64| lo >= a - 1e-9 && hi <= b + 1e-9;
    let off_plane = |d: f64| [0.0, 180.0, 360.0].iter().all(|x| (d - x).abs() > 1e-9);
    g.isotropic
        && !p.is_periodic()
        && (within(0.0, 180.0) || within(180.0, 360.0))
        && (0..p.n).any(|c| off_plane(deg(c)))
        && g.theta_o.node(g.theta_o.n - 1) > 0.0
}

/// How a table on the data's own grid was filled.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Fill {
    /// Nodes of the grid.
    pub nodes: usize,
    /// Nodes on a measured direction pair.
    pub measured: usize,
    /// Nodes no sample lies on, interpolated from their neighbours (θi°, φi°, θo°,
    /// φo°; φo − φi for isotropic data).
    pub interpolated: Vec<[f64; 4]>,
    /// The R⁶ distance (module docs of [`crate::samples`]) within which a sample must
    /// lie for a node to be interpolated.
    pub limit: f64,
}

/// The uniform axis the distinct keyed values `v` (sorted, micro-degrees) lie on:
/// from the first to the last in the smallest spacing between neighbours, which must
/// divide every other spacing (an azimuth axis whose nodes close a full turn wraps,
/// [`Axis::is_periodic`]).
fn axis_of(v: &[i64]) -> Option<Axis> {
    let deg = |k: i64| k as f64 * 1e-6;
    if v.len() == 1 {
        return Some(Axis::single(deg(v[0]).to_radians()));
    }
    let step = v.windows(2).map(|w| w[1] - w[0]).min()?;
    if step <= 0 || v.windows(2).any(|w| (w[1] - w[0]) % step != 0) {
        return None;
    }
    let n = ((v[v.len() - 1] - v[0]) / step) as usize + 1;
    Some(Axis::from_deg(deg(v[0]), deg(step), n))
}

/// The grid the samples' own angles form: per axis, the distinct values, uniformly
/// spaced; azimuths that close a full turn form a periodic axis. Isotropic samples
/// give the form (θi, φo − φi, θo).
pub fn own_grid(s: &Samples) -> Result<Grid, ProcessError> {
    let (mut pis, mut tis, mut pos, mut tos) = (
        BTreeMap::new(),
        BTreeMap::new(),
        BTreeMap::new(),
        BTreeMap::new(),
    );
    for x in &s.samples {
        let p = &x.pair;
        let (pi, po) = if s.isotropic {
            (0, wrap(p.outgoing.phi_deg - p.incident.phi_deg))
        } else {
            (wrap(p.incident.phi_deg), wrap(p.outgoing.phi_deg))
        };
        pis.insert(pi, ());
        tis.insert(q(p.incident.theta_deg), ());
        pos.insert(po, ());
        tos.insert(q(p.outgoing.theta_deg), ());
    }
    let keys = |m: &BTreeMap<i64, ()>| m.keys().copied().collect::<Vec<_>>();
    let named = |name: &'static str, m: &BTreeMap<i64, ()>| {
        axis_of(&keys(m))
            .ok_or_else(|| ProcessError::grid(name, "takes values that lie on no uniform axis"))
    };
    let grid = Grid {
        phi_i: named("phi_i", &pis)?,
        theta_i: named("theta_i", &tis)?,
        phi_o: named("phi_o", &pos)?,
        theta_o: named("theta_o", &tos)?,
        isotropic: s.isotropic,
    };
    grid.validate()?;
    Ok(grid)
}

/// The chord of an angle: the R⁶ distance of one direction moved by it.
fn chord(angle: f64) -> f64 {
    2.0 * (0.5 * angle).sin()
}

/// The largest fraction of a grid's nodes that may be interpolated for the samples to
/// count as forming it: past a quarter the data is scattered, not a plan with holes,
/// and a grid must be asked for (`--grid`).
pub const MAX_INTERPOLATED: f64 = 0.25;

/// Tabulates samples on their own grid ([`own_grid`]): measured nodes as measured
/// (repeats averaged), unmeasured ones interpolated with `kernel` when a sample lies
/// within one and a half polar steps of them (DeYoung Sec. 3.2.1), and reported.
/// Refused when any node lies farther from the data than that, or when more than
/// [`MAX_INTERPOLATED`] of the nodes would be interpolated.
pub fn own_table(s: &Samples, kernel: Kernel) -> Result<(Table, Fill), ProcessError> {
    let grid = own_grid(s)?;
    let interp = s.interpolator(kernel)?;
    let steps = [&grid.theta_i, &grid.theta_o, &grid.phi_o]
        .iter()
        .filter(|a| a.n > 1)
        .map(|a| chord(a.step))
        .fold(0.0_f64, f64::max);
    let limit = 1.5 * steps.max(1e-6);
    let n = grid.len();
    let nc = s.channels.len();
    let pair_of = |i: usize| {
        let [pi, ti, po, to] = grid.angles(i);
        PairDeg {
            incident: SphericalDeg::new(ti.to_degrees(), pi.to_degrees()),
            outgoing: SphericalDeg::new(to.to_degrees(), po.to_degrees()),
        }
    };
    let node_of = |p: &PairDeg| {
        let c = crate::grid::clean_deg;
        [
            c(p.incident.theta_deg),
            c(p.incident.phi_deg),
            c(p.outgoing.theta_deg),
            c(p.outgoing.phi_deg),
        ]
    };
    // First where each node stands against the data, stopping as soon as the grid is
    // past use (a sparse scatter can span millions of nodes): nothing is allocated
    // per node before that is known.
    let allowed = (MAX_INTERPOLATED * n as f64) as usize;
    let mut interpolated = Vec::new();
    let (mut far, mut first_far) = (0usize, None);
    for i in 0..n {
        let pair = pair_of(i);
        let d = interp.nearest_distance(&pair);
        if d < 1e-9 {
            continue;
        }
        if d <= limit {
            interpolated.push(node_of(&pair));
        } else {
            far += 1;
            first_far.get_or_insert(node_of(&pair));
        }
        if interpolated.len() + far > allowed {
            return Err(ProcessError::Unsupported(format!(
                "more than {allowed} of the {n} nodes their angles span were not measured"
            )));
        }
    }
    if let Some(first) = first_far {
        return Err(ProcessError::Unsupported(format!(
            "{far} of the {n} nodes their angles span lie farther than {:.1}° from every \
             sample, the first at θi {}°, θo {}°, φo {}°",
            (2.0 * (0.5 * limit).asin()).to_degrees(),
            first[0],
            first[2],
            first[3],
        )));
    }
    let measured = n - interpolated.len();
    let mut values = vec![0.0; n * nc];
    let mut sigma = vec![0.0; n * nc];
    let mut any_sigma = true;
    for i in 0..n {
        let (v, sg) = interp.eval(&pair_of(i));
        for ch in 0..nc {
            values[ch * n + i] = v[ch];
        }
        match sg {
            Some(sg) => {
                for ch in 0..nc {
                    sigma[ch * n + i] = sg[ch];
                }
            }
            None => any_sigma = false,
        }
    }
    if !interpolated.is_empty() {
        tracing::warn!(
            interpolated = interpolated.len(),
            nodes = n,
            "nodes of the samples' own grid were not measured; interpolated from their neighbours"
        );
    }
    let table = Table::new(s.channels.clone(), grid, values, any_sigma.then_some(sigma))?;
    Ok((
        table,
        Fill {
            nodes: n,
            measured,
            interpolated,
            limit,
        },
    ))
}
