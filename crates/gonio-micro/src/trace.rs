//! Ray–height-field intersection: a max-mip hierarchy traversed by a hierarchical 2D
//! DDA with periodic wrapping, a flat grid DDA, and brute force over every cell (the
//! benchmark baseline and the test oracle). All three share one cell test, so they
//! agree to the last bit on the cell, the triangle and `t` of a hit.
//!
//! # Cell test
//! Within a cell the ray's parameter range `[t_lo, t_hi]` is cut by the diagonal into
//! at most two pieces, each over one planar triangle. On a piece the vertical gap
//! `g(t) = z(t) − h(x(t), y(t))` is linear; the ray hits where `g` first drops to 0.
//! A ray that enters a piece already at or below the surface (`g ≤ 0` at its start,
//! which only rounding at a shared edge can cause) hits at the entry, so no ray slips
//! through a crack between cells.
//!
//! # Max-mip
//! Level 0 holds the highest corner of every cell; each level above merges 2 × 2 (or
//! 2 × 1, along an axis whose block count is still even) blocks of the one below. A
//! block is skipped when the ray's lowest height over the block's parameter range is
//! above the block's maximum. The traversal keeps integer block coordinates in the
//! unwrapped plane (the patch repeats; lookups wrap), descends into the child the ray
//! is in, steps to the next block across the nearer boundary, and climbs one level
//! when a step leaves the parent block while the ray is above the new parent's
//! maximum (below it the parent could not be skipped). The maxima are stored as `f32`
//! rounded up (plus a hair for the traversal's rounding): a bound stays a bound, the
//! cell test itself is exact `f64`.

use gonio_core::Vec3;

use crate::HeightField;
use crate::heightfield::{exact_inverse, wrap};

/// How [`Tracer::first_hit`] searches for the first hit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// The max-mip hierarchy.
    MaxMip,
    /// A flat 2D DDA over the cells (the hierarchy's level 0 only).
    Grid,
    /// Every cell of every copy of the patch that the ray's bounding box meets.
    BruteForce,
}

/// A ray in the surface frame, with what to ignore near its origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin.
    pub o: Vec3,
    /// Direction, unit length.
    pub d: Vec3,
    /// Hits at `t < t_min` are ignored (a small positive value after a bounce).
    pub t_min: f64,
    /// The triangle the ray leaves from, `(cell x, cell y, tri)` in unwrapped cell
    /// coordinates: never reported as a hit (a planar facet cannot be hit twice in a
    /// row; its copies in other tiles can).
    pub skip: Option<(i64, i64, u8)>,
}

/// The first intersection of a ray with the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit.
    pub t: f64,
    /// Unwrapped cell coordinates.
    pub cell: [i64; 2],
    /// Triangle of the cell (0: `u ≥ v`, 1: `u ≤ v`).
    pub tri: u8,
}

#[derive(Clone, Debug, PartialEq)]
struct Level {
    /// Cells per block along x and y.
    bx: usize,
    by: usize,
    /// Block widths along x and y (`bx·dx`, `by·dy`).
    wx: f64,
    wy: f64,
    /// `1/wx` and `1/wy` where they are exact (the widths powers of two).
    inv_wx: Option<f64>,
    inv_wy: Option<f64>,
    /// How far block coordinates shift right to give the parent's (0 or 1 each
    /// way: a level merges 2 × 2, 2 × 1 or 1 × 2 blocks).
    up_x: u32,
    up_y: u32,
    /// Blocks along x and y.
    nbx: usize,
    nby: usize,
    /// `nbx − 1` and `nby − 1` when the counts are powers of two (wrapping is then
    /// a mask), else `None`.
    mask_x: Option<i64>,
    mask_y: Option<i64>,
    /// Highest corner of each block, raised by a hair (see `Tracer::new`) and
    /// rounded up to `f32` (half the bytes for the cache: the lookups are what a
    /// traversal waits for), row-major.
    max: Vec<f32>,
}

impl Level {
    /// The maximum of block `(bx, by)`, wrapped onto the patch.
    #[inline(always)]
    fn max_at(&self, bx: i64, by: i64) -> f64 {
        let i = match self.mask_x {
            Some(m) => (bx & m) as usize,
            None => bx.rem_euclid(self.nbx as i64) as usize,
        };
        let j = match self.mask_y {
            Some(m) => (by & m) as usize,
            None => by.rem_euclid(self.nby as i64) as usize,
        };
        f64::from(self.max[j * self.nbx + i])
    }
}

/// One level as the power-of-two traversal ([`Tracer::traverse_fast`]) reads it:
/// plain numbers only, no `Option` to test in the loop, and a row found by a shift.
#[derive(Clone, Copy, Debug, PartialEq)]
struct FastLevel {
    /// Block widths along x and y.
    wx: f64,
    wy: f64,
    /// `1/wx` and `1/wy` (exact: the widths are powers of two).
    inv_wx: f64,
    inv_wy: f64,
    /// `nbx − 1` and `nby − 1` (the counts are powers of two).
    mask_x: i64,
    mask_y: i64,
    /// `log2 nbx`: a row starts at `by << shift`.
    shift: u32,
    /// As `Level::up_x`, `Level::up_y`.
    up_x: u32,
    up_y: u32,
    /// Where the level's maxima start in `Tracer::maxima`.
    off: usize,
}

