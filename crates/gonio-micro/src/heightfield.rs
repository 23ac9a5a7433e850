//! Periodic height fields: the microgeometry the tracer sees, and the generators of the
//! surfaces the issue names (Gaussian random, sawtooth / V-grooves, parallel cylinders,
//! an explicit map).
//!
//! # Geometry
//! Heights `h[j·nx + i]` sit on the nodes `(i·dx, j·dy)` of an `nx × ny` lattice that
//! repeats in both directions, so the patch tiles the plane. Cell `(i, j)` spans
//! `[i·dx, (i+1)·dx] × [j·dy, (j+1)·dy]` and is split along its diagonal from `(i, j)`
//! to `(i+1, j+1)` into two planar triangles: triangle 0 where `u ≥ v` (local
//! coordinates in `[0, 1]²`), with corners `(0,0), (1,0), (1,1)`, and triangle 1 where
//! `u ≤ v`, with corners `(0,0), (1,1), (0,1)`. Triangles give exact planar facets and
//! exact normals; adjacent triangles share their edges, so the surface is continuous
//! (watertight). Every triangle carries a material id (0 by default).

use gonio_core::Vec3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

use crate::MicroError;

/// A divisor with its reciprocal where that is exact (a normal power of two whose
/// inverse is normal): `x / d` is then one multiplication with the division's very
/// bits (both round the same real `x·2⁻ᵏ` once), off the division's latency.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Divisor {
    d: f64,
    inv: Option<f64>,
}

/// `1/x` when it is exact: `x` a normal power of two whose inverse is normal too.
pub(crate) fn exact_inverse(x: f64) -> Option<f64> {
    let inv = 1.0 / x;
    (x.is_normal() && inv.is_normal() && x.to_bits() & ((1u64 << 52) - 1) == 0).then_some(inv)
}

/// Index `k` of an unwrapped lattice wrapped onto `0..n`: a mask for power-of-two
/// counts (the usual patches; a remainder on every lookup showed in the profile).
#[inline]
pub(crate) fn wrap(k: i64, n: usize) -> usize {
    if n.is_power_of_two() {
        (k & (n as i64 - 1)) as usize
    } else if (0..n as i64).contains(&k) {
        k as usize
    } else {
        k.rem_euclid(n as i64) as usize
    }
}

impl Divisor {
    pub(crate) fn new(d: f64) -> Divisor {
        Divisor {
            d,
            inv: exact_inverse(d),
        }
    }

    /// `x / d`.
    #[inline]
    pub(crate) fn div(self, x: f64) -> f64 {
        match self.inv {
            Some(inv) => x * inv,
            None => x / self.d,
        }
    }
}

/// A periodic height field of two triangles a cell, with a material id a triangle.
#[derive(Clone, Debug, PartialEq)]
pub struct HeightField {
    nx: usize,
    ny: usize,
    dx: f64,
    dy: f64,
    /// `dx` and `dy` as divisors (the normals divide by them at every hit).
    div_x: Divisor,
    div_y: Divisor,
    heights: Vec<f64>,
    materials: Option<Vec<u8>>,
    h_min: f64,
    h_max: f64,
}

/// Height and slope statistics of a [`HeightField`], from its triangles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeightStats {
    /// Root-mean-square height about the mean height of the nodes.
    pub rms_height: f64,
    /// Root-mean-square of `|∇h|` over the triangles (area-weighted): the roughness
    /// `m` of a Beckmann distribution with the same second moment of slopes.
    pub rms_slope: f64,
    /// Root-mean-square of `∂h/∂x`.
    pub rms_slope_x: f64,
    /// Root-mean-square of `∂h/∂y`.
    pub rms_slope_y: f64,
}

/// Parameters of [`HeightField::gaussian`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GaussianParams {
    /// Cells along x.
    pub nx: usize,
    /// Cells along y.
    pub ny: usize,
    /// Lattice spacing (the same along x and y), any length unit.
    pub spacing: f64,
    /// RMS height σ, exactly, in the unit of `spacing`.
    pub rms_height: f64,
    /// Correlation length `l` of the autocorrelation `σ² exp(−r²/l²)`.
    pub correlation_length: f64,
    /// Seed of the white noise.
    pub seed: u64,
}

