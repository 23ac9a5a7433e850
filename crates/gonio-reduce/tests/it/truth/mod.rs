//! A simulated run of a known sample, reduced and compared with the sample's own
//! BRDF: what the closure test and the `truth` example share.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

use gonio_acquire::engine::{Engine, EngineConfig, Outcome};
use gonio_brdf::{Brdf, Model};
use gonio_driver::InstrumentConfig;
use gonio_plan::Plan;
use gonio_reduce::Reduction;
use gonio_run::{Inputs, RunStore};
use gonio_sim::{SimBench, SimConfig};

/// The repository's root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A single-channel isotropic Cook–Torrance sample (GGX, α = 0.3): the glossy
/// sample of the findings' measurement.
pub const COOK_TORRANCE: &str = r#"
kind = "cook-torrance"
channels = ["550nm"]
distribution = "ggx"
f0 = [0.9]
alpha = [0.3]
"#;

/// Measures `plan_text` (relative paths resolved against `config/`) on the
/// simulator with the sample `sample` (model text; the embedded blue paint when
/// `None`), after `tweak` has changed the simulator's config. Returns the run and
/// the sample's model.
pub fn measure(
    name: &str,
    plan_text: &str,
    sample: Option<&str>,
    seed: u64,
    tweak: impl FnOnce(&mut SimConfig),
) -> (RunStore, Model) {
    measure_in(name, plan_text, sample, seed, tweak, false)
}

/// [`measure`] with the lock-in allowed to read through its data buffer
/// (`buffer = true` in `config/instrument-sim.toml`'s `[detector.lockin]`).
#[allow(dead_code)]
pub fn measure_buffered(
    name: &str,
    plan_text: &str,
    sample: Option<&str>,
    seed: u64,
    tweak: impl FnOnce(&mut SimConfig),
) -> (RunStore, Model) {
    measure_in(name, plan_text, sample, seed, tweak, true)
}

fn measure_in(
    name: &str,
    plan_text: &str,
    sample: Option<&str>,
    seed: u64,
    tweak: impl FnOnce(&mut SimConfig),
    buffer: bool,
) -> (RunStore, Model) {
    let path = root().join("config/instrument-sim.toml");
    let mut text = std::fs::read_to_string(&path).expect("inst");
    if buffer {
        text = text.replace("[detector.lockin]\n", "[detector.lockin]\nbuffer = true\n");
    }
    let inst = InstrumentConfig::from_toml(&text, Some(&path)).expect("inst");
    let mut sim = SimConfig::default_config().expect("sim");
    if let Some(text) = sample {
        let m = Model::from_toml(text, None).expect("sample model");
        sim.set_sample(std::sync::Arc::new(m), text.to_string());
    }
    tweak(&mut sim);
    let run = Run {
        name,
        instrument: (&inst, text),
        sim: &sim,
        sim_text: gonio_sim::config::DEFAULT_SIM.into(),
        plan_text,
        seed,
    };
    let (_, store, model) = run.acquire();
    (store, model)
}

/// One simulated acquisition: an instrument config with its text, a simulator
/// config with the text a run file keeps, a plan and a seed.
pub struct Run<'a> {
    /// Names the run's temporary directory.
    pub name: &'a str,
    /// The instrument config and its text.
    pub instrument: (&'a InstrumentConfig, String),
    /// The simulator (its seed is set from `seed`).
    pub sim: &'a SimConfig,
    /// The simulator config's text, kept in the run file.
    pub sim_text: String,
    /// The plan's text (relative paths resolved against `config/`).
    pub plan_text: &'a str,
    /// The seed of every random draw.
    pub seed: u64,
}

impl Run<'_> {
    /// Measures the plan into a fresh `run.gonio` in a kept temporary directory;
    /// returns its path, the open store and the sample's model.
    pub fn acquire(self) -> (PathBuf, RunStore, Model) {
        // Kept: the returned run file stays open in it.
        let dir = tempfile::Builder::new()
            .prefix(&format!("gonio-truth-{}-", self.name))
            .tempdir()
            .expect("temp dir")
            .keep();
        let (inst, inst_text) = self.instrument;
        let mut sim = self.sim.clone();
        sim.seed = self.seed;
        let plan_path = root().join("config/plan.toml");
        let plan = Plan::from_toml(self.plan_text, Some(&plan_path)).expect("plan");
        let mech = inst.mechanics().expect("mechanics");
        let prepared = gonio_plan::prepare(&mech, inst.reading_seconds(), &plan).expect("prepares");
        let sample_text = sim.sample_model_text().expect("sample");
        let inputs = Inputs {
            instrument_text: inst_text,
            plan_text: self.plan_text.into(),
            plan_path: Some(plan_path),
            sim: Some((self.sim_text, sample_text.clone())),
            seed: Some(self.seed),
            software: "test".into(),
            ..Inputs::default()
        };
        let meta = gonio_run::create::meta_for(&plan, &prepared, &inputs).expect("meta");
        let path = dir.join("run.gonio");
        let store = gonio_run::create(&path, &plan, &prepared, &inputs).expect("creates");
        let standard = meta.standard_model.as_ref().map(|t| {
            let m = Model::from_toml(t, None).expect("standard");
            (Box::new(m) as Box<dyn Brdf>, 0)
        });
        let (g, shared) = gonio_sim::connect(inst, &sim).expect("sim");
        let cfg = EngineConfig {
            incident_transmittance: meta.transmittance,
            reading: plan
                .reading
                .as_ref()
                .map(gonio_acquire::engine::read_target),
            ..EngineConfig::default()
        };
        let engine = Engine::new(g, SimBench::new(shared, standard), store, mech, cfg);
        let (report, store) = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("runtime")
            .block_on(engine.run())
            .expect("runs");
        assert_eq!(report.outcome, Outcome::Complete);
        (
            path,
            store,
            Model::from_toml(&sample_text, None).expect("model"),
        )
    }
}