/// A height field with its max-mip hierarchy, ready to intersect rays.
#[derive(Clone, Debug, PartialEq)]
pub struct Tracer {
    hf: HeightField,
    levels: Vec<Level>,
    /// Length of a horizontal ray's search before it counts as leaving at the horizon.
    horizon: f64,
    /// `1/dx`, `1/dy`.
    inv_dx: f64,
    inv_dy: f64,
    /// Every level's block counts are powers of two and its widths have exact
    /// inverses: the traversal wraps by masks and divides by multiplications.
    fast: bool,
    /// When `fast`, the levels for [`Tracer::traverse_fast`], bottom up, and one more
    /// above the top: a parent whose single maximum is +∞, so that the top level's
    /// climb test fails without a test of the level.
    fast_levels: Vec<FastLevel>,
    /// When `fast`, the maxima (as `Level::max`) of every level but the first, one
    /// after the other, and the +∞ of the level above the top. Level 0's are worked
    /// out from the cell's corners, which its cell test reads anyway: a ray then
    /// waits for one array rather than two that no cache holds.
    maxima: Vec<f32>,
    /// What every maximum is raised by (see `Tracer::new`).
    hair: f64,
}

/// Where a search runs (see [`Tracer::plan`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Plan {
    t0: f64,
    t1: f64,
    horizon: bool,
    start: usize,
}

impl Plan {
    /// Whether the search is cut off at the horizon ([`Tracer::span`]'s flag).
    pub(crate) fn horizon(&self) -> bool {
        self.horizon
    }
}

/// What every cell test of one ray shares, worked out once a ray.
#[derive(Clone, Copy, Debug)]
struct Pre {
    o: Vec3,
    d: Vec3,
    /// `1/d.x`, `1/d.y` (infinite along an axis the ray does not move on).
    inv_x: f64,
    inv_y: f64,
    /// The direction in cell units: `d.x/dx`, `d.y/dy`.
    du: f64,
    dv: f64,
    /// The ray's `skip` triangle, or a triangle number no cell has.
    skip: (i64, i64, u8),
}

/// `floor(p / size)`, but the lower block when `p` lies on a boundary and the ray
/// moves towards −: the block the ray is about to cross.
///
/// `inv` is `1/size` when that is exact (`size` a power of two): a multiplication
/// then gives the quotient's very bits, without a division's latency on the
/// traversal's path.
#[inline]
fn coord(p: f64, d: f64, size: f64, inv: Option<f64>) -> i64 {
    let u = match inv {
        Some(inv) => p * inv,
        None => p / size,
    };
    let f = floor(u);
    if d < 0.0 && u == f {
        f as i64 - 1
    } else {
        f as i64
    }
}

/// `x.floor()`, exactly, without a call: the baseline x86-64 target has no rounding
/// instruction, and std's `floor` was a libm call costing 4 % of a table's time.
/// Below 2⁵² in magnitude the truncation to an integer is exact, and one less than
/// it is the floor of a negative non-integer; beyond, every `f64` is an integer (or
/// infinite, or NaN) and its own floor.
#[inline]
pub(crate) fn floor(x: f64) -> f64 {
    if x.abs() < 4_503_599_627_370_496.0 {
        let t = x as i64 as f64;
        if t > x { t - 1.0 } else { t }
    } else {
        x
    }
}

/// The least `l ≥ 0` with `4·2^l ≥ cells` (finite, not negative), from the
/// exponent of `cells/4` rather than a loop over levels.
#[inline]
fn start_level(cells: f64) -> usize {
    if cells <= 4.0 {
        return 0;
    }
    // `cells/4` is exact and at least 1: its exponent, one more unless it is a
    // power of two.
    let bits = (0.25 * cells).to_bits();
    let e = ((bits >> 52) & 0x7ff) as usize - 1023;
    if bits & ((1u64 << 52) - 1) == 0 {
        e
    } else {
        e + 1
    }
}

/// The least `f32` at or above `x` (a height bound stays a bound).
fn round_up(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) < x { y.next_up() } else { y }
}

/// Narrows `[lo, hi]` to the parameters where `o + t·d` lies within `[a, b]`;
/// `inv` is `1/d`.
#[inline]
fn slab(o: f64, d: f64, inv: f64, a: f64, b: f64, lo: &mut f64, hi: &mut f64) -> bool {
    if d == 0.0 {
        return o >= a && o <= b;
    }
    let (t0, t1) = ((a - o) * inv, (b - o) * inv);
    let (t0, t1) = if d > 0.0 { (t0, t1) } else { (t1, t0) };
    // Plain comparisons: `lo` and `hi` are never NaN, and a NaN bound (a ray along
    // the slab's face) leaves them as `f64::max` and `f64::min` would, without
    // their NaN tests.
    *lo = if t0 > *lo { t0 } else { *lo };
    *hi = if t1 < *hi { t1 } else { *hi };
    true
}

