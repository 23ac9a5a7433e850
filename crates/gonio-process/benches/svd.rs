#![allow(missing_docs)] // criterion_group! generates undocumented functions
//! The leading singular values P_s^(k) needs (`gonio_process::svd::spectrum`, block
//! Krylov) against faer's full SVD of the same matrix: DeYoung's A of the Phong-shading
//! table on a 10° × 5° grid (648 × 648) and a 10° × 2.5° grid (1296 × 1296), k ≤ 10.
//!
//! `cargo bench -p gonio-process --bench svd`; figures in BENCHMARKS.md ("Large tables").

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use faer::Mat;
use gonio_brdf::Model;
use gonio_process::{GridStep, Table, svd};

const PHONG_SHADING: &str = r#"
kind = "phong"
channels = ["value"]
rho_s = [0.3]
n = [10]
shading = true
[diffuse]
rho = [0.5]
"#;

fn matrix(dtheta: f64, dphi: f64) -> Mat<f64> {
    let m = Model::from_toml(PHONG_SHADING, None).expect("model");
    let g = GridStep::new(dtheta, dphi).expect("step").grid();
    let t = Table::from_brdf(&m, g).expect("table");
    let (p, q) = (t.grid.n_in(), t.grid.n_out());
    Mat::from_fn(p, q, |r, c| t.values[r * q + c])
}

fn spectrum(c: &mut Criterion) {
    for (name, dtheta, dphi) in [("648x648", 10.0, 5.0), ("1296x1296", 10.0, 2.5)] {
        let a = matrix(dtheta, dphi);
        let k = 10;
        // The two agree before either is timed.
        let t = svd::spectrum(a.as_ref(), k).expect("truncated");
        let f = svd::full(a.as_ref()).expect("full");
        assert!(!t.is_full(), "{name}: truncated");
        for j in 0..k {
            assert!((t.values[j] - f.values[j]).abs() <= 1e-10 * f.values[0]);
        }
        eprintln!("{name}: residual bound {:.2e} sigma_1", t.residual);
        let mut g = c.benchmark_group(format!("svd {name}"));
        g.sample_size(10).measurement_time(Duration::from_secs(8));
        g.bench_function("truncated: leading 10 (block Krylov)", |b| {
            b.iter(|| black_box(svd::spectrum(black_box(a.as_ref()), k).expect("svd")))
        });
        g.bench_function("faer: all singular values", |b| {
            b.iter(|| black_box(svd::full(black_box(a.as_ref())).expect("svd")))
        });
        g.finish();
    }
}

criterion_group!(benches, spectrum);
criterion_main!(benches);
