//! `gonio plan compare`: an adaptive plan against uniform plans of the same number
//! of points, on the simulated instrument, judged against the simulated sample's
//! truth.
//!
//! Three runs are measured in turn: the adaptive plan as written; `lattice`, the
//! same plan with its whole budget in the coarse pass (an equal-area Fibonacci
//! lattice and the mirror direction per incidence, the most uniform plan of that
//! size); and `grid`, a `grid` plan over the same incidences with equal polar and
//! azimuthal steps, as plans are usually written. The uniform plans are sized to the
//! sample points the adaptive run measured (to within a point or two; the counts are
//! printed). Each run is reduced as `gonio reduce` reduces it and reconstructed by
//! the nearest-j kernel, and its error is the cosine-weighted relative RMS against
//! the truth at the plan's incidences on a `--grid DTHETA,DPHI` outgoing hemisphere
//! (`gonio_process::adapt::weighted_rms_error`).

use std::io::Write;
use std::path::{Path, PathBuf};

use gonio_plan::adaptive::Adaptive;
use gonio_plan::plan::Points;
use gonio_plan::{Plan, StepKind};
use gonio_run::RunStore;
use serde_json::json;

use crate::cmd::acquire::{AcquireArgs, StopBy, acquire_with, session_result};
use crate::cmd::instrument::{SimFlag, is_simulated};
use crate::cmd::prepare::{Loaded, hms, load_and_prepare};
use crate::error::{CliError, CliResult};
use crate::flags::JsonFlag;
use crate::output;

/// `gonio plan compare`.
#[derive(clap::Args)]
pub struct CompareArgs {
    /// The adaptive plan (TOML).
    plan: PathBuf,
    /// The instrument config (TOML); its ports must be simulated ("sim").
    #[arg(long)]
    instrument: PathBuf,
    #[command(flatten)]
    sim: SimFlag,
    /// Simulator seed.
    #[arg(long)]
    seed: Option<u64>,
    /// The sample to simulate: a model file, in place of the simulator config's.
    #[arg(long, value_name = "MODEL")]
    sample: Option<PathBuf>,
    /// The budget in points, in place of the plan's.
    #[arg(long, value_name = "POINTS")]
    budget: Option<usize>,
    /// The outgoing grid the error is taken on, DTHETA,DPHI degrees (DTHETA divides
    /// 90, DPHI 360).
    #[arg(long, value_parser = parse_outgoing_grid, default_value = "2,2")]
    grid: (f64, f64),
    /// Keep the three run files in this directory (which must not hold them yet)
    /// instead of a temporary one.
    #[arg(long)]
    keep: Option<PathBuf>,
    #[command(flatten)]
    json: JsonFlag,
}

fn input(e: impl std::fmt::Display) -> CliError {
    CliError::Input(e.to_string())
}

/// One compared run.
struct Compared {
    name: &'static str,
    file: PathBuf,
    points: usize,
    steps: usize,
    physical_s: f64,
    error: f64,
}

/// `gonio plan compare PLAN --instrument INSTR [--sim SIM] [--seed N] [--grid D,D]`.
pub fn compare(a: CompareArgs) -> CliResult<()> {
    let runs = compute(&a, &StopBy::Signals)?;
    report(&a, &runs)
}

/// `gonio plan compare`'s `--json` object, the runs measured until done or stopped
/// by `stop`.
pub(crate) fn compare_json(a: &CompareArgs, stop: &StopBy) -> CliResult<serde_json::Value> {
    let runs = compute(a, stop)?;
    Ok(json_of(a, &runs))
}

