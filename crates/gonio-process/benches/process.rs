#![allow(missing_docs)] // criterion_group! generates undocumented functions
//! Throughput of processing: DeYoung's measures and transforms on tabulated BRDFs,
//! P_s^(k) against a naive reconstruction, nearest-j kernel interpolation against a
//! brute-force scan, resampling, spherical-harmonic and separable representations
//! against quadrilinear table evaluation; the albedos' quadrature σ and the
//! measures' floors.
//!
//! `cargo bench -p gonio-process --bench process`; figures and the machine are in
//! BENCHMARKS.md at the repository root. Each reference (a streaming pass over the
//! values, the naive SVD reconstruction, the brute-force nearest-j scan, the table's
//! own evaluation) is timed in the same group as the
//! figure it stands beside.

use std::hint::black_box;

use std::time::Duration;

use criterion::measurement::WallTime;
use criterion::{
    BenchmarkGroup, Criterion, SamplingMode, Throughput, criterion_group, criterion_main,
};
use faer::Mat;
use gonio_brdf::{Brdf, Model};
use gonio_core::dirfile::PairDeg;
use gonio_core::rng::SplitMix64;
use gonio_core::{Channels, Dir, SphericalDeg, Vec3};
use gonio_process::samples::Kernel;
use gonio_process::separable::SeparableBrdf;
use gonio_process::sh::{ShBrdf, ShOptions};
use gonio_process::transform::{self, EnergyMode};
use gonio_process::{Grid, Samples, Table, measure};

/// The blue paint of docs/CONVENTIONS.md (one Lafortune lobe + Lambert, RGB).
const BLUE_PAINT: &str = r#"
kind = "lafortune"
channels = ["R", "G", "B"]
[diffuse]
rho = [0.3094, 0.39667, 0.70837]
[[lobes]]
cx = [0.870567, 0.857255, 0.670982]
cy = [0.870567, 0.857255, 0.670982]
cz = [0.803624, 0.774290, 0.586674]
n  = [21.820103, 18.597755, 7.472717]
"#;

/// DeYoung's non-reciprocal "Phong shading" BRDF (config/models/phong-shading.toml).
const PHONG_SHADING: &str = r#"
kind = "phong"
channels = ["value"]
rho_s = [0.3]
n = [10]
shading = true
[diffuse]
rho = [0.5]
"#;

/// Scattered samples the kernel interpolates, and queries per timed batch.
const N_SAMPLES: usize = 20_000;
const N_QUERIES: usize = 1_000;
/// Direction pairs per timed batch of evaluations.
const N_EVAL: usize = 1024;

fn model(text: &str) -> Model {
    Model::from_toml(text, None).expect("valid bench model")
}

/// The 10° grid: 9 polar midpoints × 36 azimuths each side, 104 976 nodes.
fn grid10() -> Grid {
    Grid::hemisphere(9, 36)
}

/// The 5° grid: 18 × 72 each side, 1 679 616 nodes.
fn grid5() -> Grid {
    Grid::hemisphere(18, 72)
}

fn table(m: &Model, g: Grid) -> Table {
    Table::from_brdf(m, g).expect("tabulates")
}

/// SplitMix64: a seeded generator, so every run draws the same samples.
struct SplitMix(SplitMix64);

