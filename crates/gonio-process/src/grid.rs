//! Uniform grids of directions and the tabulated BRDFs on them (DeYoung Sec. 3.1),
//! with quadrilinear interpolation between the nodes (Sec. 3.2.1).
//!
//! A [`Table`] stores its values lexicographically in (φi, θi, φo, θo), the order of
//! DeYoung Eq. 3.1, one block per channel. The isotropic form (θi, φ+, θo) of Eq. 4.6
//! is the same layout with a single φi node at 0 whose φo axis is the difference
//! φ+ = φo − φi, so every measure, transform and file treats both alike.

use std::f64::consts::{FRAC_PI_2, TAU};

use gonio_core::{Channels, Dir};

use crate::ProcessError;

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

/// A tabulated BRDF on a [`Grid`]: values in 1/sr per channel, with standard
/// uncertainties where they are known.
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// The channels.
    pub channels: Channels,
    /// The nodes.
    pub grid: Grid,
    /// `values[ch * grid.len() + index]`.
    pub values: Vec<f64>,
    /// Standard uncertainties, same layout; none when unknown.
    pub sigma: Option<Vec<f64>>,
}

impl Table {
    /// A table of `values` (layout of [`Table::values`]).
    pub fn new(
        channels: Channels,
        grid: Grid,
        values: Vec<f64>,
        sigma: Option<Vec<f64>>,
    ) -> Result<Table, ProcessError> {
        grid.validate()?;
        let want = grid.len() * channels.len();
        if values.len() != want {
            return Err(ProcessError::Shape(format!(
                "{} values for a grid of {} nodes × {} channels",
                values.len(),
                grid.len(),
                channels.len()
            )));
        }
        if let Some(s) = &sigma
            && s.len() != want
        {
            return Err(ProcessError::Shape(format!(
                "{} uncertainties for {want} values",
                s.len()
            )));
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(ProcessError::Value(format!(
                "value {i} is not finite ({})",
                values[i]
            )));
        }
        if let Some(s) = &sigma
            && let Some(i) = s.iter().position(|v| !(v.is_finite() && *v >= 0.0))
        {
            return Err(ProcessError::Value(format!(
                "uncertainty {i} is not a finite non-negative number ({})",
                s[i]
            )));
        }
        Ok(Table {
            channels,
            grid,
            values,
            sigma,
        })
    }

    /// Tabulates any BRDF at the grid's nodes (its uncertainties unknown).
    pub fn from_brdf(brdf: &dyn gonio_brdf::Brdf, grid: Grid) -> Result<Table, ProcessError> {
        Table::from_fn(brdf.channels().clone(), grid, |wi, wo, out| {
            brdf.eval(wi, wo, out)
        })
    }

    /// Tabulates `f(wi, wo, out)`, which writes one value a channel, at the nodes.
    pub fn from_fn(
        channels: Channels,
        grid: Grid,
        f: impl Fn(Dir, Dir, &mut [f64]),
    ) -> Result<Table, ProcessError> {
        grid.validate()?;
        let nc = channels.len();
        let n = grid.len();
        let mut values = vec![0.0; n * nc];
        let mut out = vec![0.0; nc];
        for i in 0..n {
            let [pi, ti, po, to] = grid.angles(i);
            f(Dir::from_angles(ti, pi), Dir::from_angles(to, po), &mut out);
            for (ch, v) in out.iter().enumerate() {
                values[ch * n + i] = *v;
            }
        }
        Table::new(channels, grid, values, None)
    }

    /// Values of channel `ch`, in grid order.
    pub fn channel(&self, ch: usize) -> &[f64] {
        let n = self.grid.len();
        &self.values[ch * n..(ch + 1) * n]
    }

    /// Uncertainties of channel `ch`, when known.
    pub fn channel_sigma(&self, ch: usize) -> Option<&[f64]> {
        let n = self.grid.len();
        self.sigma.as_ref().map(|s| &s[ch * n..(ch + 1) * n])
    }

    /// Quadrilinear interpolation of channel `ch` at angles (φi, θi, φo, θo), radians
    /// (DeYoung Sec. 3.2.1: the 16 nodes around the incident and outgoing directions).
    /// Exact at nodes; azimuths wrap on full-turn axes; beyond a polar or partial
    /// azimuth axis the end value holds.
    pub fn eval_angles(&self, ch: usize, ang: [f64; 4]) -> f64 {
        interpolate(&self.grid, self.channel(ch), ang)
    }

