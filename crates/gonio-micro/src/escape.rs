//! Rays that certainly leave: a per-cell bound on how steeply the surface around a
//! cell can rise, so that a ray leaving a facet more steeply than that is known to
//! escape without a search.
//!
//! A ray leaves a point `p` of cell `C` on the surface (`p.z = h(p)`) with
//! horizontal unit direction `u` and slope `s = d_z / |d_xy|`; at horizontal
//! distance `r` it is at `h(p) + s·r`. It meets nothing if that is above the surface
//! everywhere along its way:
//!
//! - **Near** (within the 3 × 3 cells around `C`, a convex square holding the
//!   segment from `p`): the surface is piecewise planar and continuous, so along the
//!   segment it rises at most `L_C·r`, `L_C` the largest gradient norm of the
//!   neighbourhood's 18 triangles. `s > L_C` clears it.
//! - **Far** (a cell `Q` at Chebyshev distance `k ≥ 2` from `C`): every point of `Q`
//!   is at least `(k − 1)·δ` from every point of `C` (`δ` the smaller spacing), and
//!   the surface over `Q` is at most `M_k(C)`, the highest node of the cells within
//!   distance `k` of `C`. `s·(k − 1)·δ > M_k(C) − z_C` clears `Q`, `z_C` the lowest
//!   corner of `C` (no point of `C`'s surface is lower); past `K` rings the highest
//!   node of all bounds `M_k`.
//!
//! So `s > B_C = max(L_C, max_k (M_k − z_C)/((k − 1)δ))` proves the ray escapes,
//! and the search it skips would have found no hit: the path's bytes are the same.
//! The bound is stored rounded up by a relative 10⁻⁶, far above the rounding of the
//! heights, the hit point and the direction. The patch repeats, so the rings are
//! read with wrapped indices (on a small patch a ring meets cells twice: the
//! maximum of a superset is still a bound). For a Gaussian surface of RMS slope 0.3
//! `B_C` is about 1, so most rays leaving above 45° of elevation need no search.

use rayon::prelude::*;

use gonio_core::Vec3;

use crate::HeightField;

/// Rings bounded one by one (`2 ≤ k < RINGS`); beyond, the highest node.
const RINGS: usize = 10;

/// Steps of the stored `B_C²` a doubling: codes are `2^((q − 128)/16)` (steps of
/// 4.4 %), so a byte spans `2⁻⁸ … 2^7.9` and the table stays in a core's cache.
const STEPS: f64 = 16.0;

/// The code of a bound too steep to store: never clears.
const NEVER: u8 = u8::MAX;

/// The per-cell escape slopes of a height field (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Escape {
    nx: usize,
    ny: usize,
    /// Each cell's `B_C²` rounded up to a code, row-major.
    code: Vec<u8>,
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

/// The least code whose value (`values[q]`, [`level`]'s) is at least `b2`.
fn encode(b2: f64, values: &[f64]) -> u8 {
    let guess = ((b2.log2() * STEPS).ceil() + 128.0).clamp(0.0, f64::from(NEVER));
    // `log2` may round either way: settle on the least code at or above `b2`.
    let mut q = guess as u8;
    while q < NEVER && values[usize::from(q)] < b2 {
        q += 1;
    }
    while q > 0 && values[usize::from(q - 1)] >= b2 {
        q -= 1;
    }
    q
}

/// `max` over the 3 × 3 cells around each cell of a periodic `nx × ny` field (rows
/// of `nx`), into `out`; `tmp` holds the rows' pass.
fn max3x3(v: &[f64], nx: usize, out: &mut [f64], tmp: &mut [f64]) {
    let ny = v.len() / nx;
    // Along x: the three neighbours of a row, wrapped at its two ends only.
    tmp.par_chunks_mut(nx)
        .zip(v.par_chunks(nx))
        .for_each(|(t, r)| {
            for i in 0..nx {
                let l = if i == 0 { nx - 1 } else { i - 1 };
                let h = if i + 1 == nx { 0 } else { i + 1 };
                t[i] = r[l].max(r[i]).max(r[h]);
            }
        });
    let tmp = &*tmp;
    out.par_chunks_mut(nx).enumerate().for_each(|(j, o)| {
        let d = &tmp[(if j == 0 { ny - 1 } else { j - 1 }) * nx..][..nx];
        let m = &tmp[j * nx..][..nx];
        let u = &tmp[(if j + 1 == ny { 0 } else { j + 1 }) * nx..][..nx];
        for i in 0..nx {
            o[i] = d[i].max(m[i]).max(u[i]);
        }
    });
}

