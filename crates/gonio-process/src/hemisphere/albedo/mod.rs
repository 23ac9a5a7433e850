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
//! The albedo's quadrature uncertainty is its child module `quadrature`.

mod quadrature;

use std::collections::BTreeMap;

use gonio_core::dirfile::PairDeg;
use rayon::prelude::*;
use serde::Serialize;

use std::f64::consts::PI;

use super::{half_turn, q, wrap};
use crate::{ProcessError, Samples, Table};
use quadrature::{band_sigma, interior_sigma};

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
    /// the data (the `quadrature` module's docs): [`Self::quadrature_band`]
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