/// The steepest facet a height field may have, as rise over run: 10⁴, a wall
/// 89.994° from the horizontal. Steeper, and the heights' rounding swallows the
/// tracer's offset off a facet.
pub const MAX_SLOPE: f64 = 1e4;

/// The most kernel products a Gaussian surface may take to generate (cells × kernel
/// taps along x and along y): 2³⁴, about ten seconds on one core. A correlation
/// length of many cells on a large lattice is refused rather than left to run for
/// hours.
pub const MAX_GAUSSIAN_WORK: f64 = (1u64 << 34) as f64;

/// The kernel products [`HeightField::gaussian`] takes for `nx × ny` cells with a
/// correlation length of `l` cells.
pub fn gaussian_work(nx: usize, ny: usize, l: f64) -> f64 {
    let taps = |n: usize| (2.0 * (4.0 * l).ceil().min(1e6) + 1.0).min(n as f64);
    nx as f64 * ny as f64 * (taps(nx) + taps(ny))
}

impl HeightField {
    /// A height field of `nx × ny` cells with spacings `dx`, `dy` and node heights in
    /// row-major order (`heights[j·nx + i]`); every triangle gets material 0.
    pub fn new(
        nx: usize,
        ny: usize,
        dx: f64,
        dy: f64,
        heights: Vec<f64>,
    ) -> Result<HeightField, MicroError> {
        if nx == 0 || ny == 0 {
            return Err(MicroError::invalid(
                "size",
                "needs at least one cell each way",
            ));
        }
        if nx > (1 << 24) || ny > (1 << 24) || nx.saturating_mul(ny) > (1 << 30) {
            return Err(MicroError::invalid("size", "more than 2^30 cells"));
        }
        for (name, v) in [("dx", dx), ("dy", dy)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(MicroError::invalid(name, "must be finite and positive"));
            }
        }
        if heights.len() != nx * ny {
            return Err(MicroError::invalid(
                "heights",
                format!("{} heights for {nx} × {ny} nodes", heights.len()),
            ));
        }
        if let Some(k) = heights.iter().position(|h| !h.is_finite()) {
            return Err(MicroError::invalid(
                "heights",
                format!("height {k} (node {}, {}) is not finite", k % nx, k / nx),
            ));
        }
        // The steepest facet: beyond MAX_SLOPE the tracer's self-intersection offset
        // (a fraction of the spacing) is lost in the heights' rounding, and rays creep
        // along walls instead of leaving them.
        let at = |i: usize, j: usize| heights[(j % ny) * nx + (i % nx)];
        for j in 0..ny {
            for i in 0..nx {
                let h = at(i, j);
                let sx = (at(i + 1, j) - h).abs() / dx;
                let sy = (at(i, j + 1) - h).abs() / dy;
                let sd = (at(i + 1, j + 1) - h).abs() / dx.min(dy);
                let steepest = sx.max(sy).max(sd);
                if steepest.is_nan() || steepest > MAX_SLOPE {
                    return Err(MicroError::invalid(
                        "heights",
                        format!(
                            "the facets at node ({i}, {j}) rise {} per unit of spacing, more \
                             than {MAX_SLOPE:e} (walls steeper than 89.994°)",
                            gonio_core::limits::num(steepest)
                        ),
                    ));
                }
            }
        }
        let h_min = heights.iter().copied().fold(f64::INFINITY, f64::min);
        let h_max = heights.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Ok(HeightField {
            nx,
            ny,
            dx,
            dy,
            div_x: Divisor::new(dx),
            div_y: Divisor::new(dy),
            heights,
            materials: None,
            h_min,
            h_max,
        })
    }

    /// Sets the material id of every triangle: `ids[2·(j·nx + i) + tri]`.
    pub fn with_materials(mut self, ids: Vec<u8>) -> Result<HeightField, MicroError> {
        if ids.len() != 2 * self.nx * self.ny {
            return Err(MicroError::invalid(
                "materials",
                format!("{} ids for {} triangles", ids.len(), 2 * self.nx * self.ny),
            ));
        }
        self.materials = Some(ids);
        Ok(self)
    }

    /// Sets the material id of every triangle from its unit normal.
    pub fn with_materials_by(self, f: impl Fn(Vec3) -> u8) -> HeightField {
        let mut ids = Vec::with_capacity(2 * self.nx * self.ny);
        for j in 0..self.ny {
            for i in 0..self.nx {
                for tri in 0..2 {
                    ids.push(f(self.normal(i, j, tri)));
                }
            }
        }
        HeightField {
            materials: Some(ids),
            ..self
        }
    }

    /// Cells along x.
    pub fn nx(&self) -> usize {
        self.nx
    }
    /// Cells along y.
    pub fn ny(&self) -> usize {
        self.ny
    }
    /// Spacing along x.
    pub fn dx(&self) -> f64 {
        self.dx
    }
    /// Spacing along y.
    pub fn dy(&self) -> f64 {
        self.dy
    }
    /// The node heights, row-major.
    pub fn heights(&self) -> &[f64] {
        &self.heights
    }
    /// The lowest node.
    pub fn min_height(&self) -> f64 {
        self.h_min
    }
    /// The highest node.
    pub fn max_height(&self) -> f64 {
        self.h_max
    }
    /// The size of the periodic patch, `(nx·dx, ny·dy)`.
    pub fn period(&self) -> (f64, f64) {
        (self.nx as f64 * self.dx, self.ny as f64 * self.dy)
    }

    /// The height of node `(i, j)`, indices taken modulo the lattice.
    #[inline]
    pub fn height(&self, i: usize, j: usize) -> f64 {
        self.heights[(j % self.ny) * self.nx + (i % self.nx)]
    }

    /// The corner heights `[h00, h10, h01, h11]` of cell `(i, j)` (`i < nx`, `j < ny`).
    #[inline]
    pub(crate) fn corners(&self, i: usize, j: usize) -> [f64; 4] {
        let i1 = if i + 1 == self.nx { 0 } else { i + 1 };
        let j1 = if j + 1 == self.ny { 0 } else { j + 1 };
        self.corners_wrapped(i, i1, j, j1)
    }

    /// [`HeightField::corners`] of cell `(i, j)` with the indices of the next node
    /// along x and y already wrapped (`i1`, `j1`).
    #[inline(always)]
    pub(crate) fn corners_wrapped(&self, i: usize, i1: usize, j: usize, j1: usize) -> [f64; 4] {
        let r0 = j * self.nx;
        let r1 = j1 * self.nx;
        [
            self.heights[r0 + i],
            self.heights[r0 + i1],
            self.heights[r1 + i],
            self.heights[r1 + i1],
        ]
    }

    /// The height differences `(a, b)` across triangle `tri` of cell `(i, j)` along its
    /// local `u` and `v`: the triangle is `h = h00 + a·u + b·v`.
    #[inline]
    pub(crate) fn tri_slopes(c: [f64; 4], tri: u8) -> (f64, f64) {
        let [h00, h10, h01, h11] = c;
        if tri == 0 {
            (h10 - h00, h11 - h10)
        } else {
            (h11 - h01, h01 - h00)
        }
    }

    /// The unit upward normal of triangle `tri` (0 or 1) of cell `(i, j)`.
    #[inline]
    pub fn normal(&self, i: usize, j: usize, tri: u8) -> Vec3 {
        // Wrapped only when needed: a tracer's cells already are, and two integer
        // divisions a hit showed in the profile.
        let i = if i < self.nx { i } else { i % self.nx };
        let j = if j < self.ny { j } else { j % self.ny };
        let (a, b) = Self::tri_slopes(self.corners(i, j), tri);
        let n = Vec3::new(self.div_x.div(-a), self.div_y.div(-b), 1.0);
        n / n.norm()
    }

    /// The material id of triangle `tri` of cell `(i, j)`.
    #[inline]
    pub fn material(&self, i: usize, j: usize, tri: u8) -> u8 {
        match &self.materials {
            Some(m) => m[2 * (j * self.nx + i) + tri as usize],
            None => 0,
        }
    }

    /// The largest material id used.
    pub fn max_material(&self) -> u8 {
        self.materials
            .as_ref()
            .and_then(|m| m.iter().copied().max())
            .unwrap_or(0)
    }

    /// RMS height and slopes (see [`HeightStats`]).
    pub fn stats(&self) -> HeightStats {
        let n = self.heights.len() as f64;
        let mean = self.heights.iter().sum::<f64>() / n;
        let var = self.heights.iter().map(|h| (h - mean).powi(2)).sum::<f64>() / n;
        let (mut sx, mut sy) = (0.0, 0.0);
        for j in 0..self.ny {
            for i in 0..self.nx {
                let c = self.corners(i, j);
                for tri in 0..2 {
                    let (a, b) = Self::tri_slopes(c, tri);
                    sx += (a / self.dx).powi(2);
                    sy += (b / self.dy).powi(2);
                }
            }
        }
        let nt = 2.0 * n;
        HeightStats {
            rms_height: var.sqrt(),
            rms_slope: ((sx + sy) / nt).sqrt(),
            rms_slope_x: (sx / nt).sqrt(),
            rms_slope_y: (sy / nt).sqrt(),
        }
    }

    /// A Gaussian random surface: white noise convolved periodically and separably with
    /// the kernel `exp(−2r²/l²)`, whose autocorrelation is the Gaussian `exp(−r²/l²)`,
    /// then shifted to zero mean and scaled to exactly `rms_height`. Its RMS slope is
    /// `2σ/l` in the continuum (`√2 σ/l` along each axis); [`HeightField::stats`]
    /// gives the lattice's own.
    pub fn gaussian(p: &GaussianParams) -> Result<HeightField, MicroError> {
        if p.nx < 2 || p.ny < 2 {
            return Err(MicroError::invalid(
                "size",
                "a random surface needs at least 2 × 2 cells",
            ));
        }
        if !(p.spacing.is_finite() && p.spacing > 0.0) {
            return Err(MicroError::invalid(
                "spacing",
                "must be finite and positive",
            ));
        }
        if !(p.rms_height.is_finite() && p.rms_height >= 0.0) {
            return Err(MicroError::invalid("rms_height", "must be finite and ≥ 0"));
        }
        if !(p.correlation_length.is_finite() && p.correlation_length > 0.0) {
            return Err(MicroError::invalid(
                "correlation_length",
                "must be finite and positive",
            ));
        }
        let (nx, ny) = (p.nx, p.ny);
        if nx.saturating_mul(ny) > (1 << 30) {
            return Err(MicroError::invalid("size", "more than 2^30 cells"));
        }
        let work = gaussian_work(nx, ny, p.correlation_length / p.spacing);
        if work.is_nan() || work > MAX_GAUSSIAN_WORK {
            return Err(MicroError::invalid(
                "correlation_length",
                format!(
                    "generating {nx} × {ny} cells with it takes {work:.2e} kernel products, \
                     more than 2^34"
                ),
            ));
        }
        let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
        let mut h: Vec<f64> = (0..nx * ny)
            .map(|_| StandardNormal.sample(&mut rng))
            .collect();
        let l = p.correlation_length / p.spacing;
        let kx = periodic_kernel(nx, l);
        let ky = periodic_kernel(ny, l);
        // Rows, then columns (through a transposed copy), each on its own: in
        // parallel, and every value is the same sum in the same order on any number
        // of threads.
        let mut rows = vec![0.0; nx * ny];
        rows.par_chunks_mut(nx)
            .zip(h.par_chunks(nx))
            .for_each(|(out, row)| convolve(row, &kx, out));
        let mut cols = vec![0.0; nx * ny];
        cols.par_chunks_mut(ny).enumerate().for_each(|(i, col)| {
            for (j, c) in col.iter_mut().enumerate() {
                *c = rows[j * nx + i];
            }
        });
        drop(rows);
        h.par_chunks_mut(ny)
            .zip(cols.par_chunks(ny))
            .for_each(|(out, col)| convolve(col, &ky, out));
        // `h` holds the columns: back to rows.
        cols.par_chunks_mut(nx).enumerate().for_each(|(j, row)| {
            for (i, r) in row.iter_mut().enumerate() {
                *r = h[i * ny + j];
            }
        });
        let mut h = cols;
        let n = h.len() as f64;
        let mean = h.iter().sum::<f64>() / n;
        h.iter_mut().for_each(|v| *v -= mean);
        let rms = (h.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
        if rms > 0.0 {
            let s = p.rms_height / rms;
            h.iter_mut().for_each(|v| *v *= s);
        }
        HeightField::new(nx, ny, p.spacing, p.spacing, h)
    }

    /// A sawtooth of V-grooves with ridges along y (DeYoung Sec. 2.2.3, Fig. 2.3), one
    /// period wide: the face facing +x (normal leaning towards +x) is tilted by
    /// `tilt_plus_x` from the macro-surface and gets material 0; the face facing −x is
    /// tilted by `tilt_minus_x` and gets material 1. Both faces are planar and end on
    /// lattice nodes, so the ridge splits the period into `k₁ + k₂ ≤ 64` cells with
    /// `k₁/k₂` the best rational approximation of `tan(tilt_plus_x)/tan(tilt_minus_x)`;
    /// [`HeightField::stats`] or the face normals give the tilts actually built
    /// (exact when the two tilts are equal).
    pub fn sawtooth(
        period: f64,
        tilt_plus_x: f64,
        tilt_minus_x: f64,
    ) -> Result<HeightField, MicroError> {
        if !(period.is_finite() && period > 0.0) {
            return Err(MicroError::invalid("period", "must be finite and positive"));
        }
        let lim = 89f64.to_radians();
        for (name, a) in [
            ("tilt (+x face)", tilt_plus_x),
            ("tilt (−x face)", tilt_minus_x),
        ] {
            if !(a.is_finite() && a >= 1f64.to_radians() && a <= lim) {
                return Err(MicroError::invalid(name, "must be between 1° and 89°"));
            }
        }
        let (ta, tb) = (tilt_plus_x.tan(), tilt_minus_x.tan());
        // Rising (−x-facing) face over k1 cells, falling (+x-facing) face over k2:
        // k1·tan(b) = k2·tan(a).
        let want = ta / (ta + tb);
        let mut best = (1usize, 1usize, f64::INFINITY);
        for n in 2..=64usize {
            for k1 in 1..n {
                let e = (k1 as f64 / n as f64 - want).abs();
                if e < best.2 - 1e-12 {
                    best = (k1, n - k1, e);
                }
            }
        }
        let (k1, k2) = (best.0, best.1);
        let n = k1 + k2;
        let dx = period / n as f64;
        let ridge = k1 as f64 * dx * tb;
        let mut heights = Vec::with_capacity(n);
        for i in 0..n {
            let h = if i <= k1 {
                i as f64 * dx * tb
            } else {
                ridge * (n - i) as f64 / k2 as f64
            };
            heights.push(h);
        }
        let hf = HeightField::new(n, 1, dx, period, heights)?;
        Ok(hf.with_materials_by(|nrm| if nrm.x > 0.0 { 0 } else { 1 }))
    }

    /// Parallel cylinders of `radius` with their axes along x, `spacing` apart (brushed
    /// metal): one period of the profile `h(y) = √(r² − (y − s/2)²)` over a floor at
    /// height 0 (the upper envelope when `spacing < 2r`), sampled at `cells` nodes.
    pub fn cylinders(radius: f64, spacing: f64, cells: usize) -> Result<HeightField, MicroError> {
        if !(radius.is_finite() && radius > 0.0) {
            return Err(MicroError::invalid("radius", "must be finite and positive"));
        }
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(MicroError::invalid(
                "spacing",
                "must be finite and positive",
            ));
        }
        if !(4..=1 << 20).contains(&cells) {
            return Err(MicroError::invalid(
                "cells_per_period",
                "must be in 4..=2^20",
            ));
        }
        let dy = spacing / cells as f64;
        let heights = (0..cells)
            .map(|j| {
                let y = j as f64 * dy;
                // The cylinders centred at s/2 and its neighbours one period away.
                [-spacing, 0.0, spacing]
                    .iter()
                    .map(|off| {
                        let r = y - (0.5 * spacing + off);
                        (radius * radius - r * r).max(0.0).sqrt()
                    })
                    .fold(0.0, f64::max)
            })
            .collect();
        HeightField::new(1, cells, spacing, dy, heights)
    }
}