/// Measures the three plans and judges each run against the truth.
fn compute(a: &CompareArgs, stop: &StopBy) -> CliResult<Vec<Compared>> {
    let mut loaded = load_and_prepare(&a.instrument, &a.plan)?;
    refuse(a, &loaded)?;
    let (dir, _tmp) = out_dir(a)?;
    let mut table = plan_table(&loaded.plan_text, &a.plan)?;
    // The plan and simulator as measured: the plan's budget and the simulator's
    // sample replaced where asked, written beside the runs.
    let plan_path = match a.budget {
        None => a.plan.clone(),
        Some(b) => {
            let p = budget_plan(&mut table, b, &dir)?;
            loaded = load_and_prepare(&a.instrument, &p)?;
            p
        }
    };
    let Points::Adaptive(spec) = &loaded.plan.points else {
        return Err(input("the plan is no longer adaptive"));
    };
    let sim = match &a.sample {
        None => a.sim.sim.clone(),
        Some(model) => Some(sim_with_sample(a, model, &dir)?),
    };
    let mech = loaded
        .instrument
        .mechanics()
        .map_err(|e| input(format!("{}: {e}", a.instrument.display())))?;
    let incidences = spec.incidences().map_err(input)?;

    let mut runs = Vec::new();
    let adaptive = measure(a, &sim, &dir, "adaptive", &plan_path, stop)?;
    let target = adaptive.1;
    runs.push(adaptive);
    // The uniform plans, sized to the adaptive run's points.
    let csv = lattice_list(&mech, spec, target)?;
    write_new(&dir.join("lattice.csv"), &csv)?;
    let mut t = table.clone();
    t.insert(
        "points".into(),
        toml::Value::Table(toml::Table::from_iter([
            ("kind".to_string(), toml::Value::String("list".into())),
            (
                "file".to_string(),
                toml::Value::String("lattice.csv".into()),
            ),
        ])),
    );
    let lattice_plan = dir.join("lattice-plan.toml");
    write_new(&lattice_plan, &toml::to_string(&t).map_err(input)?)?;
    runs.push(measure(a, &sim, &dir, "lattice", &lattice_plan, stop)?);
    let grid_text = grid_plan(&mech, &table, spec, target)?;
    let grid_plan = dir.join("grid-plan.toml");
    write_new(&grid_plan, &grid_text)?;
    runs.push(measure(a, &sim, &dir, "grid", &grid_plan, stop)?);
    runs.into_iter().map(|r| judge(a, &incidences, r)).collect()
}

/// Refuses, before anything is measured, what cannot be compared: a plan that is
/// not adaptive, an instrument that is not the simulator, a sample model that does
/// not load, a budget of no points.
fn refuse(a: &CompareArgs, loaded: &Loaded) -> CliResult<()> {
    if !matches!(loaded.plan.points, Points::Adaptive(_)) {
        return Err(input(format!(
            "{}: field `points.kind`: `plan compare` compares an adaptive plan with \
             uniform ones; this plan is not adaptive",
            a.plan.display()
        )));
    }
    if !is_simulated(&loaded.instrument, &a.instrument)? {
        return Err(input(format!(
            "{}: `plan compare` measures on the simulator, whose sample is the truth the \
             plans are judged by; this instrument's ports are real",
            a.instrument.display()
        )));
    }
    if let Some(m) = &a.sample {
        gonio_brdf::Model::load(m).map_err(input)?;
    }
    if a.budget == Some(0) {
        return Err(input("--budget: at least one point"));
    }
    Ok(())
}

/// The directory the comparison writes to: `--keep`'s, which must hold none of
/// the comparison's files (refused before anything is measured), or a temporary
/// one, removed when the second value drops.
fn out_dir(a: &CompareArgs) -> CliResult<(PathBuf, Option<TempDir>)> {
    let Some(d) = &a.keep else {
        let t = TempDir::new()?;
        return Ok((t.0.clone(), Some(t)));
    };
    if !d.is_dir() {
        return Err(input(format!("{}: not a directory", d.display())));
    }
    // Everything the comparison writes, refused before anything is measured.
    for n in [
        "adaptive.gonio",
        "lattice.gonio",
        "grid.gonio",
        "lattice.csv",
        "lattice-plan.toml",
        "grid-plan.toml",
        "adaptive-plan.toml",
        "sim.toml",
    ] {
        let f = d.join(n);
        if f.exists() {
            return Err(input(format!(
                "{}: exists already; --keep needs a directory without the \
                 comparison's files",
                f.display()
            )));
        }
    }
    Ok((d.clone(), None))
}

/// The plan with `--budget`'s points in place of its own (in `table` too, which
/// the uniform plans are made from), written to `DIR/adaptive-plan.toml`.
fn budget_plan(table: &mut toml::Table, budget: usize, dir: &Path) -> CliResult<PathBuf> {
    if let Some(toml::Value::Table(p)) = table.get_mut("points") {
        p.insert(
            "budget".into(),
            toml::Value::Table(toml::Table::from_iter([(
                "points".to_string(),
                toml::Value::Integer(i64::try_from(budget).map_err(input)?),
            )])),
        );
    }
    let p = dir.join("adaptive-plan.toml");
    write_new(&p, &toml::to_string(table).map_err(input)?)?;
    Ok(p)
}