/// The highest of a cell's corners (finite heights: plain comparisons).
#[inline(always)]
fn highest(c: [f64; 4]) -> f64 {
    let a = if c[1] > c[0] { c[1] } else { c[0] };
    let b = if c[3] > c[2] { c[3] } else { c[2] };
    if b > a { b } else { a }
}

/// The first hit of the piece `[ta, tb]` of a ray's range in cell `(ix, iy)` over
/// triangle `tri`, the cell's corners `c`, `(ou, ov)` the ray's origin in the cell's
/// units (see `Tracer::cell_hit`). A function rather than a closure, so that it is
/// inlined into every copy of the fast loop.
#[inline(always)]
fn piece(
    pre: &Pre,
    c: [f64; 4],
    (ix, iy): (i64, i64),
    (ou, ov): (f64, f64),
    ta: f64,
    tb: f64,
    tri: u8,
) -> Option<Hit> {
    let (o, d, du, dv) = (pre.o, pre.d, pre.du, pre.dv);
    if ix == pre.skip.0 && iy == pre.skip.1 && tri == pre.skip.2 {
        return None;
    }
    let (a, b) = HeightField::tri_slopes(c, tri);
    let g0 = o.z - c[0] - a * ou - b * ov;
    let k = d.z - a * du - b * dv;
    let t = if g0 + k * ta <= 0.0 {
        ta
    } else if g0 + k * tb <= 0.0 {
        (-g0 / k).clamp(ta, tb)
    } else {
        return None;
    };
    Some(Hit {
        t,
        cell: [ix, iy],
        tri,
    })
}

impl Tracer {
    /// Builds the max-mip hierarchy of `hf`.
    pub fn new(hf: HeightField) -> Tracer {
        let (nx, ny) = (hf.nx(), hf.ny());
        let (dx, dy) = (hf.dx(), hf.dy());
        // Every maximum is raised by a hair above the rounding of the traversal's
        // parameters, so that a block whose highest corner the ray grazes at its
        // edge is never skipped for an error in the last bit.
        let hair = 1e-12 * (hf.max_height().abs().max(hf.min_height().abs()) + dx + dy);
        let mut max = Vec::with_capacity(nx * ny);
        for j in 0..ny {
            for i in 0..nx {
                let c = hf.corners(i, j);
                max.push(round_up(c[0].max(c[1]).max(c[2]).max(c[3]) + hair));
            }
        }
        let level = |bx: usize, by: usize, nbx: usize, nby: usize, max: Vec<f32>| Level {
            bx,
            by,
            wx: bx as f64 * dx,
            wy: by as f64 * dy,
            inv_wx: exact_inverse(bx as f64 * dx),
            inv_wy: exact_inverse(by as f64 * dy),
            up_x: 0,
            up_y: 0,
            nbx,
            nby,
            mask_x: nbx.is_power_of_two().then_some(nbx as i64 - 1),
            mask_y: nby.is_power_of_two().then_some(nby as i64 - 1),
            max,
        };
        let mut levels = vec![level(1, 1, nx, ny, max)];
        while let Some(last) = levels.last_mut() {
            let mx = last.nbx >= 2 && last.nbx % 2 == 0;
            let my = last.nby >= 2 && last.nby % 2 == 0;
            if !mx && !my {
                break;
            }
            last.up_x = u32::from(mx);
            last.up_y = u32::from(my);
            let (fx, fy) = (if mx { 2 } else { 1 }, if my { 2 } else { 1 });
            let (nbx, nby) = (last.nbx / fx, last.nby / fy);
            let mut m = vec![f32::NEG_INFINITY; nbx * nby];
            for j in 0..last.nby {
                for i in 0..last.nbx {
                    let k = (j / fy) * nbx + i / fx;
                    m[k] = m[k].max(last.max[j * last.nbx + i]);
                }
            }
            let next = level(last.bx * fx, last.by * fy, nbx, nby, m);
            levels.push(next);
        }
        let (lx, ly) = hf.period();
        let fast = levels.iter().all(|l| {
            l.mask_x.is_some() && l.mask_y.is_some() && l.inv_wx.is_some() && l.inv_wy.is_some()
        });
        let mut fast_levels = Vec::new();
        let mut maxima = Vec::new();
        if fast {
            for l in &levels {
                fast_levels.push(FastLevel {
                    wx: l.wx,
                    wy: l.wy,
                    inv_wx: l.inv_wx.unwrap_or(f64::NAN),
                    inv_wy: l.inv_wy.unwrap_or(f64::NAN),
                    mask_x: l.mask_x.unwrap_or(0),
                    mask_y: l.mask_y.unwrap_or(0),
                    shift: l.nbx.trailing_zeros(),
                    up_x: l.up_x,
                    up_y: l.up_y,
                    off: maxima.len(),
                });
                if l.bx * l.by > 1 {
                    maxima.extend_from_slice(&l.max);
                }
            }
            if let Some(&top) = fast_levels.last() {
                fast_levels.push(FastLevel {
                    mask_x: 0,
                    mask_y: 0,
                    shift: 0,
                    up_x: 0,
                    up_y: 0,
                    off: maxima.len(),
                    ..top
                });
                maxima.push(f32::INFINITY);
            }
        }
        Tracer {
            fast,
            fast_levels,
            maxima,
            hair,
            // Long enough for any ray steeper than ~1e-4 rad to cross the height range.
            horizon: (16.0 * (lx + ly))
                .max(1e4 * (hf.max_height() - hf.min_height() + hf.dx() + hf.dy())),
            inv_dx: 1.0 / dx,
            inv_dy: 1.0 / dy,
            hf,
            levels,
        }
    }

