//! What a fit minimises (the objectives and the default rule, with residual weights
//! computed by hand) and the energy-constrained fit (albedo ≤ 1 at every incident
//! direction of the data, at the constrained optimum).

use gonio_brdf::{Brdf, Model};
use gonio_core::dirfile::PairDeg;
use gonio_core::{Channels, Dir, SphericalDeg, Vec3};
use gonio_fit::data::{DataOptions, FitData, Objective, RELATIVE_FLOOR};
use gonio_fit::lobes::{Diffuse, LobeBasis, Shape};
use gonio_fit::varpro::{self, Basis};
use gonio_fit::{FitOptions, LobeFit, fit_lobes};
use gonio_process::{Sample, Samples};

fn pair(ti: f64, to: f64) -> PairDeg {
    PairDeg {
        incident: SphericalDeg::new(ti, 0.0),
        outgoing: SphericalDeg::new(to, 180.0),
    }
}

/// Three samples at (θi, θo) = (0, 60°), (60°, 0), (60°, 60°): values 0.4, 0.2, 0.001
/// with σ 0.02, 0.05, 0.004.
fn three(sigma: bool) -> Samples {
    let rows = [
        (0.0, 60.0, 0.4, 0.02),
        (60.0, 0.0, 0.2, 0.05),
        (60.0, 60.0, 0.001, 0.004),
    ];
    Samples {
        channels: Channels::from_names(&["value"]).expect("channel"),
        isotropic: false,
        samples: rows
            .iter()
            .map(|&(ti, to, v, s)| Sample {
                pair: pair(ti, to),
                value: vec![v],
                sigma: sigma.then(|| vec![s]),
                flags: 0,
            })
            .collect(),
    }
}

fn weights(s: &Samples, objective: Option<Objective>, use_sigma: bool) -> (Objective, Vec<f64>) {
    let d = FitData::from_samples(
        s,
        &DataOptions {
            objective,
            use_sigma,
            ..DataOptions::default()
        },
    )
    .expect("data");
    assert_eq!(d.chi_square, d.objective == Objective::Chi2);
    (d.objective, d.weight[0].to_vec())
}

fn close(a: &[f64], b: &[f64]) {
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(b) {
        assert!((x - y).abs() <= 1e-12 * y.abs(), "{a:?} vs {b:?}");
    }
}

#[test]
fn each_objective_weighs_the_residuals_as_computed_by_hand() {
    let s = three(true);
    // Lafortune's cosines: cos θi cos θo = 1·½, ½·1, ½·½.
    let (o, w) = weights(&s, Some(Objective::Cosine), true);
    assert_eq!(o, Objective::Cosine);
    close(&w, &[0.5, 0.5, 0.25]);
    // χ²: 1/σ.
    let (_, w) = weights(&s, Some(Objective::Chi2), true);
    close(&w, &[50.0, 20.0, 250.0]);
    // Relative: 1/max(|y|, 0.01 × mean |y|); mean |y| = 0.601/3, floor 0.0020033…, so
    // the third (0.001) is floored.
    assert_eq!(RELATIVE_FLOOR, 0.01);
    let floor = 0.01 * (0.4 + 0.2 + 0.001) / 3.0;
    let (_, w) = weights(&s, Some(Objective::Relative), true);
    close(&w, &[2.5, 5.0, 1.0 / floor]);
    // The Ngan metric's cosine objective: cos θi alone.
    let d = FitData::from_samples(
        &s,
        &DataOptions {
            objective: Some(Objective::Cosine),
            metric: gonio_fit::Metric::Ngan,
            ..DataOptions::default()
        },
    )
    .expect("data");
    close(&d.weight[0], &[1.0, 0.5, 0.5]);
}

