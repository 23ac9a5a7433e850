#![allow(missing_docs)] // criterion_group! generates undocumented functions
//! Time of a 3-lobe + Lambert RGB lobe fit to ~100 000 noisy samples, of the
//! pieces it is made of, and of its data from samples and from columns.
//!
//! `cargo bench -p gonio-fit --bench fit`; figures and the machine are in BENCHMARKS.md
//! at the repository root. Before timing, the bench fits once and asserts that the fit
//! recovers the model within a few standard errors (so a correct fit is timed), and
//! writes the data to `target/tmp/fit-bench-data.csv` for the scipy comparison
//! (`benches/scipy_fit.py`; `benches/compare.sh` runs both).
//!
//! Data: θi = 0…80° by 5° (17), φi = 0; θo = 1…89° by 2° (45); φo = 0…357.1875° by
//! 2.8125° (128): 97 920 pairs. Values: the model below plus Gaussian noise of 1% of
//! the value (ChaCha8, seed 1), σ = 1% of the value given, so the fit is a χ² fit.

use std::fmt::Write as _;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Duration;

use criterion::{Criterion, SamplingMode, criterion_group, criterion_main};
use gonio_brdf::{Brdf, Model};
use gonio_core::dirfile::PairDeg;
use gonio_core::{Channels, SphericalDeg};
use gonio_fit::data::{Columns, DataOptions, FitData};
use gonio_fit::lobes::{LobeBasis, Shape};
use gonio_fit::varpro;
use gonio_fit::{FitOptions, LobeFit, fit_lobes};
use gonio_process::Samples;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// Table 1 of Lafortune et al. 1997 (three lobes + Lambert), with slightly different
/// values in each of R, G and B (the same model as `gonio-brdf`'s bench).
const MODEL: &str = include_str!("../../../config/models/lafortune-table1-rgb.toml");

/// Relative noise (and σ) of every value.
const NOISE: f64 = 0.01;

/// The 97 920 direction pairs (module docs).
fn pairs() -> Vec<PairDeg> {
    let mut v = Vec::new();
    for ti in (0..=80).step_by(5) {
        for to in (1..=89).step_by(2) {
            for k in 0..128 {
                v.push(PairDeg {
                    incident: SphericalDeg::new(f64::from(ti), 0.0),
                    outgoing: SphericalDeg::new(f64::from(to), 2.8125 * f64::from(k)),
                });
            }
        }
    }
    v
}

/// The model's values at the pairs plus 1% Gaussian noise, σ given.
fn samples(model: &Model) -> Samples {
    let mut s = Samples::from_brdf(model, &pairs());
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let normal = Normal::new(0.0, 1.0).expect("unit normal");
    for x in &mut s.samples {
        let sigma: Vec<f64> = x.value.iter().map(|v| NOISE * v).collect();
        for (v, sg) in x.value.iter_mut().zip(&sigma) {
            *v += sg * normal.sample(&mut rng);
        }
        x.sigma = Some(sigma);
    }
    s
}

/// Writes the samples for `scipy_fit.py`: the four angles (degrees, docs/CONVENTIONS.md),
/// one value column a channel, one σ column a channel.
fn write_csv(s: &Samples, path: &Path) {
    let names = s.channels.names();
    let mut text = String::from("theta_i,phi_i,theta_o,phi_o");
    for n in &names {
        write!(text, ",{n}").expect("string");
    }
    for n in &names {
        write!(text, ",sigma_{n}").expect("string");
    }
    text.push('\n');
    for x in &s.samples {
        let p = &x.pair;
        write!(
            text,
            "{:?},{:?},{:?},{:?}",
            p.incident.theta_deg, p.incident.phi_deg, p.outgoing.theta_deg, p.outgoing.phi_deg
        )
        .expect("string");
        for v in &x.value {
            write!(text, ",{v:?}").expect("string");
        }
        for v in x.sigma.as_ref().expect("σ set") {
            write!(text, ",{v:?}").expect("string");
        }
        text.push('\n');
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).expect("target/tmp can be created");
    }
    std::fs::write(path, text).expect("the bench data can be written");
}

fn csv_path() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("fit-bench-data.csv")
}

/// CPU time of this process so far (user + system, all threads), from /proc; NaN
/// where there is no /proc.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return f64::NAN;
    };
    // Fields after the command name (which is in parentheses): utime and stime are the
    // 12th and 13th, in clock ticks of 1/100 s (USER_HZ).
    let rest = stat.rsplit_once(')').map_or("", |x| x.1);
    let f: Vec<f64> = rest
        .split_whitespace()
        .skip(11)
        .take(2)
        .filter_map(|x| x.parse().ok())
        .collect();
    f.iter().sum::<f64>() / 100.0
}

/// χ² = Σ ((f_fit − y)/σ)² per channel, from the fitted model itself.
fn chi2(model: &Model, s: &Samples) -> Vec<f64> {
    let nc = s.channels.len();
    let mut out = vec![0.0; nc];
    let mut f = vec![0.0; nc];
    for x in &s.samples {
        let d = x.pair.to_dirs();
        model.eval(d.wi, d.wo, &mut f);
        let sigma = x.sigma.as_ref().expect("σ set");
        for ch in 0..nc {
            let r = (f[ch] - x.value[ch]) / sigma[ch];
            out[ch] += r * r;
        }
    }
    out
}

