//! The table estimator: energy binned into the cells of a grid's outgoing nodes, per
//! bounce order, with Monte Carlo errors and albedos (module docs of `sim`).

use std::f64::consts::TAU;

use gonio_core::Dir;
use gonio_process::{Axis, Grid, Table};

use super::{
    BLOCK, End, IncidentAlbedo, MicroResult, PURPOSE_TABLE, Simulation, TraceStats, block_rng,
    mean_and_error, run_ordered,
};
use crate::MicroError;
use crate::material::{Scratch, uniform};

impl Simulation {
    /// Simulates the BRDF at the nodes of `grid` with `rays` rays per incident node
    /// (see the module docs for the estimator). Deterministic in `seed` whatever the
    /// number of threads.
    pub fn to_table(&self, grid: &Grid, rays: usize, seed: u64) -> Result<MicroResult, MicroError> {
        grid.validate()?;
        super::check_rays(rays)?;
        let cells = OutCells::new(&grid.phi_o, &grid.theta_o);
        let nc = self.sample.channels.len();
        let n_out = grid.n_out();
        let n_in = grid.n_in();
        let n_blocks = rays.div_ceil(BLOCK);
        let incident = |inc: usize| -> (f64, f64) {
            let (a, b) = (inc / grid.theta_i.n, inc % grid.theta_i.n);
            (grid.phi_i.node(a), grid.theta_i.node(b))
        };
        let mut accs: Vec<TableAcc> = (0..n_in).map(|_| TableAcc::new(nc, n_out)).collect();
        run_ordered(
            n_in * n_blocks,
            self.cancel_flag(),
            |task| {
                let (inc, b) = (task / n_blocks, task % n_blocks);
                let mut acc = TableAcc::new(nc, n_out);
                let (phi_i, theta_i) = incident(inc);
                let wi = Dir::from_angles(theta_i, phi_i);
                if wi.z <= 1e-12 {
                    return acc;
                }
                let mut rng = block_rng(seed, PURPOSE_TABLE, inc, b);
                let n = BLOCK.min(rays - b * BLOCK);
                let mut w = vec![0.0; nc];
                let mut scratch = Scratch::new(nc);
                for _ in 0..n {
                    let turn = if grid.isotropic {
                        TAU * uniform(&mut rng)
                    } else {
                        0.0
                    };
                    let wi_r = if grid.isotropic {
                        wi.rotate_about_normal(turn)
                    } else {
                        wi
                    };
                    let (end, k, d) =
                        self.path(self.to_surface(wi_r.vec()), &mut rng, &mut w, &mut scratch);
                    self.count(&mut acc.stats, end, k, &w);
                    if end != End::Exit {
                        continue;
                    }
                    let wo = self.to_sample(d);
                    let slot = (k.min(3)) as usize; // 1, 2, 3+
                    let cell = cells.locate(
                        wo.theta(),
                        wo.phi() - if grid.isotropic { turn } else { 0.0 },
                    );
                    acc.add(slot, cell, &w);
                }
                acc
            },
            |task, acc| accs[task / n_blocks].merge(&acc),
        )?;

        // Tables.
        let n = grid.len();
        let mut values = vec![vec![0.0; n * nc]; 4];
        let mut sigmas = vec![vec![0.0; n * nc]; 4];
        let mut albedo = Vec::with_capacity(n_in);
        let mut stats = TraceStats::default();
        for (inc, acc) in accs.iter().enumerate() {
            stats.merge(&acc.stats);
            let (phi_i, theta_i) = incident(inc);
            let rays_here = acc.stats.rays as f64;
            let (a, b) = (inc / grid.theta_i.n, inc % grid.theta_i.n);
            for slot in 0..4 {
                for ch in 0..nc {
                    for q in 0..n_out {
                        let (c, d) = (q / grid.theta_o.n, q % grid.theta_o.n);
                        let (m, s) = mean_and_error(
                            acc.sum[acc.at(slot, ch, q)],
                            acc.sq[acc.at(slot, ch, q)],
                            rays_here,
                        );
                        let om = cells.omega[q];
                        let idx = ch * n + grid.index(a, b, c, d);
                        values[slot][idx] = m / om;
                        sigmas[slot][idx] = s / om;
                    }
                }
            }
            let alb = |slot: usize| -> (Vec<f64>, Vec<f64>) {
                (0..nc)
                    .map(|ch| {
                        mean_and_error(
                            acc.alb[slot * nc + ch],
                            acc.alb_sq[slot * nc + ch],
                            rays_here,
                        )
                    })
                    .unzip()
            };
            let (al, sg) = alb(0);
            albedo.push(IncidentAlbedo {
                phi_i,
                theta_i,
                albedo: al,
                sigma: sg,
                per_order: (1..4).map(|s| alb(s).0).collect(),
                in_table: acc
                    .binned
                    .iter()
                    .map(|e| if rays_here > 0.0 { e / rays_here } else { 0.0 })
                    .collect(),
            });
        }
        let ch = self.sample.channels.clone();
        let mut tables = values
            .into_iter()
            .zip(sigmas)
            .map(|(v, s)| Table::new(ch.clone(), *grid, v, Some(s)))
            .collect::<Result<Vec<_>, _>>()?;
        let table = tables.remove(0);
        Ok(MicroResult {
            table,
            per_order: tables,
            albedo,
            stats,
        })
    }
}