/// The simulator's config with `--sample`'s model as its sample, written to
/// `DIR/sim.toml`.
fn sim_with_sample(a: &CompareArgs, model: &Path, dir: &Path) -> CliResult<PathBuf> {
    let text = match &a.sim.sim {
        Some(p) => {
            gonio_core::input::read_text(p, gonio_core::input::MAX_CONFIG_BYTES).map_err(input)?
        }
        None => gonio_sim::config::DEFAULT_SIM.to_string(),
    };
    let mut t: toml::Table = text.parse().map_err(input)?;
    let abs = std::path::absolute(model).map_err(input)?;
    t.insert(
        "sample".into(),
        toml::Value::Table(toml::Table::from_iter([(
            "model".to_string(),
            toml::Value::String(abs.display().to_string()),
        )])),
    );
    let p = dir.join("sim.toml");
    write_new(&p, &toml::to_string(&t).map_err(input)?)?;
    Ok(p)
}

/// One run judged: reduced, and its weighted RMS error against the simulator's
/// truth at the plan's `incidences` on the `--grid` of outgoing directions.
fn judge(
    a: &CompareArgs,
    incidences: &[gonio_core::SphericalDeg],
    (name, points, file): (&'static str, usize, PathBuf),
) -> CliResult<Compared> {
    let n_theta = (90.0 / a.grid.0).round() as usize;
    let n_phi = (360.0 / a.grid.1).round() as usize;
    let store = RunStore::open_read_only(&file)?;
    let red = gonio_reduce::reduce(&store, &gonio_reduce::Options::default())
        .map_err(|e| CliError::Runtime(format!("{}: {e}", file.display())))?;
    let truth = truth_of(&store)?;
    let error = gonio_process::adapt::weighted_rms_error(
        &red.samples,
        truth.as_ref(),
        incidences,
        n_theta,
        n_phi,
    )
    .map_err(|e| CliError::Runtime(format!("{}: {e}", file.display())))?;
    let steps = store.steps()?;
    let physical_s = physical_seconds(&store)?;
    Ok(Compared {
        name,
        file: a.keep.as_ref().map_or_else(|| PathBuf::from("-"), |_| file),
        points,
        steps: steps.len(),
        physical_s,
        error,
    })
}

/// Measures one plan into `DIR/NAME.gonio`: the run's name, sample points and file.
fn measure(
    a: &CompareArgs,
    sim: &Option<PathBuf>,
    dir: &Path,
    name: &'static str,
    plan: &Path,
    stop: &StopBy,
) -> CliResult<(&'static str, usize, PathBuf)> {
    let out = dir.join(format!("{name}.gonio"));
    // A caller watching the comparison sees which run its progress counts.
    if let StopBy::Caller(w) = stop {
        w.begin(name, "steps");
    }
    let args = AcquireArgs::simulated(
        a.instrument.clone(),
        plan.to_path_buf(),
        out.clone(),
        sim.clone(),
        a.seed,
    );
    let r = acquire_with(&args, true, stop)?;
    // Stopped (exit 130) or faulted as `gonio acquire` would be.
    session_result(&out, &r)?;
    let store = RunStore::open_read_only(&out)?;
    Ok((name, sample_points(&store)?, out))
}

/// Distinct sample points measured in a run.
fn sample_points(store: &RunStore) -> CliResult<usize> {
    let set: std::collections::BTreeSet<usize> = store
        .steps()?
        .iter()
        .filter(|s| s.step.kind == StepKind::Sample && s.state == "done")
        .filter_map(|s| s.step.plan_index)
        .collect();
    Ok(set.len())
}

/// The instrument time of a run, s: each session's last reading's.
fn physical_seconds(store: &RunStore) -> CliResult<f64> {
    Ok(store.session_readings()?.values().map(|(_, s)| *s).sum())
}

/// The simulated sample of a run, as the run file stores it.
fn truth_of(store: &RunStore) -> CliResult<Box<dyn gonio_brdf::Brdf>> {
    let stored = gonio_acquire::stored(store)?;
    let (sim_text, sample) = stored.sim.ok_or_else(|| {
        input(format!(
            "{}: not a simulated run: there is no truth to compare with",
            store.path().display()
        ))
    })?;
    let mut s = gonio_sim::SimConfig::from_toml(&sim_text, None).map_err(input)?;
    s.sample_text = Some(sample);
    s.prepare_sample().map_err(input)?;
    Ok(s.load_sample().map_err(input)?.0)
}

/// The plan's text as a TOML table, with its reference standard's model made
/// absolute (the derived plans live elsewhere).
fn plan_table(text: &str, path: &Path) -> CliResult<toml::Table> {
    let mut t: toml::Table = text
        .parse()
        .map_err(|e| input(format!("{}: {e}", path.display())))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    if let Some(toml::Value::Table(c)) = t.get_mut("calibration")
        && let Some(toml::Value::Table(s)) = c.get_mut("standard")
        && let Some(toml::Value::String(m)) = s.get_mut("model")
    {
        let p = Path::new(m.as_str());
        if p.is_relative() {
            let abs = std::path::absolute(dir.join(p)).map_err(input)?;
            *m = abs.display().to_string();
        }
    }
    Ok(t)
}

/// The lattice of `spec`'s coarse pass (and the mirror directions) with the most
/// measurable points not past `target`, as a directions file.
fn lattice_list(mech: &gonio_plan::Mechanics, spec: &Adaptive, target: usize) -> CliResult<String> {
    let count = |n: usize| -> CliResult<(usize, Vec<gonio_core::dirfile::PairDeg>)> {
        let pairs = spec.coarse_pairs(n).map_err(input)?;
        let ok: Vec<_> = gonio_plan::plan::check(mech, &pairs)
            .accepted
            .into_iter()
            .map(|a| a.pair)
            .collect();
        Ok((ok.len(), ok))
    };
    // Measurable points grow with the lattice (nearly one for one): bisect.
    let (mut lo, mut hi) = (1usize, target.max(8));
    let mut best = None;
    while lo <= hi {
        let mid = (lo + hi) / 2;
        let (n, pairs) = count(mid)?;
        if n <= target {
            best = Some(pairs);
            lo = mid + 1;
        } else {
            hi = mid - 1;
        }
    }
    let pairs = best.ok_or_else(|| input("no lattice is small enough"))?;
    let mut out = gonio_core::dirfile::HEADER_DEG.join(",");
    out.push('\n');
    for p in &pairs {
        out.push_str(&gonio_core::dirfile::eval_row(p, &[]));
        out.push('\n');
    }
    Ok(out)
}

/// Parses `DTHETA,DPHI` (degrees; DTHETA divides 90, DPHI 360).
fn parse_outgoing_grid(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("{s:?}: expected DTHETA,DPHI in degrees, like 2,2"))?;
    let num = |v: &str| v.trim().parse::<f64>().map_err(|e| format!("{v:?}: {e}"));
    let (t, p) = (num(a)?, num(b)?);
    let divides = |v: f64, whole: f64| {
        v.is_finite() && v >= 0.1 && (whole / v - (whole / v).round()).abs() < 1e-9
    };
    if !(divides(t, 90.0) && divides(p, 360.0)) {
        return Err(format!(
            "DTHETA must divide 90 and DPHI 360 (degrees, at least 0.1), got {t},{p}"
        ));
    }
    Ok((t, p))
}

