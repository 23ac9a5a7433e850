//! Lobe fits: the analytic Jacobian against central differences; recovery of the
//! Table 1 model of Lafortune et al. 1997 from the default start, exactly without
//! noise and within the reported standard errors with it; an anisotropic model;
//! bad data refused; fit data from columns; the same model file on one thread and two.

use gonio_brdf::{Brdf, Model};
use gonio_core::Channels;
use gonio_core::dirfile::PairDeg;
use gonio_core::{Dir, SphericalDeg};
use gonio_fit::data::{Columns, DataOptions, FitData, Objective};
use gonio_fit::lobes::{Diffuse, LobeBasis, Shape};
use gonio_fit::varpro::{self, Basis};
use gonio_fit::{FitOptions, fit_lobes};
use gonio_process::{Sample, Samples};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// Table 1 of the paper (550 nm): three lobes and a diffuse f_d = 0.13 /sr.
const TABLE1: &str = r#"
kind = "lafortune"
channels = ["550nm"]
[diffuse]
rho = [0.40840704496667307]
[[lobes]]
cx = [0.86]
cz = [0.77]
n = [18.6]
[[lobes]]
cx = [-0.41]
cz = [0.018]
n = [2.58]
[[lobes]]
cx = [-1.03]
cz = [0.70]
n = [63.8]
"#;

/// The hemisphere of Fig. 14: θi 0–80° in 10° steps, outgoing θo 0–85° in 5° steps
/// and φo in 15° steps (φi = 0; the model is isotropic).
fn hemisphere() -> Vec<PairDeg> {
    let mut v = Vec::new();
    for ti in (0..=80).step_by(10) {
        for to in (0..=85).step_by(5) {
            for po in (0..360).step_by(15) {
                if to == 0 && po > 0 {
                    continue;
                }
                v.push(PairDeg {
                    incident: SphericalDeg::new(f64::from(ti), 0.0),
                    outgoing: SphericalDeg::new(f64::from(to), f64::from(po)),
                });
            }
        }
    }
    v
}

fn samples(model: &Model, noise: Option<(f64, u64)>) -> Samples {
    let mut s = Samples::from_brdf(model, &hemisphere());
    if let Some((rel, seed)) = noise {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let n = Normal::new(0.0, 1.0).expect("normal");
        for x in &mut s.samples {
            let sigma: Vec<f64> = x.value.iter().map(|v| rel * v + 1e-4).collect();
            for (v, sg) in x.value.iter_mut().zip(&sigma) {
                *v += sg * n.sample(&mut rng);
            }
            x.sigma = Some(sigma);
        }
    }
    s
}

#[test]
fn the_analytic_jacobian_matches_central_differences() {
    for (anisotropic, diffuse) in [
        (false, Diffuse::Lambert),
        (true, Diffuse::Minnaert),
        (false, Diffuse::Minnaert),
    ] {
        let shape = Shape {
            lobes: 2,
            anisotropic,
            diffuse,
        };
        let basis = LobeBasis {
            shape,
            channels: 2,
            shared: anisotropic,
        };
        let p = basis.n_params();
        let theta: Vec<f64> = (0..p)
            .map(|i| 0.3 + 0.37 * (i as f64 * 1.7).sin())
            .collect();
        let (wi, wo) = ([0.3, -0.2, 0.9327], [-0.5, 0.1, 0.86]);
        let k = basis.n_cols();
        for ch in 0..2 {
            let mut cols = vec![0.0; k];
            let mut d = vec![0.0; k * p];
            basis.eval(&theta, ch, wi, wo, &mut cols, Some(&mut d));
            for q in 0..p {
                let h = 1e-6;
                let (mut a, mut b) = (theta.clone(), theta.clone());
                a[q] += h;
                b[q] -= h;
                let (mut ca, mut cb) = (vec![0.0; k], vec![0.0; k]);
                basis.eval(&a, ch, wi, wo, &mut ca, None);
                basis.eval(&b, ch, wi, wo, &mut cb, None);
                for u in 0..k {
                    let num = (ca[u] - cb[u]) / (2.0 * h);
                    let ana = d[u * p + q];
                    assert!(
                        (num - ana).abs() <= 1e-6 * (1.0 + ana.abs()),
                        "{shape:?} ch {ch} col {u} param {q}: {ana} vs {num}"
                    );
                }
            }
        }
    }
}