#[test]
fn the_default_rule_is_chi2_with_every_sigma_else_cosine_and_says_so() {
    let (o, w) = weights(&three(true), None, true);
    assert_eq!(o, Objective::Chi2);
    close(&w, &[50.0, 20.0, 250.0]);
    let (o, w) = weights(&three(false), None, true);
    assert_eq!(o, Objective::Cosine);
    close(&w, &[0.5, 0.5, 0.25]);
    // `--unweighted`: cosine even with σ.
    let (o, _) = weights(&three(true), None, false);
    assert_eq!(o, Objective::Cosine);
    // One σ of 0: not every sample has σ > 0.
    let mut s = three(true);
    s.samples[1].sigma = Some(vec![0.0]);
    let d = FitData::from_samples(&s, &DataOptions::default()).expect("data");
    assert_eq!(d.objective, Objective::Cosine);
    assert!(
        d.objective_rule.contains("not every sample"),
        "{}",
        d.objective_rule
    );
    // χ² asked for without σ everywhere is refused, naming the sample.
    let e = FitData::from_samples(
        &s,
        &DataOptions {
            objective: Some(Objective::Chi2),
            ..DataOptions::default()
        },
    )
    .expect_err("no σ");
    assert!(e.to_string().contains("sample 1"), "{e}");
    // Names round-trip, and the formula says what is summed.
    for o in Objective::ALL {
        assert_eq!(Objective::from_name(o.name()), Some(o));
    }
    assert!(
        Objective::Cosine
            .formula(gonio_fit::Metric::Lafortune)
            .contains("cos θi cos θo")
    );
}

/// θi 0…70° by 10°, θo 5…85° by 10°, φo by 30°.
fn grid() -> Vec<PairDeg> {
    let mut v = Vec::new();
    for ti in (0..=70).step_by(10) {
        for to in (5..=85).step_by(10) {
            for k in 0..12 {
                v.push(PairDeg {
                    incident: SphericalDeg::new(f64::from(ti), 0.0),
                    outgoing: SphericalDeg::new(f64::from(to), 30.0 * f64::from(k)),
                });
            }
        }
    }
    v
}

fn fit(model: &str, conserve: bool) -> (LobeFit, FitData, Model) {
    let truth = Model::from_toml(model, None).expect("model");
    let data = FitData::from_samples(
        &Samples::from_brdf(&truth, &grid()),
        &DataOptions::default(),
    )
    .expect("data");
    let opts = FitOptions {
        shape: Shape {
            lobes: 1,
            anisotropic: false,
            diffuse: Diffuse::Lambert,
        },
        conserve_energy: conserve,
        ..FitOptions::default()
    };
    (fit_lobes(&data, &opts).expect("fit"), data, truth)
}

/// Σ (w (f_model − y))² of a model over the data: the objective, computed from the
/// model file alone.
fn cost(model: &Model, d: &FitData) -> f64 {
    let mut f = [0.0];
    (0..d.len())
        .map(|i| {
            let (u, v) = (d.wi[i], d.wo[i]);
            model.eval(
                Dir::from_unit(Vec3::new(u[0], u[1], u[2])),
                Dir::from_unit(Vec3::new(v[0], v[1], v[2])),
                &mut f,
            );
            (d.weight[0][i] * (f[0] - d.y[0][i])).powi(2)
        })
        .sum()
}

fn albedo(model: &Model, theta_deg: f64) -> f64 {
    let mut a = [0.0];
    model.albedo(Dir::from_angles(theta_deg.to_radians(), 0.0), &mut a);
    a[0]
}

/// A diffuse 0.6 and a lobe about the mirror direction of strength 1.3 (|C|ⁿ): albedo
/// 0.6 + 1.3 · 2π/12 = 1.28 at normal incidence, falling below 1 towards grazing.
const BRIGHT: &str = "kind = \"lafortune\"\nchannels = [\"value\"]\n[diffuse]\nrho = [0.6]\n\
                      [[lobes]]\ncx = [-1.0266]\ncy = [-1.0266]\ncz = [1.0266]\nn = [10.0]\n";

