#![allow(missing_docs)] // criterion_group! generates undocumented functions
//! Spectra converted to colour per second: 81-point spectra at 5 nm (380–780 nm), CIE
//! 1931 observer, D65, Sprague interpolation to 1 nm.
//!
//! `cargo bench -p gonio-core --bench colour`; figures and the machine are in
//! BENCHMARKS.md at the repository root.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use gonio_core::colour::{Colorimeter, Illuminant, Interpolation, Observer};

const N: usize = 1000;

/// Smooth, different spectra (deterministic): a sum of two bumps per spectrum.
fn spectra() -> (Vec<f64>, Vec<Vec<f64>>) {
    let wl: Vec<f64> = (0..81).map(|i| 380.0 + 5.0 * i as f64).collect();
    let s = (0..N)
        .map(|k| {
            let c = 400.0 + 300.0 * (k as f64 / N as f64);
            wl.iter()
                .map(|l| 0.05 + 0.8 * (-((l - c) / 40.0).powi(2)).exp())
                .collect()
        })
        .collect();
    (wl, s)
}

fn bench(c: &mut Criterion) {
    let (wl, s) = spectra();
    let mut g = c.benchmark_group("colour");
    g.throughput(Throughput::Elements(N as u64));
    for (name, how) in [
        ("xyz_81pt_5nm_sprague", Interpolation::Sprague),
        ("xyz_81pt_5nm_linear", Interpolation::Linear),
    ] {
        let col = Colorimeter::new(Observer::Cie1931, Illuminant::D65).with_interpolation(how);
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut acc = 0.0;
                for v in &s {
                    acc += col.xyz(black_box(&wl), black_box(v)).map_or(0.0, |x| x.y);
                }
                acc
            })
        });
    }
    let col = Colorimeter::new(Observer::Cie1931, Illuminant::D65);
    g.bench_function("colour_81pt_5nm_xyz_xy_srgb", |b| {
        b.iter(|| {
            let mut acc = 0u32;
            for v in &s {
                if let Ok(c) = col.colour(black_box(&wl), black_box(v)) {
                    acc += u32::from(c.srgb8[1]);
                }
            }
            acc
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