impl SplitMix {
    fn next_f64(&mut self) -> f64 {
        (self.0.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A direction uniform in solid angle over the hemisphere, θ < 90°.
    fn direction(&mut self) -> SphericalDeg {
        let cos_t = 1.0 - self.next_f64(); // (0, 1]
        SphericalDeg::new(cos_t.acos().to_degrees(), 360.0 * self.next_f64())
    }
}

/// `n` random direction pairs, uniform in solid angle on each side.
fn random_pairs(seed: u64, n: usize) -> Vec<PairDeg> {
    let mut r = SplitMix(SplitMix64::new(seed));
    (0..n)
        .map(|_| PairDeg {
            incident: r.direction(),
            outgoing: r.direction(),
        })
        .collect()
}

/// Well-spread pairs strictly above the surface (a Fibonacci lattice, as the brdf
/// bench uses).
fn eval_pairs() -> Vec<(Dir, Dir)> {
    let golden = 0.5 * (1.0 + 5f64.sqrt());
    let dir = |k: usize| {
        let z = (k as f64 + 0.5) / N_EVAL as f64;
        let phi = std::f64::consts::TAU * (k as f64 / golden).fract();
        let s = (1.0 - z * z).sqrt();
        Dir::new(Vec3::new(s * phi.cos(), s * phi.sin(), z)).expect("unit")
    };
    (0..N_EVAL)
        .map(|k| (dir(k), dir((k * 7 + 3) % N_EVAL)))
        .collect()
}

/// The reference of the measures: one streaming pass over every value of the table
/// (8 independent accumulators, so the loop is bound by memory, not by the latency of
/// one chain of additions).
fn stream_sum(v: &[f64]) -> f64 {
    let mut acc = [0.0; 8];
    let chunks = v.chunks_exact(8);
    let rest: f64 = chunks.remainder().iter().sum();
    for c in chunks {
        for (a, x) in acc.iter_mut().zip(c) {
            *a += x;
        }
    }
    acc.iter().sum::<f64>() + rest
}

/// A group for work that takes from tens of milliseconds to seconds an iteration.
fn slow<'a>(c: &'a mut Criterion, name: &str, secs: f64) -> BenchmarkGroup<'a, WallTime> {
    let mut g = c.benchmark_group(name);
    g.sample_size(10)
        .sampling_mode(SamplingMode::Flat)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs_f64(secs));
    g
}

/// One channel of a table, as a single-channel table: the measures treat channels one
/// after the other, so its rates are the per-channel rates.
fn first_channel(t: &Table) -> Table {
    Table::new(Channels::Single, t.grid, t.channel(0).to_vec(), None).expect("one channel")
}

/// The four measures (and the whole report) on one channel, beside a pass over its
/// values.
fn measures_on(c: &mut Criterion, name: &str, t: &Table, secs: f64, with_report: bool) {
    let mut g = slow(c, name, secs);
    g.throughput(Throughput::Elements(t.values.len() as u64));
    g.bench_function("reference: one pass over the values (sum)", |b| {
        b.iter(|| black_box(stream_sum(black_box(&t.values))))
    });
    g.bench_function("P_r reciprocity", |b| {
        b.iter(|| black_box(measure::reciprocity(black_box(t))))
    });
    g.bench_function("P_ec energy (tau 1, 5 worst)", |b| {
        b.iter(|| black_box(measure::energy(black_box(t), 1.0, 5)))
    });
    g.bench_function("P_i isotropy", |b| {
        b.iter(|| black_box(measure::isotropy(black_box(t)).expect("isotropy")))
    });
    g.bench_function("P_s separability k = 1, 5", |b| {
        b.iter(|| black_box(measure::separability(black_box(t), &[1, 5]).expect("P_s")))
    });
    if with_report {
        g.bench_function("report (all four)", |b| {
            b.iter(|| black_box(measure::report(black_box(t), &[1, 5], 5).expect("report")))
        });
    }
    g.finish();
}

/// The measures on the blue paint's R channel.
fn measures(c: &mut Criterion) {
    let paint = model(BLUE_PAINT);
    let t10 = first_channel(&table(&paint, grid10()));
    measures_on(c, "measures 10deg one channel", &t10, 2.0, true);
    drop(t10);
    let t5 = first_channel(&table(&paint, grid5()));
    measures_on(c, "measures 5deg one channel", &t5, 3.0, false);
}

