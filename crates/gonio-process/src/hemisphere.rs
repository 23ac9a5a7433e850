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
//! **Directional albedo of scattered samples** (DeYoung Sec. 4.2.2, after Eq. 4.4):
//! the samples of one incident direction are triangulated in 2-D and each triangle
//! contributes its differential-to-finite form factor, by the Nusselt analogue the
//! area of its projection onto the base disk over π. Here the samples are projected
//! first (x, y) = sin θo (cos φ, sin φ), triangulated there (Delaunay), and the BRDF
//! taken linear over each projected triangle, so the albedo ∫ f cos θo dω = ∫ f dA
//! over the unit disk is Σ area × mean of the three vertex values. The band between
//! the data's convex hull and the horizon (from the last measured θo to 90°) holds
//! the values of the hull's edge, each hull edge extended radially to the unit
//! circle; its share of the projected hemisphere is reported, and when the hull does
//! not surround the normal nothing is extended and the albedo covers the hull only.
//!
//! **Quadrature uncertainty.** The albedo's σ from the samples' noise says nothing of
//! the error of integrating a coarse grid, which at grazing incidence is far larger.
//! Each albedo also carries a standard uncertainty of its discretisation
//! ([`IncidentAlbedo::quadrature`]), estimated from the data, in two terms added in
//! quadrature:
//! - *the band* beyond the data's edge: the albedo again with the band extrapolated
//!   from the edge's radial slope (linear in sin θo, and linear in θo, each clipped at
//!   0) instead of held; the largest change is a rectangular bound about the held
//!   value, σ = bound/√3 (GUM 4.3.7). The slope at a hull point is that of the
//!   triangle the inward ray enters: on a polar grid, the last two rings along the
//!   azimuth. The held value stays the estimate: on the materials the tests measure,
//!   the linear extrapolations move the band away from the truth at grazing
//!   incidence (a lobe that peaks between the last two rings slopes upwards into the
//!   band, then falls), and agree with holding elsewhere.
//! - *the interior*: the same rule on coarser subsets of the points against all of
//!   them (Richardson). Points on a polar grid (three quarters of the product of
//!   their rings and azimuths at least) are thinned to every other azimuth and, apart,
//!   to every other ring (the outermost kept, so that the hull and the band stay),
//!   each in both parities; a rule of second order in the spacing then errs by the
//!   difference over 2² − 1, the parities averaged in square. Scattered points are
//!   thinned to every other point (√2 the spacing: the difference over 2 − 1). With
//!   no coarser rule to compare with (too few points) the term is the albedo itself.

use std::collections::BTreeMap;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use rayon::prelude::*;
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

/// The directional albedo of one incident direction from scattered samples.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IncidentAlbedo {
    /// Incident polar angle, degrees.
    pub theta_i_deg: f64,
    /// Incident azimuth, degrees (0 for isotropic data).
    pub phi_i_deg: f64,
    /// ∫ f cos θo dω per channel.
    pub albedo: Vec<f64>,
    /// Its standard uncertainty per channel from the samples' noise (their σ through
    /// the weights, taken independent), when the samples have σ.
    pub sigma: Option<Vec<f64>>,
    /// The standard uncertainty of the discretisation per channel, estimated from
    /// the data (module docs, "Quadrature uncertainty"): [`Self::quadrature_band`]
    /// and [`Self::quadrature_interior`] in quadrature. Independent of `sigma`; the
    /// albedo's whole standard uncertainty is the two in quadrature.
    pub quadrature: Vec<f64>,
    /// The band's term: how much the albedo moves when the band from the data's edge
    /// to the horizon is extrapolated linearly (in sin θo or in θo, clipped at 0)
    /// rather than held, as a rectangular bound (÷√3).
    pub quadrature_band: Vec<f64>,
    /// The interior's term: the same rule on every other ring and every other
    /// azimuth against all of them, scaled to the fine rule's error (Richardson).
    pub quadrature_interior: Vec<f64>,
    /// Distinct outgoing directions used.
    pub directions: usize,
    /// Fraction of the projected hemisphere inside the data's convex hull.
    pub covered: f64,
    /// Fraction held from the hull's edge to the horizon.
    pub extrapolated: f64,
}