/// The lobe basis through the trait's default (per-sample) paths only.
struct PerSample(LobeBasis);

impl Basis for PerSample {
    fn n_params(&self) -> usize {
        self.0.n_params()
    }
    fn n_cols(&self) -> usize {
        self.0.n_cols()
    }
    fn eval(
        &self,
        theta: &[f64],
        ch: usize,
        wi: [f64; 3],
        wo: [f64; 3],
        cols: &mut [f64],
        d: Option<&mut [f64]>,
    ) {
        self.0.eval(theta, ch, wi, wo, cols, d)
    }
}

#[test]
fn the_vectorised_path_and_the_normal_equations_match_a_dense_jacobian() {
    // More pairs than one parallel chunk, so chunked sums are exercised too.
    let model = Model::from_toml(TABLE1, None).expect("Table 1");
    let s = samples(&model, Some((0.02, 7)));
    let d = FitData::from_samples(&s, &DataOptions::default()).expect("data");
    assert!(d.len() > 2048, "{}", d.len());
    for (anisotropic, diffuse, channels) in [
        (false, Diffuse::Lambert, 1),
        (true, Diffuse::Minnaert, 1),
        (false, Diffuse::Minnaert, 2),
    ] {
        let basis = LobeBasis {
            shape: Shape {
                lobes: 3,
                anisotropic,
                diffuse,
            },
            channels,
            shared: channels > 1,
        };
        let data = if channels == 1 {
            d.clone()
        } else {
            FitData {
                channels: Channels::from_names(&["500nm", "600nm"]).expect("two channels"),
                y: vec![d.y[0].clone(), d.y[0].iter().map(|v| 0.7 * v).collect()],
                weight: vec![d.weight[0].clone(), d.weight[0].clone()],
                ..d.clone()
            }
        };
        let p = basis.n_params();
        let theta: Vec<f64> = (0..p).map(|i| 0.4 + 0.5 * (i as f64 * 1.3).sin()).collect();
        let fast = varpro::evaluate(&basis, &data, &theta, true);
        let slow = varpro::evaluate(&PerSample(basis), &data, &theta, true);
        // The Kaufman Jacobian built densely: J = P⊥ W ∂A/∂θ c.
        let (k, m) = (basis.n_cols(), data.len());
        let mut jtj = vec![0.0; p * p];
        let mut jtr = vec![0.0; p];
        let mut cost = 0.0;
        for ch in 0..data.channels.len() {
            let c = &fast.coef[ch];
            let free: Vec<usize> = (0..k).filter(|&u| c[u] > 0.0).collect();
            let mut a = nalgebra::DMatrix::<f64>::zeros(m, free.len());
            let mut v = nalgebra::DMatrix::<f64>::zeros(m, p);
            let mut r = nalgebra::DVector::<f64>::zeros(m);
            let (mut cols, mut dd) = (vec![0.0; k], vec![0.0; k * p]);
            for i in 0..m {
                dd.fill(0.0);
                basis.eval(&theta, ch, data.wi[i], data.wo[i], &mut cols, Some(&mut dd));
                let w = data.weight[ch][i];
                r[i] = w * ((0..k).map(|u| c[u] * cols[u]).sum::<f64>() - data.y[ch][i]);
                for (x, &u) in free.iter().enumerate() {
                    a[(i, x)] = w * cols[u];
                }
                for q in 0..p {
                    v[(i, q)] = w * (0..k).map(|u| c[u] * dd[u * p + q]).sum::<f64>();
                }
            }
            let q = a.clone().qr().q();
            let j = &v - &q * (q.transpose() * &v);
            let (jj, jr) = (j.transpose() * &j, j.transpose() * &r);
            for x in 0..p {
                jtr[x] += jr[x];
                for z in 0..p {
                    jtj[x * p + z] += jj[(x, z)];
                }
            }
            cost += r.norm_squared();
        }
        let (fj, fr) = fast.normal.as_ref().expect("asked for");
        let (sj, sr) = slow.normal.as_ref().expect("asked for");
        let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-9 * scale;
        assert!(close(fast.cost, cost, cost) && close(slow.cost, cost, cost));
        assert_eq!(fast.coef.len(), slow.coef.len());
        for (a, b) in fast.coef.iter().flatten().zip(slow.coef.iter().flatten()) {
            assert!(close(*a, *b, a.abs().max(1e-300)), "{a} vs {b}");
        }
        for x in 0..p {
            let scale = jtr.iter().fold(0.0f64, |s, v| s.max(v.abs()));
            assert!(
                close(fr[x], jtr[x], scale) && close(sr[x], jtr[x], scale),
                "Jᵀr[{x}]"
            );
            for z in 0..p {
                let scale = (jtj[x * p + x] * jtj[z * p + z]).sqrt();
                let want = jtj[x * p + z];
                assert!(
                    close(fj[x * p + z], want, scale) && close(sj[x * p + z], want, scale),
                    "{anisotropic} {diffuse:?} JᵀJ[{x},{z}]: fast {} per-sample {} dense {want}",
                    fj[x * p + z],
                    sj[x * p + z]
                );
            }
        }
    }
}

