//! DeYoung's measures and transforms: hand-computed values on small tables, the
//! invariants of Ch. 4–5, and the Phong results of Sec. 5.2.

use std::f64::consts::PI;

use gonio_brdf::Model;
use gonio_core::Channels;
use gonio_process::measure::{self, Separability};
use gonio_process::transform::{self, EnergyMode};
use gonio_process::{Axis, Grid, Table};

fn model(text: &str) -> Model {
    Model::from_toml(text, None).expect("model")
}

use crate::RGB_PAINT as LAFORTUNE;

const PHONG_SHADING: &str = r#"
kind = "phong"
channels = ["value"]
rho_s = [0.6]
n = [20]
shading = true
[diffuse]
rho = [0.3]
"#;

const WARD_ANISO: &str = r#"
kind = "ward"
channels = ["value"]
rho_s = [0.2]
alpha_x = [0.08]
alpha_y = [0.3]
[diffuse]
rho = [0.4]
"#;

const LAMBERT: &str = r#"
kind = "lambert"
channels = ["value"]
rho = [0.8]
"#;

/// The 1 × 2 × 1 × 2 table f(θi, θo) at θ = 30°, 60° (one azimuth node).
fn tiny(a: f64, b: f64, c: f64, d: f64) -> Table {
    let t = Axis::from_deg(30.0, 30.0, 2);
    let g = Grid::full(Axis::single(0.0), t, Axis::single(0.0), t);
    Table::new(Channels::Single, g, vec![a, b, c, d], None).expect("table")
}

#[test]
fn hand_computed_measures_on_a_two_by_two_table() {
    let (a, b, c, d) = (0.2, 0.3, 0.1, 0.9);
    let t = tiny(a, b, c, d);
    // Eq. 4.1: the pair (30°, 60°) differs by b − c and counts twice; four nodes.
    let (pr, used) = measure::reciprocity(&t);
    assert_eq!(used, 4);
    assert!((pr[0] - ((2.0 * (b - c) * (b - c)) / 8.0f64).sqrt()).abs() < 1e-15);
    // Eq. 4.4 with Δφ = 2π (one azimuth node) and Δθ = π/6.
    let w = |th: f64| th.to_radians().sin() * th.to_radians().cos() * 2.0 * PI * PI / 6.0;
    let alb30 = a * w(30.0) + b * w(60.0);
    let alb60 = c * w(30.0) + d * w(60.0);
    let e = measure::energy(&t, 1.0, 2);
    assert!((e.albedo[0][0] - alb30).abs() < 1e-15 && (e.albedo[0][1] - alb60).abs() < 1e-15);
    let expect = ((alb30 - 1.0).max(0.0) + (alb60 - 1.0).max(0.0)) / 2.0;
    assert!(
        (e.p_ec[0] - expect).abs() < 1e-15,
        "{} vs {expect}",
        e.p_ec[0]
    );
    assert!(
        expect > 0.0,
        "the table is meant to violate energy at one θi"
    );
    // Eq. 4.16: the 2 × 2 matrix's smaller singular value, from σ1² + σ2² = ‖A‖² and
    // σ1 σ2 = |det A|.
    let f2 = a * a + b * b + c * c + d * d;
    let det = a * d - b * c;
    let s2sq = (f2 - (f2 * f2 - 4.0 * det * det).sqrt()) / 2.0;
    let sep = measure::separability(&t, &[1, 2]).expect("svd");
    let Separability { p_s, .. } = &sep[0];
    assert!((p_s[0].1 - (s2sq / 4.0).sqrt()).abs() < 1e-14, "{p_s:?}");
    assert!(p_s[1].1.abs() < 1e-15);
}

#[test]
fn hand_computed_isotropy() {
    // φi, φo ∈ {0°, 180°}, one θ: φ+ = 0 pairs f(0,0) with f(180,180), φ+ = 180 pairs
    // f(0,180) with f(180,0); σ of two values is half their difference (Eq. 4.9).
    let (p, q, r, s) = (0.4, 0.1, 0.25, 0.2);
    let phi = Axis::full_turn(2);
    let th = Axis::from_deg(45.0, 10.0, 1);
    let g = Grid::full(phi, th, phi, th);
    let t = Table::new(Channels::Single, g, vec![p, q, r, s], None).expect("table");
    let pi = measure::isotropy(&t).expect("isotropy");
    assert!((pi[0] - ((p - s).abs() + (q - r).abs()) / 4.0).abs() < 1e-15);
    let iso = transform::isotropy(&t, 1.0).expect("transform");
    assert_eq!(
        iso.values,
        vec![(p + s) / 2.0, (q + r) / 2.0, (q + r) / 2.0, (p + s) / 2.0]
    );
}