/// One projected outgoing direction with its values.
struct Node {
    x: f64,
    y: f64,
    value: Vec<f64>,
    var: Option<Vec<f64>>,
}

/// The outgoing directions of one incidence projected onto the base disk, repeats of
/// a point (every azimuth at θo = 0, a sample measured twice) averaged.
#[derive(Default)]
struct Disk {
    /// Point keyed at 1e-9 → its sums.
    pts: BTreeMap<(i64, i64), Sums>,
}

/// (x, y, Σ value, Σ σ² when every repeat has σ, count) of one projected point.
type Sums = (f64, f64, Vec<f64>, Option<Vec<f64>>, usize);

impl Disk {
    /// Adds the values (and squared uncertainties) at polar radius `r` = sin θo,
    /// azimuth `phi` (radians).
    fn add(&mut self, r: f64, phi: f64, value: &[f64], var: Option<&[f64]>) {
        let (x, y) = (r * phi.cos(), r * phi.sin());
        let key = ((x * 1e9).round() as i64, (y * 1e9).round() as i64);
        let nc = value.len();
        let e = self
            .pts
            .entry(key)
            .or_insert_with(|| (x, y, vec![0.0; nc], var.map(|_| vec![0.0; nc]), 0));
        for (a, v) in e.2.iter_mut().zip(value) {
            *a += v;
        }
        match (&mut e.3, var) {
            (Some(a), Some(v2)) => {
                for (a, s2) in a.iter_mut().zip(v2) {
                    *a += s2;
                }
            }
            (a, _) => *a = None,
        }
        e.4 += 1;
    }

    /// The averaged points.
    fn nodes(self) -> Vec<Node> {
        self.pts
            .into_values()
            .map(|(x, y, v, var, n)| {
                let n = n as f64;
                Node {
                    x,
                    y,
                    value: v.into_iter().map(|a| a / n).collect(),
                    var: var.map(|a| a.into_iter().map(|s2| s2 / (n * n)).collect()),
                }
            })
            .collect()
    }
}

/// Directional albedos of scattered samples, one per incident direction with at
/// least three outgoing directions not on a line (module docs), each with the
/// uncertainty of its discretisation. Isotropic samples are taken in the frame
/// φi = 0 (so all of one θi form one direction).
pub fn albedos(s: &Samples) -> Result<Vec<IncidentAlbedo>, ProcessError> {
    albedos_with(s, true)
}

/// The key of the incident direction a sample's albedo belongs to: θi and φi in
/// micro-degrees, φi 0 for isotropic samples and at normal incidence.
pub(crate) fn incidence_key(isotropic: bool, p: &PairDeg) -> (i64, i64) {
    let ti = q(p.incident.theta_deg);
    let pi = if isotropic || ti == 0 {
        0
    } else {
        wrap(p.incident.phi_deg)
    };
    (ti, pi)
}

/// [`albedos`], with the quadrature uncertainty only when asked (the floors' noise
/// draws need the albedos alone). Incidences are integrated in parallel; each is
/// the same sum on any number of threads.
pub(crate) fn albedos_with(
    s: &Samples,
    quadrature: bool,
) -> Result<Vec<IncidentAlbedo>, ProcessError> {
    s.validate()?;
    let nc = s.channels.len();
    let mut groups: BTreeMap<(i64, i64), Disk> = BTreeMap::new();
    for x in &s.samples {
        let p = &x.pair;
        let phi = if s.isotropic {
            p.outgoing.phi_deg - p.incident.phi_deg
        } else {
            p.outgoing.phi_deg
        };
        let var: Option<Vec<f64>> = x.sigma.as_ref().map(|v| v.iter().map(|s| s * s).collect());
        groups
            .entry(incidence_key(s.isotropic, p))
            .or_default()
            .add(
                p.outgoing.theta_deg.to_radians().sin(),
                phi.to_radians(),
                &x.value,
                var.as_deref(),
            );
    }
    let groups: Vec<((i64, i64), Disk)> = groups.into_iter().collect();
    let out: Vec<Option<IncidentAlbedo>> = groups
        .into_par_iter()
        .map(|((ti, pi), disk)| {
            let nodes = disk.nodes();
            integrate(&nodes, nc, quadrature).map(|a| IncidentAlbedo {
                theta_i_deg: ti as f64 * 1e-6,
                phi_i_deg: pi as f64 * 1e-6,
                directions: nodes.len(),
                ..a
            })
        })
        .collect();
    some_area(out.into_iter().flatten().collect())
}