    /// All channels at a pair of directions.
    pub fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        let ang = [wi.phi(), wi.theta(), wo.phi(), wo.theta()];
        for (ch, o) in out.iter_mut().enumerate() {
            *o = self.eval_angles(ch, ang);
        }
    }

    /// The full 4D form of an isotropic table, with `n_phi_i` incident azimuths over a
    /// full turn (the φ+ axis's step when it has a full turn of nodes).
    pub fn to_full(&self, n_phi_i: usize) -> Result<Table, ProcessError> {
        if !self.grid.isotropic {
            return Ok(self.clone());
        }
        let g = Grid::full(
            Axis::full_turn(n_phi_i),
            self.grid.theta_i,
            self.grid.phi_o,
            self.grid.theta_o,
        );
        let n = g.len();
        let nc = self.channels.len();
        let mut values = vec![0.0; n * nc];
        let mut sigma = self.sigma.as_ref().map(|_| vec![0.0; n * nc]);
        for ch in 0..nc {
            for i in 0..n {
                let ang = g.angles(i);
                values[ch * n + i] = self.eval_angles(ch, ang);
                if let (Some(s), Some(src)) = (sigma.as_mut(), self.channel_sigma(ch)) {
                    s[ch * n + i] = interpolate(&self.grid, src, ang);
                }
            }
        }
        Table::new(self.channels.clone(), g, values, sigma)
    }

    /// The table with other values (same channels and grid).
    pub fn with_values(&self, values: Vec<f64>, sigma: Option<Vec<f64>>) -> Table {
        Table {
            channels: self.channels.clone(),
            grid: self.grid,
            values,
            sigma,
        }
    }
}

/// The proposal tabulated BRDFs sample with: cosine-weighted about the normal (a
/// table's shape is unknown in advance, and this density covers the hemisphere).
pub(crate) fn cosine_proposal(out: &mut Vec<gonio_brdf::Weighted>) {
    out.push(gonio_brdf::Weighted {
        weight: 1.0,
        proposal: gonio_brdf::Proposal::CosinePower {
            axis: Dir::from_angles(0.0, 0.0),
            n: 1.0,
        },
    });
}

impl gonio_brdf::Brdf for Table {
    fn channels(&self) -> &Channels {
        &self.channels
    }

    fn eval(&self, wi: Dir, wo: Dir, out: &mut [f64]) {
        Table::eval(self, wi, wo, out);
    }

    fn proposals(&self, _wi: Dir, out: &mut Vec<gonio_brdf::Weighted>) {
        cosine_proposal(out);
    }

    fn is_reciprocal(&self) -> bool {
        false
    }

    /// The integral of the table's own interpolant, `∫ f_r cos θo dωo`, to rounding.
    /// For a fixed incidence the interpolant is bilinear in (φo, θo) between nodes
    /// (and constant beyond an axis's ends). So the hemisphere is cut at the nodes
    /// (and at φ = 0, π, where a clamped azimuth axis may jump), and each piece is
    /// integrated by Gauss–Legendre: 2 points in φ, exact for a linear integrand,
    /// and 8 in θ for the smooth `cos θ sin θ` factor. That is a few thousand
    /// evaluations; an adaptive rule spends millions on the kinks.
    fn albedo(&self, wi: Dir, out: &mut [f64]) {
        out.fill(0.0);
        if !wi.is_above() {
            return;
        }
        let g = &self.grid;
        let mut theta = vec![0.0, FRAC_PI_2];
        theta.extend(
            (0..g.theta_o.n)
                .map(|k| g.theta_o.node(k))
                .filter(|x| *x > 0.0 && *x < FRAC_PI_2),
        );
        // An isotropic table's azimuth axis is φo − φi.
        let shift = if g.isotropic { wi.phi() } else { 0.0 };
        let mut phi = vec![0.0, std::f64::consts::PI, TAU];
        if g.phi_o.n > 1 {
            phi.extend((0..g.phi_o.n).map(|k| (g.phi_o.node(k) + shift).rem_euclid(TAU)));
        }
        for cuts in [&mut theta, &mut phi] {
            cuts.sort_by(f64::total_cmp);
            cuts.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
        }
        let mut f = vec![0.0; out.len()];
        for p in phi.windows(2) {
            let (pm, ph) = (0.5 * (p[0] + p[1]), 0.5 * (p[1] - p[0]));
            for (xp, wp) in GL2 {
                for t in theta.windows(2) {
                    let (tm, th) = (0.5 * (t[0] + t[1]), 0.5 * (t[1] - t[0]));
                    for (xt, wt) in GL8 {
                        let (th_o, ph_o) = (tm + th * xt, pm + ph * xp);
                        let w = wp * ph * wt * th * th_o.cos() * th_o.sin();
                        Table::eval(self, wi, Dir::from_angles(th_o, ph_o), &mut f);
                        for (o, v) in out.iter_mut().zip(&f) {
                            *o += w * v;
                        }
                    }
                }
            }
        }
    }
}

/// Gauss–Legendre nodes and weights on [−1, 1], 2 points (±1/√3, weights 1).
const GL2: [(f64, f64); 2] = [
    (-0.577_350_269_189_625_8, 1.0),
    (0.577_350_269_189_625_8, 1.0),
];