    /// The height field.
    pub fn surface(&self) -> &HeightField {
        &self.hf
    }

    /// Number of levels of the hierarchy (1 for a flat grid).
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    /// The parameter range in which `ray` can meet the surface; `None` when it cannot
    /// (it points up from above the highest node). The range is cut off after a
    /// search length of 16 patch perimeters or 10⁴ times the height range plus the
    /// spacings, whichever is longer; `horizon` is true when it was (rays within
    /// ~1e-4 rad of horizontal, which could otherwise travel for ever along a
    /// groove).
    pub fn span(&self, ray: &Ray) -> Option<(f64, f64, bool)> {
        let (o, d) = (ray.o, ray.d);
        let (h_min, h_max) = (self.hf.min_height(), self.hf.max_height());
        let mut lo = ray.t_min;
        let mut hi;
        if d.z > 0.0 {
            if o.z >= h_max {
                return None;
            }
            hi = (h_max - o.z) / d.z;
        } else if d.z < 0.0 {
            if o.z > h_max {
                lo = lo.max((h_max - o.z) / d.z);
            }
            // The surface lies above h_min: the hit comes before the ray passes it (a
            // small margin keeps a hit exactly at the lowest node).
            let t = (h_min - o.z) / d.z;
            hi = t + 1e-9 * (t.abs() + self.hf.dx() + self.hf.dy());
        } else {
            if o.z > h_max {
                return None;
            }
            hi = f64::INFINITY;
        }
        let mut horizon = false;
        if hi - lo > self.horizon || (hi - lo).is_nan() {
            hi = lo + self.horizon;
            horizon = true;
        }
        (lo <= hi).then_some((lo, hi, horizon))
    }

    /// The first hit of `ray` on the surface, found by `method`; `None` when the ray
    /// leaves (or, for a horizontal ray, travels the search length without a hit).
    pub fn first_hit(&self, ray: &Ray, method: Method) -> Option<Hit> {
        self.first_hit_or_horizon(ray, method).ok()
    }

    /// [`Tracer::first_hit`], or why there is none: `Err(true)` when the search
    /// was cut off at the horizon (the `span`'s flag, without working it out again).
    pub(crate) fn first_hit_or_horizon(&self, ray: &Ray, method: Method) -> Result<Hit, bool> {
        self.first_hit_planned(ray, self.plan(ray, method), method)
    }

    /// Where `method` searches along `ray`: its span and the max-mip level it
    /// starts at; `None` when it cannot meet the surface. A function of the ray's
    /// height, direction and `t_min` alone, so rays that share them (a table's
    /// primary rays) share their plan.
    pub(crate) fn plan(&self, ray: &Ray, method: Method) -> Option<Plan> {
        let (t0, t1, horizon) = self.span(ray)?;
        let top = self.levels.len() - 1;
        let start = if method == Method::MaxMip {
            // Start at the level whose blocks are as wide as the ray's horizontal
            // travel, not at the top: most rays meet the surface within a few
            // cells, and descending ten levels would cost more than it saves.
            let (d, span) = (ray.d, t1 - t0);
            let cells = (d.x.abs() * span * self.inv_dx).max(d.y.abs() * span * self.inv_dy);
            if cells.is_finite() {
                start_level(cells).min(top)
            } else {
                top
            }
        } else {
            0
        };
        Some(Plan {
            t0,
            t1,
            horizon,
            start,
        })
    }

    /// [`Tracer::first_hit_or_horizon`] with the ray's [`Tracer::plan`].
    #[inline]
    pub(crate) fn first_hit_planned(
        &self,
        ray: &Ray,
        plan: Option<Plan>,
        method: Method,
    ) -> Result<Hit, bool> {
        let p = plan.ok_or(false)?;
        let hit = match method {
            Method::MaxMip => self.traverse(ray, p.t0, p.t1, p.start, self.levels.len() - 1),
            Method::Grid => self.traverse(ray, p.t0, p.t1, 0, 0),
            Method::BruteForce => self.brute(ray, p.t0, p.t1),
        };
        hit.ok_or(p.horizon)
    }