/// The periodic kernel `exp(−2 (k/l)²)` for offsets `k` (in cells) wrapped onto
/// `0..n`, with its images summed, as (offset, weight) pairs with weight > 1e-16 of
/// the peak.
fn periodic_kernel(n: usize, l: f64) -> Vec<(usize, f64)> {
    let radius = (4.0 * l).ceil().min(1e6) as i64;
    let mut w = vec![0.0; n];
    for k in -radius..=radius {
        let x = k as f64 / l;
        w[k.rem_euclid(n as i64) as usize] += (-2.0 * x * x).exp();
    }
    w.into_iter()
        .enumerate()
        .filter(|(_, v)| *v > 1e-16)
        .collect()
}

/// Circular convolution `out[i] = Σ w · x[(i + k) mod n]`.
fn convolve(x: &[f64], kernel: &[(usize, f64)], out: &mut [f64]) {
    let n = x.len();
    for (i, o) in out.iter_mut().enumerate() {
        let mut s = 0.0;
        for &(k, w) in kernel {
            let idx = i + k;
            s += w * x[if idx >= n { idx - n } else { idx }];
        }
        *o = s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaussian_has_exact_rms_and_the_expected_slope() {
        let p = GaussianParams {
            nx: 256,
            ny: 256,
            spacing: 1.0,
            rms_height: 0.75,
            correlation_length: 6.0,
            seed: 3,
        };
        let hf = HeightField::gaussian(&p).expect("surface");
        let s = hf.stats();
        assert!((s.rms_height - 0.75).abs() < 1e-12, "{s:?}");
        // Continuum 2σ/l = 0.25; the lattice's finite differences see a little less,
        // and a finite patch scatters it by a few percent.
        assert!((s.rms_slope - 0.25).abs() < 0.02, "{s:?}");
        assert!((s.rms_slope_x / s.rms_slope_y - 1.0).abs() < 0.08, "{s:?}");
    }

    #[test]
    fn sawtooth_faces_are_planar_with_the_asked_tilts() {
        let hf =
            HeightField::sawtooth(1.0, 45f64.to_radians(), 45f64.to_radians()).expect("sawtooth");
        assert_eq!(hf.nx(), 2);
        let n0 = hf.normal(0, 0, 0);
        let n1 = hf.normal(1, 0, 0);
        // Cell 0 rises: its face looks towards −x (material 1); cell 1 falls.
        assert!((n0.x + 45f64.to_radians().sin()).abs() < 1e-15);
        assert!((n1.x - 45f64.to_radians().sin()).abs() < 1e-15);
        assert_eq!((hf.material(0, 0, 0), hf.material(1, 0, 1)), (1, 0));
        // Both triangles of a cell are coplanar.
        assert!((hf.normal(0, 0, 1) - n0).norm() < 1e-15);
        let hf =
            HeightField::sawtooth(1.0, 30f64.to_radians(), 60f64.to_radians()).expect("sawtooth");
        let tilt = |n: Vec3| n.x.abs().atan2(n.z).to_degrees();
        let plus = (0..hf.nx()).map(|i| hf.normal(i, 0, 0)).find(|n| n.x > 0.0);
        let minus = (0..hf.nx()).map(|i| hf.normal(i, 0, 0)).find(|n| n.x < 0.0);
        let (plus, minus) = (plus.expect("+x face"), minus.expect("−x face"));
        assert!((tilt(plus) - 30.0).abs() < 0.05, "{}", tilt(plus));
        assert!((tilt(minus) - 60.0).abs() < 0.05, "{}", tilt(minus));
    }

    #[test]
    fn cylinders_profile() {
        let hf = HeightField::cylinders(1.0, 2.0, 64).expect("cylinders");
        assert_eq!((hf.nx(), hf.ny()), (1, 64));
        assert!((hf.max_height() - 1.0).abs() < 1e-15);
        assert!(hf.min_height().abs() < 1e-15);
        // Flat along the axes.
        assert!(hf.normal(0, 10, 0).x.abs() < 1e-15);
        assert!(HeightField::cylinders(-1.0, 2.0, 64).is_err());
    }
}