/// Asserts that every fitted parameter is within `k` standard errors of the truth.
fn assert_recovered(fit: &LobeFit, truth: &Model, k: f64) {
    let Model::Lafortune(l) = truth else {
        unreachable!("a lafortune model")
    };
    for (ch, c) in fit.channels.iter().enumerate() {
        let rho = l.diffuse().expect("a diffuse term").rho()[ch];
        let mut want: Vec<[f64; 4]> = l
            .lobes()
            .iter()
            .map(|lobe| {
                let m = lobe.matrices()[ch];
                [m.xx, m.yy, m.zz, lobe.n()[ch]]
            })
            .collect();
        want.sort_by(|a, b| a[3].total_cmp(&b[3]));
        let mut idx: Vec<usize> = (0..c.params.lobes.len()).collect();
        idx.sort_by(|&a, &b| c.params.lobes[a][3].total_cmp(&c.params.lobes[b][3]));
        let z = (c.params.rho_d - rho) / c.std_err.rho_d;
        assert!(
            z.abs() <= k,
            "{}: ρd {} vs {rho} ({z:.1} σ)",
            c.channel,
            c.params.rho_d
        );
        for (w, &j) in want.iter().zip(&idx) {
            let (got, se) = (c.params.lobes[j], c.std_err.lobes[j]);
            for q in 0..4 {
                let z = (got[q] - w[q]) / se[q];
                assert!(
                    z.abs() <= k,
                    "{}: lobe {got:?} ± {se:?} vs {w:?}: parameter {q} is {z:.1} σ off",
                    c.channel
                );
            }
        }
    }
}

/// The single-channel data of channel `ch` (what `fit_lobes` fits each channel on).
fn channel(d: &FitData, ch: usize) -> FitData {
    FitData {
        // A one-channel set cannot be named "R" alone; `fit_lobes` falls back likewise.
        channels: Channels::from_names(&[d.channels.name(ch).as_str()])
            .or_else(|_| Channels::from_names(&["value"]))
            .expect("a channel"),
        wi: d.wi.clone(),
        wo: d.wo.clone(),
        y: vec![d.y[ch].clone()],
        weight: vec![d.weight[ch].clone()],
        chi_square: d.chi_square,
        objective: d.objective,
        objective_rule: d.objective_rule.clone(),
        metric: d.metric,
        cut: d.cut,
    }
}

/// Every k-th pair, so that at most `max` remain (as the fit's start search thins).
fn thin(d: &FitData, max: usize) -> FitData {
    let step = d.len().div_ceil(max);
    let keep: Vec<usize> = (0..d.len()).step_by(step).collect();
    let pick = |v: &std::sync::Arc<[f64]>| keep.iter().map(|&i| v[i]).collect();
    FitData {
        channels: d.channels.clone(),
        wi: keep.iter().map(|&i| d.wi[i]).collect(),
        wo: keep.iter().map(|&i| d.wo[i]).collect(),
        y: d.y.iter().map(pick).collect(),
        weight: d.weight.iter().map(pick).collect(),
        chi_square: d.chi_square,
        objective: d.objective,
        objective_rule: d.objective_rule.clone(),
        metric: d.metric,
        cut: d.cut,
    }
}

/// The basis of one channel and its non-linear parameters θ at the fitted optimum.
fn optimum(fit: &LobeFit, ch: usize) -> (LobeBasis, Vec<f64>) {
    let basis = LobeBasis {
        shape: fit.shape,
        channels: 1,
        shared: false,
    };
    let mut theta = vec![0.0; varpro::Basis::n_params(&basis)];
    for (j, l) in fit.channels[ch].params.lobes.iter().enumerate() {
        let norm = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
        let beta = (l[2] / norm).clamp(-1.0, 1.0).acos();
        let beta = if l[0] < 0.0 { -beta } else { beta };
        basis.set_lobe(&mut theta, 0, j, beta, std::f64::consts::FRAC_PI_4, l[3]);
    }
    (basis, theta)
}

