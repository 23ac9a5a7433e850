//! Motion ordering: permutations, optimality on small cases, and the gain over raster
//! on full-hemisphere plans.
//!
//! Run with `--nocapture` to see the raster and optimised motion times.

use std::time::{Duration, Instant};

use gonio_core::kinematics::{Layout, arm_separation_deg};
use gonio_core::{Dir, DirPair, SphericalDeg};
use gonio_plan::order::{AxisMotion, EXACT_MAX, MotionModel, nearest_neighbour, optimise, raster};
use proptest::prelude::*;

const BUDGET: Duration = Duration::from_secs(20);

fn ax(velocity: f64, acceleration: f64) -> AxisMotion {
    AxisMotion {
        velocity,
        acceleration,
    }
}

/// The coplanar-arm goniometer's stages, source/detector/sample_rot/sample_tilt; the
/// spherical layout's θi/φi/θo/φo stages get the same four in the same order.
fn model4() -> MotionModel {
    MotionModel {
        axes: vec![
            ax(20.0, 80.0),
            ax(20.0, 80.0),
            ax(30.0, 120.0),
            ax(10.0, 40.0),
        ],
    }
}

/// Tiny xorshift64 with a fixed seed: reproducible test data without a dependency.
struct XorShift(u64);

impl XorShift {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    fn point(&mut self, half: f64) -> [f64; 4] {
        [(); 4].map(|()| half * (2.0 * self.next() - 1.0))
    }
}

fn wrap180(a: f64) -> f64 {
    let r = a.rem_euclid(360.0);
    if r > 180.0 { r - 360.0 } else { r }
}

/// The full-hemisphere plan: θi ∈ {0, 15, …, 75}, φi = 0, θo ∈ {5, 15, …, 85},
/// φo ∈ {0, 15, …, 345}, in raster (nested-loop) order, each pair mapped with the
/// previous point's stages as the hint; pairs the layout cannot reach or closer than
/// 8° (the detector would shadow the source) are skipped.
///
/// `one_turn`: keep every stage within (−180°, 180°] (as a stage with a cable or a
/// travel limit must), instead of letting rotation stages accumulate turns.
fn hemisphere_plan(layout: Layout, start: [f64; 4], one_turn: bool) -> Vec<[f64; 4]> {
    let mut pts = Vec::new();
    let mut prev = start;
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

/// A lower bound on any open path from `start` through `points`: every point but the
/// last has two path edges, each no shorter than its two nearest other nodes', the
/// last at least one; so `T ≥ ½ Σ (a_v + b_v) − ½ max b_v`.
fn lower_bound(m: &MotionModel, start: [f64; 4], points: &[[f64; 4]]) -> f64 {
    let mut sum = 0.0;
    let mut max_b = 0.0f64;
    for (i, p) in points.iter().enumerate() {
        let (mut a, mut b) = (f64::INFINITY, f64::INFINITY);
        let others = points
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != i)
            .map(|(_, q)| q)
            .chain([&start]);
        for q in others {
            let d = m.step_time(p, q);
            if d < a {
                b = a;
                a = d;
            } else if d < b {
                b = d;
            }
        }
        let b = if b.is_finite() { b } else { a };
        sum += a + b;
        max_b = max_b.max(b);
    }
    0.5 * (sum - max_b)
}

fn is_permutation(order: &[usize], n: usize) -> bool {
    let mut seen = vec![false; n];
    order.len() == n
        && order
            .iter()
            .all(|&i| i < n && !std::mem::replace(&mut seen[i], true))
}

/// Shortest open path by trying every permutation (n ≤ 8).
fn brute_force(m: &MotionModel, start: [f64; 4], pts: &[[f64; 4]]) -> f64 {
    fn go(
        m: &MotionModel,
        pts: &[[f64; 4]],
        at: [f64; 4],
        left: &mut Vec<usize>,
        acc: f64,
        best: &mut f64,
    ) {
        if acc >= *best {
            return;
        }
        if left.is_empty() {
            *best = acc;
            return;
        }
        for k in 0..left.len() {
            let i = left.swap_remove(k);
            go(m, pts, pts[i], left, acc + m.step_time(&at, &pts[i]), best);
            left.push(i);
            let last = left.len() - 1;
            left.swap(k, last);
        }
    }
    let mut best = f64::INFINITY;
    go(m, pts, start, &mut (0..pts.len()).collect(), 0.0, &mut best);
    best
}