    fn pre(&self, ray: &Ray) -> Pre {
        let (o, d) = (ray.o, ray.d);
        Pre {
            o,
            d,
            inv_x: 1.0 / d.x,
            inv_y: 1.0 / d.y,
            du: d.x * self.inv_dx,
            dv: d.y * self.inv_dy,
            skip: ray.skip.unwrap_or((0, 0, u8::MAX)),
        }
    }

    /// The hierarchical DDA, starting at level `start` and climbing up to `top`: on
    /// the power-of-two patches (`fast`), up to the top level, one of the loops of
    /// [`Tracer::traverse_fast`]; else [`Tracer::traverse_in`], with remainders and
    /// divisions. Both visit the blocks in the ray's order and skip only blocks the
    /// ray passes above, so they find the same hit (the cell test decides it).
    fn traverse(&self, ray: &Ray, t0: f64, t1: f64, start: usize, top: usize) -> Option<Hit> {
        if self.fast && top + 1 == self.levels.len() {
            // One loop a quadrant of directions: the signs are constants, and fewer
            // values compete for registers. A ray along an axis takes the general
            // path (the same hit: see `traverse_fast`).
            let d = ray.d;
            match (d.x > 0.0, d.x < 0.0, d.y > 0.0, d.y < 0.0) {
                (true, _, true, _) => self.traverse_fast::<true, true>(ray, t0, t1, start),
                (true, _, _, true) => self.traverse_fast::<true, false>(ray, t0, t1, start),
                (_, true, true, _) => self.traverse_fast::<false, true>(ray, t0, t1, start),
                (_, true, _, true) => self.traverse_fast::<false, false>(ray, t0, t1, start),
                _ => self.traverse_in(ray, t0, t1, start, top),
            }
        } else {
            // The flat grid (a benchmark and a test oracle), and the other patches:
            // the general path, so that the fast cell test has the fast loops alone
            // as callers and is inlined into them.
            self.traverse_in(ray, t0, t1, start, top)
        }
    }

    /// The hierarchical DDA of [`Tracer::traverse_in`] up to the top level, for the
    /// power-of-two patches (`fast`) and a ray moving towards `+x` when `PX` (else
    /// `−x`) and `+y` when `PY`, read from [`FastLevel`]s and one flat array of
    /// maxima. It makes `traverse_in`'s decisions from the same numbers, but at
    /// level 0: there the bound is the cell's highest corner plus the hair in `f64`,
    /// a hair tighter than the `f32` one and still a bound (the hit is the same).
    #[inline(always)]
    fn traverse_fast<const PX: bool, const PY: bool>(
        &self,
        ray: &Ray,
        t0: f64,
        t1: f64,
        start: usize,
    ) -> Option<Hit> {
        let pre = self.pre(ray);
        let (o, d) = (ray.o, ray.d);
        let levels = &self.fast_levels[..];
        let maxima = &self.maxima[..];
        let hf = &self.hf;
        let (mask_x, mask_y) = (hf.nx() - 1, hf.ny() - 1);
        let (sx, sy): (i64, i64) = (if PX { 1 } else { -1 }, if PY { 1 } else { -1 });
        // The boundary ahead of block b is that of block b + 1 when moving up.
        let (ax, ay) = (i64::from(PX), i64::from(PY));
        let at = |lev: &FastLevel, bx: i64, by: i64| -> f64 {
            let i = (bx & lev.mask_x) as usize;
            let j = (by & lev.mask_y) as usize;
            f64::from(maxima[lev.off + (j << lev.shift) + i])
        };
        let mut l = start;
        let mut t = t0;
        let mut z = o.z + d.z * t;
        let (mut bx, mut by) = {
            let lev = &levels[l];
            (
                coord(o.x + d.x * t, d.x, lev.wx, Some(lev.inv_wx)),
                coord(o.y + d.y * t, d.y, lev.wy, Some(lev.inv_wy)),
            )
        };
        // The boundaries ahead, `(b + a)·w`, carried as floats (exact: integers
        // times powers of two): a step's parameter then waits for a subtraction and
        // a multiplication, not a conversion from the integers first.
        let (mut fx, mut fy) = {
            let lev = &levels[l];
            ((bx + ax) as f64 * lev.wx, (by + ay) as f64 * lev.wy)
        };
        loop {
            let lev = &levels[l];
            let tx = (fx - o.x) * pre.inv_x;
            let ty = (fy - o.y) * pre.inv_y;
            // No NaN anywhere: plain comparisons rather than `f64::min`'s.
            let t_xy = if ty < tx { ty } else { tx };
            let t_out = if t1 < t_xy { t1 } else { t_xy };
            let z_out = o.z + d.z * t_out;
            let zmin = if z_out < z { z_out } else { z };
            if l == 0 {
                let (i, j) = (bx as usize & mask_x, by as usize & mask_y);
                let c = hf.corners_wrapped(i, (i + 1) & mask_x, j, (j + 1) & mask_y);
                if zmin <= highest(c) + self.hair
                    && let Some(h) = self.cell_hit_with(&pre, bx, by, t0, t1, || c)
                {
                    return Some(h);
                }
            } else if zmin <= at(lev, bx, by) {
                // Into the child the ray is in at `t` (as `traverse_in`: the upper one
                // when `t`'s point lies past the middle boundary, or on it moving up),
                // the middle boundary found from the one ahead rather than from the
                // integers: `(2b + 1)·w` is one child's width behind it moving up, ahead
                // of it moving down, and comparing the point with it is comparing the
                // point's quotient with `2b + 1` (the widths are powers of two).
                l -= 1;
                let c = &levels[l];
                if c.up_x != 0 {
                    let x = o.x + d.x * t;
                    let mid = if PX { fx - c.wx } else { fx + c.wx };
                    let upper = if PX { x >= mid } else { x > mid };
                    bx = 2 * bx + i64::from(upper);
                    fx = if PX == upper { fx } else { mid };
                }
                if c.up_y != 0 {
                    let y = o.y + d.y * t;
                    let mid = if PY { fy - c.wy } else { fy + c.wy };
                    let upper = if PY { y >= mid } else { y > mid };
                    by = 2 * by + i64::from(upper);
                    fy = if PY == upper { fy } else { mid };
                }
                continue;
            }
            if t_out >= t1 {
                return None;
            }
            let (obx, oby) = (bx, by);
            if tx <= ty {
                bx += sx;
                fx += sx as f64 * lev.wx;
            }
            if ty <= tx {
                by += sy;
                fy += sy as f64 * lev.wy;
            }
            t = t_out;
            z = z_out;
            let (ux, uy) = (lev.up_x, lev.up_y);
            if ((bx ^ obx) >> ux) | ((by ^ oby) >> uy) != 0 {
                let (px, py) = (bx >> ux, by >> uy);
                let p = &levels[l + 1];
                if z > at(p, px, py) {
                    l += 1;
                    bx = px;
                    by = py;
                    fx = (bx + ax) as f64 * p.wx;
                    fy = (by + ay) as f64 * p.wy;
                }
            }
        }
    }