fn bench(c: &mut Criterion) {
    let truth = Model::from_toml(MODEL, None).expect("valid bench model");
    let s = samples(&truth);
    let path = csv_path();
    write_csv(&s, &path);
    let data = FitData::from_samples(&s, &DataOptions::default()).expect("fit data");
    assert!(data.chi_square && data.len() == 97_920);
    let opts = FitOptions::default();
    assert_eq!(
        opts.shape,
        Shape {
            lobes: 3,
            anisotropic: false,
            diffuse: gonio_fit::Diffuse::Lambert
        }
    );

    // One fit before timing: it must recover the model.
    let cpu0 = cpu_seconds();
    let fit = fit_lobes(&data, &opts).expect("fit");
    let cpu = cpu_seconds() - cpu0;
    let model = fit.model.as_ref().expect("fitted model");
    let x2 = chi2(model, &s);
    let x2_truth = chi2(&truth, &s);
    eprintln!(
        "{} pairs written to {}\nfit: {:.3} s wall, {cpu:.2} s CPU, {} residual evaluations \
         in the final refinement (3 channels)",
        data.len(),
        path.display(),
        fit.seconds,
        fit.evaluations
    );
    for (ch, c) in fit.channels.iter().enumerate() {
        eprintln!(
            "  {}: chi2 {:.3} (true model: {:.3}), reduced {:.4}; rho_d {:.6} ± {:.1e}; \
             lobes (Cx, Cy, Cz, n) {:?}",
            c.channel,
            x2[ch],
            x2_truth[ch],
            c.reduced_chi2,
            c.params.rho_d,
            c.std_err.rho_d,
            c.params.lobes
        );
        assert!(x2[ch] <= x2_truth[ch], "the fit is worse than the truth");
    }
    assert_recovered(&fit, &truth, 4.0);

    let mut g = c.benchmark_group("lobe_fit");
    g.sample_size(10)
        .sampling_mode(SamplingMode::Flat)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(10));
    g.bench_function("fit_lobes", |b| {
        b.iter(|| fit_lobes(black_box(&data), &opts).expect("fit"))
    });
    // The start search runs on at most `search_samples` evenly thinned pairs; the same
    // fit on that subset alone is (search + a cheap refinement + errors + albedo check).
    let sub = thin(&data, opts.search_samples);
    g.bench_function("fit_lobes_search_subset", |b| {
        b.iter(|| fit_lobes(black_box(&sub), &opts).expect("fit"))
    });
    // One residual and one Jacobian evaluation of the final refinement (one channel,
    // all pairs) at the optimum: what each Levenberg–Marquardt step costs.
    let red = channel(&data, 0);
    let (basis, theta) = optimum(&fit, 0);
    let r2 = varpro::evaluate(&basis, &red, &theta, false).cost;
    assert!(
        (r2 - x2[0]).abs() <= 1e-6 * x2[0],
        "θ at the optimum: {r2} vs {}",
        x2[0]
    );
    // The final refinement of one channel on all pairs, from where the start search
    // leaves it (approximated by the optimum of the fit on the search's subset).
    let sub_fit = fit_lobes(&sub, &opts).expect("subset fit");
    let (_, theta_sub) = optimum(&sub_fit, 0);
    let solved = varpro::solve(&basis, &red, &theta_sub, 200);
    eprintln!(
        "refinement of {} from the subset's optimum: {} residual evaluations, chi2 {:.3}",
        red.channels.name(0),
        solved.evaluations,
        solved.cost
    );
    g.bench_function("refine_one_channel", |b| {
        b.iter(|| varpro::solve(&basis, black_box(&red), &theta_sub, 200))
    });
    g.measurement_time(Duration::from_secs(3));
    g.sample_size(20);
    g.bench_function("evaluate_residuals", |b| {
        b.iter(|| varpro::evaluate(&basis, black_box(&red), &theta, false))
    });
    g.bench_function("evaluate_jacobian", |b| {
        b.iter(|| varpro::evaluate(&basis, black_box(&red), &theta, true))
    });
    g.finish();

    // The data a fit sees, from a reader's rows (a `Sample` a row) and from its
    // columns (what a column reader gives): the same FitData.
    let nc = s.channels.len();
    let col = |f: &dyn Fn(&gonio_process::Sample) -> f64| -> Vec<f64> {
        s.samples.iter().map(f).collect()
    };
    let angles = [
        col(&|x| x.pair.incident.theta_deg),
        col(&|x| x.pair.incident.phi_deg),
        col(&|x| x.pair.outgoing.theta_deg),
        col(&|x| x.pair.outgoing.phi_deg),
    ];
    let values: Vec<Vec<f64>> = (0..nc).map(|ch| col(&|x| x.value[ch])).collect();
    let sigma: Vec<Vec<f64>> = (0..nc)
        .map(|ch| col(&|x| x.sigma.as_ref().expect("σ set")[ch]))
        .collect();
    let values: Vec<&[f64]> = values.iter().map(Vec::as_slice).collect();
    let sigma: Vec<&[f64]> = sigma.iter().map(Vec::as_slice).collect();
    let columns = Columns {
        channels: &s.channels,
        theta_i: &angles[0],
        phi_i: &angles[1],
        theta_o: &angles[2],
        phi_o: &angles[3],
        values: &values,
        sigma: Some(&sigma),
    };
    let opts = DataOptions::default();
    assert_eq!(
        FitData::from_columns(&columns, &opts).expect("columns"),
        data
    );
    let mut g = c.benchmark_group("fit_data");
    g.sample_size(20).measurement_time(Duration::from_secs(3));
    g.bench_function("from_samples", |b| {
        b.iter(|| FitData::from_samples(black_box(&s), &opts).expect("data"))
    });
    g.bench_function("from_columns", |b| {
        b.iter(|| FitData::from_columns(black_box(&columns), &opts).expect("data"))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
