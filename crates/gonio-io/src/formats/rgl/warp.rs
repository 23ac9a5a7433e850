//! A piecewise-bilinear density on the unit square, conditioned on parameters, that
//! can be sampled, inverted and evaluated: the continuous `Marginal2D` warp of
//! Mitsuba 3 (`include/mitsuba/core/distr_2d.h`), which the `measured` plugin builds
//! from every 2-D field of an RGL material.
//!
//! The density is given at a `w × h` grid of nodes spanning [0, 1]² (x fastest), one
//! grid per combination of parameter values (a *slice*). Between nodes it is
//! bilinear. Sampling inverts the marginal CDF in y (trapezoid-integrated row
//! totals, linear between rows) and then the conditional CDF in x (linear between
//! columns at the sampled y), each by solving the quadratic of a linear density over
//! one patch. Parameters between their nodes blend every stored array (data and
//! CDFs) linearly, slice by slice, as the plugin does. Everything here is the
//! plugin's arithmetic in `f64` on its tables rounded to `f32` as the plugin stores
//! them, so the two agree to the plugin's own `f32` rounding (about 1e-7 relative).

/// Float epsilon of the plugin's `f32` (2⁻²⁴), by which a sample is kept off the
/// square's edges.
const EPS: f64 = 5.960_464_477_539_063e-8;

/// Up to 2^3 slices and their weights (at most three parameters).
#[derive(Clone, Copy, Debug)]
struct Blend {
    items: [(usize, f64); 8],
    n: usize,
}

impl Blend {
    fn get(&self, arr: &[f64], slice_len: usize, i: usize) -> f64 {
        self.items[..self.n]
            .iter()
            .map(|(s, w)| {
                if *w == 0.0 {
                    0.0
                } else {
                    w * arr[s * slice_len + i]
                }
            })
            .sum()
    }
}

/// A conditional piecewise-bilinear 2-D distribution (see the module).
#[derive(Clone, Debug, PartialEq)]
pub struct Warp2D {
    w: usize,
    h: usize,
    params: Vec<Vec<f64>>,
    strides: Vec<usize>,
    data: Vec<f64>,
    cond: Vec<f64>,
    marg: Vec<f64>,
    normalized: bool,
}

impl Warp2D {
    /// Builds the warp of `data`, laid out `[param 0][param 1]…[h][w]` with the
    /// parameters' node values in `params` (each strictly increasing). With
    /// `normalize`, every slice is scaled to integrate to one; `sampling` builds the
    /// CDFs ([`Warp2D::sample`], [`Warp2D::invert`]).
    pub fn new(
        data: &[f32],
        w: usize,
        h: usize,
        params: Vec<Vec<f64>>,
        normalize: bool,
        sampling: bool,
    ) -> Result<Warp2D, String> {
        if w < 2 || h < 2 {
            return Err(format!("a {h} × {w} grid: both sizes must be at least 2"));
        }
        if params.len() > 3 {
            return Err("more than three parameters".into());
        }
        for p in &params {
            if p.is_empty()
                || !p.windows(2).all(|q| q[0] < q[1])
                || !p.iter().all(|x| x.is_finite())
            {
                return Err("parameter values must be finite and strictly increasing".into());
            }
        }
        let mut slices = 1;
        let mut strides = vec![0; params.len()];
        for (i, p) in params.iter().enumerate().rev() {
            strides[i] = if p.len() > 1 { slices } else { 0 };
            slices *= p.len();
        }
        let n = w * h;
        if data.len() != slices * n {
            return Err(format!(
                "{} values where {} were expected",
                data.len(),
                slices * n
            ));
        }
        if let Some(x) = data
            .iter()
            .find(|x| !x.is_finite() || (sampling && **x < 0.0))
        {
            return Err(format!(
                "a value {x}: densities must be finite and not negative"
            ));
        }
        let (sx, sy) = (0.5 / (w - 1) as f64, 0.5 / (h - 1) as f64);
        let mut out = Vec::with_capacity(slices * n);
        let mut cond = Vec::new();
        let mut marg = Vec::new();
        for slice in data.chunks_exact(n) {
            let d = |y: usize, x: usize| slice[y * w + x] as f64;
            let mut norm = 1.0;
            if sampling {
                let c0 = cond.len();
                let mut row_sum = vec![0.0; h];
                for (y, rs) in row_sum.iter_mut().enumerate() {
                    let mut acc = 0.0;
                    for x in 0..w - 1 {
                        acc += sx * (d(y, x) + d(y, x + 1));
                        cond.push(acc);
                    }
                    *rs = acc;
                }
                let m0 = marg.len();
                let mut acc = 0.0;
                for y in 0..h - 1 {
                    acc += sy * (row_sum[y] + row_sum[y + 1]);
                    marg.push(acc);
                }
                if normalize {
                    norm = 1.0 / acc;
                }
                // Stored as f32, as the plugin stores them.
                cond[c0..].iter_mut().for_each(|c| *c = f32r(*c * norm));
                marg[m0..].iter_mut().for_each(|m| *m = f32r(*m * norm));
            } else if normalize {
                let mut sum = 0.0;
                for y in 0..h - 1 {
                    for x in 0..w - 1 {
                        sum += d(y, x) + d(y, x + 1) + d(y + 1, x) + d(y + 1, x + 1);
                    }
                }
                norm = 1.0 / (sx * sy * sum);
            }
            let norm = f32r(norm);
            out.extend(slice.iter().map(|v| f32r(*v as f64 * norm)));
        }
        Ok(Warp2D {
            w,
            h,
            params,
            strides,
            data: out,
            cond,
            marg,
            normalized: normalize,
        })
    }