    /// The general hierarchical DDA (module docs), with remainders and divisions;
    /// the power-of-two patches take [`Tracer::traverse_fast`].
    #[inline(always)]
    fn traverse_in(&self, ray: &Ray, t0: f64, t1: f64, start: usize, top: usize) -> Option<Hit> {
        let pre = self.pre(ray);
        let (o, d) = (ray.o, ray.d);
        let sx: i64 = if d.x > 0.0 {
            1
        } else if d.x < 0.0 {
            -1
        } else {
            0
        };
        let sy: i64 = if d.y > 0.0 {
            1
        } else if d.y < 0.0 {
            -1
        } else {
            0
        };
        // The boundary ahead of block b is that of block b + 1 when moving up.
        let (ax, ay) = (i64::from(sx > 0), i64::from(sy > 0));
        let (neg_x, neg_y) = (d.x < 0.0, d.y < 0.0);
        let levels = &self.levels[..=top];
        let mut l = start;
        let mut t = t0;
        // The ray's height at `t`, carried from step to step (the same bits as
        // computing it again).
        let mut z = o.z + d.z * t;
        let (mut bx, mut by) = {
            let lev = &levels[l];
            (
                coord(o.x + d.x * t, d.x, lev.wx, lev.inv_wx),
                coord(o.y + d.y * t, d.y, lev.wy, lev.inv_wy),
            )
        };
        loop {
            let lev = &levels[l];
            let tx = if sx != 0 {
                ((bx + ax) as f64 * lev.wx - o.x) * pre.inv_x
            } else {
                f64::INFINITY
            };
            let ty = if sy != 0 {
                ((by + ay) as f64 * lev.wy - o.y) * pre.inv_y
            } else {
                f64::INFINITY
            };
            let t_out = tx.min(ty).min(t1);
            let z_out = o.z + d.z * t_out;
            // Both heights are finite (so is every `t`): a plain comparison.
            let zmin = if z_out < z { z_out } else { z };
            if zmin <= lev.max_at(bx, by) {
                if l == 0 {
                    if let Some(h) = self.cell_hit(&pre, bx, by, t0, t1) {
                        return Some(h);
                    }
                } else {
                    // Into the child the ray is in at `t`: the upper one when `t`'s
                    // point lies past the middle boundary, or on it moving up (what
                    // `coord` clamped to the two children gives, without a floor).
                    l -= 1;
                    let child = &levels[l];
                    if child.up_x != 0 {
                        let u = (o.x + d.x * t) / child.wx;
                        let m = (2 * bx + 1) as f64;
                        bx = 2 * bx + i64::from(if neg_x { u > m } else { u >= m });
                    }
                    if child.up_y != 0 {
                        let u = (o.y + d.y * t) / child.wy;
                        let m = (2 * by + 1) as f64;
                        by = 2 * by + i64::from(if neg_y { u > m } else { u >= m });
                    }
                    continue;
                }
            }
            if t_out >= t1 {
                return None;
            }
            let (obx, oby) = (bx, by);
            if tx <= ty {
                bx += sx;
            }
            if ty <= tx {
                by += sy;
            }
            t = t_out;
            z = z_out;
            if l < top {
                // Climb when the step left the parent block, unless the ray is already
                // below the new parent's highest corner: then the parent could not be
                // skipped (going up, the ray is lowest where it enters; going down,
                // lower still further on), and climbing would only descend again.
                let (ux, uy) = (lev.up_x, lev.up_y);
                let (px, py) = (bx >> ux, by >> uy);
                if (px != obx >> ux || py != oby >> uy) && z > levels[l + 1].max_at(px, py) {
                    l += 1;
                    bx = px;
                    by = py;
                }
            }
        }
    }

