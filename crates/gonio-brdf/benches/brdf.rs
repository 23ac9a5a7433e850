#![allow(missing_docs)] // criterion_group! generates undocumented functions
//! Throughput of BRDF evaluation, sampling and directional albedo.
//!
//! `cargo bench -p gonio-brdf --bench brdf`; figures and the machine are in
//! BENCHMARKS.md at the repository root.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use gonio_brdf::{Brdf, IncidentSampler, Model};
use gonio_core::{Dir, SphericalDeg, Vec3};

const N: usize = 1024;

/// Deterministic, well-spread direction pairs (a Fibonacci lattice on the hemisphere).
fn pairs() -> Vec<(Dir, Dir)> {
    let golden = 0.5 * (1.0 + 5f64.sqrt());
    let dir = |k: usize| {
        let z = (k as f64 + 0.5) / N as f64;
        let phi = std::f64::consts::TAU * (k as f64 / golden).fract();
        let s = (1.0 - z * z).sqrt();
        Dir::new(Vec3::new(s * phi.cos(), s * phi.sin(), z)).expect("unit")
    };
    (0..N).map(|k| (dir(k), dir((k * 7 + 3) % N))).collect()
}

fn model(text: &str) -> Model {
    Model::from_toml(text, None).expect("valid bench model")
}

/// Table 1's three lobes in each of R, G and B (the cost does not depend on the values).
const LAFORTUNE_RGB3: &str = include_str!("../../../config/models/lafortune-table1-rgb.toml");

/// The same lobes written as full Eq. 3 matrices: the general path, as a baseline for
/// the diagonal (Eq. 4) fast path.
fn lafortune_rgb3_matrix() -> Model {
    let Model::Lafortune(l) = model(LAFORTUNE_RGB3) else {
        unreachable!("a lafortune file")
    };
    let mut text = String::from("kind = \"lafortune\"\nchannels = [\"R\", \"G\", \"B\"]\n");
    text.push_str("[diffuse]\nrho = [0.3094, 0.39667, 0.70837]\n");
    for lobe in l.lobes() {
        // A 1e-300 off-diagonal term forces the general path without changing values.
        let mats: Vec<String> = lobe
            .matrices()
            .iter()
            .map(|m| {
                format!(
                    "[[{:?}, 1e-300, 0.0], [1e-300, {:?}, 0.0], [0.0, 0.0, {:?}]]",
                    m.xx, m.yy, m.zz
                )
            })
            .collect();
        let n: Vec<String> = lobe.n().iter().map(|v| format!("{v:?}")).collect();
        text.push_str(&format!(
            "[[lobes]]\nm = [{}]\nn = [{}]\n",
            mats.join(", "),
            n.join(", ")
        ));
    }
    model(&text)
}

fn zoo() -> Vec<(&'static str, Model)> {
    vec![
        (
            "lambert-rgb",
            model("kind = \"lambert\"\nchannels = [\"R\",\"G\",\"B\"]\nrho = [0.2, 0.5, 0.8]"),
        ),
        (
            "phong",
            model(
                "kind = \"phong\"\nchannels = [\"value\"]\nrho_s = [0.2]\nn = [20]\n[diffuse]\nrho = [0.8]",
            ),
        ),
        (
            "blinn-phong",
            model("kind = \"blinn-phong\"\nchannels = [\"value\"]\nrho_s = [0.3]\nn = [80]"),
        ),
        (
            "ward-aniso",
            model(
                "kind = \"ward\"\nchannels = [\"value\"]\nrho_s = [0.1]\nalpha_x = [0.08]\nalpha_y = [0.3]",
            ),
        ),
        (
            "ct-beckmann-rgb",
            model(
                "kind = \"cook-torrance\"\nchannels = [\"R\",\"G\",\"B\"]\ndistribution = \"beckmann\"\nf0 = [0.95, 0.64, 0.54]\nalpha = [0.3, 0.3, 0.3]",
            ),
        ),
        (
            "ct-ggx-rgb",
            model(
                "kind = \"cook-torrance\"\nchannels = [\"R\",\"G\",\"B\"]\ndistribution = \"ggx\"\nf0 = [0.95, 0.64, 0.54]\nalpha = [0.3, 0.3, 0.3]",
            ),
        ),
        (
            "oren-nayar",
            model("kind = \"oren-nayar\"\nchannels = [\"value\"]\nrho = [0.8]\nsigma_deg = [30]"),
        ),
        (
            "lafortune-table1",
            model(include_str!("../../../config/models/blue-paint-550nm.toml")),
        ),
        ("lafortune-rgb-3lobe", model(LAFORTUNE_RGB3)),
        ("lafortune-rgb-3lobe-matrix", lafortune_rgb3_matrix()),
    ]
}