fn transforms(c: &mut Criterion) {
    let t = table(&model(BLUE_PAINT), grid10());
    let mut g = slow(c, "transforms 10deg RGB", 2.0);
    g.throughput(Throughput::Elements(t.values.len() as u64));
    g.bench_function("reciprocity delta 1", |b| {
        b.iter(|| black_box(transform::reciprocity(black_box(&t), 1.0).expect("transform")))
    });
    g.bench_function("energy delta 1 per direction", |b| {
        b.iter(|| {
            black_box(
                transform::energy(black_box(&t), 1.0, EnergyMode::PerDirection, 1.0)
                    .expect("transform"),
            )
        })
    });
    g.bench_function("isotropy delta 1", |b| {
        b.iter(|| black_box(transform::isotropy(black_box(&t), 1.0).expect("transform")))
    });
    g.bench_function("separable k 5 delta 1", |b| {
        b.iter(|| black_box(transform::separable(black_box(&t), 5, 1.0).expect("transform")))
    });
    g.finish();
}

/// The naive P_s^(k): form A^(k) = U D_k Vᵀ from a thin SVD and take the Frobenius
/// norm of A − A^(k) (DeYoung Eq. 4.18–4.20 as written), for one channel.
fn naive_p_s(t: &Table, ks: &[usize]) -> Vec<f64> {
    let (p, q) = (t.grid.n_in(), t.grid.n_out());
    let v = t.channel(0);
    let a = Mat::from_fn(p, q, |r, c| v[r * q + c]);
    let svd = a.thin_svd().expect("SVD converges");
    let (u, s, vt) = (svd.U(), svd.S().column_vector(), svd.V());
    ks.iter()
        .map(|&k| {
            let us = Mat::from_fn(p, k, |r, j| u[(r, j)] * s[j]);
            let vk = Mat::from_fn(q, k, |c, j| vt[(c, j)]);
            let ak = &us * vk.transpose();
            (&a - &ak).norm_l2() / ((p * q) as f64).sqrt()
        })
        .collect()
}

fn separability(c: &mut Criterion) {
    let phong = model(PHONG_SHADING);
    for (name, grid, secs) in [
        ("P_s one channel 10deg", grid10(), 3.0),
        ("P_s one channel 5deg", grid5(), 8.0),
    ] {
        let t = table(&phong, grid);
        let ks = [1, 5];
        // The two agree before either is timed.
        let fast = measure::separability(&t, &ks).expect("P_s");
        let naive = naive_p_s(&t, &ks);
        for ((k, a), b) in fast[0].p_s.iter().zip(&naive) {
            assert!(
                (a - b).abs() <= 1e-9 * b.abs().max(1e-300),
                "P_s^({k}): {a} vs naive {b}"
            );
        }
        eprintln!("{name}: P_s^(1), P_s^(5) = {:?}", fast[0].p_s);
        let mut g = slow(c, name, secs);
        g.bench_function("crate: singular values, Eckart-Young tail", |b| {
            b.iter(|| black_box(measure::separability(black_box(&t), &ks).expect("P_s")))
        });
        g.bench_function("naive: thin SVD, A^(k) = U D_k V^T, |A - A^(k)|_F", |b| {
            b.iter(|| black_box(naive_p_s(black_box(&t), &ks)))
        });
        g.finish();
    }
}

/// The crate's R⁶ point of a pair (samples.rs, not isotropic).
fn key(p: &PairDeg) -> [f64; 6] {
    let (wi, wo) = (Dir::from(p.incident), Dir::from(p.outgoing));
    [wi.x, wi.y, wi.z, wo.x, wo.y, wo.z]
}

/// The nearest-j Gaussian kernel by a linear scan of every sample: what one writes
/// without a spatial index. Same distance, same weights as the crate.
struct BruteForce {
    keys: Vec<[f64; 6]>,
    values: Vec<Vec<f64>>,
    kernel: Kernel,
}

impl BruteForce {
    fn new(s: &Samples, kernel: Kernel) -> BruteForce {
        BruteForce {
            keys: s.samples.iter().map(|x| key(&x.pair)).collect(),
            values: s.samples.iter().map(|x| x.value.clone()).collect(),
            kernel,
        }
    }