    /// The slices and weights of the parameter values `param` (one a parameter):
    /// linear between nodes, clamped outside them.
    fn blend(&self, param: &[f64]) -> Blend {
        let mut b = Blend {
            items: [(0, 0.0); 8],
            n: 1,
        };
        b.items[0] = (0, 1.0);
        for (dim, values) in self.params.iter().enumerate() {
            if values.len() == 1 {
                continue;
            }
            let p = param.get(dim).copied().unwrap_or(0.0);
            // The last node below p (as `find_interval`), within [0, n − 2].
            let i = values[1..values.len() - 1].partition_point(|v| *v < p);
            let (p0, p1) = (values[i], values[i + 1]);
            let w1 = ((p - p0) / (p1 - p0)).clamp(0.0, 1.0);
            let w1 = if w1.is_nan() { 0.0 } else { w1 };
            let stride = self.strides[dim];
            let n = b.n;
            for k in 0..n {
                let (s, w) = b.items[k];
                b.items[k] = (s + i * stride, w * (1.0 - w1));
                b.items[n + k] = (s + (i + 1) * stride, w * w1);
            }
            b.n = 2 * n;
        }
        b
    }

    /// The density at `pos` (clamped into the square) for `param`: bilinear between
    /// the nodes (unnormalised data when built without `normalize`).
    pub fn eval(&self, pos: [f64; 2], param: &[f64]) -> f64 {
        let b = self.blend(param);
        let n = self.w * self.h;
        let (ix, fx) = cell(pos[0], self.w);
        let (iy, fy) = cell(pos[1], self.h);
        let i = iy * self.w + ix;
        let v = |o: usize| b.get(&self.data, n, i + o);
        let (v00, v10, v01, v11) = (v(0), v(1), v(self.w), v(self.w + 1));
        (1.0 - fx) * (1.0 - fy) * v00
            + fx * (1.0 - fy) * v10
            + (1.0 - fx) * fy * v01
            + fx * fy * v11
    }

