//! The tabulated BRDF on a grid: its values and uncertainties by channel, its
//! quadrilinear interpolation between the nodes (DeYoung Sec. 3.2.1), and its
//! albedo by quadrature over that interpolant.

use std::f64::consts::{FRAC_PI_2, TAU};

use gonio_core::{Channels, Dir};
use rayon::prelude::*;

use super::{Axis, Grid};
use crate::ProcessError;

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
        // The first bad value in order, looked for on rayon.
        if let Some(i) = values.par_iter().position_first(|v| !v.is_finite()) {
            return Err(ProcessError::Value(format!(
                "value {i} is not finite ({})",
                values[i]
            )));
        }
        if let Some(s) = &sigma
            && let Some(i) = s
                .par_iter()
                .position_first(|v| !(v.is_finite() && *v >= 0.0))
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
    out.push(gonio_brdf::Weighted::COSINE);
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
pub(crate) const GL8: [(f64, f64); 8] = [
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
    interpolate_by(g, |k| v[k], ang)
}

/// [`interpolate`] of the values `v(node)` gives, formed where they are read (the
/// floors' counterparts are measured without being stored).
#[inline]
pub(crate) fn interpolate_by(g: &Grid, v: impl Fn(usize) -> f64, ang: [f64; 4]) -> f64 {
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
                    acc += wa * wb * wc * wd * v(g.index(a, b, c, d));
                }
            }
        }
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::GridStep;

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
}
