//! Uniform grids of directions and the tabulated BRDFs on them (DeYoung Sec. 3.1),
//! with quadrilinear interpolation between the nodes (Sec. 3.2.1).
//!
//! A [`Table`] stores its values lexicographically in (φi, θi, φo, θo), the order of
//! DeYoung Eq. 3.1, one block per channel. The isotropic form (θi, φ+, θo) of Eq. 4.6
//! is the same layout with a single φi node at 0 whose φo axis is the difference
//! φ+ = φo − φi, so every measure, transform and file treats both alike.

use std::f64::consts::{FRAC_PI_2, TAU};

use crate::ProcessError;

pub(crate) mod table;

pub use table::Table;
pub(crate) use table::{cosine_proposal, interpolate, interpolate_by};

/// Tolerance, in radians, within which an angle counts as lying on a node; far below
/// any grid spacing a goniometer uses and far above the rounding of degree ↔ radian
/// conversions.
const ON_NODE: f64 = 1e-9;

/// The most nodes a grid may have: 2²⁵ (33.5 million), a 2.5° × 2.5° full 4-D grid
/// with room to spare. A table holds a value (and an uncertainty) per node and
/// channel, so this keeps an RGB table with uncertainties under about 1.6 GB; a
/// finer `--grid` is refused before anything is allocated.
pub const MAX_GRID_NODES: usize = 1 << 25;

/// One axis of a uniform grid: `n` nodes `start + k·step`, radians.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Axis {
    /// First node, radians.
    pub start: f64,
    /// Spacing, radians (any positive value when `n == 1`).
    pub step: f64,
    /// Number of nodes.
    pub n: usize,
}

impl Axis {
    /// `n` nodes from `start` in steps of `step` (radians).
    pub fn new(start: f64, step: f64, n: usize) -> Axis {
        Axis { start, step, n }
    }

    /// The same from degrees.
    pub fn from_deg(start_deg: f64, step_deg: f64, n: usize) -> Axis {
        Axis::new(start_deg.to_radians(), step_deg.to_radians(), n)
    }

    /// A full turn of azimuth in `n` equal steps from 0: the nodes 0, 2π/n, ….
    pub fn full_turn(n: usize) -> Axis {
        Axis::new(0.0, TAU / n as f64, n)
    }

    /// `n` polar nodes at the midpoints of equal bands over [0, 90°]: the midpoint
    /// rule DeYoung's sums (Eq. 4.4) converge fastest with.
    pub fn polar_midpoints(n: usize) -> Axis {
        let step = FRAC_PI_2 / n as f64;
        Axis::new(0.5 * step, step, n)
    }

    /// A single node (its step a full turn, the span DeYoung's sums give it).
    pub fn single(at: f64) -> Axis {
        Axis::new(at, TAU, 1)
    }

    /// Node `k`, radians.
    pub fn node(&self, k: usize) -> f64 {
        self.start + k as f64 * self.step
    }

    /// Node `k` in degrees, cleaned of the radian round trip's last-digit noise so
    /// that nodes print as the numbers they were given as (30, not 29.999999999999996).
    pub fn node_deg(&self, k: usize) -> f64 {
        clean_deg(self.node(k).to_degrees())
    }

    /// Whether the nodes close a full turn (azimuth axes that wrap around).
    pub fn is_periodic(&self) -> bool {
        self.n > 1 && (self.n as f64 * self.step - TAU).abs() < 1e-9
    }

    /// The two nodes around `x` and the weight of the second. Periodic axes wrap; the
    /// others hold the end value beyond their ends (no extrapolation of data).
    pub fn locate(&self, x: f64) -> (usize, usize, f64) {
        if self.n == 1 {
            return (0, 0, 0.0);
        }
        let mut u = (x - self.start) / self.step;
        if self.is_periodic() {
            u = u.rem_euclid(self.n as f64);
            let k = u.floor();
            let mut t = u - k;
            let mut k0 = k as usize % self.n;
            if t > 1.0 - ON_NODE / self.step {
                k0 = (k0 + 1) % self.n;
                t = 0.0;
            } else if t < ON_NODE / self.step {
                t = 0.0;
            }
            return (k0, (k0 + 1) % self.n, t);
        }
        let last = (self.n - 1) as f64;
        if u <= 0.0 {
            return (0, 0, 0.0);
        }
        if u >= last {
            return (self.n - 1, self.n - 1, 0.0);
        }
        let k = u.floor();
        let mut t = u - k;
        let mut k0 = k as usize;
        if t > 1.0 - ON_NODE / self.step {
            k0 += 1;
            t = 0.0;
        } else if t < ON_NODE / self.step {
            t = 0.0;
        }
        (k0, (k0 + 1).min(self.n - 1), t)
    }