#[test]
fn table_1_is_recovered_exactly_from_the_default_start_without_noise() {
    let truth = Model::from_toml(TABLE1, None).expect("model");
    let data =
        FitData::from_samples(&samples(&truth, None), &DataOptions::default()).expect("data");
    let fit = fit_lobes(&data, &FitOptions::default()).expect("fit");
    let c = &fit.channels[0];
    eprintln!("{:?}\nrms {} rel {}", c.params, c.rms, c.relative_rms);
    let want: [[f64; 4]; 3] = [
        [0.86, 0.86, 0.77, 18.6],
        [-0.41, -0.41, 0.018, 2.58],
        [-1.03, -1.03, 0.70, 63.8],
    ];
    let mut got = c.params.lobes.clone();
    got.sort_by(|a, b| a[3].total_cmp(&b[3]));
    let mut want = want.to_vec();
    want.sort_by(|a, b| a[3].total_cmp(&b[3]));
    for (g, w) in got.iter().zip(&want) {
        for (x, y) in g.iter().zip(w) {
            assert!(
                (x - y).abs() <= 1e-6 * y.abs().max(0.01),
                "{got:?} vs {want:?}"
            );
        }
    }
    assert!((c.params.rho_d - 0.13 * std::f64::consts::PI).abs() < 1e-6 * 0.41);
}

#[test]
fn table_1_with_noise_is_recovered_within_the_reported_errors() {
    let truth = Model::from_toml(TABLE1, None).expect("model");
    let data = FitData::from_samples(&samples(&truth, Some((0.01, 3))), &DataOptions::default())
        .expect("data");
    assert!(data.chi_square);
    let fit = fit_lobes(&data, &FitOptions::default()).expect("fit");
    let c = &fit.channels[0];
    eprintln!("{:?}\n{:?}\nchi2 {}", c.params, c.std_err, c.reduced_chi2);
    assert!(
        (c.reduced_chi2 - 1.0).abs() < 0.1,
        "reduced χ² {}",
        c.reduced_chi2
    );
    let mut idx: Vec<usize> = (0..3).collect();
    idx.sort_by(|&a, &b| c.params.lobes[a][3].total_cmp(&c.params.lobes[b][3]));
    let want = [
        [-0.41, -0.41, 0.018, 2.58],
        [0.86, 0.86, 0.77, 18.6],
        [-1.03, -1.03, 0.70, 63.8],
    ];
    for (k, &j) in idx.iter().enumerate() {
        for q in [0, 2, 3] {
            let (x, s, y) = (c.params.lobes[j][q], c.std_err.lobes[j][q], want[k][q]);
            assert!(
                (x - y).abs() <= 3.0 * s,
                "lobe {k} param {q}: {x} ± {s} vs {y}"
            );
        }
    }
    let rd = 0.13 * std::f64::consts::PI;
    assert!((c.params.rho_d - rd).abs() <= 3.0 * c.std_err.rho_d);
    // The errors (by the delta method from the covariance of the projected fit's
    // parameters) equal those of s²(JᵀJ)⁻¹ with J the weighted Jacobian in the model
    // file's own parameters (ρd, per lobe C, Cz, n), built here directly.
    let np = 1 + 3 * c.params.lobes.len();
    let mut jtj = nalgebra::DMatrix::<f64>::zeros(np, np);
    for i in 0..data.len() {
        let (u, v) = (data.wi[i], data.wo[i]);
        let uv = [u[0] * v[0], u[1] * v[1], u[2] * v[2]];
        let mut g = vec![1.0 / std::f64::consts::PI];
        for l in &c.params.lobes {
            let x = l[0] * uv[0] + l[1] * uv[1] + l[2] * uv[2];
            let (h, dh) = if x > 0.0 {
                (x.powf(l[3]), l[3] * x.powf(l[3] - 1.0))
            } else {
                (0.0, 0.0)
            };
            g.extend([
                dh * (uv[0] + uv[1]),
                dh * uv[2],
                if x > 0.0 { h * x.ln() } else { 0.0 },
            ]);
        }
        let w = data.weight[0][i];
        for a in 0..np {
            for b in 0..np {
                jtj[(a, b)] += w * g[a] * w * g[b];
            }
        }
    }
    let cov = jtj.try_inverse().expect("determined") * c.reduced_chi2;
    let mut k = 0;
    let mut check = |got: f64| {
        let want = cov[(k, k)].sqrt();
        assert!(
            (got - want).abs() <= 1e-6 * want,
            "parameter {k}: {got} vs {want}"
        );
        k += 1;
    };
    check(c.std_err.rho_d);
    for l in &c.std_err.lobes {
        check(l[0]);
        check(l[2]);
        check(l[3]);
    }
}

