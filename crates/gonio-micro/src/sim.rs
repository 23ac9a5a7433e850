//! The virtual gonioreflectometer: rays shot at the patch, traced through every
//! bounce, and collected into a tabulated BRDF (per bounce order, with Monte Carlo
//! errors and albedos) or a spherical-harmonic matrix.
//!
//! # Rays
//! For an incident direction `wi` (sample frame, pointing to the light) a ray starts
//! at a uniformly random point of the plane `z = h_max` over the periodic patch and
//! travels along `−wi`: uniform over the macro-surface, so each of `N` rays carries the
//! fraction `1/N` of the flux falling on it. At every hit the facet's material
//! reflects it and multiplies its energy (one value a channel, starting at 1); the
//! ray leaves when it heads up above the highest node (Westin et al. Sec. 4). Its
//! *order* is the number of bounces. Rays are absorbed when every channel's energy is
//! 0, and stopped after `max_bounces` (their energy is reported, not silently lost).
//!
//! # Table estimator
//! Since `dΦo/Φi = f_r(wi, wo) cos θo dωo`, the energy leaving into a cell `C` of
//! outgoing directions estimates `∫_C f_r cos θo dωo`. Each outgoing node of the grid
//! owns the cell between the midpoints to its neighbours (clipped to `[0°, 90°]`; a
//! single azimuth node owns the full turn), and
//!
//! `f̂(wi, node) = Σ_rays e·1[wo ∈ C] / (N · Ω_proj(C))`, with
//! `Ω_proj(C) = Δφ (sin²θ_hi − sin²θ_lo)/2 = ∫_C cos θ dω`,
//!
//! the cell average of `f_r` weighted by `cos θo`. Its standard error is the sample
//! standard deviation of the per-ray terms over `√N`. An isotropic grid (φ+ = φo − φi)
//! draws a uniformly random `φi` for every ray and bins `φo − φi`: the average over
//! the sample's turns. A full grid traces every (φi, θi) node.

use std::f64::consts::{PI, TAU};

use gonio_core::{Dir, Vec3};
use gonio_process::sh::{ShBrdf, basis, eval_basis, taper};
use gonio_process::{Axis, Grid, Table};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::material::{Scratch, uniform};
use crate::trace::{Method, Ray, Tracer};
use crate::{MicroError, Sample};

/// Rays a block: each block has its own random stream, so results do not depend on
/// how blocks are spread over threads.
pub const BLOCK: usize = 1024;
/// Blocks traced in parallel before their sums are merged (in block order).
const ROUND: usize = 64;
/// The bounce orders reported separately: 1, 2 and 3 or more.
pub const ORDERS: [&str; 3] = ["1", "2", "3+"];

const PURPOSE_TRACE: u64 = 1;
const PURPOSE_TABLE: u64 = 2;
const PURPOSE_SH: u64 = 3;

/// The random stream of one block: ChaCha8 seeded with `seed`, on the stream that
/// `purpose`, the incident index and the block index name.
fn block_rng(seed: u64, purpose: u64, incident: usize, block: usize) -> ChaCha8Rng {
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    r.set_stream((purpose << 56) ^ ((incident as u64) << 28) ^ block as u64);
    r
}

/// Runs `task(k)` for `k` in `0..n` in parallel rounds and hands the results to
/// `merge` in order of `k`, whatever the number of threads.
fn run_ordered<A: Send>(
    n: usize,
    task: impl Fn(usize) -> A + Sync,
    mut merge: impl FnMut(usize, A),
) {
    let mut start = 0;
    while start < n {
        let end = (start + ROUND).min(n);
        let out: Vec<A> = (start..end).into_par_iter().map(&task).collect();
        for (k, a) in out.into_iter().enumerate() {
            merge(start + k, a);
        }
        start = end;
    }
}

/// Options of a [`Simulation`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimOptions {
    /// Bounces after which a ray is stopped (its energy reported as capped).
    pub max_bounces: u32,
    /// How rays find their hits (every method finds the same ones).
    pub method: Method,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            max_bounces: 100,
            method: Method::MaxMip,
        }
    }
}