    /// Warps the uniform `sample` to a point of the square distributed as the
    /// density for `param`; the point and its density.
    pub fn sample(&self, sample: [f64; 2], param: &[f64]) -> ([f64; 2], f64) {
        let b = self.blend(param);
        let (w, h) = (self.w, self.h);
        let (nc, nm, nd) = (h * (w - 1), h - 1, w * h);
        let mut s = [
            sample[0].clamp(EPS, 1.0 - EPS),
            sample[1].clamp(EPS, 1.0 - EPS),
        ];
        let marg = |i: usize| b.get(&self.marg, nm, i);
        if !self.normalized {
            s[1] *= marg(nm - 1);
        }
        // The first row whose CDF reaches s.y (as `binary_search` over [0, h − 2]).
        let row = (0..nm - 1).find(|&i| marg(i) >= s[1]).unwrap_or(nm - 1);
        s[1] -= if row > 0 { marg(row - 1) } else { 0.0 };
        let oc = row * (w - 1);
        let cond = |i: usize| b.get(&self.cond, nc, i);
        let (r0, r1) = (cond(oc + w - 2), cond(oc + 2 * (w - 1) - 1));
        s[1] = sample_segment(s[1], (h - 1) as f64, r0, r1);
        s[0] *= lerp(r0, r1, s[1]);
        let fetch = |i: usize| lerp(cond(oc + i), cond(oc + i + w - 1), s[1]);
        let col = (0..w - 2).find(|&i| fetch(i) >= s[0]).unwrap_or(w - 2);
        s[0] -= if col > 0 { fetch(col - 1) } else { 0.0 };
        let od = row * w + col;
        let v = |o: usize| b.get(&self.data, nd, od + o);
        let c0 = lerp(v(0), v(w), s[1]);
        let c1 = lerp(v(1), v(w + 1), s[1]);
        s[0] = sample_segment(s[0], (w - 1) as f64, c0, c1);
        let pdf = lerp(c0, c1, s[0]);
        (
            [
                (col as f64 + s[0]) / (w - 1) as f64,
                (row as f64 + s[1]) / (h - 1) as f64,
            ],
            pdf,
        )
    }

    /// The inverse of [`Warp2D::sample`]: the uniform sample that warps to `p`, and
    /// the density at `p`.
    pub fn invert(&self, p: [f64; 2], param: &[f64]) -> ([f64; 2], f64) {
        let b = self.blend(param);
        let (w, h) = (self.w, self.h);
        let (nc, nm, nd) = (h * (w - 1), h - 1, w * h);
        let (ix, x) = cell(p[0], w);
        let (iy, y) = cell(p[1], h);
        let od = iy * w + ix;
        let v = |o: usize| b.get(&self.data, nd, od + o);
        let c0 = lerp(v(0), v(w), y);
        let c1 = lerp(v(1), v(w + 1), y);
        let pdf = lerp(c0, c1, x);
        let mut sx = invert_segment(x, 1.0 / (w - 1) as f64, c0, c1);
        let oc = iy * (w - 1);
        let cond = |i: usize| b.get(&self.cond, nc, i);
        if ix > 0 {
            sx += lerp(cond(oc + ix - 1), cond(oc + ix - 1 + w - 1), y);
        }
        let (r0, r1) = (cond(oc + w - 2), cond(oc + 2 * (w - 1) - 1));
        sx /= lerp(r0, r1, y);
        let mut sy = invert_segment(y, 1.0 / (h - 1) as f64, r0, r1);
        let marg = |i: usize| b.get(&self.marg, nm, i);
        if iy > 0 {
            sy += marg(iy - 1);
        }
        if !self.normalized {
            sy /= marg(nm - 1);
        }
        ([sx, sy], pdf)
    }
}

/// `x` rounded to the nearest `f32`.
fn f32r(x: f64) -> f64 {
    x as f32 as f64
}

/// The patch a coordinate falls in (clamped into [0, 1], the last patch for 1) and
/// the fraction across it.
fn cell(x: f64, n: usize) -> (usize, f64) {
    let x = x.clamp(0.0, 1.0) * (n - 1) as f64;
    let i = (x as usize).min(n - 2);
    (i, x - i as f64)
}

fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + (b - a) * t
}