#[test]
fn the_energy_constrained_fit_meets_albedo_one_at_every_incidence_at_a_higher_cost() {
    let (free, data, truth) = fit(BRIGHT, false);
    let free_model = free.model.as_ref().expect("model");
    // The unconstrained fit recovers the truth, whose albedo exceeds 1.
    assert!(albedo(&truth, 0.0) > 1.2);
    assert!(albedo(free_model, 0.0) > 1.2, "{}", albedo(free_model, 0.0));
    assert!(free.energy.is_none());

    let (held, _, _) = fit(BRIGHT, true);
    let model = held.model.as_ref().expect("model");
    let e = held.energy.as_ref().expect("energy report");
    assert!(e.constrained);
    assert_eq!(e.directions, 8);
    // At every incident direction of the data, from the model file's own albedo
    // (gonio-brdf's exact integrals, not the fit's): ≤ 1, and 1 where it binds.
    let alb: Vec<f64> = (0..8).map(|t| albedo(model, f64::from(10 * t))).collect();
    let max = alb.iter().copied().fold(0.0, f64::max);
    assert!(alb.iter().all(|a| *a <= 1.0 + 1e-6), "{alb:?}");
    assert!(max >= 1.0 - 1e-6, "the constraint is active: {alb:?}");
    let c = &e.channels[0];
    assert!(!c.active.is_empty() && c.active.iter().all(|x| x.multiplier > 0.0));
    assert!(
        (c.max_albedo - max).abs() < 1e-6,
        "{} vs {max}",
        c.max_albedo
    );
    // The constrained optimum costs more than the unconstrained one (both from the
    // model files), and the report's costs are those.
    let (c_free, c_held) = (cost(free_model, &data), cost(model, &data));
    assert!(c_held >= c_free, "{c_held} < {c_free}");
    assert!(c_held > 0.0);
    assert!(
        (c.cost - c_held).abs() <= 1e-6 * c_held,
        "{} vs {c_held}",
        c.cost
    );
    assert!((c.unconstrained_cost - c_free).abs() <= 1e-6 * c_held + 1e-20);
    // A constrained optimum: no small move of the non-linear parameters (each with
    // its best feasible strengths) lowers the constrained cost.
    let basis = LobeBasis {
        shape: held.shape,
        channels: 1,
        shared: false,
    };
    let l = held.channels[0].params.lobes[0];
    let norm = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
    let beta = -(l[2] / norm).acos();
    let mut theta = vec![0.0; basis.n_params()];
    basis.set_lobe(&mut theta, 0, 0, beta, std::f64::consts::FRAC_PI_4, l[3]);
    let limits: Vec<[f64; 3]> = (0..8)
        .map(|t| {
            let r = f64::from(10 * t).to_radians();
            [r.sin(), 0.0, r.cos()]
        })
        .collect();
    let at = |t: &[f64]| {
        let mut prep = varpro::Prepared::new(&data);
        prep.limits = Some(limits.clone());
        varpro::evaluate_prepared(&basis, &prep, t, false).cost
    };
    let c0 = at(&theta);
    assert!((c0 - c_held).abs() <= 1e-6 * c_held, "{c0} vs {c_held}");
    for q in 0..theta.len() {
        for h in [-1e-3, 1e-3] {
            let mut t = theta.clone();
            t[q] += h;
            assert!(
                at(&t) >= c0 * (1.0 - 1e-9),
                "parameter {q} {h:+}: {} < {c0}",
                at(&t)
            );
        }
    }
}