#[test]
fn every_measure_is_zero_on_a_table_with_the_property() {
    let g = Grid::hemisphere(9, 36);
    // A tabulated Lafortune model is reciprocal (to rounding: the nodes pair exactly).
    let laf = Table::from_brdf(&model(LAFORTUNE), g).expect("table");
    let (pr, _) = measure::reciprocity(&laf);
    let peak = laf.values.iter().copied().fold(0.0, f64::max);
    assert!(pr.iter().all(|p| *p <= 1e-15 * peak), "{pr:?}");
    // ... and, isotropic lobes tabulated in 4D, isotropic.
    let pi = measure::isotropy(&laf).expect("isotropy");
    assert!(pi.iter().all(|p| *p <= 1e-15 * peak), "{pi:?}");
    // A Lambertian table of albedo 0.8 conserves energy. Its albedo is the midpoint
    // rule's: Σ sin 2θ_k over the band midpoints is 1/sin Δθ, so the sum of Eq. 4.4
    // gives ρ Δθ / sin Δθ (0.5 % high for 10° bands).
    let lam = Table::from_brdf(&model(LAMBERT), g).expect("table");
    let e = measure::energy(&lam, 1.0, 3);
    assert_eq!(e.p_ec, vec![0.0]);
    let dt = 10f64.to_radians();
    let expect = 0.8 * dt / dt.sin();
    assert!(
        e.albedo[0].iter().all(|a| (a - expect).abs() < 1e-13),
        "{:?}",
        e.albedo[0]
    );
    // ... and is separable (rank one).
    let sep = measure::separability(&lam, &[1]).expect("svd");
    assert!(sep[0].p_s[0].1 < 1e-15, "{:?}", sep[0].p_s);
}

#[test]
fn phong_shading_is_non_reciprocal_and_breaks_energy_at_grazing_incidence() {
    // DeYoung Sec. 5.2: the Phong shading BRDF has P_r > 0 and loses energy
    // conservation as θi grows; its worst incident directions are the grazing ones.
    let g = Grid::hemisphere(18, 72);
    let t = Table::from_brdf(&model(PHONG_SHADING), g).expect("table");
    let r = measure::report(&t, &[1], 3).expect("report");
    assert!(r.reciprocity[0] > 0.05, "P_r = {}", r.reciprocity[0]);
    assert!(r.energy.p_ec[0] > 0.0, "P_ec = {}", r.energy.p_ec[0]);
    assert!(
        (r.energy.worst[0].0 - 87.5).abs() < 1e-9,
        "{:?}",
        r.energy.worst[0]
    );
    // The lobe's albedo at normal incidence is what the model says (0.6 + 0.3 = 0.9
    // within the rule's error), and it only exceeds 1 towards grazing.
    assert!(
        (r.energy.albedo[0][0] - 0.9).abs() < 0.02,
        "{}",
        r.energy.albedo[0][0]
    );
    let first_bad = (0..18)
        .find(|&b| r.energy.albedo[0][b] > 1.0)
        .expect("a violation");
    assert!(
        first_bad >= 9,
        "violates from θi = {}°",
        2.5 + 5.0 * first_bad as f64
    );
}

#[test]
fn after_each_transform_with_delta_one_its_measure_is_zero() {
    let g = Grid::hemisphere(9, 36);
    let phong = Table::from_brdf(&model(PHONG_SHADING), g).expect("table");
    let peak = phong.values.iter().copied().fold(0.0, f64::max);

    let (before, _) = measure::reciprocity(&phong);
    let half = transform::reciprocity(&phong, 0.5).expect("δ = 0.5");
    let full = transform::reciprocity(&phong, 1.0).expect("δ = 1");
    // Eq. 5.2 is linear in δ: f'(x) − f'(xʳ) = (1 − δ)(f(x) − f(xʳ)).
    assert!((measure::reciprocity(&half).0[0] - 0.5 * before[0]).abs() < 1e-14 * peak);
    assert!(measure::reciprocity(&full).0[0] < 1e-15 * peak);

    for mode in [EnergyMode::PerDirection, EnergyMode::Global] {
        let ec = transform::energy(&phong, 1.0, mode, 1.0).expect("energy");
        let e = measure::energy(&ec, 1.0, 1);
        assert!(e.p_ec[0] < 1e-15, "{mode:?}: {}", e.p_ec[0]);
        assert!(e.albedo[0].iter().all(|a| *a <= 1.0 + 1e-14));
    }
    let tau = transform::energy(&phong, 1.0, EnergyMode::PerDirection, 0.85).expect("τ");
    let e = measure::energy(&tau, 0.85, 1);
    assert!(e.p_ec[0] < 1e-15 && e.albedo[0].iter().all(|a| *a <= 0.85 + 1e-14));
    // Directions that conserve energy are left alone (Eq. 5.4: x = 1 there).
    let ec = transform::energy(&phong, 1.0, EnergyMode::PerDirection, 1.0).expect("energy");
    let q = g.n_out();
    assert_eq!(ec.values[..q], phong.values[..q]);

    let ward = Table::from_brdf(&model(WARD_ANISO), g).expect("table");
    let pi = measure::isotropy(&ward).expect("P_i")[0];
    assert!(pi > 1e-3, "anisotropic Ward measures P_i = {pi}");
    let half = transform::isotropy(&ward, 0.5).expect("δ = 0.5");
    assert!((measure::isotropy(&half).expect("P_i")[0] - 0.5 * pi).abs() < 1e-12 * pi);
    let iso = transform::isotropy(&ward, 1.0).expect("δ = 1");
    assert!(measure::isotropy(&iso).expect("P_i")[0] < 1e-15 * pi.max(1.0));

    for k in [1, 3] {
        let sep = transform::separable(&phong, k, 1.0).expect("separable");
        let p = measure::separability(&sep, &[k]).expect("svd")[0].p_s[0].1;
        assert!(p < 1e-12 * peak, "k = {k}: P_s^(k) = {p}");
    }
}

