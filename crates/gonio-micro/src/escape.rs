//! Rays that certainly leave: per-cell bounds on how steeply the surface ahead of
//! a cell can rise, so that a ray leaving a facet more steeply than that is known to
//! escape without a search.
//!
//! A ray leaves a point `p` of cell `C = (i, j)` on the surface (`p.z = h(p)`) along
//! the unit `d`, `d_z > 0`. Moving towards +x and +y (the other quadrants are
//! mirrored) it only ever lies over cells `(i + a, j + b)`, `a, b ≥ 0`. It meets
//! nothing if it is above the surface everywhere along its way:
//!
//! - **Near** (the cells `a, b ≤ n`, a convex rectangle holding the ray from `p`
//!   until it leaves it): the surface is piecewise planar and continuous, so along
//!   the ray's horizontal way `r` it rises at most `L_n·r`, `L_n` the largest
//!   gradient norm of their triangles. `d_z > L_n·|d_xy|` clears them, and
//!   `|d_xy| ≤ m·√(Δx² + Δy²)` with `m = max(|d_x|/Δx, |d_y|/Δy)`.
//! - **Far** (a cell at `max(a, b) = k > n`): the ray is over it only once it has
//!   moved `(k − 1)·Δx` along x or `(k − 1)·Δy` along y, at a parameter
//!   `t ≥ (k − 1)/m`, so at least `d_z·(k − 1)/m` above `z_C`, the lowest corner of
//!   `C`. The surface there is at most `M_k`, the highest node of the cells
//!   `a, b ≤ k`. `d_z > m·(M_k − z_C)/(k − 1)` clears the ring; past `K` rings the
//!   highest node of all bounds `M_k`.
//!
//! So `d_z > m·B`, `B = min_n max(L_n·√(Δx² + Δy²), max_{k>n} (M_k − z_C)/(k − 1))`
//! (`n` = 1, 2, 3) per cell and quadrant, proves the ray escapes: the search it
//! skips would have found no hit, and the path's bytes are the same. The inputs are rounded outwards to `f32` and
//! the bound up by a relative 10⁻⁶, far above the rounding of the heights, the hit
//! point and the direction; it is stored as a byte ([`STEPS`] codes a doubling,
//! rounded up). The patch repeats, so the rings are read with wrapped indices (on a
//! small patch a ring meets cells twice: the maximum of a superset is still a
//! bound). On the gold surface (`config/micro-gaussian-gold.toml`) 76 % of the rays
//! leaving a facet need no search.

use rayon::prelude::*;

use gonio_core::Vec3;

use crate::HeightField;
use crate::heightfield::wrap;

/// Rings bounded one by one (`2 ≤ k < RINGS`); beyond, the highest node.
const RINGS: usize = 10;

/// Near windows tried (1 to `NEAR` cells ahead).
const NEAR: usize = 3;

/// Codes of the stored bound a doubling: code `q` is `2^((q − 128)/STEPS)` (steps
/// of 4.4 %), so a byte spans `2⁻⁸ … 2^7.9` and the table stays in a core's cache.
const STEPS: f64 = 16.0;

/// The code of a bound too steep to store: never clears.
const NEVER: u8 = u8::MAX;

/// The per-cell, per-quadrant escape bounds of a height field (module docs).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Escape {
    nx: usize,
    ny: usize,
    /// `1/Δx`, `1/Δy`.
    inv: (f64, f64),
    /// Each cell's four bounds (quadrant `q`: bit 0 set towards −x, bit 1 towards
    /// −y) rounded up to codes, row-major.
    code: Vec<[u8; 4]>,
    /// The value of each code.
    value: Vec<f64>,
}

/// The value of code `q`.
fn level(q: u8) -> f64 {
    if q == NEVER {
        f64::INFINITY
    } else {
        ((f64::from(q) - 128.0) / STEPS).exp2()
    }
}

/// The least code whose value (`values[q]`, [`level`]'s, ascending) is at least `b`.
fn encode(b: f64, values: &[f64]) -> u8 {
    // From the exponent and the mantissa's linear part (log2(1 + f) ≈ f, off by
    // under 0.09, so at most two codes), then settled on the least code at or
    // above `b`: no logarithm a cell and quadrant. A NaN bound never clears.
    let guess = if b.is_nan() {
        f64::from(NEVER)
    } else if b.is_normal() && b > 0.0 {
        let bits = b.to_bits();
        let e = ((bits >> 52) & 0x7ff) as f64 - 1023.0;
        let f = (bits & ((1u64 << 52) - 1)) as f64 / (1u64 << 52) as f64;
        ((e + f) * STEPS + 128.0).clamp(0.0, f64::from(NEVER))
    } else if b > 0.0 {
        f64::from(NEVER)
    } else {
        0.0
    };
    let mut q = guess as u8;
    while q < NEVER && values[usize::from(q)] < b {
        q += 1;
    }
    while q > 0 && values[usize::from(q - 1)] >= b {
        q -= 1;
    }
    q
}

