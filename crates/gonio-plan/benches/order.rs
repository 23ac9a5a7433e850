#![allow(missing_docs)] // criterion_group! generates undocumented functions
//! Time to order a measurement plan, and the motion time it saves over raster order.
//!
//! `cargo bench -p gonio-plan --bench order`; prints (stderr) the raster and
//! optimised motion times quoted in BENCHMARKS.md as "ordering gain vs raster".

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use gonio_core::kinematics::{Layout, arm_separation_deg};
use gonio_core::{Dir, DirPair, SphericalDeg};
use gonio_plan::order::{AxisMotion, MotionModel, optimise, raster};

const BUDGET: Duration = Duration::from_secs(30);

/// Source, detector, sample rotation, sample tilt (the same four for the spherical
/// layout's θi, φi, θo, φo).
fn model() -> MotionModel {
    let ax = |velocity, acceleration| AxisMotion {
        velocity,
        acceleration,
    };
    MotionModel {
        axes: vec![
            ax(20.0, 80.0),
            ax(20.0, 80.0),
            ax(30.0, 120.0),
            ax(10.0, 40.0),
        ],
    }
}

fn wrap180(a: f64) -> f64 {
    let r = a.rem_euclid(360.0);
    if r > 180.0 { r - 360.0 } else { r }
}

/// θi ∈ {0, 15, …, 75}, φi = 0, θo ∈ {5, 15, …, 85}, φo ∈ {0, 15, …, 345} in raster
/// order, hinted by the previous point, pairs closer than 8° skipped; `one_turn`
/// keeps every stage within (−180°, 180°].
fn hemisphere_plan(layout: Layout, one_turn: bool) -> Vec<[f64; 4]> {
    let mut pts = Vec::new();
    let mut prev = [0.0; 4];
    for ti in (0..6).map(|k| 15.0 * f64::from(k)) {
        let wi = Dir::from(SphericalDeg::new(ti, 0.0));
        for to in (0..9).map(|k| 5.0 + 10.0 * f64::from(k)) {
            for po in (0..24).map(|k| 15.0 * f64::from(k)) {
                let pair = DirPair::new(wi, Dir::from(SphericalDeg::new(to, po)));
                if arm_separation_deg(pair) < 8.0 {
                    continue;
                }
                let Ok(mut s) = layout.inverse(pair, Some(prev)) else {
                    continue;
                };
                if one_turn {
                    s = s.map(wrap180);
                }
                pts.push(s);
                prev = s;
            }
        }
    }
    pts
}

/// 10 000 stage positions spread uniformly over ±90° (fixed-seed xorshift, the same
/// plan as the `ten_thousand_points` test).
fn random_plan() -> Vec<[f64; 4]> {
    let mut s = 0x2545_F491_4F6C_DD1Du64;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..10_000)
        .map(|_| [(); 4].map(|()| 90.0 * (2.0 * next() - 1.0)))
        .collect()
}

fn gain(name: &str, pts: &[[f64; 4]]) {
    let (m, start) = (model(), [0.0; 4]);
    let t_raster = m.path_time(&start, pts, &raster(pts.len()));
    let t_opt = m.path_time(&start, pts, &optimise(&m, start, pts, BUDGET));
    eprintln!(
        "ordering gain vs raster, {name} ({} points): raster {t_raster:.1} s, \
         optimised {t_opt:.1} s, {:.1}% less",
        pts.len(),
        100.0 * (1.0 - t_opt / t_raster)
    );
}

fn bench(c: &mut Criterion) {
    let arms = hemisphere_plan(Layout::CoplanarArms, false);
    let random = random_plan();
    gain("hemisphere, coplanar arms, hint-chained", &arms);
    gain(
        "hemisphere, coplanar arms, one-turn stages",
        &hemisphere_plan(Layout::CoplanarArms, true),
    );
    gain(
        "hemisphere, spherical, hint-chained",
        &hemisphere_plan(Layout::Spherical, false),
    );
    gain(
        "hemisphere, spherical, one-turn stages",
        &hemisphere_plan(Layout::Spherical, true),
    );
    gain("random", &random);

    let m = model();
    let mut g = c.benchmark_group("order");
    g.sample_size(10);
    g.bench_function("hemisphere_coplanar_arms_1261", |b| {
        b.iter(|| optimise(&m, [0.0; 4], black_box(&arms), BUDGET))
    });
    g.bench_function("random_10000", |b| {
        b.iter(|| optimise(&m, [0.0; 4], black_box(&random), BUDGET))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