/// What became of the rays of a simulation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TraceStats {
    /// Rays shot.
    pub rays: u64,
    /// Rays that left the surface.
    pub exits: u64,
    /// Rays whose energy went to 0 in every channel.
    pub absorbed: u64,
    /// Rays stopped at `max_bounces`.
    pub capped: u64,
    /// Rays lost to numerical trouble (passed below the surface, or hit a facet from
    /// behind); 0 in every test.
    pub leaked: u64,
    /// Rays given up after the search length without a hit (within ~1e-4 rad of
    /// horizontal, travelling along a groove; see [`Tracer::span`]); their energy is
    /// lost.
    pub horizon: u64,
    /// Hits over all rays (bounces).
    pub hits: u64,
    /// The highest order of an exit.
    pub max_order: u32,
    /// Energy (mean over channels, summed over rays) of capped rays.
    pub capped_energy: f64,
    /// Energy of leaked and horizontal rays (mean over channels, summed over rays).
    pub lost_energy: f64,
}

impl TraceStats {
    fn merge(&mut self, o: &TraceStats) {
        self.rays += o.rays;
        self.exits += o.exits;
        self.absorbed += o.absorbed;
        self.capped += o.capped;
        self.leaked += o.leaked;
        self.horizon += o.horizon;
        self.hits += o.hits;
        self.max_order = self.max_order.max(o.max_order);
        self.capped_energy += o.capped_energy;
        self.lost_energy += o.lost_energy;
    }

    /// Capped energy as a fraction of the energy shot.
    pub fn capped_fraction(&self) -> f64 {
        if self.rays == 0 {
            0.0
        } else {
            self.capped_energy / self.rays as f64
        }
    }
}

/// How a path ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum End {
    Exit,
    Absorbed,
    Capped,
    Leaked,
    Horizon,
}

/// Every exit of [`Simulation::trace`].
#[derive(Clone, Debug, PartialEq)]
pub struct Exits {
    /// The incident direction (sample frame).
    pub wi: Dir,
    /// Rays shot.
    pub rays: usize,
    /// Outgoing direction of each exit (sample frame).
    pub wo: Vec<Dir>,
    /// Bounce order of each exit.
    pub order: Vec<u32>,
    /// Energy of each exit, `energy[exit · channels + ch]`.
    pub energy: Vec<f64>,
    /// What became of the rays.
    pub stats: TraceStats,
}

/// The directional albedo for one incident node, with its Monte Carlo error.
#[derive(Clone, Debug, PartialEq)]
pub struct IncidentAlbedo {
    /// Incident azimuth, radians (0 and averaged over turns for an isotropic grid).
    pub phi_i: f64,
    /// Incident polar angle, radians.
    pub theta_i: f64,
    /// Albedo per channel: energy out over energy in.
    pub albedo: Vec<f64>,
    /// Its standard error per channel.
    pub sigma: Vec<f64>,
    /// Albedo of each order of [`ORDERS`], per channel: `per_order[order][ch]`.
    pub per_order: Vec<Vec<f64>>,
    /// The part of the albedo that fell in the table's cells, per channel (less than
    /// the albedo when the polar cells do not reach 90°).
    pub in_table: Vec<f64>,
}

/// A tabulated BRDF simulated by [`Simulation::to_table`].
#[derive(Clone, Debug, PartialEq)]
pub struct MicroResult {
    /// The BRDF, all orders, with the Monte Carlo standard error as `sigma`.
    pub table: Table,
    /// The BRDF of each order of [`ORDERS`], with their errors.
    pub per_order: Vec<Table>,
    /// The albedo per incident node, in grid order (φi-major).
    pub albedo: Vec<IncidentAlbedo>,
    /// What became of the rays.
    pub stats: TraceStats,
}

/// A spherical-harmonic BRDF estimated by [`Simulation::estimate_sh`].
#[derive(Clone, Debug, PartialEq)]
pub struct ShEstimate {
    /// The representation (symmetric, tapered).
    pub sh: ShBrdf,
    /// Standard error of each coefficient before tapering, per channel, K × K
    /// row-major (symmetric).
    pub sigma: Vec<Vec<f64>>,
    /// What became of the rays.
    pub stats: TraceStats,
}

/// A sample ready to be traced: the surface with its hierarchy and the materials.
#[derive(Clone, Debug)]
pub struct Simulation {
    tracer: Tracer,
    sample: Sample,
    opts: SimOptions,
    eps: f64,
}

