//! The table estimator: energy binned into the cells of a grid's outgoing nodes, per
//! bounce order, with Monte Carlo errors and albedos (module docs of `sim`).

use std::f64::consts::TAU;

use gonio_core::{Dir, Vec3};
use gonio_process::{Axis, Grid, Table};

use super::rays::KeyRng;
use super::{
    BLOCK, End, IncidentAlbedo, MicroResult, PURPOSE_TABLE, Simulation, TraceStats, mean_and_error,
    run_ordered,
};
use crate::MicroError;
use crate::material::{Scratch, uniform};
use crate::trace::floor;

/// Blocks a segment: the unit a table's sums are kept in, merged in segment order.
/// A chunk of a simulation traced apart ([`Simulation::table_part`]) is whole
/// segments, so a table merged from chunks is bit for bit the one traced at once.
pub const SEGMENT_BLOCKS: usize = 256;

/// Rays a segment: 262 144.
pub const SEGMENT_RAYS: usize = SEGMENT_BLOCKS * BLOCK;

/// The segments of a simulation of `rays` rays an incident node.
pub fn segments(rays: usize) -> usize {
    rays.div_ceil(SEGMENT_RAYS)
}

/// The estimator's sums (per-ray energy and its square per bin, albedos, ray
/// counts) over consecutive segments of one incident node of a table: a chunk of a
/// simulation traced apart — in another process, on another machine — and merged
/// by [`Simulation::table_from_parts`]. Sums, not means and errors, cross: the
/// merged mean and standard error are those of one simulation of all the rays
/// (module docs), not an approximation.
#[derive(Clone, Debug, PartialEq)]
pub struct TablePart {
    /// The seed of the simulation it is part of.
    pub seed: u64,
    /// The rays an incident node of that simulation.
    pub rays: usize,
    /// The incident node (grid order, φi-major).
    pub incident: usize,
    /// The first segment.
    pub first: usize,
    segments: Vec<TableAcc>,
}

/// The sums of one incident node folded segment by segment as its blocks arrive
/// (in order): one segment open, the closed ones added to the total. The memory is
/// two accumulators whatever the ray count, and the order of additions is that of
/// [`Simulation::table_from_parts`], so both give the same bits.
struct Fold {
    total: TableAcc,
    open: Option<TableAcc>,
}

impl Fold {
    fn new(nc: usize, n_out: usize) -> Fold {
        Fold {
            total: TableAcc::new(nc, n_out),
            open: None,
        }
    }

    /// Block `k` of the node, in order.
    fn add_block(&mut self, k: usize, acc: TableAcc) {
        if k.is_multiple_of(SEGMENT_BLOCKS) {
            self.close();
            self.open = Some(acc);
        } else if let Some(open) = &mut self.open {
            open.merge(&acc);
        }
    }

    /// Adds the open segment, if any, to the total.
    fn close(&mut self) {
        if let Some(done) = self.open.take() {
            self.total.merge(&done);
        }
    }

    fn finish(mut self) -> TableAcc {
        self.close();
        self.total
    }
}

/// What a table's blocks share: the grid, its outgoing cells, the rays, the seed.
struct TableJob<'a> {
    grid: &'a Grid,
    cells: OutCells,
    rays: usize,
    seed: u64,
    nc: usize,
}

impl TableJob<'_> {
    /// Incident node `inc`: (φi, θi), radians.
    fn incident(&self, inc: usize) -> (f64, f64) {
        let g = self.grid;
        let (a, b) = (inc / g.theta_i.n, inc % g.theta_i.n);
        (g.phi_i.node(a), g.theta_i.node(b))
    }
}