#[test]
fn step_time_is_the_slowest_axis() {
    let m = MotionModel {
        axes: vec![ax(20.0, 80.0), ax(10.0, 40.0)],
    };
    // Axis 1: 10° at 20 °/s, 80 °/s² is a trapezoid, 2·20/80 + (10 − 5)/20 = 0.75 s.
    // Axis 2: 3° ≥ its ramp 10²/40 = 2.5°, so 2·10/40 + 0.5/10 = 0.55 s.
    assert!((m.step_time(&[0.0, 0.0], &[10.0, 3.0]) - 0.75).abs() < 1e-15);
    // 1° on axis 1 is a triangle, 2√(1/80) ≈ 0.2236 s: axis 2's 0.55 s wins.
    assert!((m.step_time(&[0.0, 0.0], &[1.0, 3.0]) - 0.55).abs() < 1e-15);
    // Both triangles: max(2√(1/80), 2√(2/40)) = 2√(1/20).
    let t = m.step_time(&[0.0, 0.0], &[1.0, 2.0]);
    assert!((t - 2.0 * (1.0f64 / 20.0).sqrt()).abs() < 1e-15, "{t}");
    // Signs do not matter, only the distances: symmetric.
    assert_eq!(
        m.step_time(&[5.0, -1.0], &[-5.0, 1.0]),
        m.step_time(&[-5.0, 1.0], &[5.0, -1.0])
    );
    assert!((m.step_time(&[5.0, -1.0], &[-5.0, 1.0]) - 0.75).abs() < 1e-15);

    // The four stages: 10°, 0°, 7.5° (= ramp of 30 °/s, 120 °/s²: 0.5 s), 3° (0.55 s).
    let t = model4().step_time(&[0.0; 4], &[10.0, 0.0, 7.5, 3.0]);
    assert!((t - 0.75).abs() < 1e-15, "{t}");

    // A path: (0,0) → (10,3) → (11,5) takes 0.75 + max(2√(1/80), 2√(2/40)) s; the
    // other way (0,0) → (11,5) [11°: 0.5 + 6/20 = 0.8 s] → (10,3) takes 0.8 + 2√(1/20).
    let pts = [[10.0, 3.0, 0.0, 0.0], [11.0, 5.0, 0.0, 0.0]];
    let s = [0.0; 4];
    let tri = 2.0 * (1.0f64 / 20.0).sqrt();
    assert!((m.path_time(&s, &pts, &[0, 1]) - (0.75 + tri)).abs() < 1e-15);
    assert!((m.path_time(&s, &pts, &[1, 0]) - (0.8 + tri)).abs() < 1e-15);
    assert_eq!(m.path_time(&s, &pts, &[]), 0.0);
    assert_eq!(optimise(&m, s, &pts, BUDGET), vec![0, 1]);
}

#[test]
fn trivial_inputs() {
    let m = model4();
    assert_eq!(optimise(&m, [0.0; 4], &[], BUDGET), Vec::<usize>::new());
    assert_eq!(optimise(&m, [0.0; 4], &[[1.0; 4]], BUDGET), vec![0]);
    assert_eq!(raster(3), vec![0, 1, 2]);
    // Non-finite input cannot be ordered meaningfully: the raster order comes back.
    let pts = [[1.0; 4], [f64::NAN, 0.0, 0.0, 0.0], [2.0; 4]];
    assert_eq!(optimise(&m, [0.0; 4], &pts, BUDGET), vec![0, 1, 2]);
    let bad = MotionModel {
        axes: vec![ax(0.0, 80.0); 4],
    };
    assert_eq!(
        optimise(&bad, [0.0; 4], &[[3.0; 4], [1.0; 4]], BUDGET),
        vec![0, 1]
    );
    // All points alike: any order is optimal, every point still appears once.
    let same = vec![[7.0; 4]; 500];
    let o = optimise(&m, [0.0; 4], &same, BUDGET);
    assert!(is_permutation(&o, 500));
    assert!((m.path_time(&[0.0; 4], &same, &o) - m.step_time(&[0.0; 4], &[7.0; 4])).abs() < 1e-12);
}