    fn eval(&self, pair: &PairDeg) -> Vec<f64> {
        let q = key(pair);
        let j = self.kernel.j;
        let mut best: Vec<(f64, usize)> = Vec::with_capacity(j + 1);
        for (i, k) in self.keys.iter().enumerate() {
            let d2: f64 = (0..6).map(|d| (k[d] - q[d]).powi(2)).sum();
            if best.len() < j || d2 < best[best.len() - 1].0 {
                let at = best.partition_point(|e| e.0 <= d2);
                best.insert(at, (d2, i));
                best.truncate(j);
            }
        }
        let mean_d = best.iter().map(|(d2, _)| d2.sqrt()).sum::<f64>() / best.len() as f64;
        let s2 = 2.0 * (self.kernel.width * mean_d).powi(2);
        let w: Vec<(f64, usize)> = best.iter().map(|&(d2, i)| ((-d2 / s2).exp(), i)).collect();
        let sw: f64 = w.iter().map(|x| x.0).sum();
        let mut out = vec![0.0; self.values[0].len()];
        for (wk, i) in w {
            for (o, x) in out.iter_mut().zip(&self.values[i]) {
                *o += wk * x / sw;
            }
        }
        out
    }
}

fn interpolation(c: &mut Criterion) {
    let paint = model(BLUE_PAINT);
    let samples = Samples::from_brdf(&paint, &random_pairs(1, N_SAMPLES));
    let queries = random_pairs(2, N_QUERIES);
    let kernel = Kernel::default();
    let interp = samples.interpolator(kernel).expect("interpolator");
    let brute = BruteForce::new(&samples, kernel);
    for q in queries.iter().take(100) {
        let (a, b) = (interp.eval(q).0, brute.eval(q));
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() <= 1e-12 * y.abs().max(1.0), "{a:?} vs {b:?}");
        }
    }
    let mut g = c.benchmark_group("interpolate 20k scattered samples, j = 8");
    g.warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(2));
    g.throughput(Throughput::Elements(N_QUERIES as u64));
    g.bench_function("crate: k-d tree nearest-j kernel, eval", |b| {
        b.iter(|| {
            for q in &queries {
                black_box(interp.eval(black_box(q)));
            }
        })
    });
    g.sample_size(10).sampling_mode(SamplingMode::Flat);
    g.bench_function("naive: linear scan nearest-j kernel, eval", |b| {
        b.iter(|| {
            for q in &queries {
                black_box(brute.eval(black_box(q)));
            }
        })
    });
    g.throughput(Throughput::Elements(N_SAMPLES as u64));
    g.bench_function("build the interpolator (validate, k-d tree)", |b| {
        b.iter(|| black_box(samples.interpolator(kernel).expect("interpolator")))
    });
    g.finish();

    let mut g = slow(c, "resample 20k samples onto the 10deg grid", 3.0);
    g.throughput(Throughput::Elements(grid10().len() as u64));
    g.bench_function("crate: Samples::resample (rayon, 2 threads)", |b| {
        b.iter(|| black_box(samples.resample(grid10(), kernel).expect("resamples")))
    });
    g.bench_function("reference: Table::from_brdf of the model itself", |b| {
        b.iter(|| black_box(table(black_box(&paint), grid10())))
    });
    g.finish();
}