/// Per sample: the normalised residual (f − f_true)/σ and the relative error
/// (f − f_true)/f_true, f_true the model at the sample's nominal directions.
pub fn residuals(red: &Reduction, model: &Model) -> Vec<(f64, f64)> {
    let mut out = vec![0.0; model.channels().len()];
    red.samples
        .samples
        .iter()
        .map(|s| {
            let d = s.pair.to_dirs();
            model.eval(d.wi, d.wo, &mut out);
            let sigma = s.sigma.as_ref().expect("sigma")[0];
            (
                (s.value[0] - out[0]) / sigma,
                (s.value[0] - out[0]) / out[0],
            )
        })
        .collect()
}

/// χ²/n of the residuals.
pub fn chi2(r: &[(f64, f64)]) -> f64 {
    r.iter().map(|(z, _)| z * z).sum::<f64>() / r.len() as f64
}

/// The mean of the relative errors.
pub fn mean_rel(r: &[(f64, f64)]) -> f64 {
    r.iter().map(|(_, e)| e).sum::<f64>() / r.len() as f64
}

/// χ²/n with the budget's correlations: rᵀ C⁻¹ r / n, with C the diagonal of the
/// independent terms (noise, resolution, drift — the drift's correlation, small,
/// is left out) plus one rank-one term for each term shared by every sample
/// (dark, calibration, standard), whose error has the same sign in every sample
/// here (every signal is weaker than the calibration's). By Woodbury,
/// χ² = rᵀD⁻¹r − bᵀ(I + VᵀD⁻¹V)⁻¹b with b = VᵀD⁻¹r.
pub fn chi2_correlated(red: &Reduction, model: &Model) -> f64 {
    const SHARED: [usize; 3] = [2, 3, 5];
    let mut out = vec![0.0; model.channels().len()];
    let (mut q, mut b, mut g) = (0.0, [0.0; 3], [[0.0; 3]; 3]);
    for (s, terms) in red.samples.samples.iter().zip(&red.budget) {
        let d = s.pair.to_dirs();
        model.eval(d.wi, d.wo, &mut out);
        let r = s.value[0] - out[0];
        let t = &terms[0];
        let dvar = t[0] * t[0] + t[1] * t[1] + t[4] * t[4];
        q += r * r / dvar;
        for (a, &ka) in SHARED.iter().enumerate() {
            b[a] += t[ka] * r / dvar;
            for (c, &kc) in SHARED.iter().enumerate() {
                g[a][c] += t[ka] * t[kc] / dvar;
            }
        }
    }
    for (a, row) in g.iter_mut().enumerate() {
        row[a] += 1.0;
    }
    let x = solve3(g, b);
    let chi2 = q - b.iter().zip(x).map(|(b, x)| b * x).sum::<f64>();
    chi2 / red.samples.samples.len() as f64
}

/// Solves the 3 × 3 system g x = b (g symmetric positive definite) by Gaussian
/// elimination.
pub fn solve3(mut g: [[f64; 3]; 3], mut b: [f64; 3]) -> [f64; 3] {
    for i in 0..3 {
        let (top, rest) = g.split_at_mut(i + 1);
        let pivot = top[i];
        for (j, row) in rest.iter_mut().enumerate() {
            let f = row[i] / pivot[i];
            for (x, p) in row.iter_mut().zip(pivot).skip(i) {
                *x -= f * p;
            }
            b[i + 1 + j] -= f * b[i];
        }
    }
    let mut x = [0.0; 3];
    for i in (0..3).rev() {
        let s: f64 = ((i + 1)..3).map(|k| g[i][k] * x[k]).sum();
        x[i] = (b[i] - s) / g[i][i];
    }
    x
}

/// Every sample's covariance parts add up to its σ on every channel: the
/// independent σ and the coefficients on the shared errors in quadrature.
pub fn assert_covariance_adds_up(red: &Reduction) {
    let c = &red.covariance;
    assert_eq!(c.independent.len(), red.samples.samples.len());
    assert_eq!(c.coefficients.len(), red.samples.samples.len());
    for (i, s) in red.samples.samples.iter().enumerate() {
        for (ch, sigma) in s.sigma.as_ref().expect("σ").iter().enumerate() {
            let parts = c.sigma(i, ch);
            assert!(
                (parts - sigma).abs() <= 1e-9 * sigma,
                "sample {i} channel {ch}: parts {parts} vs σ {sigma}"
            );
        }
    }
}