/// Per-incident-node sums: energy and its square per (slot, channel, outgoing cell);
/// slot 0 is all orders, 1–3 the orders of [`ORDERS`].
struct TableAcc {
    nc: usize,
    n_out: usize,
    sum: Vec<f64>,
    sq: Vec<f64>,
    alb: Vec<f64>,
    alb_sq: Vec<f64>,
    binned: Vec<f64>,
    stats: TraceStats,
}

impl TableAcc {
    fn new(nc: usize, n_out: usize) -> TableAcc {
        TableAcc {
            nc,
            n_out,
            sum: vec![0.0; 4 * nc * n_out],
            sq: vec![0.0; 4 * nc * n_out],
            alb: vec![0.0; 4 * nc],
            alb_sq: vec![0.0; 4 * nc],
            binned: vec![0.0; nc],
            stats: TraceStats::default(),
        }
    }

    #[inline]
    fn at(&self, slot: usize, ch: usize, q: usize) -> usize {
        (slot * self.nc + ch) * self.n_out + q
    }

    /// One exit of order slot (1, 2, 3) with energy `w`, into `cell` if any.
    fn add(&mut self, slot: usize, cell: Option<usize>, w: &[f64]) {
        for (ch, &e) in w.iter().enumerate() {
            let e2 = e * e;
            for s in [0, slot] {
                self.alb[s * self.nc + ch] += e;
                self.alb_sq[s * self.nc + ch] += e2;
                if let Some(q) = cell {
                    let i = self.at(s, ch, q);
                    self.sum[i] += e;
                    self.sq[i] += e2;
                }
            }
            if cell.is_some() {
                self.binned[ch] += e;
            }
        }
    }

    fn merge(&mut self, o: &TableAcc) {
        for (a, b) in [
            (&mut self.sum, &o.sum),
            (&mut self.sq, &o.sq),
            (&mut self.alb, &o.alb),
            (&mut self.alb_sq, &o.alb_sq),
            (&mut self.binned, &o.binned),
        ] {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        }
        self.stats.merge(&o.stats);
    }
}

/// The cells of outgoing directions around a grid's outgoing nodes.
struct OutCells {
    phi: Axis,
    theta: Axis,
    /// `(lo, hi)` polar bounds of each θo node.
    bounds: Vec<(f64, f64)>,
    /// `Ω_proj` of each outgoing node, index `c·nθ + d`.
    omega: Vec<f64>,
}

impl OutCells {
    fn new(phi: &Axis, theta: &Axis) -> OutCells {
        let half = std::f64::consts::FRAC_PI_2;
        let bounds: Vec<(f64, f64)> = (0..theta.n)
            .map(|d| {
                if theta.n == 1 {
                    (0.0, half)
                } else {
                    let x = theta.node(d);
                    (
                        (x - 0.5 * theta.step).max(0.0),
                        (x + 0.5 * theta.step).min(half),
                    )
                }
            })
            .collect();
        let dphi = if phi.n == 1 { TAU } else { phi.step };
        let mut omega = Vec::with_capacity(phi.n * theta.n);
        for _ in 0..phi.n {
            for &(lo, hi) in &bounds {
                omega.push(dphi * (hi.sin().powi(2) - lo.sin().powi(2)) / 2.0);
            }
        }
        OutCells {
            phi: *phi,
            theta: *theta,
            bounds,
            omega,
        }
    }

    /// The outgoing node whose cell holds `(theta, phi)`, if any.
    fn locate(&self, theta: f64, phi: f64) -> Option<usize> {
        let d = if self.theta.n == 1 {
            0
        } else {
            let k = ((theta - self.theta.start) / self.theta.step + 0.5).floor();
            if !(k >= 0.0 && k < self.theta.n as f64) {
                return None;
            }
            k as usize
        };
        let (lo, hi) = self.bounds[d];
        if !(theta >= lo && theta <= hi) || self.omega[d] <= 0.0 {
            return None;
        }
        let c = if self.phi.n == 1 {
            0
        } else if self.phi.is_periodic() {
            let k = ((phi - self.phi.start) / self.phi.step + 0.5).floor();
            k.rem_euclid(self.phi.n as f64) as usize % self.phi.n
        } else {
            let mut found = None;
            for p in [phi, phi - TAU, phi + TAU] {
                let k = ((p - self.phi.start) / self.phi.step + 0.5).floor();
                if k >= 0.0 && k < self.phi.n as f64 {
                    found = Some(k as usize);
                    break;
                }
            }
            found?
        };
        Some(c * self.theta.n + d)
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;

    #[test]
    fn cells_tile_the_hemisphere() {
        let cells = OutCells::new(&Axis::full_turn(36), &Axis::polar_midpoints(9));
        let total: f64 = cells.omega.iter().sum();
        assert!((total - PI).abs() < 1e-12, "{total}");
        assert_eq!(cells.locate(0.01, 0.0), Some(0));
        assert_eq!(cells.locate(0.01, TAU - 0.01), Some(0));
        assert_eq!(cells.locate(0.2, 14f64.to_radians()), Some(9 + 1));
        // Nodes 0°..80° every 10°: the last cell stops at 85°.
        let cells = OutCells::new(&Axis::single(0.0), &Axis::from_deg(0.0, 10.0, 9));
        assert_eq!(cells.locate(86f64.to_radians(), 1.0), None);
        assert_eq!(cells.locate(84f64.to_radians(), 1.0), Some(8));
        assert_eq!(cells.locate(4f64.to_radians(), 1.0), Some(0));
    }
}