/// A `grid` plan over the adaptive plan's incidences: polar band midpoints and a full
/// turn of azimuth, the azimuthal step within 25% of the polar one, with the most
/// measurable points that do not pass `target`.
fn grid_plan(
    mech: &gonio_plan::Mechanics,
    table: &toml::Table,
    spec: &Adaptive,
    target: usize,
) -> CliResult<String> {
    let theta_i: Vec<toml::Value> = spec
        .incidences()
        .map_err(input)?
        .iter()
        .map(|d| toml::Value::Float(d.theta_deg))
        .collect();
    let make = |n_theta: usize, n_phi: usize| -> CliResult<(usize, String)> {
        let mut t = table.clone();
        let (dt, dp) = (90.0 / n_theta as f64, 360.0 / n_phi as f64);
        let range = |from: f64, to: f64, step: f64| {
            toml::Value::Table(toml::Table::from_iter([
                ("from".to_string(), toml::Value::Float(from)),
                ("to".to_string(), toml::Value::Float(to)),
                ("step".to_string(), toml::Value::Float(step)),
            ]))
        };
        t.insert(
            "points".into(),
            toml::Value::Table(toml::Table::from_iter([
                ("kind".to_string(), toml::Value::String("grid".into())),
                ("theta_i".to_string(), toml::Value::Array(theta_i.clone())),
                ("phi_i".to_string(), toml::Value::Float(spec.phi_i)),
                ("theta_o".to_string(), range(dt / 2.0, 90.0 - dt / 4.0, dt)),
                ("phi_o".to_string(), range(0.0, 360.0 - dp / 2.0, dp)),
            ])),
        );
        let text = toml::to_string(&t).map_err(input)?;
        let plan = Plan::from_toml(&text, None).map_err(input)?;
        let pairs = plan.pairs().map_err(input)?;
        Ok((gonio_plan::plan::check(mech, &pairs).accepted.len(), text))
    };
    let mut best: Option<(usize, String)> = None;
    for n_theta in 1..=90usize {
        // Equal steps would be n_phi = 4 n_theta; allow ±25% to come closer to the
        // target, and bisect (the measurable points grow with n_phi).
        let (mut lo, mut hi) = (3 * n_theta, 5 * n_theta);
        while lo <= hi {
            let mid = (lo + hi) / 2;
            let (n, text) = make(n_theta, mid)?;
            if n <= target {
                if best.as_ref().is_none_or(|b| n > b.0) {
                    best = Some((n, text));
                }
                lo = mid + 1;
            } else {
                hi = mid - 1;
            }
        }
        if make(n_theta, 3 * n_theta)?.0 > target {
            break;
        }
    }
    best.map(|b| b.1)
        .ok_or_else(|| input("no grid plan is small enough"))
}