    /// The node `x` lies on, if it lies on one (wrapping periodic axes).
    pub fn node_at(&self, x: f64) -> Option<usize> {
        let u = (x - self.start) / if self.n == 1 { 1.0 } else { self.step };
        let u = if self.is_periodic() {
            u.rem_euclid(self.n as f64)
        } else {
            u
        };
        let k = u.round();
        let on = (u - k).abs() * self.step.abs().min(1.0) < ON_NODE;
        if !on {
            return None;
        }
        let k = if self.is_periodic() {
            k as usize % self.n
        } else if k < 0.0 || k >= self.n as f64 {
            return None;
        } else {
            k as usize
        };
        Some(k)
    }

    /// Whether two axes have the same nodes.
    pub fn same_as(&self, o: &Axis) -> bool {
        self.n == o.n
            && (self.start - o.start).abs() < ON_NODE
            && (self.n == 1 || (self.step - o.step).abs() < ON_NODE)
    }

    /// The spacing DeYoung's sums use as Δθ or Δφ (Eq. 4.4): the step, or a full
    /// turn for a single azimuth node.
    pub fn delta(&self) -> f64 {
        if self.n == 1 { TAU } else { self.step }
    }
}

/// A node count as messages print it: whole below 10¹⁵, in exponent form above.
pub(crate) fn fmt_count(n: f64) -> String {
    if n < 1e15 {
        format!("{n:.0}")
    } else {
        format!("{n:.2e}")
    }
}

/// Degrees rounded to 1e-9° when within that of such a number.
pub fn clean_deg(d: f64) -> f64 {
    let r = (d * 1e9).round() / 1e9;
    if (d - r).abs() < 1e-9 { r } else { d }
}

/// The four axes of a tabulated BRDF, and whether it is the isotropic form.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// Incident azimuth φi (a single node at 0 when isotropic).
    pub phi_i: Axis,
    /// Incident polar angle θi.
    pub theta_i: Axis,
    /// Outgoing azimuth φo, or φ+ = φo − φi when isotropic.
    pub phi_o: Axis,
    /// Outgoing polar angle θo.
    pub theta_o: Axis,
    /// The isotropic form (θi, φ+, θo) of DeYoung Eq. 4.6.
    pub isotropic: bool,
}

impl Grid {
    /// A full 4D grid.
    pub fn full(phi_i: Axis, theta_i: Axis, phi_o: Axis, theta_o: Axis) -> Grid {
        Grid {
            phi_i,
            theta_i,
            phi_o,
            theta_o,
            isotropic: false,
        }
    }

    /// The isotropic form: θi, φ+ = φo − φi, θo.
    pub fn isotropic(theta_i: Axis, phi_plus: Axis, theta_o: Axis) -> Grid {
        Grid {
            phi_i: Axis::single(0.0),
            theta_i,
            phi_o: phi_plus,
            theta_o,
            isotropic: true,
        }
    }

    /// The same nodes for incidence and exitance: `n_theta` polar midpoints and
    /// `n_phi` azimuths over a full turn (the grid the measures are exact on).
    pub fn hemisphere(n_theta: usize, n_phi: usize) -> Grid {
        let t = Axis::polar_midpoints(n_theta);
        let p = Axis::full_turn(n_phi);
        Grid::full(p, t, p, t)
    }

    /// The isotropic form of [`hemisphere`](Self::hemisphere): `n_theta` polar
    /// midpoints for θi and θo, `n_phi` values of φo − φi over a full turn.
    pub fn hemisphere_isotropic(n_theta: usize, n_phi: usize) -> Grid {
        let t = Axis::polar_midpoints(n_theta);
        let p = Axis::full_turn(n_phi);
        Grid::isotropic(t, p, t)
    }

    /// Number of incident nodes, P = nφi·nθi (rows of DeYoung's matrix A).
    pub fn n_in(&self) -> usize {
        self.phi_i.n * self.theta_i.n
    }

