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

mod rays;
mod sh;
mod table;

pub use table::{SEGMENT_BLOCKS, SEGMENT_RAYS, TablePart, segments};

use gonio_core::{Dir, Vec3};
use gonio_process::Table;
use gonio_process::sh::ShBrdf;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use crate::escape::Escape;
use crate::heightfield::Divisor;
use crate::material::{Scratch, uniform};
use crate::trace::{Method, Plan, Ray, Tracer, floor};
use crate::{MicroError, Sample};
use rays::{KeyRng, Rect, SegmentOrder};

/// Rays a block: the unit of work a thread takes. A block's rays and their random
/// streams depend on the seed and their indices alone (module `rays`), so results do
/// not depend on how blocks are spread over threads.
pub const BLOCK: usize = 1024;
/// The most rays a simulation may trace per incident direction of a table, or in all
/// for a spherical-harmonic estimate: 10⁹, hours of tracing at the default
/// hundred thousand's pace of a second or so. More is refused, not left to run for
/// days (or forever, as 2⁶⁴ − 1 would).
pub const MAX_RAYS: usize = 1_000_000_000;

/// The most bounces a ray may be followed through (`max_bounces`): 10⁴. The default
/// 100 already leaves less than 10⁻¹⁰ of the energy on any realistic surface.
pub const MAX_BOUNCES: u32 = 10_000;

/// Checks a ray count against `2..=MAX_RAYS`.
pub(crate) fn check_rays(rays: usize) -> Result<(), MicroError> {
    gonio_core::limits::count(rays as u64, 2, MAX_RAYS as u64, "rays")
        .map(|_| ())
        .map_err(|m| MicroError::invalid("rays", m))
}

/// The bounce orders reported separately: 1, 2 and 3 or more.
pub const ORDERS: [&str; 3] = ["1", "2", "3+"];

const PURPOSE_TRACE: u64 = 1;
const PURPOSE_TABLE: u64 = 2;
const PURPOSE_SH: u64 = 3;

/// Runs `task(k)` for `k` in `0..n` on every thread of the current rayon pool and
/// hands the results to `merge` in order of `k`, whatever the number of threads. A
/// raised `cancel` flag stops it before the next task: [`MicroError::Cancelled`].
///
/// There are no rounds: each worker takes the next `k`, runs it, and files the
/// result; whoever files the one `merge` waits for merges it and every result
/// queued behind it. So no worker idles at a barrier while the slowest task of a
/// round finishes, and the merging runs beside the tracing instead of between it.
/// The queue holds only the results that finished before an earlier one: about
/// one per thread.
fn run_ordered<A: Send>(
    n: usize,
    cancel: Option<&AtomicBool>,
    task: impl Fn(usize) -> A + Sync,
    merge: impl FnMut(usize, A) + Send,
) -> Result<(), MicroError> {
    struct Queue<A, M> {
        next: usize,
        done: BTreeMap<usize, A>,
        merge: M,
    }
    let queue = Mutex::new(Queue {
        next: 0,
        done: BTreeMap::new(),
        merge,
    });
    let handed = AtomicUsize::new(0);
    let stopped = AtomicBool::new(false);
    let worker = || {
        loop {
            if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                stopped.store(true, Ordering::Relaxed);
                return;
            }
            let k = handed.fetch_add(1, Ordering::Relaxed);
            if k >= n {
                return;
            }
            let a = task(k);
            // A panicking merge poisons the lock; the panic itself reaches the caller
            // through rayon, so the poison carries no new information.
            let mut q = queue.lock().unwrap_or_else(|e| e.into_inner());
            let q = &mut *q;
            q.done.insert(k, a);
            while let Some(a) = q.done.remove(&q.next) {
                (q.merge)(q.next, a);
                q.next += 1;
            }
        }
    };
    let threads = rayon::current_num_threads().clamp(1, n.max(1));
    rayon::scope(|s| {
        for _ in 0..threads {
            s.spawn(|_| worker());
        }
    });
    if stopped.load(Ordering::Relaxed) {
        return Err(MicroError::Cancelled);
    }
    Ok(())
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
    /// The patch's periods as divisors (a path folds its origin back at every bounce).
    period: (Divisor, Divisor),
    /// Which rays leaving a facet certainly escape (no search needed).
    escape: Escape,
    cancel: Option<Arc<AtomicBool>>,
}

impl Simulation {
    /// Prepares `sample` (checks it again — its fields are public — and builds the
    /// max-mip hierarchy).
    pub fn new(sample: Sample, opts: SimOptions) -> Result<Simulation, MicroError> {
        gonio_core::limits::count(opts.max_bounces.into(), 1, MAX_BOUNCES.into(), "bounces")
            .map_err(|m| MicroError::invalid("max_bounces", m))?;
        let sample = Sample::new(
            sample.channels,
            sample.surface,
            sample.materials,
            sample.orientation,
        )?;
        let tracer = Tracer::new(sample.surface.clone());
        let eps = 1e-9 * sample.surface.dx().min(sample.surface.dy());
        let (lx, ly) = sample.surface.period();
        let period = (Divisor::new(lx), Divisor::new(ly));
        let escape = Escape::new(&sample.surface);
        Ok(Simulation {
            tracer,
            sample,
            opts,
            eps,
            period,
            escape,
            cancel: None,
        })
    }

    /// Stops any tracing of this simulation, between rounds of blocks, once `flag`
    /// is raised (another thread's Ctrl-C): it then fails with
    /// [`MicroError::Cancelled`].
    pub fn cancel_on(&mut self, flag: Arc<AtomicBool>) {
        self.cancel = Some(flag);
    }

