#![allow(missing_docs)] // criterion_group! generates undocumented functions
//! Simulator throughput at time scale 0 and where the time goes.
//!
//! `cargo bench -p gonio-sim --bench sim`; figures in BENCHMARKS.md.

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use gonio_driver::InstrumentConfig;
use gonio_sim::{SimConfig, lock};

fn configs() -> (InstrumentConfig, SimConfig) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config");
    (
        InstrumentConfig::load(&root.join("instrument-sim.toml")).expect("instrument config"),
        SimConfig::load(&root.join("sim-example.toml")).expect("sim config"),
    )
}

/// Two configurations in the plane of incidence, visited alternately so every point
/// includes a move of the source and detector arms.
const A: [(&str, f64); 4] = [
    ("source", -30.0),
    ("detector", 40.0),
    ("sample_rot", 0.0),
    ("sample_tilt", 0.0),
];
const B: [(&str, f64); 4] = [
    ("source", -35.0),
    ("detector", 45.0),
    ("sample_rot", 0.0),
    ("sample_tilt", 0.0),
];

fn point(c: &mut Criterion) {
    let (icfg, scfg) = configs();
    let (mut g, sim) = gonio_sim::connect(&icfg, &scfg).expect("connects");
    g.start().expect("starts");
    g.home().expect("homes");
    // Settle the lock-in's range once, as a run's first point does.
    g.measure_at(&A).expect("first point");
    let mut grp = c.benchmark_group("sim");
    grp.throughput(Throughput::Elements(1));
    let mut flip = false;
    grp.bench_function(
        "point: move 4 axes + 10-sample reading (driver + simulator)",
        |b| {
            b.iter(|| {
                flip = !flip;
                let t = if flip { &B } else { &A };
                black_box(g.measure_at(t).expect("point"))
            })
        },
    );
    grp.finish();
    // Where a point's work goes: count the lines it exchanges.
    let before = lock(&sim).stats().clone();
    let t0 = lock(&sim).clock().seconds();
    for k in 0..20 {
        let t = if k % 2 == 0 { &B } else { &A };
        g.measure_at(t).expect("point");
    }
    let after = lock(&sim).stats().clone();
    let t1 = lock(&sim).clock().seconds();
    eprintln!(
        "per point: {:.1} motion lines, {:.1} detector lines, {:.2} s of physical time",
        (after.motion_lines - before.motion_lines) as f64 / 20.0,
        (after.detector_lines - before.detector_lines) as f64 / 20.0,
        (t1 - t0) / 20.0
    );
}

fn parts(c: &mut Criterion) {
    let (_, scfg) = configs();
    let sim = gonio_sim::instrument(&scfg).expect("sim");
    let mut grp = c.benchmark_group("sim-parts");
    {
        let s = lock(&sim);
        grp.bench_function("optics: signal (kinematics + BRDF + radiometry)", |b| {
            b.iter(|| black_box(s.signal(black_box(1.0))))
        });
    }
    {
        let mut s = lock(&sim);
        grp.bench_function("motion line: 1TS in, status out", |b| {
            b.iter(|| black_box(s.motion_bytes(b"1TS\r\n")))
        });
    }
    {
        let mut s = lock(&sim);
        s.lockin_bytes(b"OUTX 0\n");
        grp.bench_function("detector line: SNAP? 1,2 in, X,Y out", |b| {
            b.iter(|| black_box(s.lockin_bytes(b"SNAP? 1,2\n")))
        });
    }
    grp.finish();
}

criterion_group!(benches, point, parts);
criterion_main!(benches);