/// Points on a coarse grid drawn from a small pool (many duplicates), or spread out.
fn plans() -> impl Strategy<Value = ([f64; 4], Vec<[f64; 4]>)> {
    let grid = prop::array::uniform4(-6i32..=6).prop_map(|a| a.map(|v| 7.5 * f64::from(v)));
    let pooled = (
        prop::collection::vec(grid.clone(), 1..30),
        prop::collection::vec(any::<prop::sample::Index>(), 0..200),
    )
        .prop_map(|(pool, picks)| picks.iter().map(|i| pool[i.index(pool.len())]).collect());
    let spread = prop::collection::vec(prop::array::uniform4(-90.0..90.0f64), 0..200);
    (grid, prop_oneof![pooled, spread])
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 200,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn optimise_is_a_permutation_no_slower_than_raster_or_nearest_neighbour(
        (start, pts) in plans()
    ) {
        let m = model4();
        let o = optimise(&m, start, &pts, BUDGET);
        prop_assert!(is_permutation(&o, pts.len()), "{o:?}");
        let nn = nearest_neighbour(&m, start, &pts);
        prop_assert!(is_permutation(&nn, pts.len()));
        let t = m.path_time(&start, &pts, &o);
        let t_raster = m.path_time(&start, &pts, &raster(pts.len()));
        let t_nn = m.path_time(&start, &pts, &nn);
        prop_assert!(t <= t_raster, "{t} > raster {t_raster}");
        prop_assert!(t <= t_nn, "{t} > nearest neighbour {t_nn}");
        prop_assert!(t >= lower_bound(&m, start, &pts) - 1e-9);
    }
}

#[test]
fn small_plans_reach_the_brute_force_optimum() {
    // Up to EXACT_MAX (12) points `optimise` is exact (Held–Karp): checked against
    // every permutation, including a plan with duplicates.
    let m = model4();
    let mut rng = XorShift(0x9E37_79B9_7F4A_7C15);
    for n in 1..=8 {
        for _ in 0..12 {
            let start = rng.point(45.0);
            let mut pts: Vec<[f64; 4]> = (0..n).map(|_| rng.point(90.0)).collect();
            if n > 3 {
                pts[n - 1] = pts[1];
            }
            let o = optimise(&m, start, &pts, BUDGET);
            assert!(is_permutation(&o, n));
            let t = m.path_time(&start, &pts, &o);
            let best = brute_force(&m, start, &pts);
            assert!((t - best).abs() <= 1e-9, "n = {n}: {t} vs optimum {best}");
        }
    }
    assert_eq!(EXACT_MAX, 12);
}

