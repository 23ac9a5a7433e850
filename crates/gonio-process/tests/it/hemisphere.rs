//! Measured samples over the hemisphere: bilateral unfolding of an isotropic half
//! turn, the samples' own grid with its holes reported, and DeYoung's triangulated
//! directional albedo (Sec. 4.2.2) against closed forms.

use gonio_brdf::{Brdf, Model};
use gonio_core::dirfile::PairDeg;
use gonio_core::{Channels, Dir, SphericalDeg};
use gonio_process::hemisphere::{self, Symmetry};
use gonio_process::samples::Kernel;
use gonio_process::{Sample, Samples, measure};

fn pair(ti: f64, pi: f64, to: f64, po: f64) -> PairDeg {
    PairDeg {
        incident: SphericalDeg::new(ti, pi),
        outgoing: SphericalDeg::new(to, po),
    }
}

/// Samples of `f(θi, θo, Δφ)` (degrees) on the given axes, isotropic, with σ.
fn iso(
    ti: &[f64],
    to: &[f64],
    dphi: &[f64],
    f: impl Fn(f64, f64, f64) -> f64,
    sigma: f64,
) -> Samples {
    let mut samples = Vec::new();
    for &a in ti {
        for &b in to {
            for &d in dphi {
                samples.push(Sample {
                    pair: pair(a, 30.0, b, 30.0 + d),
                    value: vec![f(a, b, d)],
                    sigma: Some(vec![sigma]),
                    flags: 0,
                });
            }
        }
    }
    Samples {
        channels: Channels::Single,
        samples,
        isotropic: true,
    }
}

fn steps(from: f64, to: f64, step: f64) -> Vec<f64> {
    let n = ((to - from) / step).round() as usize;
    (0..=n).map(|k| from + k as f64 * step).collect()
}

#[test]
fn a_half_turn_unfolds_and_nothing_else_does() {
    let half = iso(
        &[30.0],
        &[0.0, 20.0, 40.0],
        &steps(0.0, 180.0, 30.0),
        |_, _, d| d,
        0.0,
    );
    let (u, sym) = hemisphere::unfold(&half);
    assert_eq!(sym, Symmetry::IsotropicBilateral);
    // 21 samples; θo = 0 (7) and the mirror plane Δφ = 0, 180 (2 × 2) stay single:
    // 10 mirrored.
    assert_eq!(u.samples.len(), 21 + 10);
    for s in &u.samples[21..] {
        let d = s.pair.outgoing.phi_deg - s.pair.incident.phi_deg;
        // The mirrored sample carries the value measured at −Δφ.
        assert!((s.value[0] + d).abs() < 1e-9, "{d} {}", s.value[0]);
    }
    // A full turn is not unfolded; nor is an anisotropic half turn.
    let full = iso(&[30.0], &[20.0], &steps(0.0, 330.0, 30.0), |_, _, d| d, 0.0);
    assert_eq!(hemisphere::unfold(&full).1, Symmetry::Isotropic);
    assert_eq!(hemisphere::unfold(&full).0, full);
    let aniso = Samples {
        isotropic: false,
        ..half.clone()
    };
    assert_eq!(hemisphere::unfold(&aniso).1, Symmetry::None);
    assert_eq!(hemisphere::unfold(&aniso).0.samples.len(), 21);
    // The other half (Δφ in [180°, 360°]) unfolds too; the plane alone does not.
    let other = iso(
        &[30.0],
        &[20.0],
        &steps(180.0, 360.0, 30.0),
        |_, _, d| d,
        0.0,
    );
    assert_eq!(hemisphere::unfold(&other).1, Symmetry::IsotropicBilateral);
    let plane = iso(&[30.0], &[20.0, 40.0], &[0.0, 180.0], |_, _, d| d, 0.0);
    assert_eq!(hemisphere::unfold(&plane).1, Symmetry::Isotropic);
}