/// Directional albedos of a table's incident rows over the triangulated hemisphere
/// of its outgoing nodes ([`albedos`] without forming a sample a node: one row's
/// nodes at a time, so a large table costs no more memory than a row a thread), each
/// with the uncertainty of its discretisation. An isotropic table whose φ+ axis
/// spans a half turn is unfolded row by row (module docs, bilateral symmetry).
pub fn albedos_of_table(t: &Table) -> Result<Vec<IncidentAlbedo>, ProcessError> {
    albedos_of_table_with(t, true)
}

/// [`albedos_of_table`], with the quadrature uncertainty only when asked. Rows are
/// integrated in parallel; each is the same sum on any number of threads.
pub(crate) fn albedos_of_table_with(
    t: &Table,
    quadrature: bool,
) -> Result<Vec<IncidentAlbedo>, ProcessError> {
    let g = &t.grid;
    let (n, q, nc) = (g.len(), g.n_out(), t.channels.len());
    let p = &g.phi_o;
    let half = half_turn(g);
    let on_plane = |phi: f64| [0.0, 180.0, 360.0].iter().any(|x| (phi - x).abs() < 1e-9);
    let out: Vec<Option<IncidentAlbedo>> = (0..g.n_in())
        .into_par_iter()
        .map(|r| {
            let (a, b) = (r / g.theta_i.n, r % g.theta_i.n);
            let mut disk = Disk::default();
            for k in 0..q {
                let (c, d) = (k / g.theta_o.n, k % g.theta_o.n);
                let phi = p.node(c).to_degrees();
                let rad = g.theta_o.node(d).sin();
                let i = r * q + k;
                let v: Vec<f64> = (0..nc).map(|ch| t.values[ch * n + i]).collect();
                let var: Option<Vec<f64>> = t
                    .sigma
                    .as_ref()
                    .map(|s| (0..nc).map(|ch| s[ch * n + i].powi(2)).collect());
                disk.add(rad, phi.to_radians(), &v, var.as_deref());
                if half && !on_plane(phi) && rad > 0.0 {
                    disk.add(rad, (-phi).to_radians(), &v, var.as_deref());
                }
            }
            let nodes = disk.nodes();
            integrate(&nodes, nc, quadrature).map(|al| IncidentAlbedo {
                theta_i_deg: g.theta_i.node_deg(b),
                phi_i_deg: g.phi_i.node_deg(a),
                directions: nodes.len(),
                ..al
            })
        })
        .collect();
    some_area(out.into_iter().flatten().collect())
}

/// The albedos, or why there are none: no incidence spans an area.
fn some_area(out: Vec<IncidentAlbedo>) -> Result<Vec<IncidentAlbedo>, ProcessError> {
    if out.is_empty() {
        return Err(ProcessError::Unsupported(
            "no incident direction has three outgoing directions that span an area of the \
             hemisphere; the energy measure needs a hemisphere of exitance"
                .into(),
        ));
    }
    Ok(out)
}

/// The triangulated rule over one incidence's projected points: each point's weight
/// in Σ w_k f_k (a third of each triangle it is a corner of, and half of each band
/// sector beside it), with the triangulation it came from.
struct Rule {
    /// The triangles, by corner index.
    triangles: Vec<[usize; 3]>,
    /// The convex hull, counter-clockwise.
    hull: Vec<usize>,
    /// Whether the hull surrounds the normal, so that the band to the horizon is held.
    surrounds: bool,
    /// The weight of each point.
    w: Vec<f64>,
    /// The hull's area.
    hull_area: f64,
    /// The band's area (0 when the hull does not surround the normal).
    band: f64,
}