#[test]
fn the_constrained_gradient_is_the_derivative_of_the_constrained_cost() {
    // 2 Jᵀr from the evaluation (Kaufman's J with the active albedo rows) against
    // central differences of the constrained projected cost, away from the optimum.
    let truth = Model::from_toml(BRIGHT, None).expect("model");
    let data = FitData::from_samples(
        &Samples::from_brdf(&truth, &grid()),
        &DataOptions::default(),
    )
    .expect("data");
    let basis = LobeBasis {
        shape: Shape {
            lobes: 1,
            anisotropic: false,
            diffuse: Diffuse::Minnaert,
        },
        channels: 1,
        shared: false,
    };
    let mut theta = vec![0.0; basis.n_params()];
    basis.set_lobe(&mut theta, 0, 0, -0.6, std::f64::consts::FRAC_PI_4, 8.0);
    if let Some(k) = basis.kappa_idx(0) {
        theta[k] = 0.3;
    }
    let mut prep = varpro::Prepared::new(&data);
    prep.limits = Some(vec![[0.0, 0.0, 1.0], [0.5f64.sin(), 0.0, 0.5f64.cos()]]);
    let e = varpro::evaluate_prepared(&basis, &prep, &theta, true);
    assert!(
        e.constraints[0].multiplier.iter().any(|m| *m > 0.0),
        "an active row: {:?}",
        e.constraints
    );
    let (_, jtr) = e.normal.expect("normal equations");
    for q in 0..theta.len() {
        let h = 1e-5;
        let mut t = theta.clone();
        t[q] += h;
        let up = varpro::evaluate_prepared(&basis, &prep, &t, false).cost;
        t[q] -= 2.0 * h;
        let down = varpro::evaluate_prepared(&basis, &prep, &t, false).cost;
        let fd = (up - down) / (2.0 * h);
        assert!(
            (2.0 * jtr[q] - fd).abs() <= 1e-4 * fd.abs().max(1e-3 * e.cost),
            "parameter {q}: 2Jᵀr {} vs {fd}",
            2.0 * jtr[q]
        );
    }
}

#[test]
fn with_no_row_active_the_constrained_evaluation_is_the_unconstrained_one() {
    // Limits where the albedo is far below 1 (a dim model), with and without a lobe
    // switched off: the same coefficients, cost and normal equations as without them.
    let truth = Model::from_toml(BRIGHT, None).expect("model");
    let mut s = Samples::from_brdf(&truth, &grid());
    for x in &mut s.samples {
        x.value[0] *= 0.2;
    }
    let data = FitData::from_samples(&s, &DataOptions::default()).expect("data");
    let basis = LobeBasis {
        shape: Shape {
            lobes: 2,
            anisotropic: false,
            diffuse: Diffuse::Lambert,
        },
        channels: 1,
        shared: false,
    };
    for second in [-0.7, 1.2] {
        let mut theta = vec![0.0; basis.n_params()];
        basis.set_lobe(&mut theta, 0, 0, -0.78, std::f64::consts::FRAC_PI_4, 10.0);
        basis.set_lobe(&mut theta, 0, 1, second, std::f64::consts::FRAC_PI_4, 30.0);
        let free = varpro::evaluate(&basis, &data, &theta, true);
        let mut prep = varpro::Prepared::new(&data);
        prep.limits = Some(vec![[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]]);
        let held = varpro::evaluate_prepared(&basis, &prep, &theta, true);
        assert!(held.constraints[0].albedo.iter().all(|a| *a < 0.5));
        assert!(held.constraints[0].multiplier.iter().all(|m| *m == 0.0));
        let (a, b) = (free.normal.expect("jac"), held.normal.expect("jac"));
        let scale = a.0.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for (x, y) in a.0.iter().chain(&a.1).zip(b.0.iter().chain(&b.1)) {
            assert!((x - y).abs() <= 1e-6 * scale, "{x} vs {y}");
        }
        assert!((free.cost - held.cost).abs() <= 1e-9 * free.cost);
        for (x, y) in free.coef[0].iter().zip(&held.coef[0]) {
            assert!((x - y).abs() <= 1e-8 * x.abs().max(1e-12), "{x} vs {y}");
        }
    }
}

#[test]
fn a_fit_already_within_albedo_one_is_left_unchanged() {
    // The blue paint's diffuse with a modest lobe: albedo ≤ 0.62 everywhere.
    let text = "kind = \"lafortune\"\nchannels = [\"value\"]\n[diffuse]\nrho = [0.4]\n\
                [[lobes]]\ncx = [-0.9]\ncy = [-0.9]\ncz = [0.9]\nn = [12.0]\n";
    let (free, _, _) = fit(text, false);
    let (held, _, _) = fit(text, true);
    assert_eq!(free.channels[0].params, held.channels[0].params);
    let e = held.energy.as_ref().expect("energy");
    assert!(!e.constrained && e.channels[0].active.is_empty());
    assert!(e.channels[0].max_albedo < 1.0);
    assert_eq!(e.channels[0].cost, e.channels[0].unconstrained_cost);
}