#[test]
fn own_grid_reports_its_holes_and_refuses_to_invent() {
    let f = |a: f64, b: f64, d: f64| 1.0 + 0.01 * a + 0.02 * b + 0.001 * d.to_radians().cos();
    let mut s = iso(
        &steps(0.0, 60.0, 15.0),
        &steps(0.0, 80.0, 10.0),
        &steps(0.0, 345.0, 15.0),
        f,
        1e-3,
    );
    // Retro-reflection shadowed: θo = θi at Δφ = 0 not measured.
    s.samples.retain(|x| {
        let d = (x.pair.outgoing.phi_deg - x.pair.incident.phi_deg).rem_euclid(360.0);
        !((x.pair.outgoing.theta_deg - x.pair.incident.theta_deg).abs() < 1e-9
            && d.abs() < 1e-9
            && x.pair.incident.theta_deg > 0.0)
    });
    let (t, fill) = hemisphere::own_table(&s, Kernel::default()).expect("own grid");
    assert_eq!(t.grid.theta_i.n, 5);
    assert_eq!(t.grid.theta_o.n, 9);
    assert!(t.grid.phi_o.is_periodic());
    assert_eq!(fill.nodes, 5 * 9 * 24);
    // θo = θi, Δφ = 0 where both axes have the angle: θi 30° and 60°.
    assert_eq!(fill.interpolated.len(), 2, "{:?}", fill.interpolated);
    assert_eq!(fill.measured, fill.nodes - 2);
    for h in &fill.interpolated {
        assert_eq!(h[0], h[2]);
        // A hole takes its neighbours' values: within the function's change over a step.
        let v = t.eval_angles(
            0,
            [0.0, h[0].to_radians(), h[3].to_radians(), h[2].to_radians()],
        );
        assert!((v - f(h[0], h[2], 0.0)).abs() < 0.25, "{v}");
    }
    // Measured nodes are the measurements.
    let v = t.eval_angles(
        0,
        [
            0.0,
            30f64.to_radians(),
            90f64.to_radians(),
            50f64.to_radians(),
        ],
    );
    assert!((v - f(30.0, 50.0, 90.0)).abs() < 1e-12);

    // A band of rings missing in the middle: its edges are interpolated, its middle
    // (10° from the data, past 1.5 steps of 5°) is far, and refused.
    let fine = iso(
        &[30.0],
        &steps(0.0, 85.0, 5.0),
        &steps(0.0, 355.0, 5.0),
        f,
        1e-3,
    );
    let mut gap = fine.clone();
    gap.samples
        .retain(|x| !(x.pair.outgoing.theta_deg > 37.5 && x.pair.outgoing.theta_deg < 52.5));
    let e = hemisphere::own_table(&gap, Kernel::default()).expect_err("refused");
    assert!(e.to_string().contains("72 of the 1296 nodes"), "{e}");
    assert!(e.to_string().contains("farther than 7.5°"), "{e}");
    // More than a quarter of the span unmeasured: refused at once, however near.
    let mut sparse = fine.clone();
    sparse.samples.retain(|x| {
        let d = x.pair.outgoing.phi_deg - x.pair.incident.phi_deg;
        ((x.pair.outgoing.theta_deg + d) / 5.0).round() as i64 % 2 == 0
    });
    let e = hemisphere::own_table(&sparse, Kernel::default()).expect_err("refused");
    assert!(e.to_string().contains("were not measured"), "{e}");
    // Axes on no uniform spacing: refused, naming the axis.
    let mut odd = s.clone();
    odd.samples[0].pair.outgoing.theta_deg = 3.0;
    let e = hemisphere::own_grid(&odd).expect_err("refused");
    assert!(e.to_string().contains("theta_o"), "{e}");
}

#[test]
fn triangulated_albedo_is_exact_for_constants_and_linear_functions() {
    // Lambertian ρ = 0.7 measured to θo = 80° over a full turn: the band is held, so
    // the albedo is ρ exactly, and the stated σ is the weights' propagation.
    let rho = 0.7;
    let lam = iso(
        &[0.0, 40.0],
        &steps(0.0, 80.0, 10.0),
        &steps(0.0, 345.0, 15.0),
        |_, _, _| rho / std::f64::consts::PI,
        1e-3,
    );
    let rows = hemisphere::albedos(&lam).expect("albedos");
    assert_eq!(rows.len(), 2);
    for r in &rows {
        assert!((r.albedo[0] - rho).abs() < 1e-12, "{}", r.albedo[0]);
        // Covered: the 24-gon inscribed in the 80° circle.
        let poly = 12.0 * (15f64.to_radians()).sin() * 80f64.to_radians().sin().powi(2);
        assert!((r.covered - poly / std::f64::consts::PI).abs() < 1e-12);
        assert!((r.covered + r.extrapolated - 1.0).abs() < 1e-12);
        // Σ w_k = π (the disk) and every w_k ≤ π: σ lies between the all-in-one
        // bound π σ and the even split π σ / √n.
        let s = r.sigma.as_ref().expect("σ")[0];
        let n = r.directions as f64;
        assert!(s < std::f64::consts::PI * 1e-3 && s > std::f64::consts::PI * 1e-3 / n.sqrt());
    }
    // f linear in the projected coordinates, f = a + b x: exact over the triangles
    // (the x term cancels over the symmetric polygon, a over its area), and the thin
    // band between the polygon and the horizon holds a + b x̄ of each edge, whose x
    // terms cancel again: aπ in all.
    let lin = iso(
        &[20.0],
        &steps(0.0, 90.0, 10.0),
        &steps(0.0, 345.0, 15.0),
        |_, b, d| 0.3 + 0.2 * b.to_radians().sin() * d.to_radians().cos(),
        0.0,
    );
    let r = &hemisphere::albedos(&lin).expect("albedos")[0];
    let poly = 12.0 * (15f64.to_radians()).sin();
    assert!(
        (r.albedo[0] - 0.3 * std::f64::consts::PI).abs() < 1e-12,
        "{}",
        r.albedo[0]
    );
    assert!((r.covered * std::f64::consts::PI - poly).abs() < 1e-12);
}