/// Writes a new file (never over one).
fn write_new(path: &Path, text: &str) -> CliResult<()> {
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .map_err(|e| CliError::Runtime(format!("{}: {e}", path.display())))?;
    f.write_all(text.as_bytes())
        .map_err(|e| CliError::Runtime(format!("{}: {e}", path.display())))
}

/// A directory removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new() -> CliResult<TempDir> {
        use std::sync::atomic::{AtomicU64, Ordering};
        static N: AtomicU64 = AtomicU64::new(0);
        let p = std::env::temp_dir().join(format!(
            "gonio-compare-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir(&p).map_err(|e| CliError::Runtime(format!("{}: {e}", p.display())))?;
        Ok(TempDir(p))
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Each run's error over the adaptive run's (the first).
fn ratio(runs: &[Compared], e: f64) -> f64 {
    let base = runs[0].error;
    if base > 0.0 { e / base } else { f64::INFINITY }
}

/// The `--json` object of the comparison.
fn json_of(a: &CompareArgs, runs: &[Compared]) -> serde_json::Value {
    json!({
        "plan": a.plan.display().to_string(),
        "grid": [a.grid.0, a.grid.1],
        "runs": runs.iter().map(|r| json!({
            "plan": r.name,
            "points": r.points,
            "steps": r.steps,
            "physical_s": r.physical_s,
            "error": r.error,
            "error_over_adaptive": ratio(runs, r.error),
            "file": (r.file != Path::new("-")).then(|| r.file.display().to_string()),
        })).collect::<Vec<_>>(),
    })
}

/// Prints the comparison.
fn report(a: &CompareArgs, runs: &[Compared]) -> CliResult<()> {
    if a.json.json {
        return output::json(&json_of(a, runs));
    }
    let ratio = |e: f64| ratio(runs, e);
    let mut w = output::stdout();
    output::finish((|| {
        writeln!(
            w,
            "{}: error E (cosine-weighted relative RMS against the truth, {}°×{}° outgoing grid at the plan's incidences)",
            a.plan.display(),
            a.grid.0,
            a.grid.1
        )?;
        writeln!(
            w,
            "{:<9} {:>7} {:>7} {:>10} {:>9} {:>12}",
            "plan", "points", "steps", "time", "E", "E/adaptive"
        )?;
        for r in runs {
            writeln!(
                w,
                "{:<9} {:>7} {:>7} {:>10} {:>9.4} {:>11.2}×",
                r.name,
                r.points,
                r.steps,
                hms(r.physical_s),
                r.error,
                ratio(r.error)
            )?;
        }
        w.flush()
    })())
}
