//! The measures against their floors (`gonio_process::floor`): a material that has
//! the property lies within its floor's 95% bound in most noise seeds, on the grid the
//! shipped hemisphere plan forms (whose reciprocal partners are interpolated) and on
//! 4D grids; a table made to lack it lies clearly above.

use gonio_brdf::Model;
use gonio_core::rng::SplitMix64;
use gonio_process::floor::{self, Floor};
use gonio_process::{Axis, Grid, Table, measure};

use crate::albedo_quadrature::{materials, plan_axes, run_sigma};

/// The shipped hemisphere plan's own grid, unfolded to a full turn: θi 0…75 by 15,
/// Δφ a full turn by 15, θo 0…80 by 10.
fn plan_grid() -> Grid {
    let [ti, to, dphi] = plan_axes();
    let step = |v: &[f64]| v[1] - v[0];
    Grid::isotropic(
        Axis::from_deg(ti[0], step(&ti), ti.len()),
        Axis::full_turn((360.0 / step(&dphi)).round() as usize),
        Axis::from_deg(to[0], step(&to), to.len()),
    )
}

/// A 4D grid whose incident and outgoing azimuths differ (8 and 12 a turn), so that
/// P_i's φi + φ+ and P_r's partners are interpolated.
fn grid_4d() -> Grid {
    Grid::full(
        Axis::full_turn(8),
        Axis::from_deg(5.0, 15.0, 6),
        Axis::full_turn(12),
        Axis::from_deg(0.0, 10.0, 9),
    )
}

/// `m` on `g`, each value scaled by `scale(φi, θi, φo, θo)` (radians), with a run's σ
/// and its noise drawn from `seed`.
fn noisy(m: &Model, g: Grid, seed: u64, scale: impl Fn([f64; 4]) -> f64) -> Table {
    let mut t = Table::from_brdf(m, g).expect("table");
    let mut rng = SplitMix64::new(seed);
    let sigma: Vec<f64> = t.values.iter().map(|v| run_sigma(*v)).collect();
    for (i, v) in t.values.iter_mut().enumerate() {
        *v = *v * scale(g.angles(i)) + sigma[i] * rng.next_normal();
    }
    t.sigma = Some(sigma);
    t
}

/// The draws a table of this size gets in `gonio check`.
fn draws(t: &Table) -> usize {
    floor::draws_for(t.values.len())
}

/// "value (floor mean, 95%)" for messages.
fn show(value: f64, f: &Floor) -> String {
    format!(
        "{value:.3e} (floor {:.3e}, 95% {:.3e}, interpolation {:.3e} ± {:.1e})",
        f.mean, f.p95, f.interpolation, f.interpolation_sigma
    )
}

/// Over 8 seeds: how many P_r lie above their floor's 95% bound, and the smallest
/// ratio P_r / 95% bound.
fn reciprocity_over_seeds(
    m: &Model,
    g: Grid,
    scale: impl Fn([f64; 4]) -> f64 + Copy,
) -> (usize, f64, String) {
    let (mut above, mut ratio, mut last) = (0, f64::INFINITY, String::new());
    for seed in 1..=8 {
        let t = noisy(m, g, seed, scale);
        let (p_r, _) = measure::reciprocity(&t);
        let f = &floor::reciprocity_floor(&t, &p_r, draws(&t)).expect("floor")[0];
        above += usize::from(!f.consistent);
        assert_eq!(f.consistent, p_r[0] <= f.p95 * (1.0 + 1e-9) + 1e-12);
        ratio = ratio.min(p_r[0] / f.p95);
        last = show(p_r[0], f);
    }
    (above, ratio, last)
}

#[test]
fn reciprocal_materials_lie_within_their_p_r_floor_and_skewed_ones_above() {
    let skew = |[_, ti, _, to]: [f64; 4]| 1.0 + 0.2 * (ti - to);
    for (g, grid) in [("plan", plan_grid()), ("4D", grid_4d())] {
        for (name, m) in materials() {
            let (above, _, last) = reciprocity_over_seeds(&m, grid, |_| 1.0);
            println!("{g} {name}: reciprocal, P_r {last}: {above} of 8 above");
            assert!(above <= 1, "{g} {name}: {above} of 8 seeds above: {last}");
            let (above, ratio, last) = reciprocity_over_seeds(&m, grid, skew);
            println!("{g} {name}: skewed, P_r {last}: {above} of 8 above, ratio ≥ {ratio:.2}");
            // The sharp lobe's interpolation error on these grids is larger than the
            // skew (P_r 0.07 against 0.004 of skew): no grid this coarse can tell, and
            // the floor says so. The plan grid's 4D twin interpolates every axis and
            // hides the skew of the two darker materials as well.
            let visible = !matches!((g, name), (_, "sharp") | ("4D", "dark" | "paint"));
            if visible {
                assert_eq!(above, 8, "{g} {name}: {last}");
                assert!(
                    ratio > 1.3,
                    "{g} {name}: only {ratio:.2} × the floor's 95% bound"
                );
            }
        }
    }
}