impl Simulation {
    /// Prepares `sample` (checks it again — its fields are public — and builds the
    /// max-mip hierarchy).
    pub fn new(sample: Sample, opts: SimOptions) -> Result<Simulation, MicroError> {
        if opts.max_bounces == 0 {
            return Err(MicroError::invalid("max_bounces", "must be at least 1"));
        }
        let sample = Sample::new(
            sample.channels,
            sample.surface,
            sample.materials,
            sample.orientation,
        )?;
        let tracer = Tracer::new(sample.surface.clone());
        let eps = 1e-9 * sample.surface.dx().min(sample.surface.dy());
        Ok(Simulation {
            tracer,
            sample,
            opts,
            eps,
        })
    }

    /// The sample.
    pub fn sample(&self) -> &Sample {
        &self.sample
    }

    /// The tracer (for benchmarks and tests of the intersection methods).
    pub fn tracer(&self) -> &Tracer {
        &self.tracer
    }

    /// Traces one path from `wi_s` (surface frame). `w` starts at 1 and ends as the
    /// energy carried out; returns how it ended, its bounces and last direction.
    fn path(
        &self,
        wi_s: Vec3,
        rng: &mut ChaCha8Rng,
        w: &mut [f64],
        scratch: &mut Scratch,
    ) -> (End, u32, Vec3) {
        let hf = self.tracer.surface();
        let (lx, ly) = hf.period();
        let (nx, ny) = (hf.nx() as i64, hf.ny() as i64);
        w.fill(1.0);
        let mut o = Vec3::new(uniform(rng) * lx, uniform(rng) * ly, hf.max_height());
        let mut d = -wi_s;
        let mut ray_skip = None;
        let mut t_min = 0.0;
        let mut bounces = 0u32;
        loop {
            let ray = Ray {
                o,
                d,
                t_min,
                skip: ray_skip,
            };
            let Some(h) = self.tracer.first_hit(&ray, self.opts.method) else {
                let cut_off = self.tracer.span(&ray).is_some_and(|s| s.2);
                let end = if cut_off {
                    End::Horizon
                } else if d.z > 0.0 {
                    End::Exit
                } else {
                    End::Leaked
                };
                return (end, bounces, d);
            };
            if bounces == self.opts.max_bounces {
                return (End::Capped, bounces, d);
            }
            bounces += 1;
            let n = self.tracer.hit_normal(&h);
            if d.dot(n) >= 0.0 {
                return (End::Leaked, bounces, d);
            }
            let mat = &self.sample.materials[self.tracer.hit_material(&h) as usize];
            let p = o + d * h.t;
            let Some(nd) = mat.scatter(d, n, rng, w, scratch) else {
                return (End::Absorbed, bounces, d);
            };
            if w.iter().all(|v| *v == 0.0) {
                return (End::Absorbed, bounces, d);
            }
            let Some(nd) = nd.normalized() else {
                return (End::Leaked, bounces, d);
            };
            d = nd;
            let kx = (p.x / lx).floor();
            let ky = (p.y / ly).floor();
            o = Vec3::new(p.x - kx * lx, p.y - ky * ly, p.z);
            ray_skip = Some((
                h.cell[0] - kx as i64 * nx,
                h.cell[1] - ky as i64 * ny,
                h.tri,
            ));
            t_min = self.eps;
        }
    }

    /// Sample frame → surface frame.
    fn to_surface(&self, v: Vec3) -> Vec3 {
        if self.sample.orientation == 0.0 {
            v
        } else {
            Dir::from_unit(v)
                .rotate_about_normal(-self.sample.orientation)
                .vec()
        }
    }

    /// Surface frame → sample frame.
    fn to_sample(&self, v: Vec3) -> Dir {
        let d = Dir::from_unit(v);
        if self.sample.orientation == 0.0 {
            d
        } else {
            d.rotate_about_normal(self.sample.orientation)
        }
    }

    /// Records one path's end in `stats`.
    fn count(&self, stats: &mut TraceStats, end: End, bounces: u32, w: &[f64]) {
        stats.rays += 1;
        stats.hits += u64::from(bounces);
        let mean = w.iter().sum::<f64>() / w.len() as f64;
        match end {
            End::Exit => {
                stats.exits += 1;
                stats.max_order = stats.max_order.max(bounces);
            }
            End::Absorbed => stats.absorbed += 1,
            End::Capped => {
                stats.capped += 1;
                stats.capped_energy += mean;
            }
            End::Leaked => {
                stats.leaked += 1;
                stats.lost_energy += mean;
            }
            End::Horizon => {
                stats.horizon += 1;
                stats.lost_energy += mean;
            }
        }
    }