#[test]
fn the_model_file_records_the_objective_and_old_files_still_load() {
    let (held, _, _) = fit(BRIGHT, true);
    let text = &held.model_toml;
    assert!(text.contains("[fit]\nobjective = \"cosine\""), "{text}");
    let back = Model::from_toml(text, None).expect("reads back");
    let Model::Lafortune(l) = &back else {
        panic!("a lafortune model")
    };
    let note = l.fit_note().expect("the [fit] table");
    assert_eq!(note.objective, "cosine");
    assert!(note.minimised.contains("cos θi cos θo"));
    assert!(note.constraint.is_some());
    assert_eq!(back.to_toml(), *text);
    // Without the table (every model file written before it): loads, no note.
    let old = Model::from_toml(BRIGHT, None).expect("old file");
    let Model::Lafortune(l) = &old else {
        panic!("a lafortune model")
    };
    assert!(l.fit_note().is_none());
    // An unknown key in it is an error, as anywhere in a model file.
    let bad = format!("{BRIGHT}[fit]\nobjective = \"chi2\"\nminimised = \"x\"\nseed = 3\n");
    assert!(Model::from_toml(&bad, None).is_err());
}

#[test]
fn the_constrained_linear_solution_is_the_best_feasible_point() {
    // Random convex problems (seeded) with nearly parallel albedo rows, as adjacent
    // incidences give: the solution is feasible, and no feasible point on a grid of
    // convex combinations with random feasible points does better.
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    for case in 0..200 {
        let k = 2 + case % 4;
        let m = 30;
        let a: Vec<f64> = (0..m * k).map(|_| rng.random::<f64>()).collect();
        let y: Vec<f64> = (0..m).map(|_| 2.0 * rng.random::<f64>()).collect();
        let rows = 1 + case % 6;
        let base: Vec<f64> = (0..k).map(|_| 0.2 + rng.random::<f64>()).collect();
        let b: Vec<f64> = (0..rows * k)
            .map(|i| base[i % k] * (1.0 + 1e-3 * rng.random::<f64>()))
            .collect();
        let mut g = vec![0.0; k * k];
        let mut h = vec![0.0; k];
        for r in 0..m {
            for u in 0..k {
                h[u] += a[r * k + u] * y[r];
                for v in 0..k {
                    g[u * k + v] += a[r * k + u] * a[r * k + v];
                }
            }
        }
        let cost = |c: &[f64]| -> f64 {
            (0..m)
                .map(|r| ((0..k).map(|u| a[r * k + u] * c[u]).sum::<f64>() - y[r]).powi(2))
                .sum()
        };
        let feasible = |c: &[f64]| {
            c.iter().all(|x| *x >= 0.0)
                && (0..rows).all(|l| (0..k).map(|u| b[l * k + u] * c[u]).sum::<f64>() <= 1.0)
        };
        let s = varpro::qp(&g, &h, k, &b, rows);
        let tol = 1e-9;
        assert!(s.c.iter().all(|x| *x >= 0.0));
        for l in 0..rows {
            let v: f64 = (0..k).map(|u| b[l * k + u] * s.c[u]).sum();
            assert!(v <= 1.0 + tol, "case {case}: row {l} at {v}");
        }
        let best = cost(&s.c);
        for _ in 0..200 {
            // A random feasible point, and points between it and the solution.
            let mut p: Vec<f64> = (0..k).map(|_| rng.random::<f64>()).collect();
            let worst = (0..rows)
                .map(|l| (0..k).map(|u| b[l * k + u] * p[u]).sum::<f64>())
                .fold(0.0, f64::max);
            if worst > 1.0 {
                p.iter_mut().for_each(|x| *x /= worst);
            }
            for t in [1.0, 0.1, 0.01, 0.001] {
                let q: Vec<f64> = s.c.iter().zip(&p).map(|(c, p)| c + t * (p - c)).collect();
                if feasible(&q) {
                    assert!(
                        cost(&q) >= best * (1.0 - 1e-9) - 1e-12,
                        "case {case}: {} < {best} at {q:?} (solution {:?})",
                        cost(&q),
                        s.c
                    );
                }
            }
        }
    }
}