/// The least `f32` at or above `x`.
fn up(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) < x { y.next_up() } else { y }
}

/// The greatest `f32` at or below `x`.
fn down(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) > x { y.next_down() } else { y }
}

/// `out(i, j) = max` of `v` over the 2 × 2 cells `(i, j)`, `(i + sx, j)`,
/// `(i, j + sy)`, `(i + sx, j + sy)` of a periodic field of rows of `nx`
/// (`sx`, `sy` = ±1); `tmp` holds the rows' pass.
fn max2x2(v: &[f32], nx: usize, (sx, sy): (isize, isize), out: &mut [f32], tmp: &mut [f32]) {
    let ny = v.len() / nx;
    let step = |k: usize, s: isize, n: usize| (k as isize + s).rem_euclid(n as isize) as usize;
    tmp.par_chunks_mut(nx)
        .zip(v.par_chunks(nx))
        .for_each(|(t, r)| {
            // The wrapped neighbour only at the end of the row the step runs off.
            let (lo, hi) = if sx > 0 { (0, nx - 1) } else { (1, nx) };
            for i in lo..hi {
                t[i] = r[i].max(r[(i as isize + sx) as usize]);
            }
            let e = if sx > 0 { nx - 1 } else { 0 };
            t[e] = r[e].max(r[step(e, sx, nx)]);
        });
    let tmp = &*tmp;
    out.par_chunks_mut(nx).enumerate().for_each(|(j, o)| {
        let (m, n) = (&tmp[j * nx..][..nx], &tmp[step(j, sy, ny) * nx..][..nx]);
        for ((o, a), b) in o.iter_mut().zip(m).zip(n) {
            *o = a.max(*b);
        }
    });
}

impl Escape {
    /// The bounds of every cell of `hf`.
    pub(crate) fn new(hf: &HeightField) -> Escape {
        let (nx, ny) = (hf.nx(), hf.ny());
        let (dx, dy) = (hf.dx(), hf.dy());
        let n = nx * ny;
        // Per cell, rounded outwards: the steeper triangle's gradient norm, the
        // highest and the lowest corner.
        let (mut grad, mut top, mut low) = (vec![0f32; n], vec![0f32; n], vec![0f32; n]);
        grad.par_chunks_mut(nx)
            .zip(top.par_chunks_mut(nx))
            .zip(low.par_chunks_mut(nx))
            .enumerate()
            .for_each(|(j, ((g, t), l))| {
                for i in 0..nx {
                    let c = hf.corners(i, j);
                    let norm = |tri: u8| {
                        let (a, b) = HeightField::tri_slopes(c, tri);
                        ((a / dx).powi(2) + (b / dy).powi(2)).sqrt()
                    };
                    g[i] = up(norm(0).max(norm(1)));
                    t[i] = up(c[0].max(c[1]).max(c[2]).max(c[3]));
                    l[i] = down(c[0].min(c[1]).min(c[2]).min(c[3]));
                }
            });
        let diag = (dx * dx + dy * dy).sqrt();
        let h_max = hf.max_height();
        let tail = (RINGS - 1) as f64;
        let value: Vec<f64> = (0..=NEVER).map(level).collect();
        let mut code = vec![[NEVER; 4]; n];
        let (mut tmp, mut near, mut ring, mut next) =
            (vec![0f32; n], vec![0f32; n], vec![0f32; n], vec![0f32; n]);
        for q in 0..4 {
            let dir = (
                if q & 1 == 0 { 1 } else { -1 },
                if q & 2 == 0 { 1 } else { -1 },
            );
            // The near part may stop after 1, 2 or 3 cells ahead (the steepest
            // triangle of a larger window against rings further out): each is a
            // proof, so the least of the three bounds is one too.
            let mut nears = Vec::with_capacity(NEAR);
            let mut src = grad.clone();
            for _ in 0..NEAR {
                max2x2(&src, nx, dir, &mut near, &mut tmp);
                std::mem::swap(&mut src, &mut near);
                nears.push(src.clone());
            }
            // `far[n]`: the tail's bound and every ring's from `n + 2` cells on.
            let mut far: Vec<[f64; NEAR]> = low
                .par_iter()
                .map(|z| [(h_max - f64::from(*z)) / tail; NEAR])
                .collect();
            max2x2(&top, nx, dir, &mut ring, &mut tmp);
            for k in 2..RINGS {
                max2x2(&ring, nx, dir, &mut next, &mut tmp);
                std::mem::swap(&mut ring, &mut next);
                let gap = (k - 1) as f64;
                far.par_iter_mut()
                    .zip(&ring)
                    .zip(&low)
                    .for_each(|((f, m), z)| {
                        let b = (f64::from(*m) - f64::from(*z)) / gap;
                        for f in f.iter_mut().take(k - 1) {
                            *f = f.max(b);
                        }
                    });
            }
            let bound: Vec<f64> = far
                .par_iter()
                .enumerate()
                .map(|(c, f)| {
                    (0..NEAR)
                        .map(|n| (f64::from(nears[n][c]) * diag).max(f[n]))
                        .fold(f64::INFINITY, f64::min)
                })
                .collect();
            code.par_iter_mut()
                .zip(&bound)
                .for_each(|(c, b)| c[q] = encode(b * (1.0 + 1e-6) + 1e-9, &value));
        }
        Escape {
            nx,
            ny,
            inv: (1.0 / dx, 1.0 / dy),
            code,
            value,
        }
    }