impl Simulation {
    /// Simulates the BRDF at the nodes of `grid` with `rays` rays per incident node
    /// (see the module docs for the estimator). Deterministic in `seed` whatever the
    /// number of threads.
    pub fn to_table(&self, grid: &Grid, rays: usize, seed: u64) -> Result<MicroResult, MicroError> {
        let job = self.table_job(grid, rays, seed)?;
        let n_blocks = rays.div_ceil(BLOCK);
        let mut folds: Vec<Fold> = (0..grid.n_in())
            .map(|_| Fold::new(job.nc, grid.n_out()))
            .collect();
        run_ordered(
            grid.n_in() * n_blocks,
            self.cancel_flag(),
            |task| self.table_block(&job, task / n_blocks, task % n_blocks),
            |task, acc| folds[task / n_blocks].add_block(task % n_blocks, acc),
        )?;
        let accs: Vec<TableAcc> = folds.into_iter().map(Fold::finish).collect();
        self.finish_table(&job, &accs)
    }

    /// Traces segments `segs` of incident node `incident` of the simulation
    /// [`Simulation::to_table`] would run with the same `grid`, `rays` and `seed`
    /// (the same random streams): a chunk of it, for [`Simulation::table_from_parts`].
    pub fn table_part(
        &self,
        grid: &Grid,
        rays: usize,
        seed: u64,
        incident: usize,
        segs: std::ops::Range<usize>,
    ) -> Result<TablePart, MicroError> {
        let job = self.table_job(grid, rays, seed)?;
        if incident >= grid.n_in() {
            return Err(MicroError::invalid(
                "incident",
                format!("node {incident} of a grid of {}", grid.n_in()),
            ));
        }
        if segs.is_empty() || segs.end > segments(rays) {
            return Err(MicroError::invalid(
                "segments",
                format!(
                    "{}..{} is not within the {} segment(s) of {rays} rays",
                    segs.start,
                    segs.end,
                    segments(rays)
                ),
            ));
        }
        let first_block = segs.start * SEGMENT_BLOCKS;
        let end_block = (segs.end * SEGMENT_BLOCKS).min(rays.div_ceil(BLOCK));
        let mut part = TablePart {
            seed,
            rays,
            incident,
            first: segs.start,
            segments: Vec::new(),
        };
        run_ordered(
            end_block - first_block,
            self.cancel_flag(),
            |k| self.table_block(&job, incident, first_block + k),
            |k, acc| part.add_block(k, acc),
        )?;
        Ok(part)
    }

    /// The table of [`Simulation::to_table`] from its parts: for every incident node,
    /// parts of this `seed` and `rays` that cover its segments once each (in any
    /// order). Bit for bit the table traced at once with the same `grid`, `rays`
    /// and `seed`.
    pub fn table_from_parts(
        &self,
        grid: &Grid,
        rays: usize,
        seed: u64,
        parts: &[TablePart],
    ) -> Result<MicroResult, MicroError> {
        let job = self.table_job(grid, rays, seed)?;
        let n_out = grid.n_out();
        let n_seg = segments(rays);
        let bad = |why: String| MicroError::invalid("parts", why);
        let mut sorted: Vec<&TablePart> = parts.iter().collect();
        sorted.sort_by_key(|p| (p.incident, p.first));
        let mut accs = Vec::with_capacity(grid.n_in());
        let mut it = sorted.into_iter().peekable();
        for incident in 0..grid.n_in() {
            let mut total = TableAcc::new(job.nc, n_out);
            let mut next = 0;
            while let Some(p) = it.next_if(|p| p.incident == incident) {
                if p.seed != seed || p.rays != rays {
                    return Err(bad(format!(
                        "a part of another simulation (seed {}, {} rays; this one: seed {seed}, {rays} rays)",
                        p.seed, p.rays
                    )));
                }
                if p.first != next {
                    return Err(bad(format!(
                        "incident node {incident}: a part starts at segment {} where {next} was expected",
                        p.first
                    )));
                }
                for (k, a) in p.segments.iter().enumerate() {
                    let s = p.first + k;
                    let expected = SEGMENT_RAYS.min(rays.saturating_sub(s * SEGMENT_RAYS)) as u64;
                    // A node at the horizon traces nothing.
                    if a.nc != job.nc
                        || a.n_out != n_out
                        || !(a.stats.rays == expected || a.stats.rays == 0)
                    {
                        return Err(bad(format!(
                            "incident node {incident}, segment {s}: not a segment of this grid, surface and ray count"
                        )));
                    }
                    total.merge(a);
                }
                next = p.first + p.segments.len();
            }
            if next != n_seg {
                return Err(bad(format!(
                    "incident node {incident}: {next} of its {n_seg} segments"
                )));
            }
            accs.push(total);
        }
        if let Some(p) = it.next() {
            return Err(bad(format!(
                "incident node {} of a grid of {}",
                p.incident,
                grid.n_in()
            )));
        }
        self.finish_table(&job, &accs)
    }