    fn brute(&self, ray: &Ray, t0: f64, t1: f64) -> Option<Hit> {
        let pre = self.pre(ray);
        let (o, d) = (ray.o, ray.d);
        let (nx, ny) = (self.hf.nx() as i64, self.hf.ny() as i64);
        let (a, b) = (o + d * t0, o + d * t1);
        let cx0 = (a.x.min(b.x) / self.hf.dx()).floor() as i64 - 1;
        let cx1 = (a.x.max(b.x) / self.hf.dx()).floor() as i64 + 1;
        let cy0 = (a.y.min(b.y) / self.hf.dy()).floor() as i64 - 1;
        let cy1 = (a.y.max(b.y) / self.hf.dy()).floor() as i64 + 1;
        let mut best: Option<Hit> = None;
        for ky in cy0.div_euclid(ny)..=cy1.div_euclid(ny) {
            for kx in cx0.div_euclid(nx)..=cx1.div_euclid(nx) {
                for j in 0..ny {
                    for i in 0..nx {
                        if let Some(h) = self.cell_hit(&pre, kx * nx + i, ky * ny + j, t0, t1)
                            && best.is_none_or(|b| h.t < b.t)
                        {
                            best = Some(h);
                        }
                    }
                }
            }
        }
        best
    }

    /// The first hit in unwrapped cell `(ix, iy)` within `[t0, t1]` (see the module
    /// docs).
    #[inline]
    fn cell_hit(&self, pre: &Pre, ix: i64, iy: i64, t0: f64, t1: f64) -> Option<Hit> {
        let hf = &self.hf;
        self.cell_hit_with(pre, ix, iy, t0, t1, || {
            hf.corners(wrap(ix, hf.nx()), wrap(iy, hf.ny()))
        })
    }

    /// [`Tracer::cell_hit`] with the cell's corners from `corners`, asked for once
    /// the ray is known to cross the cell within `[t0, t1]`.
    #[inline(always)]
    fn cell_hit_with(
        &self,
        pre: &Pre,
        ix: i64,
        iy: i64,
        t0: f64,
        t1: f64,
        corners: impl FnOnce() -> [f64; 4],
    ) -> Option<Hit> {
        let hf = &self.hf;
        let (o, d) = (pre.o, pre.d);
        let (dx, dy) = (hf.dx(), hf.dy());
        let x0 = ix as f64 * dx;
        let y0 = iy as f64 * dy;
        let (mut lo, mut hi) = (t0, t1);
        if !slab(
            o.x,
            d.x,
            pre.inv_x,
            x0,
            (ix + 1) as f64 * dx,
            &mut lo,
            &mut hi,
        ) || !slab(
            o.y,
            d.y,
            pre.inv_y,
            y0,
            (iy + 1) as f64 * dy,
            &mut lo,
            &mut hi,
        ) {
            return None;
        }
        if lo > hi {
            return None;
        }
        let c = corners();
        let (ou, du) = ((o.x - x0) * self.inv_dx, pre.du);
        let (ov, dv) = ((o.y - y0) * self.inv_dy, pre.dv);
        // The diagonal u = v: w(t) = u − v.
        let (w0, dw) = (ou - ov, du - dv);
        let tri_at = |t: f64| -> u8 { if w0 + dw * t >= 0.0 { 0 } else { 1 } };
        // One piece, or two when the diagonal cuts the range.
        let mut pieces = [(lo, hi), (hi, hi)];
        let mut n = 1;
        if dw != 0.0 {
            let td = -w0 / dw;
            if td > lo && td < hi {
                pieces = [(lo, td), (td, hi)];
                n = 2;
            }
        }
        for &(ta, tb) in &pieces[..n] {
            let tri = tri_at(0.5 * (ta + tb));
            if let Some(h) = piece(pre, c, (ix, iy), (ou, ov), ta, tb, tri) {
                return Some(h);
            }
        }
        None
    }

    /// The unit normal of the triangle of a hit.
    #[inline]
    pub fn hit_normal(&self, h: &Hit) -> Vec3 {
        let (i, j) = self.wrap_cell(h.cell);
        self.hf.normal(i, j, h.tri)
    }

    /// The material id of the triangle of a hit.
    #[inline]
    pub fn hit_material(&self, h: &Hit) -> u8 {
        let (i, j) = self.wrap_cell(h.cell);
        self.hf.material(i, j, h.tri)
    }