#[test]
fn isotropic_materials_lie_within_their_p_i_floor_and_turned_ones_above() {
    // Equal azimuth axes (P_i's partners looked up: the floor is the noise alone)
    // and unequal ones (interpolated).
    let same = Grid::full(
        Axis::full_turn(12),
        Axis::from_deg(5.0, 15.0, 6),
        Axis::full_turn(12),
        Axis::from_deg(0.0, 10.0, 9),
    );
    let turned = |[pi, ..]: [f64; 4]| 1.0 + 0.2 * pi.cos();
    // With equal azimuths the floor is the noise alone, as narrow as P_i's own
    // scatter, and a correct 95% bound is exceeded by chance one seed in twenty:
    // over 16 seeds at most 3 a material (a 0.7% chance of 4 or more) and 8 of the
    // grid's 64 (0.6% of 9 or more). Unequal azimuths add the interpolation's
    // floor, whose own uncertainty widens the bound: at most 2 of 8 seeds.
    for (g, grid, seeds, most) in [
        ("equal azimuths", same, 16, 3),
        ("unequal azimuths", grid_4d(), 8, 2),
    ] {
        let mut pooled = 0;
        for (name, m) in materials() {
            let (mut above, mut above_turned, mut ratio) = (0, 0, f64::INFINITY);
            let mut last = String::new();
            for seed in 1..=seeds {
                let t = noisy(&m, grid, seed, |_| 1.0);
                let p_i = measure::isotropy(&t).expect("P_i");
                let f = &floor::isotropy_floor(&t, &p_i, draws(&t)).expect("floor")[0];
                above += usize::from(!f.consistent);
                last = show(p_i[0], f);
                if seed > 4 {
                    continue;
                }
                let t = noisy(&m, grid, seed, turned);
                let p_i = measure::isotropy(&t).expect("P_i");
                let f = &floor::isotropy_floor(&t, &p_i, draws(&t)).expect("floor")[0];
                above_turned += usize::from(!f.consistent);
                ratio = ratio.min(p_i[0] / f.p95);
            }
            println!(
                "{g} {name}: isotropic P_i {last}: {above} of {seeds} above; turned: \
                 {above_turned} of 4 above, ≥ {ratio:.2} × the 95% bound"
            );
            assert!(above <= most, "{g} {name}: {above} of {seeds}: {last}");
            pooled += above;
            assert_eq!(above_turned, 4, "{g} {name}");
            // The sharp lobe's interpolation error between unequal azimuths is of
            // the turn's size: above its floor, but not by much.
            let clearly = if (g, name) == ("unequal azimuths", "sharp") {
                1.0
            } else {
                1.3
            };
            assert!(ratio > clearly, "{g} {name}: {ratio}");
        }
        if seeds == 16 {
            assert!(pooled <= 8, "{g}: {pooled} of 64 above");
        }
    }
}

#[test]
fn without_sigma_the_floor_is_the_interpolation_alone() {
    let (_, paint) = materials().swap_remove(3);
    // A paired grid (band midpoints, equal axes): the counterpart is exactly
    // reciprocal at the nodes, and a reciprocal model reads its rounding.
    let t = Table::from_brdf(&paint, Grid::hemisphere(9, 12)).expect("table");
    let r = measure::report(&t, &[1], 1).expect("report");
    let f = r.floor.as_ref().expect("floors");
    assert_eq!(f.draws, 0);
    assert_eq!(f.reciprocity[0].mean, 0.0);
    assert_eq!(f.reciprocity[0].interpolation_sigma, 0.0);
    assert!(
        f.reciprocity[0].consistent,
        "{}",
        show(r.reciprocity[0], &f.reciprocity[0])
    );
    // On the plan's grid the partners are interpolated: the floor is M₀ and its
    // bound M₀ + 1.645 σ, and holds the reciprocal model's P_r.
    let t = Table::from_brdf(&paint, plan_grid()).expect("table");
    let (p_r, _) = measure::reciprocity(&t);
    let f = &floor::reciprocity_floor(&t, &p_r, 32).expect("floor")[0];
    assert!(
        f.interpolation > 0.0 && f.mean == f.interpolation,
        "{}",
        show(p_r[0], f)
    );
    assert!((f.p95 - (f.mean + 1.644_853_626_951_472_2 * f.interpolation_sigma)).abs() < 1e-15);
    assert!(f.consistent, "{}", show(p_r[0], f));
    // The extrapolation recovers the bulk of the interpolation error the
    // counterpart's averaging smooths away (the counterpart alone reads 0.65 of it).
    let once = measure::reciprocity(&floor::reciprocal_counterpart(&t)).0[0];
    assert!(once < 0.7 * p_r[0], "{once} vs {}", p_r[0]);
    assert!(f.interpolation > 0.9 * p_r[0], "{}", show(p_r[0], f));
}

