//! `gonio demo`: what Gonio does today, on an embedded default — the blue paint of
//! Lafortune et al. 1997, Table 1, at 550 nm.

use std::io::Write;
use std::path::{Path, PathBuf};

use gonio_brdf::albedo::{DEFAULT_TOLERANCE, integrate};
use gonio_brdf::{Brdf, Lafortune, Model};
use gonio_core::{Dir, SphericalDeg};
use serde_json::json;

use crate::error::{CliError, CliResult};
use crate::flags::JsonFlag;
use crate::output;

/// `gonio demo`: what Gonio does, on an embedded default.
#[derive(clap::Args)]
pub struct DemoArgs {
    #[command(flatten)]
    json: JsonFlag,
    /// Keep the demo's run file here (a temporary file, removed, otherwise).
    #[arg(long)]
    out: Option<PathBuf>,
}

/// The embedded default model.
const BLUE_PAINT: &str = include_str!("../../../../config/models/blue-paint-550nm.toml");

const ALBEDO_THETAS: [f64; 12] = [
    0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 65.0, 70.0, 75.0, 80.0, 85.0,
];
/// The incidence angles of Fig. 13.
const CUT_THETAS: [f64; 3] = [0.0, 35.0, 65.0];

fn deg(t: f64, p: f64) -> Dir {
    Dir::from(SphericalDeg::new(t, p))
}

fn albedo1(b: &dyn Brdf, wi: Dir) -> f64 {
    let mut a = vec![0.0; b.channels().len()];
    b.albedo(wi, &mut a);
    a[0]
}

fn eval1(b: &dyn Brdf, wi: Dir, wo: Dir) -> f64 {
    let mut a = vec![0.0; b.channels().len()];
    b.eval(wi, wo, &mut a);
    a[0]
}

/// A point of the plane of incidence: negative θo on the source's side (φo = 0),
/// positive on the specular side (φo = 180°).
fn in_plane(theta_o: f64) -> Dir {
    if theta_o < 0.0 {
        deg(-theta_o, 0.0)
    } else {
        deg(theta_o, 180.0)
    }
}

struct AlbedoRow {
    theta: f64,
    total: f64,
    diffuse: f64,
    lobes: Vec<f64>,
    cubature: f64,
}

/// What the demo computes from the model alone, before the acquisition: the albedo
/// table, the in-plane cuts and the reciprocity check.
struct Study {
    rows: Vec<AlbedoRow>,
    max_dev: f64,
    cut_thetas_o: Vec<f64>,
    cuts: Vec<Vec<f64>>,
    recip: f64,
}

/// How far the acquisition's readings stray from the model: the largest deviation
/// in sigmas and relative to the model.
struct Deviation {
    worst: f64,
    worst_rel: f64,
}

/// Runs the demo.
pub fn run(a: DemoArgs) -> CliResult<()> {
    let (json, keep) = (a.json.json, a.out.as_deref());
    let model = Model::from_toml(BLUE_PAINT, None)
        .map_err(|e| CliError::Runtime(format!("embedded demo model: {e}")))?;
    let Model::Lafortune(paint) = &model else {
        return Err(CliError::Runtime(
            "embedded demo model is not a Lafortune model".into(),
        ));
    };
    let ch = paint.channels().clone();
    let study = study(paint)?;
    refuse_existing(keep)?;
    let acq = acquisition(keep)?;
    let props = properties(paint)?;
    let dev = Deviation {
        worst: acq
            .points
            .iter()
            .map(|p| ((p.measured - p.model) / p.sigma).abs())
            .fold(0.0, f64::max),
        worst_rel: acq
            .points
            .iter()
            .map(|p| ((p.measured - p.model) / p.model).abs())
            .fold(0.0, f64::max),
    };
    if json {
        return output::json(&json_report(&ch, &study, &acq, &dev, &props));
    }
    let mut w = output::stdout();
    output::finish((|| {
        write_model(&mut w, &study)?;
        write_acquisition(&mut w, &acq, &dev)?;
        write_properties(&mut w, &props)?;
        writeln!(w)?;
        writeln!(w, "Gonio today:")?;
        for line in today() {
            writeln!(w, "  {line}")?;
        }
        writeln!(w)?;
        writeln!(
            w,
            "The run's report (one self-contained HTML page): {}",
            acq.report.display()
        )?;
        w.flush()
    })())
}