fn harmonics(c: &mut Criterion) {
    let paint = model(BLUE_PAINT);
    let t = table(&paint, grid10());
    let mut g = slow(c, "SH projection from the 10deg RGB table", 3.0);
    for l in [4, 8, 16] {
        g.bench_function(format!("l_max {l}"), |b| {
            b.iter(|| black_box(ShBrdf::from_table(black_box(&t), &ShOptions::new(l)).expect("SH")))
        });
    }
    g.finish();

    let sh8 = ShBrdf::from_table(&t, &ShOptions::new(8)).expect("SH");
    let sh16 = ShBrdf::from_table(&t, &ShOptions::new(16)).expect("SH");
    let sep = SeparableBrdf::from_table(&t, 5, false).expect("separates");
    let pairs = eval_pairs();
    let mut out = [0.0; 3];
    let mut g = c.benchmark_group("eval RGB");
    g.warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(2));
    g.throughput(Throughput::Elements(N_EVAL as u64));
    let mut run = |name: &str, f: &dyn Fn(Dir, Dir, &mut [f64])| {
        g.bench_function(name, |b| {
            b.iter(|| {
                for &(wi, wo) in &pairs {
                    f(black_box(wi), black_box(wo), &mut out);
                    black_box(&out);
                }
            })
        });
    };
    run("reference: Table::eval quadrilinear, 10deg", &|a, b, o| {
        t.eval(a, b, o)
    });
    run("reference: the analytic model", &|a, b, o| {
        paint.eval(a, b, o)
    });
    run("ShBrdf::eval l_max 8", &|a, b, o| sh8.eval(a, b, o));
    run("ShBrdf::eval l_max 16", &|a, b, o| sh16.eval(a, b, o));
    run("SeparableBrdf::eval k 5", &|a, b, o| sep.eval(a, b, o));
    g.finish();

    let mut g = slow(c, "separable factorisation 10deg RGB", 3.0);
    g.bench_function("SeparableBrdf::from_table k 5", |b| {
        b.iter(|| black_box(SeparableBrdf::from_table(black_box(&t), 5, false).expect("separates")))
    });
    g.finish();
    eprintln!(
        "separable k = 5: storage ratio {:.4}; SH l_max 8: {} coefficients (compression {:.4}), l_max 16: {} ({:.4})",
        sep.storage_ratio(),
        sh8.coefficient_count(),
        sh8.compression(&t),
        sh16.coefficient_count(),
        sh16.compression(&t)
    );
}

/// The plan's own grid (config/plan-hemisphere.toml unfolded: θi 0…75 by 15, a full
/// turn of Δφ by 15, θo 0…80 by 10; 1 296 nodes), one channel of the paint, with a
/// run's σ (1e-4 relative) when `sigma`.
fn plan_table(sigma: bool) -> Table {
    use gonio_process::Axis;
    let g = Grid::isotropic(
        Axis::from_deg(0.0, 15.0, 6),
        Axis::full_turn(24),
        Axis::from_deg(0.0, 10.0, 9),
    );
    let mut t = first_channel(&table(&model(BLUE_PAINT), g));
    if sigma {
        t.sigma = Some(t.values.iter().map(|v| 1e-4 * v.abs() + 1e-6).collect());
    }
    t
}

/// The albedos' quadrature σ and the measures' floors, against the measures alone.
fn floors(c: &mut Criterion) {
    use gonio_process::{floor, hemisphere};
    let t = plan_table(true);
    let mut g = slow(c, "floors, plan grid one channel", 2.0);
    g.throughput(Throughput::Elements(t.values.len() as u64));
    g.bench_function("triangulated albedos with quadrature σ (6 rows)", |b| {
        b.iter(|| black_box(hemisphere::albedos_of_table(black_box(&t)).expect("albedos")))
    });
    let r = measure::report(&t, &[1], 5).expect("report");
    g.bench_function("P_r floor, 64 noise draws", |b| {
        b.iter(|| black_box(floor::reciprocity_floor(black_box(&t), &r.reciprocity, 64)))
    });
    g.bench_function("all floors, 64 noise draws (P_s k = 1)", |b| {
        b.iter(|| black_box(floor::floors(black_box(&t), None, &r, &[1], 64).expect("floors")))
    });
    g.bench_function("report with floors (k = 1)", |b| {
        b.iter(|| black_box(measure::report(black_box(&t), &[1], 5).expect("report")))
    });
    g.finish();
    let t10 = first_channel(&table(&model(BLUE_PAINT), grid10()));
    let r10 = measure::report(&t10, &[1, 5], 5).expect("report");
    let mut g = slow(c, "floors 10deg one channel, no sigma", 2.0);
    g.throughput(Throughput::Elements(t10.values.len() as u64));
    g.bench_function("all floors, interpolation alone", |b| {
        b.iter(|| {
            black_box(floor::floors(black_box(&t10), None, &r10, &[1, 5], 0).expect("floors"))
        })
    });
    g.finish();
}

criterion_group!(
    benches,
    floors,
    measures,
    transforms,
    separability,
    interpolation,
    harmonics
);
criterion_main!(benches);