#[test]
fn an_anisotropic_model_is_recovered() {
    let text = r#"
kind = "lafortune"
channels = ["value"]
[diffuse]
rho = [0.2]
[[lobes]]
cx = [-1.1]
cy = [-0.7]
cz = [0.9]
n = [12.0]
"#;
    let truth = Model::from_toml(text, None).expect("model");
    let mut pairs = Vec::new();
    for ti in (10..=70).step_by(15) {
        for pi in (0..360).step_by(45) {
            for to in (5..=85).step_by(10) {
                for po in (0..360).step_by(20) {
                    pairs.push(PairDeg {
                        incident: SphericalDeg::new(f64::from(ti), f64::from(pi)),
                        outgoing: SphericalDeg::new(f64::from(to), f64::from(po)),
                    });
                }
            }
        }
    }
    let data = FitData::from_samples(&Samples::from_brdf(&truth, &pairs), &DataOptions::default())
        .expect("data");
    let opts = FitOptions {
        shape: Shape {
            lobes: 1,
            anisotropic: true,
            diffuse: Diffuse::Lambert,
        },
        ..FitOptions::default()
    };
    let fit = fit_lobes(&data, &opts).expect("fit");
    let l = fit.channels[0].params.lobes[0];
    for (x, y) in l.iter().zip([-1.1, -0.7, 0.9, 12.0]) {
        assert!((x - y).abs() < 1e-6 * y.abs(), "{l:?}");
    }
    let _ = truth.channels();
}