/// z of the cross product of two plane vectors.
fn cross(a: (f64, f64), b: (f64, f64)) -> f64 {
    a.0 * b.1 - a.1 * b.0
}

/// The rule over `pts` (module docs), or none when they span no area.
fn rule(pts: &[delaunator::Point]) -> Option<Rule> {
    if pts.len() < 3 {
        return None;
    }
    let tri = delaunator::triangulate(pts);
    // Points on a line (an in-plane scan) span no area; rounding may still leave
    // slivers, which are not a hemisphere either.
    if tri.triangles.is_empty() {
        return None;
    }
    let p = |k: usize| (pts[k].x, pts[k].y);
    let mut w = vec![0.0; pts.len()];
    let mut hull_area = 0.0;
    let mut triangles = Vec::with_capacity(tri.triangles.len() / 3);
    for t in tri.triangles.chunks_exact(3) {
        let (a, b, c) = (p(t[0]), p(t[1]), p(t[2]));
        let area = 0.5 * cross((b.0 - a.0, b.1 - a.1), (c.0 - a.0, c.1 - a.1)).abs();
        hull_area += area;
        for &k in t {
            w[k] += area / 3.0;
        }
        triangles.push([t[0], t[1], t[2]]);
    }
    if hull_area < 1e-9 {
        return None;
    }
    // The hull, counter-clockwise in (x, y).
    let mut hull = tri.hull.clone();
    let signed: f64 = (0..hull.len())
        .map(|i| cross(p(hull[i]), p(hull[(i + 1) % hull.len()])))
        .sum();
    if signed < 0.0 {
        hull.reverse();
    }
    // The band to the horizon, only when the hull surrounds the normal: every edge
    // then sees the origin on its left, and its sector to the unit circle is the
    // circular sector less the triangle (origin, a, b).
    let surrounds =
        (0..hull.len()).all(|i| cross(p(hull[i]), p(hull[(i + 1) % hull.len()])) > 1e-12);
    let mut band = 0.0;
    if surrounds {
        for i in 0..hull.len() {
            let (ia, ib) = (hull[i], hull[(i + 1) % hull.len()]);
            let (a, b) = (p(ia), p(ib));
            let turn = cross(a, b).atan2(a.0 * b.0 + a.1 * b.1);
            let sector = (0.5 * turn - 0.5 * cross(a, b)).max(0.0);
            band += sector;
            w[ia] += 0.5 * sector;
            w[ib] += 0.5 * sector;
        }
    }
    Some(Rule {
        triangles,
        hull,
        surrounds,
        w,
        hull_area,
        band,
    })
}

/// Σ w_k f_k per channel over the points `idx` of `nodes` (weights in `idx` order).
fn weighted_sum(nodes: &[Node], idx: &[usize], w: &[f64], nc: usize) -> Vec<f64> {
    let mut out = vec![0.0; nc];
    for (&k, wk) in idx.iter().zip(w) {
        for (a, x) in out.iter_mut().zip(&nodes[k].value) {
            *a += wk * x;
        }
    }
    out
}

/// ∫ f dA over the unit disk for one incidence (module docs), or none when the
/// points span no area; with `quadrature`, the discretisation's uncertainty as well
/// (else zeros: the floors' noise draws need the albedo alone).
fn integrate(nodes: &[Node], nc: usize, quadrature: bool) -> Option<IncidentAlbedo> {
    let pts: Vec<delaunator::Point> = nodes
        .iter()
        .map(|n| delaunator::Point { x: n.x, y: n.y })
        .collect();
    let r = rule(&pts)?;
    let all: Vec<usize> = (0..nodes.len()).collect();
    let albedo = weighted_sum(nodes, &all, &r.w, nc);
    let mut var = nodes[0].var.as_ref().map(|_| vec![0.0; nc]);
    for (n, wk) in nodes.iter().zip(&r.w) {
        match (&mut var, &n.var) {
            (Some(v), Some(nv)) => {
                for (a, x) in v.iter_mut().zip(nv) {
                    *a += wk * wk * x;
                }
            }
            (v, _) => *v = None,
        }
    }
    let (band, interior) = if quadrature {
        (
            band_sigma(nodes, &r, nc),
            interior_sigma(nodes, &pts, &albedo),
        )
    } else {
        (vec![0.0; nc], vec![0.0; nc])
    };
    Some(IncidentAlbedo {
        theta_i_deg: 0.0,
        phi_i_deg: 0.0,
        quadrature: band
            .iter()
            .zip(&interior)
            .map(|(a, b)| a.hypot(*b))
            .collect(),
        quadrature_band: band,
        quadrature_interior: interior,
        albedo,
        sigma: var.map(|v| v.into_iter().map(f64::sqrt).collect()),
        directions: nodes.len(),
        covered: (r.hull_area / PI).min(1.0),
        extrapolated: r.band / PI,
    })
}