    /// Number of outgoing nodes, Q = nφo·nθo (columns of A).
    pub fn n_out(&self) -> usize {
        self.phi_o.n * self.theta_o.n
    }

    /// Number of nodes, n_fr of DeYoung Eq. 3.1 (Eq. 4.7 when isotropic).
    pub fn len(&self) -> usize {
        self.n_in() * self.n_out()
    }

    /// Whether the grid has no nodes.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Flat index of node (a, b, c, d) = (φi, θi, φo, θo).
    pub fn index(&self, a: usize, b: usize, c: usize, d: usize) -> usize {
        ((a * self.theta_i.n + b) * self.phi_o.n + c) * self.theta_o.n + d
    }

    /// The node indices (a, b, c, d) of a flat index.
    pub fn unindex(&self, i: usize) -> [usize; 4] {
        let d = i % self.theta_o.n;
        let r = i / self.theta_o.n;
        let c = r % self.phi_o.n;
        let r = r / self.phi_o.n;
        [r / self.theta_i.n, r % self.theta_i.n, c, d]
    }

    /// The angles (φi, θi, φo, θo) of a flat index, radians; φo is absolute (φi + φ+
    /// in the isotropic form, whose φi is 0).
    pub fn angles(&self, i: usize) -> [f64; 4] {
        let [a, b, c, d] = self.unindex(i);
        [
            self.phi_i.node(a),
            self.theta_i.node(b),
            self.phi_o.node(c),
            self.theta_o.node(d),
        ]
    }

    /// Whether every incident node is also an outgoing node and the reverse, so that
    /// reciprocal values are looked up, not interpolated (DeYoung Sec. 4.2.1).
    pub fn is_paired(&self) -> bool {
        if self.isotropic {
            // f(θo, −φ+, θi): the φ+ nodes must be symmetric about 0.
            let p = &self.phi_o;
            return self.theta_i.same_as(&self.theta_o)
                && (0..p.n).all(|c| p.node_at(-p.node(c)).is_some());
        }
        self.phi_i.same_as(&self.phi_o) && self.theta_i.same_as(&self.theta_o)
    }