#[test]
fn bad_data_is_refused_with_a_reason() {
    let ch = Channels::Single;
    let one = |ti: f64, v: f64| Sample {
        pair: PairDeg {
            incident: SphericalDeg::new(ti, 0.0),
            outgoing: SphericalDeg::new(30.0, 180.0),
        },
        value: vec![v],
        sigma: None,
        flags: 0,
    };
    let opts = DataOptions::default();
    let s = |v: Vec<Sample>| Samples {
        channels: ch.clone(),
        samples: v,
        isotropic: false,
    };
    let e = FitData::from_samples(&s(vec![]), &opts).expect_err("empty");
    assert!(e.to_string().contains("no samples"));
    let e = FitData::from_samples(&s(vec![one(10.0, f64::NAN), one(20.0, 0.1)]), &opts)
        .expect_err("nan");
    assert!(e.to_string().contains("not a finite number"), "{e}");
    let e =
        FitData::from_samples(&s(vec![one(10.0, 0.1), one(10.0, 0.2)]), &opts).expect_err("one θi");
    assert!(e.to_string().contains("one incident direction"), "{e}");
    // Negative values (noise about a dark BRDF) are kept.
    let d = FitData::from_samples(&s(vec![one(10.0, -0.01), one(20.0, 0.1)]), &opts)
        .expect("negatives");
    assert_eq!(d.len(), 2);
    let cut = DataOptions {
        cutoff_deg: 5.0,
        ..DataOptions::default()
    };
    let e = FitData::from_samples(&s(vec![one(10.0, 0.1), one(20.0, 0.1)]), &cut).expect_err("cut");
    assert!(e.to_string().contains("cutoff"), "{e}");
    // More lobes than a fit places: refused before any search, as bad input.
    let d = FitData::from_samples(&s(vec![one(10.0, 0.1), one(20.0, 0.1)]), &opts).expect("data");
    let many = FitOptions {
        shape: Shape {
            lobes: 100_000,
            anisotropic: false,
            diffuse: Diffuse::Lambert,
        },
        ..FitOptions::default()
    };
    match fit_lobes(&d, &many) {
        Err(gonio_fit::FitError::Options(m)) => {
            assert_eq!(m, "100000 lobes: at most 8 are fitted");
        }
        other => panic!("{:?}", other.map(|f| f.model_toml)),
    }
    // The projection's coefficients are never negative.
    let basis = LobeBasis {
        shape: Shape {
            lobes: 1,
            anisotropic: false,
            diffuse: Diffuse::Lambert,
        },
        channels: 1,
        shared: false,
    };
    let e = varpro::evaluate(&basis, &d, &[0.5, 1.0], false);
    assert!(e.coef[0].iter().all(|c| *c >= 0.0));
}

#[test]
fn shared_exponents_minnaert_and_the_ngan_metric_recover_their_models() {
    // RGB lobes with one exponent per lobe across channels, a Minnaert diffuse term,
    // fitted with shared exponents under the Ngan metric.
    let text = r#"
kind = "lafortune"
channels = ["R", "G", "B"]
[diffuse]
rho = [0.30, 0.40, 0.70]
n = [0.4, 0.4, 0.4]
[[lobes]]
cx = [-0.95, -0.90, -0.80]
cz = [0.80, 0.75, 0.60]
n = [15.0, 15.0, 15.0]
[[lobes]]
cx = [0.60, 0.55, 0.50]
cz = [0.55, 0.50, 0.45]
n = [6.0, 6.0, 6.0]
"#;
    let truth = Model::from_toml(text, None).expect("model");
    let opts = DataOptions {
        metric: gonio_fit::Metric::Ngan,
        ..DataOptions::default()
    };
    let data =
        FitData::from_samples(&Samples::from_brdf(&truth, &hemisphere()), &opts).expect("data");
    let fit = fit_lobes(
        &data,
        &FitOptions {
            shape: Shape {
                lobes: 2,
                anisotropic: false,
                diffuse: Diffuse::Minnaert,
            },
            share_exponents: true,
            ..FitOptions::default()
        },
    )
    .expect("fit");
    assert!(fit.shared_exponents);
    let want = [
        [[-0.95, 0.80, 15.0], [0.60, 0.55, 6.0]],
        [[-0.90, 0.75, 15.0], [0.55, 0.50, 6.0]],
        [[-0.80, 0.60, 15.0], [0.50, 0.45, 6.0]],
    ];
    let rho = [0.30, 0.40, 0.70];
    for (ch, c) in fit.channels.iter().enumerate() {
        assert!((c.params.rho_d - rho[ch]).abs() < 1e-6, "{:?}", c.params);
        assert!((c.params.m - 0.4).abs() < 1e-6, "{:?}", c.params);
        let mut got = c.params.lobes.clone();
        got.sort_by(|a, b| b[3].total_cmp(&a[3]));
        for (g, w) in got.iter().zip(&want[ch]) {
            for (x, y) in [g[0], g[2], g[3]].iter().zip(w) {
                assert!((x - y).abs() < 1e-6 * y.abs(), "channel {ch}: {got:?}");
            }
        }
    }
}