// Gauss–Legendre nodes and weights on [−1, 1], 8 points (the table's): the band's integrals across
// each hull edge.
use crate::grid::table::GL8;

/// The outward radial derivative ∂f/∂ρ (ρ = sin θo) per channel at hull point `a`,
/// from the triangle that the inward ray from `a` enters: on a polar grid, the
/// difference to the point one ring in along the same azimuth over their radial
/// distance. 0 when no triangle is entered (a point at the normal).
fn radial_slope(nodes: &[Node], r: &Rule, around: &[usize], a: usize, nc: usize) -> Vec<f64> {
    let pa = (nodes[a].x, nodes[a].y);
    let ra = pa.0.hypot(pa.1);
    if ra < 1e-12 {
        return vec![0.0; nc];
    }
    let u = (-pa.0 / ra, -pa.1 / ra);
    for &t in around {
        let tri = r.triangles[t];
        let Some(k) = tri.iter().position(|&c| c == a) else {
            continue;
        };
        let (b, c) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
        let e1 = (nodes[b].x - pa.0, nodes[b].y - pa.1);
        let e2 = (nodes[c].x - pa.0, nodes[c].y - pa.1);
        let det = cross(e1, e2);
        if det.abs() < 1e-300 {
            continue;
        }
        let (l1, l2) = (cross(u, e2) / det, cross(e1, u) / det);
        let tol = -1e-9 * (l1.abs() + l2.abs());
        if l1 >= tol && l2 >= tol {
            return (0..nc)
                .map(|ch| {
                    let fa = nodes[a].value[ch];
                    -(l1 * (nodes[b].value[ch] - fa) + l2 * (nodes[c].value[ch] - fa))
                })
                .collect();
        }
    }
    vec![0.0; nc]
}

/// ∫ max(0, A + D (ρ − ρc)) ρ dρ over [ρc, 1]: the band along one ray, extrapolated
/// linearly in ρ = sin θo and clipped at 0.
fn band_linear_in_rho(a: f64, d: f64, rc: f64) -> f64 {
    let (lo, hi) = positive_part(a, d, rc, 1.0);
    if lo >= hi {
        return 0.0;
    }
    let f = |x: f64| (a - d * rc) * x * x / 2.0 + d * x * x * x / 3.0;
    f(hi) - f(lo)
}

/// ∫ max(0, A + E (θ − θc)) sin θ cos θ dθ over [θc, 90°]: the band along one ray,
/// extrapolated linearly in θo and clipped at 0.
fn band_linear_in_theta(a: f64, e: f64, tc: f64) -> f64 {
    let (lo, hi) = positive_part(a, e, tc, FRAC_PI_2);
    if lo >= hi {
        return 0.0;
    }
    let g = |t: f64| {
        -(a - e * tc) * (2.0 * t).cos() / 4.0
            + e * (-t * (2.0 * t).cos() / 4.0 + (2.0 * t).sin() / 8.0)
    };
    g(hi) - g(lo)
}

/// The part of [x0, x1] where A + D (x − x0) ≥ 0.
fn positive_part(a: f64, d: f64, x0: f64, x1: f64) -> (f64, f64) {
    if d == 0.0 {
        return if a > 0.0 { (x0, x1) } else { (x1, x1) };
    }
    let z = x0 - a / d;
    if d > 0.0 {
        (z.max(x0), x1)
    } else {
        (x0, z.min(x1))
    }
}