fn eval(c: &mut Criterion) {
    let ps = pairs();
    let mut g = c.benchmark_group("eval");
    g.throughput(Throughput::Elements(N as u64));
    for (name, m) in zoo() {
        let mut out = vec![0.0; m.channels().len()];
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut acc = 0.0;
                for (wi, wo) in &ps {
                    m.eval(*wi, *wo, &mut out);
                    acc += out[0];
                }
                black_box(acc)
            })
        });
    }
    // The floor for a 3-lobe RGB Lafortune model: its 9 `powf` calls alone, on the same
    // pairs (the lobe dot products, clamped positive, raised to the lobes' exponents).
    let ns = [
        21.820103, 18.597755, 7.472717, 2.774989, 2.58128, 2.58, 66.899274, 63.767356, 63.8,
    ];
    g.bench_function("floor-9-powf", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for (wi, wo) in &ps {
                let d = wi.dot(**wo).abs().max(1e-3);
                for n in &ns {
                    acc += d.powf(*n);
                }
            }
            black_box(acc)
        })
    });
    g.finish();
}

fn sample(c: &mut Criterion) {
    let mut g = c.benchmark_group("sample+pdf");
    g.throughput(Throughput::Elements(N as u64));
    let wi = Dir::from(SphericalDeg::new(40.0, 10.0));
    let us: Vec<(f64, [f64; 2])> = (0..N)
        .map(|k| {
            let x = (k as f64 + 0.5) / N as f64;
            ((x * 0.618_034).fract(), [x, (x * 1.324_718).fract()])
        })
        .collect();
    for (name, m) in zoo() {
        let s = IncidentSampler::new(&m, wi);
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut acc = 0.0;
                for (uc, u) in &us {
                    if let Some(x) = s.sample(*uc, *u) {
                        acc += x.pdf;
                    }
                }
                black_box(acc)
            })
        });
    }
    g.finish();
}

fn albedo(c: &mut Criterion) {
    let mut g = c.benchmark_group("albedo");
    g.sample_size(10);
    let wi = Dir::from(SphericalDeg::new(60.0, 10.0));
    for (name, m) in zoo() {
        let mut out = vec![0.0; m.channels().len()];
        g.bench_function(name, |b| {
            b.iter(|| {
                m.albedo(wi, &mut out);
                black_box(out[0])
            })
        });
    }
    // The baseline a user would otherwise write: a midpoint rule on a 0.1° grid in
    // (θo, φo), 3.24 million evaluations.
    let paint = model(include_str!("../../../config/models/blue-paint-550nm.toml"));
    g.bench_function("lafortune-table1-midpoint-0.1deg", |b| {
        b.iter(|| black_box(midpoint_albedo(&paint, wi, 900, 3600)))
    });
    g.finish();
}

/// ∫ f cos θo dω by the midpoint rule on an `nt × np` grid in (θo, φo).
pub fn midpoint_albedo(m: &Model, wi: Dir, nt: usize, np: usize) -> f64 {
    let mut f = vec![0.0; m.channels().len()];
    let (dt, dp) = (
        0.5 * std::f64::consts::PI / nt as f64,
        std::f64::consts::TAU / np as f64,
    );
    let mut sum = 0.0;
    for i in 0..nt {
        let t = (i as f64 + 0.5) * dt;
        let (st, ct) = t.sin_cos();
        for j in 0..np {
            let p = (j as f64 + 0.5) * dp;
            let wo = Dir::from_angles(t, p);
            m.eval(wi, wo, &mut f);
            sum += f[0] * ct * st;
        }
    }
    sum * dt * dp
}

criterion_group!(benches, eval, sample, albedo);
criterion_main!(benches);