    /// The cancel flag, if any.
    fn cancel_flag(&self) -> Option<&AtomicBool> {
        self.cancel.as_deref()
    }

    /// The sample.
    pub fn sample(&self) -> &Sample {
        &self.sample
    }

    /// The tracer (for benchmarks and tests of the intersection methods).
    pub fn tracer(&self) -> &Tracer {
        &self.tracer
    }

    /// Block `b`'s rays among the `rays` rays of incident node `inc` (0 where there
    /// is one): each one's start, a uniform point of the plane `z = h_max` over the
    /// patch, and its own random stream, drawn in the spatial order of its segment
    /// (module `rays`).
    fn block_rays(
        &self,
        seed: u64,
        purpose: u64,
        inc: usize,
        rays: usize,
        b: usize,
    ) -> Vec<(Vec3, KeyRng)> {
        let seg = b / SEGMENT_BLOCKS;
        let n_seg = SEGMENT_RAYS.min(rays - seg * SEGMENT_RAYS);
        let first = (b % SEGMENT_BLOCKS) * BLOCK;
        let end = (first + BLOCK).min(n_seg);
        let hf = self.tracer.surface();
        let (lx, ly) = hf.period();
        let order = SegmentOrder {
            key: [seed, purpose, inc as u64, seg as u64],
            n: n_seg as u64,
            patch: Rect {
                x0: 0.0,
                y0: 0.0,
                w: lx,
                h: ly,
            },
        };
        let base = (seg * SEGMENT_RAYS) as u64;
        // Every ray's key starts with these three words: chained once.
        let prefix = KeyRng::new(&[seed, purpose, inc as u64]);
        let mut out = Vec::with_capacity(end - first);
        order.visit(first as u64..end as u64, &mut |k, leaf| {
            let mut rng = prefix.then(&[base + k]);
            let (x, y) = leaf.at(uniform(&mut rng), uniform(&mut rng));
            out.push((Vec3::new(x, y, hf.max_height()), rng));
        });
        out
    }

    /// The plan of the first search of every path from the plane `z = h_max`
    /// towards `−wi_s` (they share it: [`Tracer::plan`]).
    fn primary_plan(&self, wi_s: Vec3) -> Option<Plan> {
        let ray = Ray {
            o: Vec3::new(0.0, 0.0, self.tracer.surface().max_height()),
            d: -wi_s,
            t_min: 0.0,
            skip: None,
        };
        self.tracer.plan(&ray, self.opts.method)
    }

    /// Traces one path from `o` (a [`Simulation::start`]) towards `−wi_s` (surface
    /// frame), whose first search is `plan0` when given (the
    /// [`Simulation::primary_plan`] of `wi_s`). `w` starts at 1 and ends as the
    /// energy carried out; returns how it ended, its bounces and last direction.
    #[allow(clippy::too_many_arguments)]
    fn path(
        &self,
        o: Vec3,
        wi_s: Vec3,
        plan0: Option<Option<Plan>>,
        rng: &mut KeyRng,
        w: &mut [f64],
        scratch: &mut Scratch,
    ) -> (End, u32, Vec3) {
        let hf = self.tracer.surface();
        let (lx, ly) = hf.period();
        let (nx, ny) = (hf.nx() as i64, hf.ny() as i64);
        w.fill(1.0);
        let mut o = o;
        let mut d = -wi_s;
        let mut ray_skip = None;
        let mut t_min = 0.0;
        let mut bounces = 0u32;
        let mut plan0 = plan0;
        // The escape bound of the cell the ray leaves (none for the first search).
        let mut leaving: Option<[u8; 4]> = None;
        loop {
            let ray = Ray {
                o,
                d,
                t_min,
                skip: ray_skip,
            };
            let plan = match plan0.take() {
                Some(p) => p,
                None => self.tracer.plan(&ray, self.opts.method),
            };
            // A ray leaving a facet more steeply than anything around can rise
            // escapes: the search would find nothing (module `escape`).
            if let (Some(codes), Some(p)) = (leaving, plan)
                && !p.horizon()
                && self.escape.clears(codes, d)
            {
                return (End::Exit, bounces, d);
            }
            let h = match self.tracer.first_hit_planned(&ray, plan, self.opts.method) {
                Ok(h) => h,
                Err(cut_off) => {
                    let end = if cut_off {
                        End::Horizon
                    } else if d.z > 0.0 {
                        End::Exit
                    } else {
                        End::Leaked
                    };
                    return (end, bounces, d);
                }
            };
            if bounces == self.opts.max_bounces {
                return (End::Capped, bounces, d);
            }
            bounces += 1;
            // Read now, so that the load overlaps the shading below.
            leaving = Some(self.escape.codes(h.cell[0], h.cell[1]));
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
            let kx = floor(self.period.0.div(p.x));
            let ky = floor(self.period.1.div(p.y));
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
            self.cancel_flag(),
            |b| {
                let mut w = vec![0.0; nc];
                let mut scratch = Scratch::new(nc);
                let mut out = (Vec::new(), Vec::new(), Vec::new(), TraceStats::default());
                let plan0 = self.primary_plan(wi_s);
                for (o, mut rng) in self.block_rays(seed, PURPOSE_TRACE, 0, n_rays, b) {
                    let (end, k, d) =
                        self.path(o, wi_s, Some(plan0), &mut rng, &mut w, &mut scratch);
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
        )?;
        Ok(ex)
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