    /// The four bounds' codes of cell `(i, j)` (unwrapped), for [`Escape::clears`]:
    /// read when the cell is hit, before the new direction is known, so that the
    /// load overlaps the shading.
    #[inline]
    pub(crate) fn codes(&self, i: i64, j: i64) -> [u8; 4] {
        self.code[wrap(j, self.ny) * self.nx + wrap(i, self.nx)]
    }

    /// True when a ray along `d` from a point on the surface of a cell whose
    /// [`Escape::codes`] are `codes` certainly meets no facet.
    #[inline]
    pub(crate) fn clears(&self, codes: [u8; 4], d: Vec3) -> bool {
        let q = usize::from(d.x < 0.0) | usize::from(d.y < 0.0) << 1;
        let m = (d.x.abs() * self.inv.0).max(d.y.abs() * self.inv.1);
        d.z > 0.0 && d.z > self.value[usize::from(codes[q])] * m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Method, Ray, Tracer};

    #[test]
    fn codes_round_up_by_less_than_a_step() {
        let values: Vec<f64> = (0..=NEVER).map(level).collect();
        for b in [
            1e-12,
            2f64.powi(-8),
            0.01,
            0.3,
            1.0,
            1.0 + 1e-15,
            2.0,
            7.7,
            239.0,
            1e6,
        ] {
            let q = encode(b, &values);
            assert!(level(q) >= b, "{b}: code {q}");
            if q > 0 && q < NEVER {
                assert!(level(q - 1) < b, "{b}: code {q} is not the least");
            }
        }
        assert_eq!(encode(1e6, &values), NEVER);
        assert_eq!(encode(f64::NAN, &values), NEVER);
        assert_eq!(encode(0.0, &values), 0);
        assert_eq!(encode(1.0, &values), 128);
    }

    /// Every ray the bound clears finds no hit in an exact search, on rough and
    /// smooth surfaces, from points on every cell and directions of every slope.
    #[test]
    fn a_cleared_ray_meets_nothing() {
        use rand::{Rng, SeedableRng};
        for (seed, l, dy) in [(3u64, 2.0, 1.0), (4, 5.0, 0.5), (5, 12.0, 2.0)] {
            let g = HeightField::gaussian(&crate::GaussianParams {
                nx: 48,
                ny: 32,
                spacing: 1.0,
                rms_height: 0.75,
                correlation_length: l,
                seed,
            })
            .unwrap();
            // The same heights on a lattice stretched along y: unequal spacings.
            let hf = HeightField::new(48, 32, 1.0, dy, g.heights().to_vec()).unwrap();
            let esc = Escape::new(&hf);
            let tracer = Tracer::new(hf.clone());
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let (mut cleared, mut total) = (0, 0);
            for _ in 0..20_000 {
                let i = rng.random_range(0..hf.nx());
                let j = rng.random_range(0..hf.ny());
                let (u, v): (f64, f64) = (rng.random(), rng.random());
                let tri = u8::from(v > u);
                let c = hf.corners(i, j);
                let (a, b) = HeightField::tri_slopes(c, tri);
                let z = c[0] + a * u + b * v;
                let o = Vec3::new((i as f64 + u) * hf.dx(), (j as f64 + v) * hf.dy(), z);
                let phi = rng.random_range(0.0..std::f64::consts::TAU);
                let elev = rng.random_range(0.01..1.55f64);
                let d = Vec3::new(elev.cos() * phi.cos(), elev.cos() * phi.sin(), elev.sin());
                if d.dot(hf.normal(i, j, tri)) <= 0.0 {
                    continue;
                }
                total += 1;
                if !esc.clears(esc.codes(i as i64, j as i64), d) {
                    continue;
                }
                cleared += 1;
                let ray = Ray {
                    o,
                    d,
                    t_min: 1e-9,
                    skip: Some((i as i64, j as i64, tri)),
                };
                assert_eq!(
                    tracer.first_hit(&ray, Method::Grid),
                    None,
                    "seed {seed}: cleared ray from {o:?} along {d:?}"
                );
            }
            // The bound is worth having: a good share of the rays is cleared.
            assert!(cleared * 5 > total, "seed {seed}: {cleared} of {total}");
        }
    }
}