/// Gauss–Legendre nodes and weights on [−1, 1], 8 points (Abramowitz & Stegun,
/// Table 25.4).
const GL8: [(f64, f64); 8] = [
    (-0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
    (-0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (-0.525_532_409_916_329_0, 0.313_706_645_877_887_3),
    (-0.183_434_642_495_649_8, 0.362_683_783_378_362_0),
    (0.183_434_642_495_649_8, 0.362_683_783_378_362_0),
    (0.525_532_409_916_329_0, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
];

/// Quadrilinear interpolation of `v` (one channel, grid order) at (φi, θi, φo, θo).
pub(crate) fn interpolate(g: &Grid, v: &[f64], ang: [f64; 4]) -> f64 {
    let [mut pi, ti, mut po, to] = ang;
    if g.isotropic {
        po -= pi;
        pi = 0.0;
    }
    let la = g.phi_i.locate(pi);
    let lb = g.theta_i.locate(ti);
    let lc = g.phi_o.locate(po);
    let ld = g.theta_o.locate(to);
    let mut acc = 0.0;
    for (a, wa) in [(la.0, 1.0 - la.2), (la.1, la.2)] {
        if wa == 0.0 {
            continue;
        }
        for (b, wb) in [(lb.0, 1.0 - lb.2), (lb.1, lb.2)] {
            if wb == 0.0 {
                continue;
            }
            for (c, wc) in [(lc.0, 1.0 - lc.2), (lc.1, lc.2)] {
                if wc == 0.0 {
                    continue;
                }
                for (d, wd) in [(ld.0, 1.0 - ld.2), (ld.1, ld.2)] {
                    if wd == 0.0 {
                        continue;
                    }
                    acc += wa * wb * wc * wd * v[g.index(a, b, c, d)];
                }
            }
        }
    }
    acc
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
    fn a_tables_albedo_integrates_its_interpolant() {
        use gonio_brdf::Brdf;
        // A Lambertian table: ρ exactly, whatever the grid.
        for (iso, g) in [
            (
                true,
                GridStep::new(10.0, 15.0).expect("steps").isotropic_grid(),
            ),
            (false, GridStep::new(15.0, 30.0).expect("steps").grid()),
        ] {
            let t = Table::new(
                Channels::Single,
                g,
                vec![0.3 / std::f64::consts::PI; g.len()],
                None,
            )
            .expect("table");
            let mut a = [0.0];
            t.albedo(Dir::from_angles(0.4, 1.0), &mut a);
            assert!((a[0] - 0.3).abs() < 1e-12, "{iso}: {}", a[0]);
        }
        // Any table: the adaptive rule on the same interpolant agrees, in far fewer
        // evaluations (an isotropic table and a full one, off the nodes).
        for g in [
            GridStep::new(10.0, 15.0).expect("steps").isotropic_grid(),
            GridStep::new(15.0, 30.0).expect("steps").grid(),
        ] {
            let v: Vec<f64> = (0..g.len())
                .map(|i| {
                    let [pi, ti, po, to] = g.angles(i);
                    0.1 + 0.05 * (3.0 * to).cos() * (po - pi).cos() + 0.02 * ti
                })
                .collect();
            let t = Table::new(Channels::Single, g, v, None).expect("table");
            for wi in [Dir::from_angles(0.2, 0.3), Dir::from_angles(1.1, 2.0)] {
                let mut a = [0.0];
                t.albedo(wi, &mut a);
                let tol = gonio_core::quad::Tolerance::new(1e-11, 1e-9);
                let want = gonio_brdf::albedo::integrate(&t, wi, tol).values[0];
                assert!((a[0] - want).abs() < 1e-7 * want, "{} vs {want}", a[0]);
            }
        }
    }

    #[test]
    fn quadrilinear_reproduces_multilinear_functions() {
        let g = Grid::full(
            Axis::from_deg(0.0, 45.0, 3),
            Axis::from_deg(0.0, 30.0, 4),
            Axis::from_deg(10.0, 20.0, 5),
            Axis::from_deg(5.0, 20.0, 5),
        );
        let f = |a: [f64; 4]| 1.0 + 2.0 * a[0] - a[1] + 0.5 * a[2] * a[3] + a[0] * a[1] * a[2];
        let v: Vec<f64> = (0..g.len()).map(|i| f(g.angles(i))).collect();
        let t = Table::new(Channels::Single, g, v, None).expect("table");
        for q in [
            [0.3, 0.4, 0.5, 0.6],
            [1.2, 1.0, 1.1, 0.2],
            [0.0, 0.0, 0.2, 0.1],
        ] {
            assert!((t.eval_angles(0, q) - f(q)).abs() < 1e-12, "{q:?}");
        }
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