/// Optimal open-path time by Held–Karp (for checking the heuristic beyond EXACT_MAX).
fn held_karp_time(m: &MotionModel, start: [f64; 4], pts: &[[f64; 4]]) -> f64 {
    let n = pts.len();
    let full = (1usize << n) - 1;
    let mut best = vec![f64::INFINITY; (full + 1) * n];
    for j in 0..n {
        best[(1 << j) * n + j] = m.step_time(&start, &pts[j]);
    }
    for set in 1..=full {
        for j in (0..n).filter(|j| set & (1 << j) != 0) {
            let here = best[set * n + j];
            for k in (0..n).filter(|k| set & (1 << k) == 0) {
                let next = (set | (1 << k)) * n + k;
                best[next] = best[next].min(here + m.step_time(&pts[j], &pts[k]));
            }
        }
    }
    (0..n)
        .map(|j| best[full * n + j])
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn heuristic_is_near_optimal_beyond_the_exact_range() {
    // 13–15 points take the heuristic (2-opt, Or-opt, kicks): it only guarantees a
    // local optimum, but on these fixed instances it reaches the optimum in all 18
    // (measured); the assertion leaves room for retuning: within 3%, mostly exact.
    let m = model4();
    let mut rng = XorShift(0xD1B5_4A32_D192_ED03);
    let (mut exact, mut total, mut worst) = (0, 0, 1.0f64);
    for n in 13..=15 {
        for _ in 0..6 {
            let start = rng.point(45.0);
            let pts: Vec<[f64; 4]> = (0..n).map(|_| rng.point(90.0)).collect();
            let o = optimise(&m, start, &pts, BUDGET);
            assert!(is_permutation(&o, n));
            let t = m.path_time(&start, &pts, &o);
            let best = held_karp_time(&m, start, &pts);
            assert!(t >= best - 1e-9);
            worst = worst.max(t / best);
            exact += usize::from(t <= best + 1e-9);
            total += 1;
        }
    }
    eprintln!("heuristic on 13–15 points: {exact}/{total} optimal, worst ratio {worst:.4}");
    assert!(worst <= 1.03, "{worst}");
    assert!(exact >= 15, "{exact}/{total}");
}

fn report(name: &str, start: [f64; 4], pts: &[[f64; 4]]) -> (f64, f64, f64) {
    let m = model4();
    let t0 = Instant::now();
    let o = optimise(&m, start, pts, BUDGET);
    let elapsed = t0.elapsed();
    assert!(is_permutation(&o, pts.len()));
    let t_raster = m.path_time(&start, pts, &raster(pts.len()));
    let t_opt = m.path_time(&start, pts, &o);
    let lb = lower_bound(&m, start, pts);
    eprintln!(
        "{name}: {} points, raster {t_raster:.1} s, optimised {t_opt:.1} s \
         ({:.1}% less, in {elapsed:.2?}); no order below {lb:.1} s ({:.1}% less at best)",
        pts.len(),
        100.0 * (1.0 - t_opt / t_raster),
        100.0 * (1.0 - lb / t_raster),
    );
    (t_raster, t_opt, lb)
}

/// THE KEY RESULT, as specified: coplanar arms, stages hinted by the previous point.
///
/// The 40% the issue asks for is out of reach here for ANY order: the hint makes the
/// raster plan already least-motion point to point (the sample rotation follows φo
/// continuously, accumulating turns, ρ ends near −10 700°), so every point's two
/// nearest neighbours are about as far as its raster neighbours. The lower bound shows
/// no order can save more than ~10%; the optimiser gets about half of that.
#[test]
fn hemisphere_coplanar_arms() {
    let start = [0.0; 4];
    let pts = hemisphere_plan(Layout::CoplanarArms, start, false);
    assert_eq!(pts.len(), 1261);
    let (t_raster, t_opt, lb) = report("coplanar arms, hint-chained", start, &pts);
    assert!(t_opt <= 0.95 * t_raster, "{t_opt} vs raster {t_raster}");
    assert!(lb > 0.9 * t_raster, "the bound no longer rules out 40%");
}

/// The spherical layout with the same plan: φo on the slowest stage advances 15° at
/// every raster step and, hinted, never wraps; raster is optimal to within 0.2%.
#[test]
fn hemisphere_spherical() {
    let start = [0.0; 4];
    let pts = hemisphere_plan(Layout::Spherical, start, false);
    assert_eq!(pts.len(), 1261);
    let (t_raster, t_opt, lb) = report("spherical, hint-chained", start, &pts);
    assert!(t_opt <= t_raster);
    assert!(lb > 0.995 * t_raster);
}

/// The same plans on stages kept within one turn, (−180°, 180°]: raster pays for
/// unwinding at every ring, which ordering avoids. Spherical: ≥ 40% (about 79%).
/// Coplanar arms: ~34%, and the lower bound shows 40% is impossible there too.
#[test]
fn hemisphere_one_turn_stages() {
    let start = [0.0; 4];
    let pts = hemisphere_plan(Layout::Spherical, start, true);
    let (t_raster, t_opt, _) = report("spherical, one-turn stages", start, &pts);
    assert!(t_opt <= 0.6 * t_raster, "{t_opt} vs raster {t_raster}");
    assert!(t_opt <= 0.25 * t_raster, "{t_opt} vs raster {t_raster}");

    let pts = hemisphere_plan(Layout::CoplanarArms, start, true);
    let (t_raster, t_opt, lb) = report("coplanar arms, one-turn stages", start, &pts);
    assert!(t_opt <= 0.67 * t_raster, "{t_opt} vs raster {t_raster}");
    assert!(lb > 0.6 * t_raster, "the bound no longer rules out 40%");
}

#[test]
fn deterministic_whatever_the_budget() {
    let start = [0.0; 4];
    let m = model4();
    let pts = hemisphere_plan(Layout::CoplanarArms, start, true);
    let a = optimise(&m, start, &pts, Duration::from_secs(10));
    let b = optimise(&m, start, &pts, Duration::from_secs(600));
    assert_eq!(a, b);
    let mut rng = XorShift(7);
    let pts: Vec<[f64; 4]> = (0..2000).map(|_| rng.point(90.0)).collect();
    assert_eq!(
        optimise(&m, start, &pts, BUDGET),
        optimise(&m, start, &pts, BUDGET)
    );
}

#[test]
fn ten_thousand_points() {
    let m = model4();
    let start = [0.0; 4];
    let mut rng = XorShift(0x2545_F491_4F6C_DD1D);
    let pts: Vec<[f64; 4]> = (0..10_000).map(|_| rng.point(90.0)).collect();
    let t0 = Instant::now();
    let o = optimise(&m, start, &pts, BUDGET);
    let elapsed = t0.elapsed();
    assert!(is_permutation(&o, pts.len()));
    let t_raster = m.path_time(&start, &pts, &raster(pts.len()));
    let t_nn = m.path_time(&start, &pts, &nearest_neighbour(&m, start, &pts));
    let t_opt = m.path_time(&start, &pts, &o);
    eprintln!(
        "10 000 random points: raster {t_raster:.0} s, nearest neighbour {t_nn:.0} s, \
         optimised {t_opt:.0} s in {elapsed:.2?}"
    );
    // Measured: 8072 s, against 8596 s for nearest neighbour and 73 981 s for raster.
    assert!(t_opt <= 0.95 * t_nn, "{t_opt} vs nearest neighbour {t_nn}");
    assert!(t_opt <= 0.2 * t_raster);
}