/// A table of a function of the angles (φi, θi, φo, θo).
fn from_fn(g: Grid, f: impl Fn([f64; 4]) -> f64) -> Table {
    let v = (0..g.len()).map(|i| f(g.angles(i))).collect();
    Table::new(Channels::Single, g, v, None).expect("table")
}

#[test]
fn measures_do_not_depend_on_grid_resolution_for_a_smooth_model() {
    // DeYoung Sec. 4.1: the measures are means, not sums, so a smooth BRDF measures
    // the same on coarse and fine grids. Each measure is taken on 10° × 10° and
    // 5° × 5° grids of a smooth function that lacks the property.
    let grids = [Grid::hemisphere(9, 36), Grid::hemisphere(18, 72)];
    let close = |name: &str, m: [f64; 2], tol: f64| {
        assert!(
            m[0] > 0.0 && (m[0] - m[1]).abs() < tol * m[1],
            "{name}: {m:?}"
        );
    };
    // Not reciprocal: the incident and outgoing cosines enter with other powers.
    let nonrecip = |a: [f64; 4]| 0.1 + 0.2 * a[1].cos().powi(2) * a[3].cos();
    close(
        "P_r",
        grids.map(|g| measure::reciprocity(&from_fn(g, nonrecip)).0[0]),
        0.03,
    );
    // Anisotropic: a broad lobe that depends on φi itself.
    let aniso = |a: [f64; 4]| 0.1 * (1.0 + 0.5 * (2.0 * a[0]).cos() * a[1].sin() * a[3].sin());
    close(
        "P_i",
        grids.map(|g| measure::isotropy(&from_fn(g, aniso)).expect("P_i")[0]),
        0.03,
    );
    // Not energy conserving: Lambertian of albedo 1.2 (P_ec → 0.2).
    let over = |_: [f64; 4]| 1.2 / PI;
    close(
        "P_ec",
        grids.map(|g| measure::energy(&from_fn(g, over), 1.0, 1).p_ec[0]),
        0.03,
    );
    // Not separable: a lobe about the mirror direction.
    let lobe = |a: [f64; 4]| {
        let (wi, wo) = (
            gonio_core::Dir::from_angles(a[1], a[0]),
            gonio_core::Dir::from_angles(a[3], a[2]),
        );
        0.1 + wi.mirror().dot(*wo).max(0.0).powi(4)
    };
    close(
        "P_s",
        grids.map(|g| measure::separability(&from_fn(g, lobe), &[1]).expect("svd")[0].p_s[0].1),
        0.03,
    );
}

#[test]
fn uncertainties_weight_the_reciprocity_average() {
    // A certain value and an uncertain reciprocal: the average leans to the certain
    // one by inverse variance, and its uncertainty is that of the weighted mean.
    let mut t = tiny(0.2, 0.3, 0.1, 0.5);
    t.sigma = Some(vec![0.01, 0.01, 0.03, 0.01]);
    let r = transform::reciprocity(&t, 1.0).expect("transform");
    let (w1, w2) = (1.0 / 0.01f64.powi(2), 1.0 / 0.03f64.powi(2));
    let expect = (w1 * 0.3 + w2 * 0.1) / (w1 + w2);
    assert!((r.values[1] - expect).abs() < 1e-15 && (r.values[2] - expect).abs() < 1e-15);
    let s = r.sigma.expect("sigma");
    assert!((s[1] - (w1 + w2).sqrt().recip()).abs() < 1e-15, "{}", s[1]);
}

#[test]
fn isotropic_tables_measure_and_expand() {
    // The isotropic form of a Lafortune table: P_i is 0 by construction, its
    // reciprocity pairs (φ+ nodes symmetric), and its 4D expansion equals the 4D table.
    let th = Axis::polar_midpoints(9);
    let iso_grid = Grid::isotropic(th, Axis::full_turn(36), th);
    let m = model(LAFORTUNE);
    let iso = Table::from_brdf(&m, iso_grid).expect("iso");
    assert!(iso.grid.is_paired());
    assert_eq!(measure::isotropy(&iso).expect("P_i"), vec![0.0; 3]);
    assert!(measure::reciprocity(&iso).0.iter().all(|p| *p < 1e-15));
    let full = iso.to_full(36).expect("full");
    let direct = Table::from_brdf(&m, Grid::hemisphere(9, 36)).expect("direct");
    let worst = full
        .values
        .iter()
        .zip(&direct.values)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-12, "{worst}");
}