#[test]
fn a_hull_that_misses_the_normal_is_not_extended() {
    // An in-plane fan of one side only: the albedo covers the hull and nothing more.
    let side = iso(
        &[30.0],
        &steps(10.0, 80.0, 10.0),
        &steps(0.0, 90.0, 15.0),
        |_, _, _| 1.0,
        0.0,
    );
    let r = &hemisphere::albedos(&side).expect("albedos")[0];
    assert_eq!(r.extrapolated, 0.0);
    assert!(r.covered < 0.25 && r.covered > 0.15, "{}", r.covered);
    assert!((r.albedo[0] - r.covered * std::f64::consts::PI).abs() < 1e-12);
    // A line of samples spans no area: no albedo at all.
    let line = iso(
        &[30.0],
        &steps(0.0, 80.0, 10.0),
        &[0.0, 180.0],
        |_, _, _| 1.0,
        0.0,
    );
    assert!(hemisphere::albedos(&line).is_err());
}

#[test]
fn energy_of_a_model_on_a_half_turn_plan_matches_its_albedo() {
    // A broad Lafortune paint measured over a half turn, unfolded, integrated: within
    // 0.5% of the closed-form albedo (the band beyond 85° held).
    let m = Model::from_toml(
        "kind = \"lafortune\"\nchannels = [\"value\"]\n[diffuse]\nrho = [0.5]\n\
         [[lobes]]\ncx = [-0.8]\ncy = [-0.8]\ncz = [0.7]\nn = [8]\n",
        None,
    )
    .expect("model");
    let f = |a: f64, b: f64, d: f64| {
        let mut v = [0.0];
        m.eval(
            Dir::from(SphericalDeg::new(a, 0.0)),
            Dir::from(SphericalDeg::new(b, d)),
            &mut v,
        );
        v[0]
    };
    let half = iso(
        &[0.0, 20.0, 40.0, 60.0],
        &steps(0.0, 85.0, 5.0),
        &steps(0.0, 180.0, 10.0),
        f,
        1e-4,
    );
    let (u, sym) = hemisphere::unfold(&half);
    assert_eq!(sym, Symmetry::IsotropicBilateral);
    let e = measure::energy_scattered(&u, 1.0, 4).expect("energy");
    assert_eq!(e.method, measure::EnergyMethod::Triangulated);
    for (k, (ti, _)) in e.incident.iter().enumerate() {
        let mut a = [0.0];
        m.albedo(Dir::from(SphericalDeg::new(*ti, 0.0)), &mut a);
        let got = e.albedo[0][k];
        assert!(
            (got - a[0]).abs() < 5e-3 * a[0],
            "θi {ti}: {got} vs {}",
            a[0]
        );
    }
    assert_eq!(e.p_ec, vec![0.0]);
    // The half turn alone, not unfolded, covers half the disk and is not extended.
    let e_half = measure::energy_scattered(&half, 1.0, 1).expect("energy");
    assert!(e_half.coverage < 0.51 && e_half.extrapolated == 0.0);
}

#[test]
fn a_half_turn_table_measures_the_whole_albedo() {
    // The review's finding: the energy measure of an isotropic table over Δφ = 0…180°
    // read 0.54 of the truth (the sum saw half the azimuths). Unfolded, the
    // triangulated albedo of the table's nodes is within 1% of the closed form.
    use gonio_process::{Axis, Grid, Table};
    let m = Model::from_toml(
        "kind = \"lafortune\"\nchannels = [\"value\"]\n[diffuse]\nrho = [0.6]\n\
         [[lobes]]\ncx = [-0.7]\ncy = [-0.7]\ncz = [0.6]\nn = [5]\n",
        None,
    )
    .expect("model");
    let t = Axis::polar_midpoints(18);
    let g = Grid::isotropic(t, Axis::from_deg(0.0, 10.0, 19), t);
    let table = Table::from_brdf(&m, g).expect("table");
    let r = measure::report(&table, &[1], 1).expect("report");
    assert_eq!(r.energy.method, measure::EnergyMethod::Triangulated);
    for (k, (ti, _)) in r.energy.incident.iter().enumerate() {
        let mut a = [0.0];
        m.albedo(Dir::from(SphericalDeg::new(*ti, 0.0)), &mut a);
        let got = r.energy.albedo[0][k];
        assert!(
            (got - a[0]).abs() < 0.01 * a[0],
            "θi {ti}: {got} vs {}",
            a[0]
        );
    }
}