#[test]
fn a_lambertian_fit_has_no_lobes_to_search() {
    let model = Model::from_toml(
        "kind = \"lafortune\"\nchannels = [\"550nm\"]\n[diffuse]\nrho = [0.5]\n",
        None,
    )
    .expect("Lambert");
    let data = FitData::from_samples(&samples(&model, Some((0.01, 9))), &DataOptions::default())
        .expect("data");
    let opts = FitOptions {
        shape: Shape {
            lobes: 0,
            anisotropic: false,
            diffuse: Diffuse::Lambert,
        },
        ..FitOptions::default()
    };
    let fit = fit_lobes(&data, &opts).expect("fit");
    let c = &fit.channels[0];
    assert!(c.params.lobes.is_empty());
    assert!(
        (c.params.rho_d - 0.5).abs() < 4.0 * c.std_err.rho_d && c.std_err.rho_d > 0.0,
        "{} ± {}",
        c.params.rho_d,
        c.std_err.rho_d
    );
}

/// Table 1 with slightly different values in R, G and B (the bench's model).
const RGB: &str = include_str!("../../../../config/models/lafortune-table1-rgb.toml");

/// The samples' columns: θi, φi, θo, φo, values by channel, σ by channel.
type Cols = ([Vec<f64>; 4], Vec<Vec<f64>>, Vec<Vec<f64>>);

fn columns_of(s: &Samples) -> Cols {
    let col = |f: &dyn Fn(&Sample) -> f64| s.samples.iter().map(f).collect::<Vec<f64>>();
    let nc = s.channels.len();
    (
        [
            col(&|x| x.pair.incident.theta_deg),
            col(&|x| x.pair.incident.phi_deg),
            col(&|x| x.pair.outgoing.theta_deg),
            col(&|x| x.pair.outgoing.phi_deg),
        ],
        (0..nc).map(|ch| col(&|x| x.value[ch])).collect(),
        (0..nc)
            .map(|ch| col(&|x| x.sigma.as_ref().map_or(0.0, |v| v[ch])))
            .collect(),
    )
}

fn from_cols(
    channels: &Channels,
    c: &Cols,
    sigma: bool,
    opts: &DataOptions,
) -> Result<FitData, gonio_fit::FitError> {
    let values: Vec<&[f64]> = c.1.iter().map(Vec::as_slice).collect();
    let sg: Vec<&[f64]> = c.2.iter().map(Vec::as_slice).collect();
    FitData::from_columns(
        &Columns {
            channels,
            theta_i: &c.0[0],
            phi_i: &c.0[1],
            theta_o: &c.0[2],
            phi_o: &c.0[3],
            values: &values,
            sigma: sigma.then_some(sg.as_slice()),
        },
        opts,
    )
}

/// Columns fit as the rows they hold: each kept row's directions are its angles'
/// unit vectors, its values and weights (1/σ under χ², the metric's cosines without
/// σ) are its own, and the rows above the cutoff are counted and left out.
#[test]
fn columns_give_each_kept_rows_directions_values_and_weights() {
    let truth = Model::from_toml(RGB, None).expect("model");
    let s = samples(&truth, Some((0.01, 11)));
    let c = columns_of(&s);
    let cut = DataOptions {
        cutoff_deg: 62.0,
        ..DataOptions::default()
    };
    for (sigma, opts) in [(true, DataOptions::default()), (true, cut), (false, cut)] {
        let d = from_cols(&s.channels, &c, sigma, &opts).expect("data");
        let rows: Vec<usize> = (0..s.samples.len())
            .filter(|&i| c.0[0][i] <= opts.cutoff_deg && c.0[2][i] <= opts.cutoff_deg)
            .collect();
        assert_eq!(d.len(), rows.len());
        assert_eq!(d.cut, s.samples.len() - rows.len());
        assert_eq!(d.chi_square, sigma);
        if opts.cutoff_deg < 90.0 {
            assert!(d.cut > 1000, "{}", d.cut);
        }
        for (k, &i) in rows.iter().enumerate() {
            let wi = Dir::from(SphericalDeg::new(c.0[0][i], c.0[1][i]));
            let wo = Dir::from(SphericalDeg::new(c.0[2][i], c.0[3][i]));
            assert_eq!(d.wi[k], [wi.x, wi.y, wi.z]);
            assert_eq!(d.wo[k], [wo.x, wo.y, wo.z]);
            for ch in 0..3 {
                assert_eq!(d.y[ch][k], c.1[ch][i]);
                let w = if sigma { 1.0 / c.2[ch][i] } else { wi.z * wo.z };
                assert_eq!(d.weight[ch][k], w, "row {i} channel {ch}");
            }
        }
        // The samples' path gives the same data (without σ: samples without σ).
        let mut bare = s.clone();
        for x in &mut bare.samples {
            x.sigma = None;
        }
        let from_samples = FitData::from_samples(if sigma { &s } else { &bare }, &opts);
        assert_eq!(from_samples.expect("samples"), d);
    }
}