    /// Checks the axes are usable: non-empty, finite, polar nodes within [0, 90°].
    pub fn validate(&self) -> Result<(), ProcessError> {
        let named = [
            ("phi_i", &self.phi_i),
            ("theta_i", &self.theta_i),
            ("phi_o", &self.phi_o),
            ("theta_o", &self.theta_o),
        ];
        for (name, ax) in named {
            if ax.n == 0 {
                return Err(ProcessError::grid(name, "has no nodes"));
            }
            if !ax.start.is_finite() || !ax.step.is_finite() || ax.step <= 0.0 {
                return Err(ProcessError::grid(
                    name,
                    "needs a finite start and a positive step",
                ));
            }
            if ax.n as f64 * ax.step > TAU + 1e-9 {
                return Err(ProcessError::grid(name, "spans more than a full turn"));
            }
        }
        let nodes = [self.phi_i.n, self.theta_i.n, self.phi_o.n, self.theta_o.n]
            .iter()
            .try_fold(1usize, |a, n| a.checked_mul(*n));
        if nodes.is_none_or(|n| n > MAX_GRID_NODES) {
            return Err(ProcessError::grid(
                "nodes",
                &format!(
                    "{} nodes, more than the {MAX_GRID_NODES} a grid may have",
                    nodes.map_or_else(|| "over 2^64".to_string(), |n| n.to_string())
                ),
            ));
        }
        for (name, ax) in [("theta_i", &self.theta_i), ("theta_o", &self.theta_o)] {
            let last = ax.node(ax.n - 1);
            if ax.start < -ON_NODE || last > FRAC_PI_2 + ON_NODE {
                return Err(ProcessError::grid(
                    name,
                    "polar nodes must lie within 0..=90°",
                ));
            }
        }
        if self.isotropic && self.phi_i.n != 1 {
            return Err(ProcessError::grid(
                "phi_i",
                "the isotropic form has one φi node",
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locate_is_exact_on_nodes_and_wraps() {
        let p = Axis::full_turn(12);
        assert_eq!(p.locate(0.0), (0, 1, 0.0));
        assert_eq!(p.locate(330f64.to_radians()), (11, 0, 0.0));
        assert_eq!(p.locate(-30f64.to_radians()), (11, 0, 0.0));
        assert_eq!(p.locate(360f64.to_radians()), (0, 1, 0.0));
        let (a, b, t) = p.locate(345f64.to_radians());
        assert_eq!((a, b), (11, 0));
        assert!((t - 0.5).abs() < 1e-12);
        let th = Axis::from_deg(0.0, 10.0, 10);
        assert_eq!(th.locate(95f64.to_radians()), (9, 9, 0.0));
        assert_eq!(th.node_at(40f64.to_radians()), Some(4));
        assert_eq!(th.node_at(41f64.to_radians()), None);
        assert_eq!(p.node_at(-30f64.to_radians()), Some(11));
    }

    #[test]
    fn pairing() {
        assert!(Grid::hemisphere(9, 36).is_paired());
        let t = Axis::polar_midpoints(9);
        assert!(Grid::isotropic(t, Axis::full_turn(36), t).is_paired());
        assert!(!Grid::isotropic(t, Axis::from_deg(0.0, 10.0, 19), t).is_paired());
        let g = Grid::full(Axis::full_turn(36), t, Axis::full_turn(24), t);
        assert!(!g.is_paired());
    }
}

/// A hemisphere grid given by its steps in degrees, as `--grid DTHETA,DPHI` and
/// config files write it: polar band midpoints every DTHETA, a full turn of azimuth
/// every DPHI, the same for incidence and exitance.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct GridStep {
    /// Polar step, degrees; divides 90.
    pub dtheta_deg: f64,
    /// Azimuth step, degrees; divides 360.
    pub dphi_deg: f64,
}

impl GridStep {
    /// The steps, checked: both positive and finite, DTHETA dividing 90° and DPHI
    /// dividing 360°, and the full 4-D grid within [`MAX_GRID_NODES`] (so that
    /// neither form of the grid can exhaust memory or overflow its node count).
    pub fn new(dtheta_deg: f64, dphi_deg: f64) -> Result<GridStep, String> {
        let ok = |v: f64, whole: f64| {
            v.is_finite() && v > 0.0 && (whole / v - (whole / v).round()).abs() < 1e-9
        };
        if !(ok(dtheta_deg, 90.0) && ok(dphi_deg, 360.0)) {
            return Err(format!(
                "DTHETA must divide 90 and DPHI 360 (degrees, positive), got {dtheta_deg},{dphi_deg}"
            ));
        }
        let step = GridStep {
            dtheta_deg,
            dphi_deg,
        };
        // In floating point: 0.0001° steps make 10^25 nodes, past usize.
        let nodes = (step.n_theta() as f64 * step.n_phi() as f64).powi(2);
        if nodes > MAX_GRID_NODES as f64 {
            return Err(format!(
                "{dtheta_deg},{dphi_deg} makes a grid of {} nodes, more than the {MAX_GRID_NODES} \
                 a grid may have (the finest is about 2.5,2.5)",
                crate::grid::fmt_count(nodes)
            ));
        }
        Ok(step)
    }

    /// Polar bands.
    pub fn n_theta(&self) -> usize {
        (90.0 / self.dtheta_deg).round() as usize
    }

    /// Azimuths over a full turn.
    pub fn n_phi(&self) -> usize {
        (360.0 / self.dphi_deg).round() as usize
    }

    /// The full 4-D grid.
    pub fn grid(&self) -> Grid {
        Grid::hemisphere(self.n_theta(), self.n_phi())
    }

    /// The isotropic (θi, φo − φi, θo) grid.
    pub fn isotropic_grid(&self) -> Grid {
        Grid::hemisphere_isotropic(self.n_theta(), self.n_phi())
    }
}

impl std::str::FromStr for GridStep {
    type Err = String;

    /// `DTHETA,DPHI` in degrees.
    fn from_str(s: &str) -> Result<GridStep, String> {
        let (a, b) = s
            .split_once(',')
            .ok_or_else(|| format!("expected DTHETA,DPHI in degrees, got {s:?}"))?;
        let num = |x: &str| x.trim().parse::<f64>().ok();
        match (num(a), num(b)) {
            (Some(dt), Some(dp)) => GridStep::new(dt, dp),
            _ => Err(format!(
                "DTHETA must divide 90 and DPHI 360 (degrees, positive), got {s:?}"
            )),
        }
    }
}