/// The model's own numbers: the directional albedo by term and by cubature, the
/// BRDF in the plane of incidence, and reciprocity over a grid of pairs.
fn study(paint: &Lafortune) -> CliResult<Study> {
    let ch = paint.channels().clone();
    // Each term on its own, to show what each lobe contributes.
    let lobes: Vec<Lafortune> = paint
        .lobes()
        .iter()
        .map(|l| Lafortune::new(ch.clone(), vec![l.clone()]))
        .collect::<Result<_, _>>()
        .map_err(|e| CliError::Runtime(format!("embedded demo model: {e}")))?;
    let rows: Vec<AlbedoRow> = ALBEDO_THETAS
        .iter()
        .map(|t| {
            let wi = deg(*t, 0.0);
            AlbedoRow {
                theta: *t,
                total: albedo1(paint, wi),
                diffuse: paint.diffuse().map_or(0.0, |d| albedo1(d, wi)),
                lobes: lobes.iter().map(|l| albedo1(l, wi)).collect(),
                // Independent check: generic cubature instead of the exact lobe integral.
                cubature: integrate(paint, wi, DEFAULT_TOLERANCE).values[0],
            }
        })
        .collect();
    let max_dev = rows
        .iter()
        .map(|r| (r.total - r.cubature).abs())
        .fold(0.0, f64::max);
    let cut_thetas_o: Vec<f64> = (-8..=8).map(|k| 10.0 * k as f64).collect();
    let cuts: Vec<Vec<f64>> = CUT_THETAS
        .iter()
        .map(|ti| {
            cut_thetas_o
                .iter()
                .map(|to| eval1(paint, deg(*ti, 0.0), in_plane(*to)))
                .collect()
        })
        .collect();
    Ok(Study {
        rows,
        max_dev,
        cut_thetas_o,
        cuts,
        recip: reciprocity(paint),
    })
}

/// The largest relative difference between f(wi, wo) and f(wo, wi) over a 5° by
/// 30° grid of pairs: exact by construction (Eq. 3 with M = Mᵀ).
fn reciprocity(paint: &Lafortune) -> f64 {
    let mut recip: f64 = 0.0;
    for ti in (0..90).step_by(5) {
        for pi in (0..360).step_by(30) {
            for to in (0..90).step_by(5) {
                for po in (0..360).step_by(30) {
                    let (a, b) = (deg(ti as f64, pi as f64), deg(to as f64, po as f64));
                    let (x, y) = (eval1(paint, a, b), eval1(paint, b, a));
                    recip = recip.max((x - y).abs() / x.max(y));
                }
            }
        }
    }
    recip
}

/// Refuses, before acquiring anything, a kept run file or its report that exists
/// already: neither is ever replaced.
fn refuse_existing(keep: Option<&Path>) -> CliResult<()> {
    if let Some(p) = keep {
        if p.exists() {
            return Err(CliError::Input(format!(
                "{}: exists already; a run file is never replaced (choose another name)",
                p.display()
            )));
        }
        let report_dir = p.with_extension("report");
        if report_dir.exists() {
            crate::output::Target::new(&report_dir.join("report.html"), false)?;
        }
    }
    Ok(())
}