#[test]
fn energy_and_separability_floors() {
    let (_, paint) = materials().swap_remove(3);
    let g = Grid::hemisphere_isotropic(9, 24);
    // The paint conserves energy: P_ec is 0 and lies on its floor; three times the
    // paint does not, and exceeds it.
    for (gain, conserves) in [(1.0, true), (3.0, false)] {
        let t = noisy(&paint, g, 5, |_| gain);
        let r = measure::report(&t, &[1], 1).expect("report");
        let f = &r.floor.as_ref().expect("floors").energy[0];
        assert_eq!(
            f.consistent,
            conserves,
            "×{gain}: {}",
            show(r.energy.p_ec[0], f)
        );
        assert!(f.p95 < 1e-3, "{}", show(r.energy.p_ec[0], f));
    }
    // A separable table on a 4D grid, f = g(ωi) h(ωo), with a run's noise: P_s^(1)
    // is noise, within its floor in most seeds; the paint is not separable and lies
    // far above.
    let g4 = Grid::hemisphere(9, 12);
    let sep = |[pi, ti, po, to]: [f64; 4]| {
        (1.0 + ti.cos()) * (1.0 + 0.1 * pi.cos()) * (0.3 + to.sin() * (1.0 + 0.2 * po.cos()))
    };
    let lambert: Model = Model::from_toml(
        "kind = \"lambert\"\nchannels = [\"value\"]\nrho = [0.5]",
        None,
    )
    .expect("model");
    let mut above = 0;
    for seed in 1..=8 {
        let t = noisy(&lambert, g4, seed, sep);
        let r = measure::report(&t, &[1], 1).expect("report");
        let f = &r
            .floor
            .as_ref()
            .expect("floors")
            .separability
            .as_ref()
            .expect("P_s floor")[0][0];
        assert_eq!(f.0, 1);
        above += usize::from(!f.1.consistent);
        let p_s = r.separability.as_ref().expect("P_s")[0].p_s[0].1;
        println!("separable, seed {seed}: P_s^(1) {}", show(p_s, &f.1));
        // Noise alone: of the order of a value's σ (1e-4 of values near 0.1).
        assert!(f.1.mean < 1e-4, "{}", show(p_s, &f.1));
    }
    assert!(above <= 1, "{above} of 8 above");
    let t = noisy(&paint, g, 1, |_| 1.0);
    let r = measure::report(&t, &[1], 1).expect("report");
    let f = &r
        .floor
        .as_ref()
        .expect("floors")
        .separability
        .as_ref()
        .expect("P_s floor")[0][0]
        .1;
    let p_s = r.separability.as_ref().expect("P_s")[0].p_s[0].1;
    assert!(!f.consistent && p_s > 10.0 * f.p95, "{}", show(p_s, f));
}

#[test]
fn floors_are_the_same_on_any_number_of_threads() {
    let (_, m) = materials().swap_remove(0);
    // One channel, and RGB with σ (each draw's noise drawn block by block) on a
    // paired and an interpolated grid.
    for t in [
        noisy(&m, grid_4d(), 9, |_| 1.0),
        rgb(grid_4d(), 9),
        rgb(Grid::hemisphere(6, 12), 9),
    ] {
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool")
                .install(|| measure::report(&t, &[1, 2], 2).expect("report"))
        };
        let (one, two) = (run(1), run(2));
        assert!(one.floor.as_ref().is_some_and(|f| f.draws > 0));
        assert_eq!(one, two);
    }
}