    /// Traces `n_rays` rays from `wi` (sample frame) and returns every exit.
    /// Deterministic in `seed` whatever the number of threads.
    pub fn trace(&self, wi: Dir, n_rays: usize, seed: u64) -> Result<Exits, MicroError> {
        if wi.z <= 0.0 || wi.z.is_nan() {
            return Err(MicroError::invalid("wi", "must point above the surface"));
        }
        let nc = self.sample.channels.len();
        let wi_s = self.to_surface(wi.vec());
        let n_blocks = n_rays.div_ceil(BLOCK);
        let mut ex = Exits {
            wi,
            rays: n_rays,
            wo: Vec::new(),
            order: Vec::new(),
            energy: Vec::new(),
            stats: TraceStats::default(),
        };
        run_ordered(
            n_blocks,
            |b| {
                let mut rng = block_rng(seed, PURPOSE_TRACE, 0, b);
                let rays = BLOCK.min(n_rays - b * BLOCK);
                let mut w = vec![0.0; nc];
                let mut scratch = Scratch::new(nc);
                let mut out = (Vec::new(), Vec::new(), Vec::new(), TraceStats::default());
                for _ in 0..rays {
                    let (end, k, d) = self.path(wi_s, &mut rng, &mut w, &mut scratch);
                    self.count(&mut out.3, end, k, &w);
                    if end == End::Exit {
                        out.0.push(self.to_sample(d));
                        out.1.push(k);
                        out.2.extend_from_slice(&w);
                    }
                }
                out
            },
            |_, (wo, order, energy, stats)| {
                ex.wo.extend(wo);
                ex.order.extend(order);
                ex.energy.extend(energy);
                ex.stats.merge(&stats);
            },
        );
        Ok(ex)
    }

    /// Simulates the BRDF at the nodes of `grid` with `rays` rays per incident node
    /// (see the module docs for the estimator). Deterministic in `seed` whatever the
    /// number of threads.
    pub fn to_table(&self, grid: &Grid, rays: usize, seed: u64) -> Result<MicroResult, MicroError> {
        grid.validate()?;
        if rays < 2 {
            return Err(MicroError::invalid(
                "rays",
                "need at least 2 rays per direction",
            ));
        }
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
        );

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