/// The demo's `--json` document.
fn json_report(
    ch: &gonio_core::Channels,
    study: &Study,
    acq: &Acquired,
    dev: &Deviation,
    props: &[(&'static str, gonio_process::measure::Report, f64)],
) -> serde_json::Value {
    json!({
        "acquisition": {
            "plan": "config/plan-in-plane.toml",
            "steps": acq.steps,
            "rejected": acq.rejected.iter().map(|(k, v)| (k.to_string(), *v)).collect::<std::collections::BTreeMap<_, _>>(),
            "motion_s": acq.motion_s,
            "raster_motion_s": acq.raster_motion_s,
            "physical_s": acq.physical_s,
            "wall_s": acq.wall_s,
            "dark_v": acq.dark_v,
            "incident_v": acq.incident_v,
            "max_deviation_sigmas": dev.worst,
            "max_relative_deviation": dev.worst_rel,
            "run_file": acq.run_file.as_ref().map(|p| p.display().to_string()),
            "report": acq.report.display().to_string(),
            "points": acq.points.iter().map(|p| json!({
                "theta_i": p.theta_i, "theta_o": p.theta_o, "model": p.model,
                "measured": p.measured, "sigma": p.sigma, "z_full": p.z_full,
            })).collect::<Vec<_>>(),
            "agreement": {
                "chi2_per_sample": acq.agreement.chi2_plain,
                "chi2_full_covariance": acq.agreement.chi2_full,
                "mean_z": acq.agreement.mean_z,
                "shared_fraction": acq.agreement.shared_fraction,
                "shifts": acq.shifts.iter().map(|(s, e)| json!({"source": s, "sigmas": e})).collect::<Vec<_>>(),
            },
        },
        "model": "Lafortune et al. 1997, Table 1: blue paint",
        "channels": ch.names(),
        "albedo": study.rows.iter().map(|r| json!({
            "theta_i": r.theta, "total": r.total, "diffuse": r.diffuse,
            "lobes": r.lobes, "cubature": r.cubature,
        })).collect::<Vec<_>>(),
        "albedo_max_method_difference": study.max_dev,
        "in_plane": CUT_THETAS.iter().zip(&study.cuts).map(|(ti, c)| json!({
            "theta_i": ti,
            "theta_o": study.cut_thetas_o,
            "brdf": c,
        })).collect::<Vec<_>>(),
        "reciprocity_max_relative_difference": study.recip,
        "properties": props.iter().map(|(name, r, ratio)| json!({
            "table": name, "measures": r, "separable_5_storage_ratio": ratio,
        })).collect::<Vec<_>>(),
    })
}

/// The text report's model part: the lobes, the albedo table, the in-plane cuts
/// and reciprocity.
fn write_model(w: &mut dyn Write, study: &Study) -> std::io::Result<()> {
    writeln!(
        w,
        "Gonio demo: the blue paint of Lafortune et al. 1997, Table 1 (550 nm)"
    )?;
    writeln!(
        w,
        "model: Lambertian rho_d = 0.13 pi + three generalized cosine lobes (Eq. 8)"
    )?;
    writeln!(
        w,
        "  lobe I   Cx = Cy = 0.86, Cz = 0.77,  n = 18.6  (retro-reflective)"
    )?;
    writeln!(
        w,
        "  lobe II  Cx = Cy = -0.41, Cz = 0.018, n = 2.58 (broad forward)"
    )?;
    writeln!(
        w,
        "  lobe III Cx = Cy = -1.03, Cz = 0.70,  n = 63.8 (off-specular forward)"
    )?;
    writeln!(w)?;
    writeln!(
        w,
        "Directional albedo rho(theta_i) = integral of f_r cos(theta_o) over the hemisphere"
    )?;
    writeln!(
        w,
        "{:>7} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "theta_i", "total", "diffuse", "lobe I", "lobe II", "lobe III"
    )?;
    for r in &study.rows {
        write!(w, "{:>7} {:>9.5} {:>9.5}", r.theta, r.total, r.diffuse)?;
        for l in &r.lobes {
            write!(w, " {l:>9.5}")?;
        }
        writeln!(w)?;
    }
    writeln!(
        w,
        "exact lobe integrals and generic 2-D cubature agree to {:.1e} at every angle",
        study.max_dev
    )?;
    writeln!(w)?;
    writeln!(
        w,
        "BRDF in the plane of incidence (1/sr), the cuts of Fig. 13; theta_o < 0 is the"
    )?;
    writeln!(w, "source side, theta_o > 0 the specular side")?;
    write!(w, "{:>7}", "theta_o")?;
    for ti in CUT_THETAS {
        write!(w, "  {:>12}", format!("theta_i={ti}"))?;
    }
    writeln!(w)?;
    for (k, to) in study.cut_thetas_o.iter().enumerate() {
        write!(w, "{to:>7}")?;
        for c in &study.cuts {
            write!(w, "  {:>12.5}", c[k])?;
        }
        writeln!(w)?;
    }
    writeln!(w)?;
    writeln!(
        w,
        "reciprocity: max |f(wi,wo) - f(wo,wi)| / f over {} grid pairs = {:e}",
        18 * 12 * 18 * 12,
        study.recip
    )?;
    writeln!(w)
}

/// The text report's acquisition part: the plan's steps and times, then the
/// reduced readings every 10° against the model.
fn write_acquisition(w: &mut dyn Write, acq: &Acquired, dev: &Deviation) -> std::io::Result<()> {
    writeln!(
        w,
        "Acquired on the simulated goniometer (gonio-sim: coplanar arms, this paint, seed 1)"
    )?;
    writeln!(
        w,
        "through the real stack: plan check, motion ordering, run file, engine, SMC100 and"
    )?;
    writeln!(w, "SR830 drivers. Plan config/plan-in-plane.toml:")?;
    let rejected: Vec<String> = acq
        .rejected
        .iter()
        .map(|(k, v)| format!("{v} {k}"))
        .collect();
    writeln!(
        w,
        "  {} steps ({} left out: {}); motion {:.0} s ordered vs {:.0} s in plan order",
        acq.steps,
        acq.rejected.iter().map(|(_, v)| v).sum::<usize>(),
        rejected.join(", "),
        acq.motion_s,
        acq.raster_motion_s
    )?;
    writeln!(
        w,
        "  {:.0} s of instrument time in {:.2} s of wall time; dark {:.2e} V, incident {:.3e} V \
         above dark (ND 1e-3)",
        acq.physical_s, acq.wall_s, acq.dark_v, acq.incident_v
    )?;
    writeln!(
        w,
        "Reduced with the run's own dark and incident readings (DeYoung Eq. A.15), every 10°:"
    )?;
    writeln!(
        w,
        "{:>7} {:>7} {:>11} {:>11} {:>10} {:>7} {:>7}",
        "theta_i", "theta_o", "model", "measured", "sigma", "dev/s", "z full"
    )?;
    for p in acq
        .points
        .iter()
        .filter(|p| p.theta_o.rem_euclid(10.0) == 0.0)
    {
        writeln!(
            w,
            "{:>7} {:>7} {:>11.6} {:>11.6} {:>10.2e} {:>7.2} {:>7.2}",
            p.theta_i,
            p.theta_o,
            p.model,
            p.measured,
            p.sigma,
            (p.measured - p.model) / p.sigma,
            p.z_full
        )?;
    }
    writeln!(
        w,
        "{} sample readings: largest deviation {:.2} sigma, {:.2} % of the model",
        acq.points.len(),
        dev.worst,
        100.0 * dev.worst_rel
    )?;
    let a = &acq.agreement;
    let zs: Vec<f64> = acq.points.iter().map(|p| p.z_full).collect();
    let n = zs.len().max(1) as f64;
    let mean = zs.iter().sum::<f64>() / n;
    let rms = (zs.iter().map(|z| z * z).sum::<f64>() / n).sqrt();
    writeln!(
        w,
        "dev/s is each sample's own deviation; its errors are shared (one dark, one \
         calibration), so they move together: mean dev/s {:+.2} (the shared terms allow \
         ±{:.2}), χ²/n {:.2}",
        a.mean_z,
        2.5 * a.shared_fraction,
        a.chi2_plain
    )?;
    writeln!(
        w,
        "z full: the deviations whitened by the full covariance, mean {mean:+.2}, RMS \
         {rms:.2}, χ²/n {:.2} (N(0, 1): mean 0 ± {:.2}, RMS 1 ± {:.2}); the run was moved \
         most by {}",
        a.chi2_full,
        1.0 / n.sqrt(),
        (0.5 / n).sqrt(),
        acq.shifts
            .iter()
            .take(2)
            .map(|(s, e)| format!("the {s} ({e:+.2} of its σ)"))
            .collect::<Vec<_>>()
            .join(" and ")
    )?;
    if let Some(p) = &acq.run_file {
        writeln!(w, "run file: {} (gonio show {})", p.display(), p.display())?;
    }
    writeln!(w)
}

/// The text report's table of DeYoung's measures for the paint and Phong shading.
fn write_properties(
    w: &mut dyn Write,
    props: &[(&'static str, gonio_process::measure::Report, f64)],
) -> std::io::Result<()> {
    writeln!(
        w,
        "DeYoung's measures (Ch. 4) of 10°-grid tables (gonio check): the paint is reciprocal"
    )?;
    writeln!(
        w,
        "and isotropic; the Phong shading model is neither reciprocal nor energy-conserving:"
    )?;
    writeln!(
        w,
        "{:<22} {:>10} {:>10} {:>10} {:>10} {:>10} {:>8}",
        "table (first channel)", "P_r", "P_ec", "P_i", "P_s^(1)", "P_s^(5)", "5-sep."
    )?;
    for (name, r, ratio) in props {
        let sep = r
            .separability
            .as_ref()
            .map(|s| (s[0].p_s[0].1, s[0].p_s[1].1));
        let (s1, s5) = sep.unwrap_or((f64::NAN, f64::NAN));
        writeln!(
            w,
            "{name:<22} {:>10.2e} {:>10.2e} {:>10.2e} {:>10.2e} {:>10.2e} {:>7.1}%",
            r.reciprocity[0],
            r.energy.p_ec[0],
            r.isotropy[0],
            s1,
            s5,
            100.0 * ratio
        )?;
    }
    Ok(())
}

/// What Gonio does, by command, for the demo's closing summary: the drivers from
/// [`gonio_driver::DRIVERS`], so that the list stays the drivers there are.
pub(crate) fn today() -> Vec<String> {
    let drivers: Vec<&str> = gonio_driver::DRIVERS
        .iter()
        .map(|(_, what)| *what)
        .collect();
    vec![
        "BRDF models: gonio model eval | albedo".into(),
        format!("drivers: {}", drivers.join(", ")),
        "instruments: gonio instrument check [--connect] | ports | selftest; the simulated \
         instrument on pseudo-terminals: gonio sim"
            .into(),
        "acquisition: gonio plan check | compare, acquire [--serve] | resume | runs | show | \
         verify | view"
            .into(),
        "processing: gonio reduce | check | correct | harmonics | micro; lobe fitting: gonio fit \
         [--compare]"
            .into(),
        "output: gonio export (MERL, ASTM E1392, CSV) | plot | report | colour; the same in \
         Python (import gonio)"
            .into(),
    ]
}

/// The Phong shading BRDF DeYoung measures in Sec. 5.2 (non-reciprocal: the lobe is
/// divided by cos θi).
const PHONG_SHADING: &str = r#"
kind = "phong"
channels = ["value"]
rho_s = [0.6]
n = [20]
shading = true
[diffuse]
rho = [0.3]
"#;

/// DeYoung's four measures of the paint and of the Phong shading model, tabulated on
/// a 10° hemisphere grid, with the storage of their 5-separable form.
fn properties(
    paint: &dyn gonio_brdf::Brdf,
) -> CliResult<Vec<(&'static str, gonio_process::measure::Report, f64)>> {
    use gonio_process::separable::SeparableBrdf;
    use gonio_process::{Grid, Table, measure};
    let runtime = |e: &dyn std::fmt::Display| CliError::Runtime(format!("demo properties: {e}"));
    let phong = Model::from_toml(PHONG_SHADING, None).map_err(|e| runtime(&e))?;
    let mut out = Vec::new();
    let models: [(&'static str, &dyn gonio_brdf::Brdf); 2] =
        [("blue paint (Table 1)", paint), ("Phong shading", &phong)];
    for (name, m) in models {
        let t = Table::from_brdf(m, Grid::hemisphere(9, 36)).map_err(|e| runtime(&e))?;
        let r = measure::report(&t, &[1, 5], 1).map_err(|e| runtime(&e))?;
        let ratio = SeparableBrdf::from_table(&t, 5, false)
            .map_err(|e| runtime(&e))?
            .storage_ratio();
        out.push((name, r, ratio));
    }
    Ok(out)
}

/// The embedded acquisition plan.
const PLAN: &str = include_str!("../../../../config/plan-in-plane.toml");

/// The simulator's instrument config, embedded.
const INSTRUMENT_SIM: &str = include_str!("../../../../config/instrument-sim.toml");

/// One reduced sample reading.
struct Point {
    theta_i: f64,
    theta_o: f64,
    model: f64,
    measured: f64,
    sigma: f64,
    /// The residual whitened by the run's full covariance (a standard normal when
    /// the stated uncertainties are right, correlations included).
    z_full: f64,
}

/// What the demo's acquisition measured.
struct Acquired {
    points: Vec<Point>,
    /// The run against the paint it measured: χ² per sample and with the full
    /// covariance, the mean z and what the shared terms allow.
    agreement: gonio_process::covariance::Agreement,
    /// The shared errors' most likely shifts, in their own σ, largest first.
    shifts: Vec<(String, f64)>,
    steps: usize,
    rejected: Vec<(&'static str, usize)>,
    motion_s: f64,
    raster_motion_s: f64,
    physical_s: f64,
    wall_s: f64,
    dark_v: f64,
    incident_v: f64,
    run_file: Option<PathBuf>,
    report: PathBuf,
}

/// Runs the embedded plan on the embedded simulator through the real acquisition
/// stack (plan check, ordering, run file, engine, drivers, simulator), then reduces
/// it with `gonio_reduce` (DeYoung Eq. A.15 with the run's own dark,
/// incident-beam and drift readings).
fn acquisition(keep: Option<&Path>) -> CliResult<Acquired> {
    let path = match keep {
        Some(p) => p.to_path_buf(),
        None => std::env::temp_dir().join(format!("gonio-demo-{}.gonio", std::process::id())),
    };
    let ran = run_plan(&path)?;
    let steps = ran.store.steps().map_err(|e| demo_error(&e))?;
    let reduction = gonio_reduce::reduce(&ran.store, &gonio_reduce::Options::default())
        .map_err(|e| demo_error(&e))?;
    let cal = reduction
        .report
        .channels
        .first()
        .ok_or_else(|| demo_error(&"no channel reduced"))?;
    let dark_v = cal.dark_v[0].hypot(cal.dark_v[1]);
    // The report's incident flux is the full beam; the reading was through the filter.
    let incident_v = cal.incident_v * ran.transmittance;
    let Compared {
        points,
        agreement,
        shifts,
    } = against_the_paint(&reduction)?;
    let rejected = gonio_plan::rejection_counts(&ran.prepared.checked)
        .into_iter()
        .collect();
    drop(ran.store);
    let report = write_report(&path, keep)?;
    let run_file = if keep.is_some() {
        Some(path)
    } else {
        for suffix in ["", "-wal", "-shm"] {
            let _ = std::fs::remove_file(format!("{}{suffix}", path.display()));
        }
        None
    };
    Ok(Acquired {
        points,
        agreement,
        shifts,
        steps: steps.len(),
        rejected,
        motion_s: ran.prepared.schedule.motion_s,
        raster_motion_s: ran.prepared.schedule.raster_motion_s,
        physical_s: ran.report.physical_s,
        wall_s: ran.wall_s,
        dark_v,
        incident_v,
        run_file,
        report,
    })
}

/// A failure of the demo's own acquisition or reduction.
fn demo_error(e: &dyn std::fmt::Display) -> CliError {
    CliError::Runtime(format!("demo acquisition: {e}"))
}

/// What running the plan left: the run file's store, its schedule, the engine's
/// report.
struct Ran {
    store: gonio_run::RunStore,
    prepared: gonio_plan::Prepared,
    report: gonio_acquire::engine::SessionReport,
    transmittance: f64,
    wall_s: f64,
}

/// Creates the run file at `path` and runs the embedded plan into it on the
/// embedded simulator, to completion.
fn run_plan(path: &Path) -> CliResult<Ran> {
    use gonio_plan::Plan;
    use gonio_run as run;

    let inst = gonio_driver::InstrumentConfig::from_toml(INSTRUMENT_SIM, None)
        .map_err(|e| demo_error(&e))?;
    let plan = Plan::from_toml(PLAN, None).map_err(|e| demo_error(&e))?;
    let mech = inst.mechanics().map_err(|e| demo_error(&e))?;
    let prepared =
        gonio_plan::prepare(&mech, inst.reading_seconds(), &plan).map_err(|e| demo_error(&e))?;
    let sim = gonio_sim::SimConfig::default_config().map_err(|e| demo_error(&e))?;
    let inputs = run::Inputs {
        instrument_text: INSTRUMENT_SIM.into(),
        plan_text: PLAN.into(),
        sim: Some((
            gonio_sim::config::DEFAULT_SIM.into(),
            sim.sample_model_text().map_err(|e| demo_error(&e))?,
        )),
        seed: Some(sim.seed),
        notes: Some("gonio demo".into()),
        software: crate::cmd::acquire::SOFTWARE.into(),
        ..run::Inputs::default()
    };
    let store = run::create(path, &plan, &prepared, &inputs).map_err(|e| match e {
        run::CreateError::Store(s) if s.is_bad_input() => CliError::Input(s.to_string()),
        other => demo_error(&other),
    })?;
    let transmittance = plan
        .calibration
        .incident
        .as_ref()
        .map_or(1.0, |i| i.transmittance);
    let started = std::time::Instant::now();
    let (report, store) = crate::cmd::acquire::session(
        || Ok(store),
        &inst,
        "instrument-sim.toml",
        crate::cmd::acquire::Rig::Sim(Box::new(sim)),
        crate::cmd::acquire::RunSetup {
            standard: None,
            transmittance,
            reading: plan
                .reading
                .as_ref()
                .map(gonio_acquire::engine::read_target),
        },
        crate::cmd::acquire::Driving {
            quiet: true,
            stop: &crate::cmd::acquire::StopBy::Signals,
            serve: None,
        },
    )?;
    let wall_s = started.elapsed().as_secs_f64();
    if report.outcome != gonio_acquire::engine::Outcome::Complete {
        return Err(demo_error(&format!(
            "the run ended {}",
            report.outcome.status()
        )));
    }
    Ok(Ran {
        store,
        prepared,
        report,
        transmittance,
        wall_s,
    })
}

/// The reduction against the paint the simulator measured: each in-plane sample
/// beside the model with its deviation whitened by the full covariance, sorted by
/// (θi, signed θo); the agreement; and the shared sources that moved the run.
fn against_the_paint(reduction: &gonio_reduce::Reduction) -> CliResult<Compared> {
    let model = Model::from_toml(BLUE_PAINT, None).map_err(|e| demo_error(&e))?;
    let truth = gonio_reduce::agreement::truth(reduction, &model)
        .ok_or_else(|| demo_error(&"the demo's channel is not the model's"))?;
    let agreement = gonio_reduce::agreement::agreements(reduction, &truth)
        .into_iter()
        .next()
        .ok_or_else(|| demo_error(&"no covariance to compare against"))?;
    let residuals: Vec<f64> = reduction
        .samples
        .samples
        .iter()
        .zip(&truth)
        .map(|(s, t)| s.value[0] - t[0])
        .collect();
    let z_full = reduction
        .covariance
        .whiten(0, &residuals)
        .ok_or_else(|| demo_error(&"the covariance is not positive definite"))?;
    let shifts: Vec<(String, f64)> = agreement
        .shifts
        .iter()
        .map(|(k, e)| (reduction.covariance.sources[*k].label.clone(), *e))
        .collect();
    let mut points = Vec::new();
    for (s, z_full) in reduction.samples.samples.iter().zip(z_full) {
        let pair = s.pair;
        let d = pair.to_dirs();
        let signed = if pair.outgoing.theta_deg == 0.0 {
            0.0
        } else if pair.outgoing.phi_deg == pair.incident.phi_deg {
            -pair.outgoing.theta_deg
        } else {
            pair.outgoing.theta_deg
        };
        points.push(Point {
            theta_i: pair.incident.theta_deg,
            theta_o: signed,
            model: eval1(&model, d.wi, d.wo),
            measured: s.value[0],
            sigma: s.sigma.as_ref().map_or(0.0, |v| v[0]),
            z_full,
        });
    }
    points.sort_by(|a, b| {
        (a.theta_i, a.theta_o)
            .partial_cmp(&(b.theta_i, b.theta_o))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    Ok(Compared {
        points,
        agreement,
        shifts,
    })
}

/// The reduction against the paint: [`against_the_paint`]'s result.
struct Compared {
    points: Vec<Point>,
    agreement: gonio_process::covariance::Agreement,
    shifts: Vec<(String, f64)>,
}

/// Writes the run report, before a temporary run file is removed: beside a kept run
/// file, else in the temporary directory. Returns the page's path.
fn write_report(path: &Path, keep: Option<&Path>) -> CliResult<PathBuf> {
    let report_dir = match keep {
        Some(p) => p.with_extension("report"),
        None => std::env::temp_dir().join(format!("gonio-demo-report-{}", std::process::id())),
    };
    let page = crate::cmd::report::build_report(path, &crate::flags::ReduceFlags::default())?;
    std::fs::create_dir_all(&report_dir)
        .map_err(|e| demo_error(&format!("{}: {e}", report_dir.display())))?;
    let report_path = report_dir.join("report.html");
    // The temporary directory is this process's own; beside a kept run file, an
    // existing report is never replaced (checked before the acquisition too).
    crate::output::Target::new(&report_path, keep.is_none())?
        .write(gonio_io::report::html(&page).as_bytes())?;
    Ok(report_path)
}