/// Faulty columns are refused naming the first faulty row, a row's angles before its
/// values before its σ; columns of different lengths are refused.
#[test]
fn faulty_columns_name_the_first_faulty_row() {
    let truth = Model::from_toml(RGB, None).expect("model");
    let s = samples(&truth, Some((0.01, 12)));
    let opts = DataOptions::default();
    let fault = |at: &[(usize, usize, usize, f64)]| {
        let mut c = columns_of(&s);
        for &(which, ch, row, x) in at {
            if which == 1 {
                c.1[ch][row] = x;
            } else {
                c.2[ch][row] = x;
            }
        }
        from_cols(&s.channels, &c, true, &opts)
            .expect_err("refused")
            .to_string()
    };
    let e = fault(&[(1, 2, 700, f64::NAN), (1, 0, 900, f64::INFINITY)]);
    assert!(
        e.starts_with("sample 700 (") && e.contains("not a finite number"),
        "{e}"
    );
    let e = fault(&[(2, 1, 300, -1.0), (1, 0, 500, f64::NAN)]);
    assert_eq!(
        e,
        "sample 300 has an uncertainty that is not a finite non-negative number"
    );
    let e = fault(&[(2, 1, 300, f64::NAN), (1, 2, 300, f64::NAN)]);
    assert!(
        e.starts_with("sample 300 (") && e.contains("not a finite number"),
        "{e}"
    );
    // An angle that is not a number.
    let mut c = columns_of(&s);
    c.0[1][77] = f64::NAN;
    let e = from_cols(&s.channels, &c, true, &opts).expect_err("NaN φi");
    assert!(
        e.to_string().starts_with("sample 77 (") && e.to_string().contains("angle"),
        "{e}"
    );
    // σ = 0 is refused by χ² asked for, and makes the default rule choose the cosines.
    let mut c = columns_of(&s);
    c.2[1][42] = 0.0;
    let chi2 = DataOptions {
        objective: Some(Objective::Chi2),
        ..opts
    };
    let e = from_cols(&s.channels, &c, true, &chi2).expect_err("σ = 0");
    assert!(
        e.to_string().contains("sample 42 has none or a zero"),
        "{e}"
    );
    let d = from_cols(&s.channels, &c, true, &opts).expect("cosines");
    assert_eq!(d.objective, Objective::Cosine);
    // A short column.
    let mut c = columns_of(&s);
    c.0[3].pop();
    let e = from_cols(&s.channels, &c, true, &opts).expect_err("short");
    assert!(e.to_string().contains("different lengths"), "{e}");
}

/// The same data fitted on one thread and on two give the same model file, byte
/// for byte (every parallel sum is formed in a fixed order).
#[test]
fn the_model_file_is_the_same_on_one_and_two_threads() {
    let truth = Model::from_toml(RGB, None).expect("model");
    let data = FitData::from_samples(&samples(&truth, Some((0.01, 13))), &DataOptions::default())
        .expect("data");
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
            .install(|| fit_lobes(&data, &FitOptions::default()).expect("fit"))
    };
    let (one, two) = (on(1), on(2));
    assert_eq!(one.model_toml, two.model_toml);
    assert_eq!(one.evaluations, two.evaluations);
    // And the fit is the model's: every channel's ρd within 5 standard errors.
    let Model::Lafortune(l) = &truth else {
        unreachable!("a lafortune model")
    };
    for (ch, c) in one.channels.iter().enumerate() {
        let rho = l.diffuse().expect("diffuse").rho()[ch];
        assert!(
            (c.params.rho_d - rho).abs() < 5.0 * c.std_err.rho_d,
            "{}: {} vs {rho}",
            c.channel,
            c.params.rho_d
        );
    }
}