    /// Estimates the symmetric spherical-harmonic matrix of the BRDF directly from
    /// rays (Westin et al. 1992, Sec. 3, Eq. 8–10), with the taper of their Sec. 2.5
    /// above `l_filter` (`None`: no taper).
    ///
    /// # Estimator
    /// In the hemisphere-even basis of [`gonio_process::sh`] the coefficients are
    /// `M_jk = 4 ∫_H ∫_H f_r(wi, wo) Y_j(wi) Y_k(wo) dωi dωo`. Each ray draws its own
    /// `wi` uniformly over the hemisphere (pdf `1/2π`) and a start point; its exit
    /// `(wo, e)` then has `E[e·g(wo)] = ∫ f_r cos θo g(wo) dωo` for any `g`. So
    ///
    /// `M̂_jk = (1/N) Σ_rays 8π e · ½ (Y_j(wi) Y_k(wo) + Y_k(wi) Y_j(wo)) / cos θo`
    ///
    /// (rays that do not leave contribute 0) is unbiased for the reciprocal part
    /// `(M + Mᵀ)/2` — the `Y_k(V)/cos θr` weighting Westin et al. describe, symmetrised
    /// term by term, so `M̂` is symmetric by construction, and exactly reciprocal in
    /// evaluation. The `1/cos θo` makes the variance grow (logarithmically) with
    /// grazing exits; `sigma` reports the standard errors.
    pub fn estimate_sh(
        &self,
        l_max: usize,
        l_filter: Option<usize>,
        rays: usize,
        seed: u64,
    ) -> Result<ShEstimate, MicroError> {
        if l_max > gonio_process::sh::MAX_L_MAX {
            return Err(MicroError::invalid(
                "l_max",
                format!("must be at most {}", gonio_process::sh::MAX_L_MAX),
            ));
        }
        let l_filter = l_filter.unwrap_or(l_max);
        if l_filter > l_max {
            return Err(MicroError::invalid("l_filter", "must not exceed l_max"));
        }
        if rays < 2 {
            return Err(MicroError::invalid("rays", "need at least 2 rays"));
        }
        let nc = self.sample.channels.len();
        let bas = basis(l_max);
        let k = bas.len();
        let nt = k * (k + 1) / 2;
        let n_blocks = rays.div_ceil(BLOCK);
        let mut sum = vec![0.0; nc * nt];
        let mut sq = vec![0.0; nc * nt];
        let mut stats = TraceStats::default();
        run_ordered(
            n_blocks,
            |b| {
                let mut rng = block_rng(seed, PURPOSE_SH, 0, b);
                let n = BLOCK.min(rays - b * BLOCK);
                let mut s = vec![0.0; nc * nt];
                let mut s2 = vec![0.0; nc * nt];
                let mut st = TraceStats::default();
                let mut w = vec![0.0; nc];
                let mut wt = vec![0.0; nc];
                let mut scratch = Scratch::new(nc);
                let (mut ya, mut yb) = (Vec::new(), Vec::new());
                for _ in 0..n {
                    // Uniform over the hemisphere: cos θ uniform in (0, 1].
                    let z = 1.0 - uniform(&mut rng);
                    let phi = TAU * uniform(&mut rng);
                    let wi = Dir::from_angles(z.acos(), phi);
                    let (end, order, d) =
                        self.path(self.to_surface(wi.vec()), &mut rng, &mut w, &mut scratch);
                    self.count(&mut st, end, order, &w);
                    if end != End::Exit {
                        continue;
                    }
                    let wo = self.to_sample(d);
                    eval_basis(l_max, wi, &mut ya);
                    eval_basis(l_max, wo, &mut yb);
                    for (c, v) in wt.iter_mut().enumerate() {
                        *v = 8.0 * PI * w[c] / wo.z;
                    }
                    let mut p = 0;
                    for j in 0..k {
                        for kk in j..k {
                            let t = 0.5 * (ya[j] * yb[kk] + ya[kk] * yb[j]);
                            for c in 0..nc {
                                let x = wt[c] * t;
                                s[c * nt + p] += x;
                                s2[c * nt + p] += x * x;
                            }
                            p += 1;
                        }
                    }
                }
                (s, s2, st)
            },
            |_, (s, s2, st)| {
                sum.iter_mut().zip(&s).for_each(|(a, b)| *a += b);
                sq.iter_mut().zip(&s2).for_each(|(a, b)| *a += b);
                stats.merge(&st);
            },
        );
        let nr = rays as f64;
        let mut matrices = Vec::with_capacity(nc);
        let mut sigma = Vec::with_capacity(nc);
        for c in 0..nc {
            let mut m = vec![0.0; k * k];
            let mut e = vec![0.0; k * k];
            let mut p = 0;
            for j in 0..k {
                for kk in j..k {
                    let (mean, err) = mean_and_error(sum[c * nt + p], sq[c * nt + p], nr);
                    let t = taper(bas[j].0, l_filter, l_max) * taper(bas[kk].0, l_filter, l_max);
                    m[j * k + kk] = mean * t;
                    m[kk * k + j] = mean * t;
                    e[j * k + kk] = err;
                    e[kk * k + j] = err;
                    p += 1;
                }
            }
            matrices.push(m);
            sigma.push(e);
        }
        let sh = ShBrdf {
            channels: self.sample.channels.clone(),
            l_max,
            l_filter,
            basis: bas,
            matrices,
        };
        sh.validate()?;
        Ok(ShEstimate { sh, sigma, stats })
    }
}

/// The mean of `n` per-ray terms with sum `s` and sum of squares `s2`, and its
/// standard error `√(var/n)` with the unbiased sample variance.
fn mean_and_error(s: f64, s2: f64, n: f64) -> (f64, f64) {
    if n < 2.0 {
        return (if n > 0.0 { s / n } else { 0.0 }, 0.0);
    }
    let m = s / n;
    let var = ((s2 / n - m * m) * n / (n - 1.0)).max(0.0);
    (m, (var / n).sqrt())
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
pub(crate) struct OutCells {
    phi: Axis,
    theta: Axis,
    /// `(lo, hi)` polar bounds of each θo node.
    bounds: Vec<(f64, f64)>,
    /// `Ω_proj` of each outgoing node, index `c·nθ + d`.
    pub(crate) omega: Vec<f64>,
}

impl OutCells {
    pub(crate) fn new(phi: &Axis, theta: &Axis) -> OutCells {
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
    pub(crate) fn locate(&self, theta: f64, phi: f64) -> Option<usize> {
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