    #[inline]
    fn wrap_cell(&self, c: [i64; 2]) -> (usize, usize) {
        (wrap(c[0], self.hf.nx()), wrap(c[1], self.hf.ny()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_plane_is_hit_where_expected() {
        let hf = HeightField::new(4, 4, 1.0, 1.0, vec![0.0; 16]).expect("flat");
        let tr = Tracer::new(hf);
        assert_eq!(tr.levels(), 3);
        let d = Vec3::new(0.6, 0.0, -0.8);
        let ray = Ray {
            o: Vec3::new(-3.3, 0.5, 4.0),
            d,
            t_min: 0.0,
            skip: None,
        };
        for m in [Method::MaxMip, Method::Grid, Method::BruteForce] {
            let h = tr.first_hit(&ray, m).expect("hit");
            assert!((h.t - 5.0).abs() < 1e-12, "{m:?} {h:?}");
            assert_eq!(h.cell, [-1, 0], "{m:?}");
        }
        // Upwards from above: no hit.
        let up = Ray {
            d: Vec3::new(0.0, 0.6, 0.8),
            ..ray
        };
        assert!(tr.first_hit(&up, Method::MaxMip).is_none());
    }

    /// The power-of-two loops ([`Tracer::traverse_fast`]) find the general
    /// traversal's hit, to the bit, on a patch whose levels merge 2 × 2 and then
    /// 2 × 1: rays from above and from within the height range (as bounced rays,
    /// with `t_min` and a skipped triangle), in every quadrant, along the axes and
    /// through cell corners.
    #[test]
    fn fast_loops_find_the_general_hit() {
        use crate::GaussianParams;
        let hf = HeightField::gaussian(&GaussianParams {
            nx: 32,
            ny: 8,
            spacing: 0.5,
            rms_height: 0.6,
            correlation_length: 1.5,
            seed: 5,
        })
        .expect("gaussian");
        let tr = Tracer::new(hf);
        assert!(tr.fast);
        let (h0, h1) = (tr.hf.min_height(), tr.hf.max_height());
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut uniform = move || {
            // splitmix64
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut x = state;
            x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((x ^ (x >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        };
        let (mut hits, mut n) = (0, 0);
        for k in 0..20_000 {
            let from_above = k % 2 == 0;
            // Every eighth ray starts on a node and moves along an axis or a diagonal.
            let grid = k % 8 == 1;
            let mut o = Vec3::new(
                (uniform() * 3.0 - 1.0) * 16.0,
                (uniform() * 3.0 - 1.0) * 4.0,
                if from_above {
                    h1 + uniform()
                } else {
                    h0 + (h1 - h0) * uniform()
                },
            );
            let phi = if grid {
                o.x = (o.x * 2.0).round() * 0.5;
                o.y = (o.y * 2.0).round() * 0.5;
                std::f64::consts::FRAC_PI_4 * (uniform() * 8.0).floor()
            } else {
                std::f64::consts::TAU * uniform()
            };
            let z = uniform() * 2.0 - 1.0;
            let z = if from_above { -z.abs().max(1e-3) } else { z };
            let s = (1.0 - z * z).sqrt();
            let d = Vec3::new(s * phi.cos(), s * phi.sin(), z);
            let ray = Ray {
                o,
                d,
                t_min: if from_above { 0.0 } else { 1e-9 },
                skip: (!from_above).then(|| {
                    let (i, j) = ((o.x / 0.5).floor() as i64, (o.y / 0.5).floor() as i64);
                    (i, j, (k / 2 % 2) as u8)
                }),
            };
            let Some(p) = tr.plan(&ray, Method::MaxMip) else {
                continue;
            };
            let top = tr.levels() - 1;
            for start in [p.start, 0, top] {
                let fast = tr.traverse(&ray, p.t0, p.t1, start, top);
                let general = tr.traverse_in(&ray, p.t0, p.t1, start, top);
                assert_eq!(
                    fast.map(|h| (h.cell, h.tri, h.t.to_bits())),
                    general.map(|h| (h.cell, h.tri, h.t.to_bits())),
                    "ray {k} from level {start}: {ray:?}"
                );
                hits += usize::from(fast.is_some());
                n += 1;
            }
        }
        assert!(hits > n / 2, "{hits} hits of {n}");
    }

    /// The start level from the exponent is the loop's: the least `l` with
    /// `4·2^l ≥ cells`.
    #[test]
    fn start_level_is_the_least_wide_enough() {
        let by_loop = |cells: f64| {
            let mut l = 0;
            while ((4usize << l) as f64) < cells {
                l += 1;
            }
            l
        };
        for cells in [
            0.0, 1e-300, 0.5, 3.999, 4.0, 4.000001, 7.9, 8.0, 8.5, 1e6, 1e15,
        ] {
            assert_eq!(start_level(cells), by_loop(cells), "{cells}");
        }
        for k in 2..50 {
            let p = (1u64 << k) as f64;
            for c in [p, p.next_up(), p.next_down()] {
                assert_eq!(start_level(c), by_loop(c), "{c}");
            }
        }
    }
}
