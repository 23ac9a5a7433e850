#![allow(missing_docs)] // criterion_group! generates undocumented functions
//! An adaptive run's batch choice (`gonio_process::adapt::choose`) in the state of the
//! default plan's fifth batch: 420 samples of a sharp Lafortune lobe (n = 500) at two
//! incidences, 2 × 32768 candidate directions, 60 picks; each of the three aims. The
//! reference is the instrument time the batch it plans takes (the plan's estimate,
//! about 280 s for 60 points on the simulated instrument).
//!
//! `cargo bench -p gonio-process --bench adapt`; figures in BENCHMARKS.md ("Adaptive
//! acquisition").

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use gonio_brdf::{Brdf, Model};
use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use gonio_process::adapt::{Aim, choose};
use gonio_process::samples::{Sample, Samples};

const LOBE: &str = "kind = \"lafortune\"\nchannels = [\"value\"]\n[diffuse]\nrho = [0.1]\n\
                    [[lobes]]\ncx = [-1.0074]\ncy = [-1.0074]\ncz = [1.0074]\nn = [500]\n";

fn at(inc: f64, dirs: &[SphericalDeg]) -> Vec<PairDeg> {
    dirs.iter()
        .map(|o| PairDeg {
            incident: SphericalDeg::new(inc, 0.0),
            outgoing: *o,
        })
        .collect()
}

fn batch(c: &mut Criterion) {
    let model = Model::from_toml(LOBE, None).expect("model");
    let pairs: Vec<PairDeg> = [30.0, 60.0]
        .iter()
        .flat_map(|&i| at(i, &SphericalDeg::fibonacci_hemisphere(210, 0.3)))
        .collect();
    let samples = Samples {
        channels: model.channels().clone(),
        samples: pairs
            .iter()
            .map(|p| {
                let d = p.to_dirs();
                let mut v = vec![0.0];
                model.eval(d.wi, d.wo, &mut v);
                Sample {
                    pair: *p,
                    sigma: Some(vec![1e-4 * v[0]]),
                    value: v,
                    flags: 0,
                }
            })
            .collect(),
        isotropic: false,
    };
    let candidates: Vec<PairDeg> = [30.0, 60.0]
        .iter()
        .flat_map(|&i| at(i, &SphericalDeg::fibonacci_hemisphere(32768, 0.7)))
        .collect();
    let mut g = c.benchmark_group("adaptive batch: 420 samples, 65536 candidates, 60 picks");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    for (name, aim) in [
        ("residual", Aim::Residual),
        ("variation", Aim::Variation),
        ("value", Aim::Value),
    ] {
        let picks = choose(&samples, &candidates, 60, aim, 0.1).expect("choose");
        assert_eq!(picks.len(), 60);
        g.bench_function(name, |b| {
            b.iter(|| black_box(choose(&samples, black_box(&candidates), 60, aim, 0.1)))
        });
    }
    g.finish();
}

criterion_group!(benches, batch);
criterion_main!(benches);