#[test]
fn a_tables_rows_integrate_as_its_samples_do() {
    // The row-at-a-time path over a table's nodes gives what the samples of the table
    // give (unfolded), to rounding: on an isotropic half turn and on a 4-D table whose
    // polar nodes are not band midpoints.
    use gonio_process::{Axis, Grid, Table};
    let m = Model::from_toml(
        "kind = \"lafortune\"\nchannels = [\"500nm\", \"600nm\"]\n[diffuse]\nrho = [0.6, 0.3]\n\
         [[lobes]]\ncx = [-0.7, -0.9]\ncy = [-0.7, -0.9]\ncz = [0.6, 0.8]\nn = [5, 12]\n",
        None,
    )
    .expect("model");
    let theta = Axis::from_deg(0.0, 10.0, 9);
    // (A 4-D table's rows at θi = 0 and different φi are one direction to the
    // samples' grouping; these start at 5°.)
    let off = Axis::from_deg(5.0, 10.0, 8);
    for g in [
        Grid::isotropic(theta, Axis::from_deg(0.0, 15.0, 13), theta),
        Grid::full(Axis::full_turn(4), off, Axis::full_turn(24), off),
    ] {
        let mut t = Table::from_brdf(&m, g).expect("table");
        t.sigma = Some(t.values.iter().map(|v| 1e-3 * v).collect());
        let rows = measure::energy_triangulated(&t, 1.0, 3).expect("rows");
        let (s, _) = hemisphere::unfold(&gonio_process::Samples::from_table(&t));
        let samples = measure::energy_scattered(&s, 1.0, 3).expect("samples");
        assert_eq!(rows.incident.len(), samples.incident.len());
        // Rows come in grid order (φi, θi), groups in (θi, φi) order.
        for (k, inc) in rows.incident.iter().enumerate() {
            let j = samples
                .incident
                .iter()
                .position(|x| (x.0 - inc.0).abs() < 1e-9 && (x.1 - inc.1).abs() < 1e-9)
                .expect("the same incidence");
            for ch in 0..2 {
                let (a, b) = (rows.albedo[ch][k], samples.albedo[ch][j]);
                assert!((a - b).abs() < 1e-12, "{inc:?}: {a} vs {b}");
                let (sa, sb) = (
                    rows.albedo_sigma.as_ref().expect("σ")[ch][k],
                    samples.albedo_sigma.as_ref().expect("σ")[ch][j],
                );
                assert!((sa - sb).abs() < 1e-15, "{sa} vs {sb}");
                // And the same discretisation uncertainty.
                let (qa, qb) = (
                    rows.albedo_quadrature_sigma[ch][k],
                    samples.albedo_quadrature_sigma[ch][j],
                );
                assert!(
                    qa > 0.0 && (qa - qb).abs() < 1e-12 * a,
                    "{inc:?}: {qa} vs {qb}"
                );
            }
        }
        assert!((rows.coverage - samples.coverage).abs() < 1e-12);
        assert!((rows.extrapolated - samples.extrapolated).abs() < 1e-12);
    }
}

#[test]
fn half_turn_tells_from_the_axes_what_unfold_would_mirror() {
    use gonio_process::{Axis, Grid, Table};
    let t = Axis::from_deg(0.0, 15.0, 5);
    let c = |_: gonio_core::Dir, _: gonio_core::Dir, out: &mut [f64]| out[0] = 1.0;
    for (g, want) in [
        (Grid::isotropic(t, Axis::from_deg(0.0, 30.0, 7), t), true),
        (Grid::isotropic(t, Axis::from_deg(180.0, 30.0, 7), t), true),
        (Grid::isotropic(t, Axis::from_deg(90.0, 30.0, 7), t), false),
        (Grid::isotropic(t, Axis::full_turn(12), t), false),
        (Grid::isotropic(t, Axis::from_deg(0.0, 180.0, 2), t), false),
        (
            Grid::isotropic(t, Axis::from_deg(0.0, 30.0, 7), Axis::single(0.0)),
            false,
        ),
        (
            Grid::full(Axis::full_turn(4), t, Axis::from_deg(0.0, 30.0, 7), t),
            false,
        ),
    ] {
        let table = Table::from_fn(Channels::Single, g, c).expect("table");
        let (_, sym) = hemisphere::unfold(&gonio_process::Samples::from_table(&table));
        assert_eq!(hemisphere::half_turn(&g), want, "{g:?}");
        assert_eq!(sym == Symmetry::IsotropicBilateral, want, "{g:?}");
    }
}