/// The fraction across a patch of width `1/inv_width` at which a density linear from
/// `v0` to `v1` has integrated to `sample` (the quadratic's root; linear when the
/// density is nearly constant).
fn sample_segment(sample: f64, inv_width: f64, v0: f64, v1: f64) -> f64 {
    let non_const = (v0 - v1).abs() > 1e-4 * (v0 + v1);
    let divisor = if non_const { v0 - v1 } else { v0 + v1 };
    let mut s = sample * 2.0 * inv_width;
    if non_const {
        s = v0 - (v0 * v0 + s * (v1 - v0)).max(0.0).sqrt();
    }
    if divisor != 0.0 { s / divisor } else { s }
}

/// The integral over the first `t` of a patch of `width` of a density linear from
/// `v0` to `v1`.
fn invert_segment(t: f64, width: f64, v0: f64, v1: f64) -> f64 {
    t * lerp(v0, v1, 0.5 * t) * width
}

#[cfg(test)]
mod tests {
    use super::*;

    fn warp() -> Warp2D {
        // Two slices (a parameter at 0 and 1) of a 5 × 4 density.
        let data: Vec<f32> = (0..40).map(|i| 0.5 + ((i * 7) % 11) as f32).collect();
        Warp2D::new(&data, 5, 4, vec![vec![0.0, 1.0]], true, true).unwrap()
    }

    #[test]
    fn invert_undoes_sample_and_the_density_integrates_to_one() {
        let w = warp();
        for p in [0.0, 0.3, 1.0] {
            for (i, j) in (1..40).map(|k| (k, (k * 17) % 41)) {
                let u = [i as f64 / 41.0, j as f64 / 41.0];
                let (x, pdf) = w.sample(u, &[p]);
                let (back, pdf2) = w.invert(x, &[p]);
                assert!(
                    (back[0] - u[0]).abs() < 1e-9 && (back[1] - u[1]).abs() < 1e-9,
                    "{u:?} {back:?}"
                );
                assert!((pdf - pdf2).abs() < 1e-9 * pdf.max(1.0));
                assert!((w.eval(x, &[p]) - pdf).abs() < 1e-9 * pdf.max(1.0));
            }
            // Midpoint rule on a fine grid: the bilinear density integrates to 1.
            let n = 400;
            let total: f64 = (0..n * n)
                .map(|k| {
                    let (i, j) = (k % n, k / n);
                    w.eval(
                        [(i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64],
                        &[p],
                    )
                })
                .sum::<f64>()
                / (n * n) as f64;
            assert!((total - 1.0).abs() < 1e-5, "{total}");
        }
    }

    #[test]
    fn parameters_between_nodes_blend_the_slices() {
        let w = warp();
        let (a, b) = (w.eval([0.3, 0.6], &[0.0]), w.eval([0.3, 0.6], &[1.0]));
        assert!((w.eval([0.3, 0.6], &[0.25]) - (0.75 * a + 0.25 * b)).abs() < 1e-12);
        // Clamped outside the nodes.
        assert_eq!(w.eval([0.3, 0.6], &[-3.0]), a);
        assert_eq!(w.eval([0.3, 0.6], &[7.0]), b);
    }
}
#[cfg(test)]
mod probe {
    #[test]
    fn probe() {
        let w = super::tests_warp();
        for p in [0.0, 0.3, 1.0] {
            for u in [[0.2, 0.7], [0.9, 0.1], [0.55, 0.45]] {
                let (x, pdf) = w.sample(u, &[p]);
                let (inv, pdf2) = w.invert(u, &[p]);
                println!("{p} {u:?} {x:?} {pdf} {inv:?} {pdf2} {}", w.eval(u, &[p]));
            }
        }
    }
}
#[cfg(test)]
fn tests_warp() -> Warp2D {
    let data: Vec<f32> = (0..40).map(|i| 0.5 + ((i * 7) % 11) as f32).collect();
    Warp2D::new(&data, 5, 4, vec![vec![0.0, 1.0]], true, true).unwrap()
}