/// The band's term of the discretisation's uncertainty per channel (module docs):
/// the largest change to the albedo when the band beyond the data's edge is
/// extrapolated linearly in sin θo or in θo (clipped at 0) from the edge's radial
/// slope instead of held, taken as a rectangular bound about the held value,
/// σ = bound/√3 (GUM 4.3.7). 0 when nothing is extended.
fn band_sigma(nodes: &[Node], r: &Rule, nc: usize) -> Vec<f64> {
    if !r.surrounds || r.band <= 0.0 {
        return vec![0.0; nc];
    }
    let mut around: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (t, tri) in r.triangles.iter().enumerate() {
        for &c in tri {
            around.entry(c).or_default().push(t);
        }
    }
    let slopes: BTreeMap<usize, Vec<f64>> = r
        .hull
        .iter()
        .map(|&a| {
            let ts = around.get(&a).map_or(&[][..], Vec::as_slice);
            (a, radial_slope(nodes, r, ts, a, nc))
        })
        .collect();
    // (held, linear in ρ, linear in θ) per channel, all by the same rule across edges.
    let mut sums = vec![[0.0; 3]; nc];
    let h = r.hull.len();
    for i in 0..h {
        let (ia, ib) = (r.hull[i], r.hull[(i + 1) % h]);
        let (a, b) = ((nodes[ia].x, nodes[ia].y), (nodes[ib].x, nodes[ib].y));
        let turn = cross(a, b).atan2(a.0 * b.0 + a.1 * b.1);
        let psi_a = a.1.atan2(a.0);
        let ab = (b.0 - a.0, b.1 - a.1);
        for (x, wq) in GL8 {
            let psi = psi_a + 0.5 * turn * (1.0 + x);
            let u = (psi.cos(), psi.sin());
            let den = cross(u, ab);
            if den.abs() < 1e-300 {
                continue;
            }
            let t = (-cross(u, a) / den).clamp(0.0, 1.0);
            let rc = (a.0 + t * ab.0).hypot(a.1 + t * ab.1);
            if rc >= 1.0 {
                continue;
            }
            let tc = rc.asin();
            let wpsi = 0.5 * turn * wq;
            for (ch, s) in sums.iter_mut().enumerate() {
                let f = (1.0 - t) * nodes[ia].value[ch] + t * nodes[ib].value[ch];
                let d = (1.0 - t) * slopes[&ia][ch] + t * slopes[&ib][ch];
                s[0] += wpsi * f * (1.0 - rc * rc) / 2.0;
                s[1] += wpsi * band_linear_in_rho(f, d, rc);
                s[2] += wpsi * band_linear_in_theta(f, d * tc.cos(), tc);
            }
        }
    }
    sums.iter()
        .map(|s| (s[1] - s[0]).abs().max((s[2] - s[0]).abs()) / 3f64.sqrt())
        .collect()
}

/// Ring and azimuth ranks of the points (rings by sin θo, the normal ring 0 when
/// measured; azimuths among the points off the normal), and the counts.
struct Polar {
    ring: Vec<usize>,
    azimuth: Vec<Option<usize>>,
    rings: usize,
    azimuths: usize,
    centre: bool,
}

impl Polar {
    fn of(pts: &[delaunator::Point]) -> Polar {
        let turn = (TAU * 1e7).round() as i64;
        let rkey = |p: &delaunator::Point| (p.x.hypot(p.y) * 1e7).round() as i64;
        let akey = |p: &delaunator::Point| {
            let k = (p.y.atan2(p.x).rem_euclid(TAU) * 1e7).round() as i64;
            if k >= turn { 0 } else { k }
        };
        let rings: BTreeMap<i64, usize> = {
            let mut m: BTreeMap<i64, usize> = pts.iter().map(|p| (rkey(p), 0)).collect();
            for (k, v) in m.values_mut().enumerate() {
                *v = k;
            }
            m
        };
        let azimuths: BTreeMap<i64, usize> = {
            let mut m: BTreeMap<i64, usize> = pts
                .iter()
                .filter(|p| rkey(p) != 0)
                .map(|p| (akey(p), 0))
                .collect();
            for (k, v) in m.values_mut().enumerate() {
                *v = k;
            }
            m
        };
        Polar {
            ring: pts.iter().map(|p| rings[&rkey(p)]).collect(),
            azimuth: pts
                .iter()
                .map(|p| (rkey(p) != 0).then(|| azimuths[&akey(p)]))
                .collect(),
            rings: rings.len(),
            azimuths: azimuths.len(),
            centre: rings.contains_key(&0),
        }
    }