/// P_i's counterpart on a grid whose azimuth axes are the same full turn (φo − φi on
/// μ_i's nodes: looked up) equals μ_i evaluated at each node's angles (interpolated):
/// the lookup is the interpolation's value at a node, to rounding. A table whose
/// value depends on φi, so that μ_i is not the table itself.
#[test]
fn the_isotropic_counterpart_is_mu_at_each_node() {
    let g = Grid::full(
        Axis::full_turn(12),
        Axis::from_deg(5.0, 15.0, 6),
        Axis::full_turn(12),
        Axis::from_deg(0.0, 10.0, 9),
    );
    for (name, m) in &materials() {
        for seed in [3, 41] {
            let t = noisy(m, g, seed, |[pi, ..]| 1.0 + 0.3 * pi.cos());
            let (mu, _) = measure::isotropic_mean(&t, false).expect("mean");
            let c = floor::isotropic_counterpart(&t).expect("counterpart");
            let scale = t.values.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
            for ch in 0..t.channels.len() {
                for i in 0..g.len() {
                    let want = mu.eval_angles(ch, g.angles(i));
                    let got = c.channel(ch)[i];
                    assert!(
                        (got - want).abs() <= 1e-12 * scale,
                        "{name}, seed {seed}, node {i}: {got} against {want}"
                    );
                }
            }
            // μ_i is not the table: the φi dependence is averaged out.
            let apart = t.values.iter().zip(&c.values);
            assert!(
                apart.clone().any(|(a, b)| (a - b).abs() > 0.01 * scale),
                "{name}"
            );
        }
    }
}

/// An RGB table with σ: three materials' noisy tables as its channels.
fn rgb(g: Grid, seed: u64) -> Table {
    let ms = materials();
    let parts: Vec<Table> = (0..3)
        .map(|k| {
            noisy(&ms[k].1, g, seed + k as u64, |[pi, ti, ..]| {
                1.0 + 0.2 * (pi + ti).cos()
            })
        })
        .collect();
    let values = parts
        .iter()
        .flat_map(|t| t.values.iter().copied())
        .collect();
    let sigma = parts
        .iter()
        .flat_map(|t| t.sigma.iter().flatten().copied())
        .collect();
    Table::new(gonio_core::Channels::Rgb, g, values, Some(sigma)).expect("rgb")
}

/// FNV-1a over the bits of every number of the floors.
fn fingerprint(f: &floor::Floors) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325_u64;
    let mut eat = |x: f64| {
        for b in x.to_bits().to_le_bytes() {
            h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    };
    let all = f
        .reciprocity
        .iter()
        .chain(&f.energy)
        .chain(f.isotropy.iter().flatten())
        .chain(f.separability.iter().flatten().flatten().map(|(_, x)| x));
    for x in all {
        eat(x.mean);
        eat(x.p95);
        eat(x.interpolation);
        eat(x.interpolation_sigma);
        eat(f64::from(u8::from(x.consistent)));
    }
    h
}

/// The floors measured channel by channel, their counterparts read node by node and
/// each draw's noise from its place in the stream (issue 40), are the very numbers
/// of the counterparts formed whole and the draws' one stream: these fingerprints
/// are those of that earlier code (7defbeb), on a paired grid, a grid whose azimuth
/// axes agree but whose polar ones do not (P_r interpolated, P_i looked up), one
/// whose azimuths differ (both interpolated) and an isotropic one.
#[test]
fn the_floors_are_those_of_the_counterparts_formed_whole() {
    let same_phi = Grid::full(
        Axis::full_turn(12),
        Axis::from_deg(5.0, 15.0, 6),
        Axis::full_turn(12),
        Axis::from_deg(0.0, 10.0, 9),
    );
    let iso = Grid::hemisphere_isotropic(9, 24);
    let cases = [
        ("paired", Grid::hemisphere(6, 12), 0xad63_a134_b9e4_2011_u64),
        ("same azimuths", same_phi, 0x1c63_6142_cf1d_eab2),
        ("4D", grid_4d(), 0x35c1_a2f7_c4dc_81dd),
        ("isotropic", iso, 0x4c8f_ba22_2dc9_680f),
    ];
    let got: Vec<(&str, u64, u64)> = cases
        .iter()
        .map(|&(name, g, want)| {
            let t = rgb(g, 11);
            let r = measure::report(&t, &[1, 2], 2).expect("report");
            let f = r.floor.as_ref().expect("floors");
            assert!(f.draws > 0, "{name}");
            println!("{name}: {:#018x} {f:?}", fingerprint(f));
            (name, fingerprint(f), want)
        })
        .collect();
    for (name, got, want) in got {
        assert_eq!(got, want, "{name}: {got:#018x}");
    }
}
