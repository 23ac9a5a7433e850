#![allow(missing_docs)] // criterion_group! generates undocumented functions
//! Rays traced per second on a 1024 × 1024 Gaussian height field (2 097 152
//! triangles): first hits by the max-mip hierarchy, by a flat grid DDA and by brute
//! force over every cell; and whole paths (every bounce, ideal mirrors) on one thread
//! and on all. Then the issue-40 case, `gonio micro`'s own work: the Gaussian gold
//! surface of `config/micro-gaussian-gold.toml` (512 × 512 cells, a conductor)
//! tabulated on its default 10°,15° grid, 1024 rays an incident node (221 184
//! rays), on one thread and on two.
//!
//! `cargo bench -p gonio-micro --bench trace -- --warm-up-time 1 --measurement-time 3`;
//! figures and the machine are in BENCHMARKS.md ("Virtual gonioreflectometer").

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use gonio_core::{Channels, Dir, SphericalDeg, Vec3};
use gonio_micro::{
    GaussianParams, HeightField, Material, Method, Ray, Sample, SimOptions, Simulation,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// RMS slope 0.3 either way: `l = 5` cells (rough at the cell scale) or `l = 40`
/// cells (a smooth, finely sampled surface: rays cross many cells before a hit).
fn surface(l: f64) -> HeightField {
    HeightField::gaussian(&GaussianParams {
        nx: 1024,
        ny: 1024,
        spacing: 1.0,
        rms_height: 0.15 * l,
        correlation_length: l,
        seed: 1,
    })
    .expect("surface")
}

/// Primary rays: uniform start points over the patch at the highest node, directions
/// cosine-distributed over the hemisphere (as a diffuse source would send them).
/// With `grazing`, every direction is at θ = 85° instead.
fn rays(hf: &HeightField, n: usize, grazing: bool) -> Vec<Ray> {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (lx, ly) = hf.period();
    (0..n)
        .map(|_| {
            let (u0, u1): (f64, f64) = (rng.random(), rng.random());
            let u0 = if grazing {
                85f64.to_radians().sin().powi(2)
            } else {
                u0
            };
            let r = u0.sqrt();
            let phi = std::f64::consts::TAU * u1;
            let wi = Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u0).sqrt());
            Ray {
                o: Vec3::new(
                    rng.random::<f64>() * lx,
                    rng.random::<f64>() * ly,
                    hf.max_height(),
                ),
                d: -wi,
                t_min: 0.0,
                skip: None,
            }
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    bench_gold_table(c);
    for l in [5.0, 40.0] {
        bench_surface(c, l);
    }
}

/// The table `gonio micro config/micro-gaussian-gold.toml` traces (its surface and
/// grid), with 1024 rays an incident node instead of 100 000.
fn bench_gold_table(c: &mut Criterion) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../config/micro-gaussian-gold.toml");
    let sample = Sample::load(&path).expect("the gold surface");
    let sim = Simulation::new(sample, SimOptions::default()).expect("simulation");
    let grid = gonio_process::Grid::hemisphere(9, 24);
    let rays = 1024;
    let mut g = c.benchmark_group("table_gold_512x512");
    g.sample_size(10);
    g.throughput(Throughput::Elements((rays * grid.n_in()) as u64));
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        g.bench_function(format!("{threads}_threads"), |b| {
            b.iter(|| pool.install(|| sim.to_table(&grid, rays, 1).expect("table").stats.exits))
        });
    }
    g.finish();
}

fn bench_surface(c: &mut Criterion, l: f64) {
    let hf = surface(l);
    let sample = Sample::new(
        Channels::Single,
        hf.clone(),
        vec![Material::Mirror {
            reflectance: vec![1.0],
        }],
        0.0,
    )
    .expect("sample");
    let sim = Simulation::new(sample.clone(), SimOptions::default()).expect("simulation");
    let sim_grid = Simulation::new(
        sample,
        SimOptions {
            method: Method::Grid,
            ..SimOptions::default()
        },
    )
    .expect("simulation");
    let tracer = sim.tracer();

    let mut g = c.benchmark_group(format!("first_hit_1024x1024_l{l}"));
    let many = rays(&hf, 4096, false);
    let grazing = rays(&hf, 4096, true);
    for (set, rs) in [("cosine", &many), ("grazing85", &grazing)] {
        for (name, method) in [("max_mip", Method::MaxMip), ("grid_dda", Method::Grid)] {
            g.throughput(Throughput::Elements(rs.len() as u64));
            g.bench_function(format!("{set}/{name}"), |b| {
                b.iter(|| {
                    let mut hits = 0usize;
                    for r in rs.iter() {
                        hits += usize::from(tracer.first_hit(black_box(r), method).is_some());
                    }
                    hits
                })
            });
        }
    }
    let few = &many[..8];
    g.sample_size(10);
    g.throughput(Throughput::Elements(few.len() as u64));
    g.bench_function("cosine/brute_force", |b| {
        b.iter(|| {
            let mut hits = 0usize;
            for r in few {
                hits += usize::from(tracer.first_hit(black_box(r), Method::BruteForce).is_some());
            }
            hits
        })
    });
    g.finish();

    let mut g = c.benchmark_group(format!("paths_1024x1024_l{l}_mirror"));
    let n = 1 << 14;
    let wi = Dir::from(SphericalDeg::new(45.0, 0.0));
    g.throughput(Throughput::Elements(n as u64));
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        for (name, s) in [("max_mip", &sim), ("grid_dda", &sim_grid)] {
            g.bench_function(format!("{name}/{threads}_threads"), |b| {
                b.iter(|| pool.install(|| s.trace(wi, n, 3).expect("trace").stats.exits))
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