impl Escape {
    /// The bounds of every cell of `hf`.
    pub(crate) fn new(hf: &HeightField) -> Escape {
        let (nx, ny) = (hf.nx(), hf.ny());
        let (dx, dy) = (hf.dx(), hf.dy());
        let delta = dx.min(dy);
        let n = nx * ny;
        // Per cell: the steeper triangle's gradient norm, the highest and the lowest
        // corner.
        let (mut grad, mut top, mut low) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
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
                    g[i] = norm(0).max(norm(1));
                    t[i] = c[0].max(c[1]).max(c[2]).max(c[3]);
                    l[i] = c[0].min(c[1]).min(c[2]).min(c[3]);
                }
            });
        let mut tmp = vec![0.0; n];
        // B starts as the near bound and takes each ring's in turn.
        let mut bound = vec![0.0; n];
        max3x3(&grad, nx, &mut bound, &mut tmp);
        let mut ring = vec![0.0; n];
        max3x3(&top, nx, &mut ring, &mut tmp);
        let mut next = grad;
        for k in 2..RINGS {
            max3x3(&ring, nx, &mut next, &mut tmp);
            std::mem::swap(&mut ring, &mut next);
            let gap = (k - 1) as f64 * delta;
            bound
                .par_iter_mut()
                .zip(&ring)
                .zip(&low)
                .for_each(|((b, m), z)| *b = b.max((m - z) / gap));
        }
        let h_max = hf.max_height();
        let tail = (RINGS - 1) as f64 * delta;
        let value: Vec<f64> = (0..=NEVER).map(level).collect();
        let code = bound
            .par_iter()
            .zip(&low)
            .map(|(b, z)| {
                let b = b.max((h_max - z) / tail) * (1.0 + 1e-6) + 1e-9;
                encode(b * b, &value)
            })
            .collect();
        Escape {
            nx,
            ny,
            code,
            value,
        }
    }

    /// `B_C²` of cell `(i, j)` (unwrapped), rounded up, for [`clears`].
    #[inline]
    pub(crate) fn slope2(&self, i: i64, j: i64) -> f64 {
        // A mask on the usual power-of-two patches: a remainder would cost more
        // than the search it saves.
        let wrap = |k: i64, n: usize| {
            if n.is_power_of_two() {
                (k & (n as i64 - 1)) as usize
            } else {
                k.rem_euclid(n as i64) as usize
            }
        };
        self.value[usize::from(self.code[wrap(j, self.ny) * self.nx + wrap(i, self.nx)])]
    }
}

/// True when a ray along `d` from a point on the surface of a cell whose
/// [`Escape::slope2`] is `b2` certainly meets no facet: it climbs more steeply than
/// `B_C`.
#[inline]
pub(crate) fn clears(b2: f64, d: Vec3) -> bool {
    d.z > 0.0 && d.z * d.z > b2 * (d.x * d.x + d.y * d.y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Method, Ray, Tracer};

    #[test]
    fn codes_round_up_by_less_than_a_step() {
        let values: Vec<f64> = (0..=NEVER).map(level).collect();
        for b2 in [
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
            let q = encode(b2, &values);
            assert!(level(q) >= b2, "{b2}: code {q}");
            if q > 0 && q < NEVER {
                assert!(level(q - 1) < b2, "{b2}: code {q} is not the least");
            }
        }
        assert_eq!(encode(1e6, &values), NEVER);
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
                if !clears(esc.slope2(i as i64, j as i64), d) {
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