    /// Checks the arguments of a table simulation.
    fn table_job<'a>(
        &self,
        grid: &'a Grid,
        rays: usize,
        seed: u64,
    ) -> Result<TableJob<'a>, MicroError> {
        grid.validate()?;
        super::check_rays(rays)?;
        Ok(TableJob {
            grid,
            cells: OutCells::new(&grid.phi_o, &grid.theta_o),
            rays,
            seed,
            nc: self.sample.channels.len(),
        })
    }

    /// Traces block `b` of incident node `inc`: its sums.
    fn table_block(&self, job: &TableJob<'_>, inc: usize, b: usize) -> TableAcc {
        let grid = job.grid;
        let mut acc = TableAcc::new(job.nc, grid.n_out());
        let (phi_i, theta_i) = job.incident(inc);
        let wi = Dir::from_angles(theta_i, phi_i);
        if wi.z <= 1e-12 {
            return acc;
        }
        let mut w = vec![0.0; job.nc];
        let mut scratch = Scratch::new(job.nc);
        // The rays in the spatial order of their segment (module `rays`): each
        // one's turn is drawn from its own stream after its start.
        let rays: Vec<(Vec3, KeyRng, f64, Vec3)> = self
            .block_rays(job.seed, PURPOSE_TABLE, inc, job.rays, b)
            .into_iter()
            .map(|(o, mut rng)| {
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
                (o, rng, turn, self.to_surface(wi_r.vec()))
            })
            .collect();
        // Without turns every primary ray has the same direction, so the same plan.
        let plan0 = (!grid.isotropic).then(|| self.primary_plan(self.to_surface(wi.vec())));
        for (o, mut rng, turn, wi_s) in rays {
            let (end, k, d) = self.path(o, wi_s, plan0, &mut rng, &mut w, &mut scratch);
            self.count(&mut acc.stats, end, k, &w);
            if end != End::Exit {
                continue;
            }
            let wo = self.to_sample(d);
            let slot = (k.min(3)) as usize; // 1, 2, 3+
            let cell = if grid.isotropic {
                job.cells.locate(wo.z, wo.phi() - turn)
            } else {
                job.cells.locate_dir(wo.vec())
            };
            acc.add(slot, cell, &w);
        }
        acc
    }

    /// The tables, albedos and statistics of every incident node's sums.
    fn finish_table(
        &self,
        job: &TableJob<'_>,
        accs: &[TableAcc],
    ) -> Result<MicroResult, MicroError> {
        let (grid, nc, cells) = (job.grid, job.nc, &job.cells);
        let n_out = grid.n_out();
        let n = grid.len();
        let mut values = vec![vec![0.0; n * nc]; 4];
        let mut sigmas = vec![vec![0.0; n * nc]; 4];
        let mut albedo = Vec::with_capacity(grid.n_in());
        let mut stats = TraceStats::default();
        for (inc, acc) in accs.iter().enumerate() {
            stats.merge(&acc.stats);
            let (phi_i, theta_i) = job.incident(inc);
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
#[derive(Clone, Debug, PartialEq)]
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

/// The leading bytes of a serialised [`TablePart`], with its format's version.
const PART_MAGIC: &[u8; 8] = b"GMTPART2";

impl TablePart {
    /// The segments it covers.
    pub fn segments(&self) -> std::ops::Range<usize> {
        self.first..self.first.saturating_add(self.segments.len())
    }

    /// The rays it traced.
    pub fn rays_traced(&self) -> u64 {
        self.segments.iter().map(|s| s.stats.rays).sum()
    }

    /// The part as bytes (little-endian, exact: every sum keeps its bits), to
    /// cross processes and machines; [`TablePart::from_bytes`] reads them back.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = PART_MAGIC.to_vec();
        let (nc, n_out) = self.segments.first().map_or((0, 0), |a| (a.nc, a.n_out));
        out.extend_from_slice(&self.seed.to_le_bytes());
        for v in [
            self.rays,
            self.incident,
            self.first,
            self.segments.len(),
            nc,
            n_out,
        ] {
            out.extend_from_slice(&(v as u64).to_le_bytes());
        }
        for a in &self.segments {
            let st = &a.stats;
            for v in [
                st.rays,
                st.exits,
                st.absorbed,
                st.capped,
                st.leaked,
                st.horizon,
                st.hits,
                u64::from(st.max_order),
            ] {
                out.extend_from_slice(&v.to_le_bytes());
            }
            for v in [st.capped_energy, st.lost_energy] {
                out.extend_from_slice(&v.to_le_bytes());
            }
            for xs in [&a.sum, &a.sq, &a.alb, &a.alb_sq, &a.binned] {
                xs.iter()
                    .for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
            }
        }
        out
    }

    /// Reads [`TablePart::to_bytes`]'s bytes, checking their length against the
    /// header before anything is allocated.
    pub fn from_bytes(bytes: &[u8]) -> Result<TablePart, MicroError> {
        let bad = |why: &str| MicroError::invalid("part", why.to_string());
        let body = bytes
            .strip_prefix(PART_MAGIC.as_slice())
            .ok_or_else(|| bad("not a table part (or one of another format)"))?;
        let mut words = body.chunks_exact(8).map(|c| {
            let mut b = [0u8; 8];
            b.copy_from_slice(c);
            b
        });
        const HEADER: usize = 7;
        if !body.len().is_multiple_of(8) || body.len() < 8 * HEADER {
            return Err(bad("truncated"));
        }
        let seed = words.next().map_or(0, u64::from_le_bytes);
        let mut int = || -> Result<usize, MicroError> {
            let w = words.next().ok_or_else(|| bad("truncated"))?;
            usize::try_from(u64::from_le_bytes(w)).map_err(|_| bad("a count out of range"))
        };
        let (rays, incident, first, n_seg, nc, n_out) =
            (int()?, int()?, int()?, int()?, int()?, int()?);
        // Words a segment: 8 counts, 2 energies, then the sums (`TableAcc`).
        let (c, o, k) = (nc as u128, n_out as u128, n_seg as u128);
        let expected = (8 * c)
            .checked_mul(o)
            .and_then(|x| x.checked_add(9 * c + 10))
            .and_then(|x| x.checked_mul(k));
        if expected != Some((body.len() / 8 - HEADER) as u128) || nc == 0 {
            return Err(bad("its length does not match its header"));
        }
        // Past this point every count is bounded by the bytes there are.
        if rays > super::MAX_RAYS || first.saturating_add(n_seg) > segments(rays) {
            return Err(bad("its segments are not those of its ray count"));
        }
        let mut f64s = |n: usize| -> Vec<f64> {
            (0..n)
                .map(|_| words.next().map_or(0.0, f64::from_le_bytes))
                .collect()
        };
        let mut segments = Vec::with_capacity(n_seg);
        for _ in 0..n_seg {
            let head: Vec<u64> = f64s(8).into_iter().map(f64::to_bits).collect();
            let energies = f64s(2);
            // Counts a segment can hold: at most its rays, each ended one way, each
            // with at most `MAX_BOUNCES` hits; so no sum of them can overflow.
            let ends = head[1..6].iter().try_fold(0u64, |a, b| a.checked_add(*b));
            let max_bounces = u64::from(super::MAX_BOUNCES);
            if head[0] > SEGMENT_RAYS as u64
                || ends != Some(head[0])
                || head[6] > head[0] * max_bounces
                || head[7] > max_bounces
                || energies.iter().any(|e| !e.is_finite())
            {
                return Err(bad("a segment's ray counts are inconsistent"));
            }
            let stats = TraceStats {
                rays: head[0],
                exits: head[1],
                absorbed: head[2],
                capped: head[3],
                leaked: head[4],
                horizon: head[5],
                hits: head[6],
                max_order: head[7] as u32,
                capped_energy: energies[0],
                lost_energy: energies[1],
            };
            segments.push(TableAcc {
                nc,
                n_out,
                sum: f64s(4 * nc * n_out),
                sq: f64s(4 * nc * n_out),
                alb: f64s(4 * nc),
                alb_sq: f64s(4 * nc),
                binned: f64s(nc),
                stats,
            });
        }
        Ok(TablePart {
            seed,
            rays,
            incident,
            first,
            segments,
        })
    }

    /// Merges block `k` (counted from the part's first block) in block order.
    fn add_block(&mut self, k: usize, acc: TableAcc) {
        if k.is_multiple_of(SEGMENT_BLOCKS) {
            self.segments.push(acc);
        } else if let Some(last) = self.segments.last_mut() {
            last.merge(&acc);
        }
    }
}

/// The cells of outgoing directions around a grid's outgoing nodes.
struct OutCells {
    phi: Axis,
    /// `(cos lo, cos hi)` of each θo node's polar bounds.
    cos_bounds: Vec<(f64, f64)>,
    /// `Ω_proj` of each outgoing node, index `c·nθ + d`.
    omega: Vec<f64>,
    /// The polar cell at the lower end of each of `HINTS` equal steps of `cos θ`
    /// over `[0, 1]`: where [`OutCells::polar`]'s search starts.
    cos_hint: Vec<u32>,
    /// For a periodic azimuth axis of at least 4 nodes: the unit vectors of the
    /// cells' azimuth bounds, and where [`OutCells::azimuth_of`]'s search starts.
    phi_bounds: Option<PhiBounds>,
}

/// Steps of the lookup tables that start the cells' searches: small enough that a
/// step spans at most a few degrees, so the search moves by a cell at most.
const HINTS: usize = 512;

/// The azimuth bounds of a periodic axis as vectors, to find a direction's cell
/// without its angle.
struct PhiBounds {
    /// `(cos β, sin β)` of the upper bound `β_c = start + (c + ½)·step` of cell `c`.
    upper: Vec<(f64, f64)>,
    /// The cell of the lower end of each of `HINTS` equal steps of the
    /// pseudo-angle ([`pseudo_angle`], over `[0, 4)`).
    hint: Vec<u32>,
}

/// A cheap angle-like number of `(x, y)`, increasing with the azimuth over
/// `[0, 2π)` from 0 to 4 (the position along the unit diamond), without a
/// trigonometric call. Not 0 when both are.
#[inline]
fn pseudo_angle(x: f64, y: f64) -> f64 {
    let r = y / (x.abs() + y.abs());
    // 2 − r left of the y axis, 4 + r below the x axis on its right, r above:
    // without branches (the quadrant of a random exit is a coin toss).
    let (left, below) = (x < 0.0, y < 0.0);
    let offset = [0.0, 4.0, 2.0, 2.0][2 * usize::from(left) + usize::from(below)];
    let sign = 1.0 - 2.0 * f64::from(u8::from(left));
    offset + sign * r
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
        let cos_bounds: Vec<(f64, f64)> =
            bounds.iter().map(|(lo, hi)| (lo.cos(), hi.cos())).collect();
        let cos_hint = (0..HINTS)
            .map(|b| {
                let c = b as f64 / HINTS as f64;
                cos_bounds.partition_point(|&(_, c_hi)| c_hi > c) as u32
            })
            .collect();
        let mut cells = OutCells {
            phi: *phi,
            cos_bounds,
            omega,
            cos_hint,
            phi_bounds: None,
        };
        if phi.is_periodic() && phi.n >= 4 {
            let upper = (0..phi.n)
                .map(|c| {
                    let (s, co) = (phi.start + (c as f64 + 0.5) * phi.step).sin_cos();
                    (co, s)
                })
                .collect();
            // Each step's lower end, as a direction: the pseudo-angle's inverse.
            let hint = (0..HINTS)
                .map(|b| {
                    let p = 4.0 * b as f64 / HINTS as f64;
                    let (q, r) = (floor(p), p - floor(p));
                    let (x, y) = match q as u32 {
                        0 => (1.0 - r, r),
                        1 => (-r, 1.0 - r),
                        2 => (r - 1.0, -r),
                        _ => (r, r - 1.0),
                    };
                    let phi_b = {
                        let a = y.atan2(x);
                        if a < 0.0 { a + TAU } else { a }
                    };
                    cells.azimuth(phi_b).unwrap_or(0) as u32
                })
                .collect();
            cells.phi_bounds = Some(PhiBounds { upper, hint });
        }
        cells
    }

    /// The polar cell of `cos_theta`, if any: the first whose upper bound's cosine
    /// is at or below it (a search started from the lookup table, so one or two
    /// comparisons; the same answer as a binary search).
    #[inline]
    fn polar(&self, cos_theta: f64) -> Option<usize> {
        let n = self.cos_bounds.len();
        let b = ((cos_theta * HINTS as f64) as usize).min(HINTS - 1);
        let mut d = self.cos_hint[b] as usize;
        // The cells' upper bounds do not decrease, so their cosines do not increase:
        // `c_hi > cos θ` holds for a prefix of the cells, which ends at `d`.
        while d < n && self.cos_bounds[d].1 > cos_theta {
            d += 1;
        }
        while d > 0 && self.cos_bounds[d - 1].1 <= cos_theta {
            d -= 1;
        }
        let &(c_lo, _) = self.cos_bounds.get(d)?;
        if cos_theta.is_nan() || cos_theta > c_lo || self.omega[d] <= 0.0 {
            return None;
        }
        Some(d)
    }

    /// The azimuth cell of `phi` (radians), if any.
    fn azimuth(&self, phi: f64) -> Option<usize> {
        if self.phi.n == 1 {
            Some(0)
        } else if self.phi.is_periodic() {
            let k = floor((phi - self.phi.start) / self.phi.step + 0.5);
            Some(k.rem_euclid(self.phi.n as f64) as usize % self.phi.n)
        } else {
            for p in [phi, phi - TAU, phi + TAU] {
                let k = floor((p - self.phi.start) / self.phi.step + 0.5);
                if k >= 0.0 && k < self.phi.n as f64 {
                    return Some(k as usize);
                }
            }
            None
        }
    }

    /// The azimuth cell of the direction `(x, y)`: without its angle when the
    /// bounds are vectors (cell `c` holds the directions from bound `c − 1`, on
    /// it, to bound `c`, counter-clockwise: the cells of [`OutCells::azimuth`],
    /// up to the rounding of the bounds).
    #[inline]
    fn azimuth_of(&self, x: f64, y: f64) -> Option<usize> {
        // The angle's way (`Dir::phi`): straight up, not a number, or bounds that
        // are not vectors.
        let by_angle = || {
            let a = y.atan2(x);
            self.azimuth(if a < 0.0 { a + TAU } else { a })
        };
        let p = pseudo_angle(x, y);
        let Some(pb) = self.phi_bounds.as_ref().filter(|_| p >= 0.0) else {
            return by_angle();
        };
        let n = pb.upper.len();
        let b = ((p * (HINTS as f64 / 4.0)) as usize).min(HINTS - 1);
        let mut c = pb.hint[b] as usize;
        // At or past bound c (counter-clockwise, within half a turn): the next
        // cell. Before bound c − 1: the previous. A step of the table spans a few
        // degrees, a cell (at least 4 a turn) many, so one move at most; the
        // bound on the moves keeps it finite whatever the rounding.
        let past = |c: usize| {
            let (bc, bs) = pb.upper[c];
            bc * y - bs * x >= 0.0
        };
        for _ in 0..n {
            if past(c) {
                c = if c + 1 == n { 0 } else { c + 1 };
            } else if !past(if c == 0 { n - 1 } else { c - 1 }) {
                c = if c == 0 { n - 1 } else { c - 1 };
            } else {
                break;
            }
        }
        Some(c)
    }

    /// The outgoing node whose cell holds the direction of polar cosine `cos_theta`
    /// and azimuth `phi`, if any.
    fn locate(&self, cos_theta: f64, phi: f64) -> Option<usize> {
        let d = self.polar(cos_theta)?;
        let c = self.azimuth(phi)?;
        Some(c * self.cos_bounds.len() + d)
    }

    /// [`OutCells::locate`] of the unit direction `wo`, without an angle.
    #[inline]
    fn locate_dir(&self, wo: Vec3) -> Option<usize> {
        let d = self.polar(wo.z)?;
        let c = self.azimuth_of(wo.x, wo.y)?;
        Some(c * self.cos_bounds.len() + d)
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
        assert_eq!(cells.locate(0.01f64.cos(), 0.0), Some(0));
        assert_eq!(cells.locate(0.01f64.cos(), TAU - 0.01), Some(0));
        assert_eq!(cells.locate(0.2f64.cos(), 14f64.to_radians()), Some(9 + 1));
        // Nodes 0°..80° every 10°: the last cell stops at 85°.
        let cells = OutCells::new(&Axis::single(0.0), &Axis::from_deg(0.0, 10.0, 9));
        assert_eq!(cells.locate(86f64.to_radians().cos(), 1.0), None);
        assert_eq!(cells.locate(84f64.to_radians().cos(), 1.0), Some(8));
        assert_eq!(cells.locate(4f64.to_radians().cos(), 1.0), Some(0));
    }

    /// Without angles, the cells of directions are those of their angles: on
    /// random directions and on directions a hair either side of every bound.
    #[test]
    fn cells_of_directions_are_those_of_their_angles() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for (phi, theta) in [
            (Axis::full_turn(24), Axis::from_deg(0.0, 10.0, 9)),
            (Axis::from_deg(7.5, 15.0, 24), Axis::polar_midpoints(9)),
            (Axis::full_turn(5), Axis::from_deg(0.0, 3.6, 26)),
            (Axis::from_deg(0.0, 30.0, 3), Axis::single(0.5)),
            (Axis::single(0.0), Axis::from_deg(0.0, 10.0, 9)),
        ] {
            let cells = OutCells::new(&phi, &theta);
            let check = |v: Vec3| {
                let d = Dir::from_unit(v);
                assert_eq!(
                    cells.locate_dir(v),
                    cells.locate(d.z, d.phi()),
                    "{phi:?} {theta:?} {v:?}"
                );
            };
            for _ in 0..20_000 {
                let z: f64 = rng.random();
                let a = TAU * rng.random::<f64>();
                let s = (1.0 - z * z).sqrt();
                check(Vec3::new(s * a.cos(), s * a.sin(), z));
            }
            for c in 0..phi.n {
                for eps in [-1e-9, 1e-9] {
                    let a = phi.start + (c as f64 + 0.5) * phi.step + eps;
                    check(Vec3::new(0.6 * a.cos(), 0.6 * a.sin(), 0.8));
                }
            }
            check(Vec3::new(0.0, 0.0, 1.0));
            check(Vec3::new(1.0, 0.0, 0.0));
        }
    }
}