    /// Whether the points lie on (at least three quarters of) the product of their
    /// rings and azimuths: a plan's or a table's polar grid, holes allowed.
    fn is_grid(&self) -> bool {
        let off = self.azimuth.iter().filter(|a| a.is_some()).count();
        let rings_off = self.rings - usize::from(self.centre);
        off as f64 >= 0.75 * (rings_off * self.azimuths) as f64
    }
}

/// The interior term of the discretisation's uncertainty per channel (module docs):
/// the albedo by the same rule on coarser subsets of the points, against all of them,
/// scaled to the error of the fine rule as Richardson's extrapolation does for a
/// rule whose error is of second order in the spacing.
fn interior_sigma(nodes: &[Node], pts: &[delaunator::Point], full: &[f64]) -> Vec<f64> {
    let nc = full.len();
    let n = nodes.len();
    let polar = Polar::of(pts);
    // (direction, kept points); a direction's differences are averaged in square.
    let mut subsets: Vec<(usize, Vec<usize>)> = Vec::new();
    // The fine rule's error from a subset with double the spacing in one direction:
    // Δ/(2² − 1); in both (scattered points, every other one: √2 the spacing), Δ/(2 − 1).
    let factor = [1.0 / 3.0, 1.0 / 3.0, 1.0];
    if polar.is_grid() {
        if polar.azimuths >= 6 {
            for parity in 0..2 {
                let keep = (0..n)
                    .filter(|&k| polar.azimuth[k].is_none_or(|a| a % 2 == parity))
                    .collect();
                subsets.push((0, keep));
            }
        }
        if polar.rings >= 3 {
            let last = polar.rings - 1;
            for parity in 0..2 {
                let keep: Vec<usize> = (0..n)
                    .filter(|&k| {
                        let r = polar.ring[k];
                        r % 2 == parity || r == last || (parity == 1 && r == 0)
                    })
                    .collect();
                if keep.len() < n {
                    subsets.push((1, keep));
                }
            }
        }
    } else if n >= 8 {
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| {
            let key = |k: usize| (polar.ring[k], pts[k].y.atan2(pts[k].x).rem_euclid(TAU));
            let (ka, kb) = (key(a), key(b));
            ka.0.cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
        });
        for parity in 0..2 {
            let keep = order
                .iter()
                .enumerate()
                .filter(|(j, _)| j % 2 == parity)
                .map(|(_, &k)| k)
                .collect();
            subsets.push((2, keep));
        }
    }
    let mut sq = vec![[0.0; 3]; nc];
    let mut count = [0usize; 3];
    for (dir, keep) in &subsets {
        let sub: Vec<delaunator::Point> = keep.iter().map(|&k| pts[k].clone()).collect();
        let Some(r) = rule(&sub) else {
            continue;
        };
        let a = weighted_sum(nodes, keep, &r.w, nc);
        for ch in 0..nc {
            sq[ch][*dir] += (a[ch] - full[ch]).powi(2);
        }
        count[*dir] += 1;
    }
    if count.iter().all(|c| *c == 0) {
        // No coarser rule to compare with: the albedo is as uncertain as it is large.
        return full.iter().map(|a| a.abs()).collect();
    }
    (0..nc)
        .map(|ch| {
            (0..3)
                .filter(|&d| count[d] > 0)
                .map(|d| (sq[ch][d] / count[d] as f64) * factor[d] * factor[d])
                .sum::<f64>()
                .sqrt()
        })
        .collect()
}
