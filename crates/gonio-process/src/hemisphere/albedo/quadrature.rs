//! **Quadrature uncertainty.** The albedo's σ from the samples' noise says nothing of
//! the error of integrating a coarse grid, which at grazing incidence is far larger.
//! Each albedo also carries a standard uncertainty of its discretisation
//! ([`super::IncidentAlbedo::quadrature`]), estimated from the data, in two terms added in
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
use std::f64::consts::{FRAC_PI_2, TAU};

use super::{Node, Rule, cross, rule, weighted_sum};

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
pub(super) fn band_sigma(nodes: &[Node], r: &Rule, nc: usize) -> Vec<f64> {
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
pub(super) fn interior_sigma(nodes: &[Node], pts: &[delaunator::Point], full: &[f64]) -> Vec<f64> {
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
