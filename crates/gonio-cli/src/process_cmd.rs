//! `gonio reduce`, `gonio check`, `gonio correct` and `gonio harmonics`: a run's
//! readings to BRDF samples and tables, DeYoung's measures and transforms, and the
//! compressed representations.

use std::io::{Read as _, Write};
use std::path::Path;

use gonio_process::file;
use gonio_process::measure;
use gonio_process::samples::Kernel;
use gonio_process::separable::SeparableBrdf;
use gonio_process::sh::{ShBrdf, ShOptions};
use gonio_process::transform::{self, Step};
use gonio_process::{Axis, Grid, ProcessError, Samples, Table};
use gonio_reduce::{self as reduce, Calibration, Drift, Options, Reduction};
use gonio_run::RunStore;
use serde_json::json;

use crate::error::{CliError, CliResult};
use crate::output;

/// The largest text input read (a 5° full 4D RGB table with uncertainties is ~0.5 GB
/// of text; anything past this is refused rather than read into memory).
const MAX_TEXT_BYTES: u64 = 4 << 30;

/// What an input file turned out to hold.
pub enum Input {
    /// A table (a grid file, a run whose pairs form a grid, a tabulated model or
    /// separable file).
    Table(Table),
    /// Scattered samples.
    Samples(Samples),
    /// A MERL table (a BRDF of half/difference bins).
    Merl(Box<gonio_io::formats::merl::MerlBrdf>),
}

impl Input {
    /// The input as samples (a MERL table's valid bins thinned to at most `max`).
    pub fn to_samples(&self, max: usize) -> Samples {
        match self {
            Input::Table(t) => Samples::from_table(t),
            Input::Samples(s) => s.clone(),
            Input::Merl(m) => {
                m.to_samples_strided(gonio_io::formats::merl::MerlBrdf::stride_for(max))
            }
        }
    }
}

fn input_err(path: &Path, e: impl std::fmt::Display) -> CliError {
    CliError::Input(format!("{}: {e}", path.display()))
}

fn process_err(path: &Path, e: ProcessError) -> CliError {
    match e {
        ProcessError::Numerics(_) => CliError::Runtime(format!("{}: {e}", path.display())),
        _ => input_err(path, e),
    }
}

/// A grid given as `DTHETA,DPHI` in degrees: polar band midpoints and a full turn of
/// azimuth, the same for incidence and exitance.
pub fn parse_grid(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("expected DTHETA,DPHI in degrees, got {s:?}"))?;
    let num = |x: &str| {
        x.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| *v > 0.0 && v.is_finite())
    };
    let (dt, dp) = (num(a), num(b));
    match (dt, dp) {
        (Some(dt), Some(dp))
            if (90.0 / dt).fract().abs() < 1e-9 && (360.0 / dp).fract().abs() < 1e-9 =>
        {
            Ok((dt, dp))
        }
        _ => Err(format!(
            "DTHETA must divide 90 and DPHI 360 (degrees, positive), got {s:?}"
        )),
    }
}

/// The grid of `--grid DTHETA,DPHI`.
pub fn grid_of((dt, dp): (f64, f64)) -> Grid {
    let t = Axis::polar_midpoints((90.0 / dt).round() as usize);
    let p = Axis::full_turn((360.0 / dp).round() as usize);
    Grid::full(p, t, p, t)
}

/// Reduction options from the command line.
pub struct ReduceArgs {
    /// `auto`, `incident` or `standard`.
    pub calibration: String,
    /// `auto`, `calibrations` or `none`.
    pub drift: String,
}

impl ReduceArgs {
    fn options(&self) -> CliResult<Options> {
        let calibration = match self.calibration.as_str() {
            "auto" => Calibration::Auto,
            "incident" => Calibration::Incident,
            "standard" => Calibration::Standard,
            x => {
                return Err(CliError::Input(format!(
                    "--calibration: expected auto, incident or standard, got {x:?}"
                )));
            }
        };
        let drift = match self.drift.as_str() {
            "auto" => Drift::Auto,
            "calibrations" => Drift::Calibrations,
            "none" => Drift::None,
            x => {
                return Err(CliError::Input(format!(
                    "--drift: expected auto, calibrations or none, got {x:?}"
                )));
            }
        };
        Ok(Options {
            calibration,
            drift,
            ..Options::default()
        })
    }
}

fn is_sqlite(path: &Path) -> CliResult<bool> {
    let mut head = [0u8; 16];
    let mut f = std::fs::File::open(path).map_err(|e| input_err(path, e))?;
    let n = f.read(&mut head).map_err(|e| input_err(path, e))?;
    Ok(n == 16 && &head == b"SQLite format 3\0")
}

/// Reduces a run file.
fn reduce_run(path: &Path, args: &ReduceArgs) -> CliResult<Reduction> {
    let store = RunStore::open(path).map_err(|e| {
        if e.is_bad_input() {
            CliError::Input(e.to_string())
        } else {
            CliError::Runtime(e.to_string())
        }
    })?;
    reduce::reduce(&store, &args.options()?).map_err(|e| match e {
        reduce::ReduceError::Store(s) if !s.is_bad_input() => CliError::Runtime(s.to_string()),
        other => CliError::Input(other.to_string()),
    })
}

/// Reads any input: a run file (reduced), a table or sample file, a separable file,
/// or a model file (tabulated on `grid`).
pub fn load(
    path: &Path,
    reduce_args: &ReduceArgs,
    grid: Option<(f64, f64)>,
) -> CliResult<(Input, Option<Reduction>)> {
    if is_sqlite(path)? {
        let red = reduce_run(path, reduce_args)?;
        let input = match red.samples.to_table() {
            Some(t) => Input::Table(t),
            None => Input::Samples(red.samples.clone()),
        };
        return Ok((input, Some(red)));
    }
    let meta = std::fs::metadata(path).map_err(|e| input_err(path, e))?;
    if meta.len() > MAX_TEXT_BYTES {
        return Err(input_err(
            path,
            format!("larger than {MAX_TEXT_BYTES} bytes"),
        ));
    }
    let bytes = std::fs::read(path).map_err(|e| input_err(path, e))?;
    // Binary (MERL) and other non-UTF-8 files go to the format readers.
    let text = std::str::from_utf8(&bytes).unwrap_or("");
    let kind = text
        .lines()
        .map(str::trim)
        .find(|l| l.starts_with("kind"))
        .and_then(|l| l.split_once('='))
        .map(|(_, v)| v.trim().trim_matches('"').to_string());
    let looks_toml = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .is_some_and(|l| l.starts_with("kind") || l.starts_with('['));
    if looks_toml {
        return match kind.as_deref() {
            Some("separable") => {
                let s = SeparableBrdf::from_toml(text, Some(path))
                    .map_err(|e| CliError::Input(e.to_string()))?;
                let t = s.to_table().map_err(|e| process_err(path, e))?;
                Ok((Input::Table(t), None))
            }
            Some("spherical-harmonics") => {
                let sh = ShBrdf::from_toml(text, Some(path))
                    .map_err(|e| CliError::Input(e.to_string()))?;
                let g = grid_of(grid.unwrap_or((10.0, 10.0)));
                let t = Table::from_fn(sh.channels.clone(), g, |wi, wo, out| sh.eval(wi, wo, out))
                    .map_err(|e| process_err(path, e))?;
                Ok((Input::Table(t), None))
            }
            _ => {
                let m = gonio_brdf::Model::from_toml(text, Some(path))?;
                let g = grid_of(grid.unwrap_or((10.0, 10.0)));
                let t = Table::from_brdf(&m, g).map_err(|e| process_err(path, e))?;
                Ok((Input::Table(t), None))
            }
        };
    }
    let data =
        gonio_io::formats::read(&bytes, Some(path)).map_err(|e| CliError::Input(e.to_string()))?;
    Ok((
        match data {
            gonio_io::formats::Data::Table(t) => Input::Table(t),
            gonio_io::formats::Data::Merl(m) => Input::Merl(Box::new(m)),
            gonio_io::formats::Data::Samples(s) => {
                s.validate().map_err(|e| input_err(path, e))?;
                match s.to_table() {
                    Some(t) => Input::Table(t),
                    None => Input::Samples(s),
                }
            }
        },
        None,
    ))
}

/// The input as a table: samples off a grid are resampled onto `grid` with the
/// nearest-j kernel, or refused when no grid is given.
fn as_table(path: &Path, input: Input, grid: Option<(f64, f64)>) -> CliResult<Table> {
    match (input, grid) {
        (Input::Table(t), None) => Ok(t),
        (Input::Table(t), Some(g)) => {
            let s = Samples::from_table(&t);
            s.resample(grid_of(g), Kernel::default())
                .map_err(|e| process_err(path, e))
        }
        (Input::Samples(s), Some(g)) => s
            .resample(grid_of(g), Kernel::default())
            .map_err(|e| process_err(path, e)),
        (Input::Merl(m), g) => Table::from_brdf(m.as_ref(), grid_of(g.unwrap_or((10.0, 10.0))))
            .map_err(|e| process_err(path, e)),
        (Input::Samples(s), None) => Err(input_err(
            path,
            format!(
                "its {} samples do not form a complete uniform grid; pass --grid DTHETA,DPHI \
                 to resample them (nearest-j Gaussian kernel, DeYoung Sec. 3.2.1)",
                s.samples.len()
            ),
        )),
    }
}

fn write_text(out: &Path, text: &str) -> CliResult<()> {
    std::fs::write(out, text)
        .map_err(|e| CliError::Input(format!("{}: cannot write output file: {e}", out.display())))
}

fn reduction_json(r: &Reduction) -> serde_json::Value {
    serde_json::to_value(&r.report).unwrap_or_default()
}

/// `gonio reduce RUN --out TABLE`.
pub fn reduce_cmd(
    path: &Path,
    out: &Path,
    args: &ReduceArgs,
    grid: Option<(f64, f64)>,
    json_out: bool,
) -> CliResult<()> {
    if !is_sqlite(path)? {
        return Err(input_err(path, "not a run file (.gonio, SQLite)"));
    }
    let red = reduce_run(path, args)?;
    let (text, what) = match (red.samples.to_table(), grid) {
        (Some(t), None) => (
            file::write_table(&t),
            format!("a table of {} nodes", t.grid.len()),
        ),
        (_, Some(g)) => {
            let t = red
                .samples
                .resample(grid_of(g), Kernel::default())
                .map_err(|e| process_err(path, e))?;
            (
                file::write_table(&t),
                format!("a table of {} nodes (resampled)", t.grid.len()),
            )
        }
        (None, None) => (
            file::write_samples(&red.samples),
            format!("{} samples", red.samples.samples.len()),
        ),
    };
    write_text(out, &text)?;
    if json_out {
        return output::json(&json!({
            "out": out.display().to_string(),
            "wrote": what,
            "samples": red.samples.samples.len(),
            "channels": red.samples.channels.names(),
            "reduction": reduction_json(&red),
        }));
    }
    let mut w = output::open(None)?;
    output::finish((|| {
        writeln!(
            w,
            "{}: {} from {} samples",
            out.display(),
            what,
            red.samples.samples.len()
        )?;
        print_reduction(&mut w, &red)?;
        w.flush()
    })())
}

fn print_reduction(w: &mut dyn Write, red: &Reduction) -> std::io::Result<()> {
    let r = &red.report;
    writeln!(w, "detector solid angle {:.4e} sr", r.solid_angle_sr)?;
    for c in &r.channels {
        writeln!(
            w,
            "channel {}: {} calibration ({} readings), incident {:.6e} V ± {:.2e} (rel.), dark ({:.2e}, {:.2e}) V, drift {} references, max |g−1| {:.3}%",
            c.channel,
            c.calibration,
            c.calibration_readings,
            c.incident_v,
            c.incident_rel_sigma,
            c.dark_v[0],
            c.dark_v[1],
            c.drift_readings,
            100.0 * c.drift_max
        )?;
    }
    for (why, n) in &r.rejected {
        writeln!(w, "left out: {n} ({why})")?;
    }
    if r.unmeasured > 0 {
        writeln!(w, "not measured (run incomplete): {}", r.unmeasured)?;
    }
    writeln!(
        w,
        "largest read-back position error {:.4}°",
        r.max_position_error_deg
    )
}

/// `gonio check INPUT [--k 1,2,5] [--json]`.
pub fn check(
    path: &Path,
    ks: &[usize],
    grid: Option<(f64, f64)>,
    reduce_args: &ReduceArgs,
    json_out: bool,
) -> CliResult<()> {
    if ks.contains(&0) {
        return Err(CliError::Input("--k: every k must be at least 1".into()));
    }
    let (input, _) = load(path, reduce_args, grid)?;
    let table = as_table(path, input, grid)?;
    let ks = if ks.is_empty() { vec![1] } else { ks.to_vec() };
    let r = measure::report(&table, &ks, 5).map_err(|e| process_err(path, e))?;
    if json_out {
        return output::json(&serde_json::to_value(&r).unwrap_or_default());
    }
    let mut w = output::open(None)?;
    output::finish((|| {
        let g = &table.grid;
        writeln!(
            w,
            "{}: {} nodes ({}{} φi × {} θi × {} φo × {} θo), channels {}",
            path.display(),
            r.nodes,
            if g.isotropic { "isotropic: " } else { "" },
            g.phi_i.n,
            g.theta_i.n,
            g.phi_o.n,
            g.theta_o.n,
            r.channels.join(",")
        )?;
        writeln!(
            w,
            "{:<28}{}",
            "measure",
            r.channels
                .iter()
                .map(|c| format!("{c:>14}"))
                .collect::<String>()
        )?;
        let row = |w: &mut dyn Write, name: &str, v: &[f64]| {
            writeln!(
                w,
                "{name:<28}{}",
                v.iter().map(|x| format!("{x:>14.6e}")).collect::<String>()
            )
        };
        row(
            &mut w,
            if r.paired {
                "P_r (Eq. 4.1)"
            } else {
                "P_r (Eq. 4.1, interpolated)"
            },
            &r.reciprocity,
        )?;
        row(&mut w, "P_ec (Eq. 4.5)", &r.energy.p_ec)?;
        row(&mut w, "P_i (Eq. 4.10)", &r.isotropy)?;
        if let Some(sep) = &r.separability {
            for (j, k) in ks.iter().enumerate() {
                let v: Vec<f64> = sep.iter().map(|s| s.p_s[j].1).collect();
                row(&mut w, &format!("P_s^({k}) (Eq. 4.20)"), &v)?;
            }
        } else {
            writeln!(
                w,
                "P_s: not available (an isotropic table whose φ+ axis is not a full turn)"
            )?;
        }
        if r.energy.coverage < 0.999 {
            writeln!(
                w,
                "note: the outgoing nodes cover {:.1}% of the projected hemisphere; albedos undercount",
                100.0 * r.energy.coverage
            )?;
        }
        writeln!(w, "highest directional albedo (θi, φi: per channel):")?;
        for (th, ph, a) in &r.energy.worst {
            writeln!(
                w,
                "  {th:>6.2}° {ph:>7.2}°: {}",
                a.iter()
                    .map(|x| format!("{x:.4}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            )?;
        }
        w.flush()
    })())
}

/// `gonio correct INPUT --reciprocity δ --energy … --isotropy δ --separable k[:δ]
/// --out OUTPUT`, the steps in the order given.
pub fn correct(
    path: &Path,
    steps: &[Step],
    out: &Path,
    grid: Option<(f64, f64)>,
    reduce_args: &ReduceArgs,
    json_out: bool,
) -> CliResult<()> {
    if steps.is_empty() {
        return Err(CliError::Input(
            "give at least one of --reciprocity, --energy, --isotropy, --separable".into(),
        ));
    }
    let (input, _) = load(path, reduce_args, grid)?;
    let mut table = as_table(path, input, grid)?;
    let ks: Vec<usize> = steps
        .iter()
        .filter_map(|s| match s {
            Step::Separable(k, _) => Some(*k),
            _ => None,
        })
        .chain([1])
        .collect();
    let before = measure::report(&table, &ks, 1).map_err(|e| process_err(path, e))?;
    for s in steps {
        table = s.apply(&table).map_err(|e| process_err(path, e))?;
    }
    let after = measure::report(&table, &ks, 1).map_err(|e| process_err(path, e))?;
    // A last separable step with δ = 1 writes its factors when the output is TOML:
    // the compressed representation.
    let factors = match steps.last() {
        Some(Step::Separable(k, d))
            if *d == 1.0 && out.extension().is_some_and(|e| e == "toml") =>
        {
            Some(SeparableBrdf::from_table(&table, *k, true).map_err(|e| process_err(path, e))?)
        }
        _ => None,
    };
    match &factors {
        Some(f) => write_text(out, &f.to_toml())?,
        None => write_text(out, &file::write_table(&table))?,
    }
    let ratio = factors.as_ref().map(SeparableBrdf::storage_ratio);
    if json_out {
        return output::json(&json!({
            "out": out.display().to_string(),
            "steps": steps,
            "before": before,
            "after": after,
            "storage_ratio": ratio,
        }));
    }
    let mut w = output::open(None)?;
    output::finish((|| {
        writeln!(w, "{}: {} step(s) applied", out.display(), steps.len())?;
        let pair = |name: &str, b: &[f64], a: &[f64]| {
            format!(
                "{name:<8}{}",
                b.iter()
                    .zip(a)
                    .map(|(x, y)| format!("  {x:.4e} → {y:.4e}"))
                    .collect::<String>()
            )
        };
        writeln!(
            w,
            "{}",
            pair("P_r", &before.reciprocity, &after.reciprocity)
        )?;
        writeln!(
            w,
            "{}",
            pair("P_ec", &before.energy.p_ec, &after.energy.p_ec)
        )?;
        writeln!(w, "{}", pair("P_i", &before.isotropy, &after.isotropy))?;
        if let (Some(b), Some(a)) = (&before.separability, &after.separability) {
            for (j, k) in ks.iter().enumerate().take(ks.len() - 1) {
                let bv: Vec<f64> = b.iter().map(|s| s.p_s[j].1).collect();
                let av: Vec<f64> = a.iter().map(|s| s.p_s[j].1).collect();
                writeln!(w, "{}", pair(&format!("P_s^({k})"), &bv, &av))?;
            }
        }
        if let Some(r) = ratio {
            writeln!(
                w,
                "stored as {} factor values: {:.2}% of the table",
                factors.as_ref().map_or(0, SeparableBrdf::stored_values),
                100.0 * r
            )?;
        }
        w.flush()
    })())
}

/// `gonio harmonics INPUT --order L [--filter LF] --out SH.toml`.
pub fn harmonics(
    path: &Path,
    order: usize,
    filter: Option<usize>,
    out: &Path,
    grid: Option<(f64, f64)>,
    reduce_args: &ReduceArgs,
    json_out: bool,
) -> CliResult<()> {
    let (input, _) = load(path, reduce_args, grid)?;
    let table = as_table(path, input, grid)?;
    let opts = ShOptions {
        l_max: order,
        l_filter: filter,
        quadrature: None,
    };
    let sh = ShBrdf::from_table(&table, &opts).map_err(|e| process_err(path, e))?;
    let err = sh.error_against(&table).map_err(|e| process_err(path, e))?;
    write_text(out, &sh.to_toml())?;
    let ratio = sh.coefficient_count() as f64 / table.values.len() as f64;
    if json_out {
        return output::json(&json!({
            "out": out.display().to_string(),
            "order": order,
            "coefficients": sh.coefficient_count(),
            "storage_ratio": ratio,
            "rms": err.rms,
            "relative_rms": err.relative_rms,
            "max_abs": err.max_abs,
        }));
    }
    let mut w = output::open(None)?;
    output::finish((|| {
        writeln!(
            w,
            "{}: spherical harmonics to order {order}, {} coefficients ({:.2}% of the table), exactly reciprocal",
            out.display(),
            sh.coefficient_count(),
            100.0 * ratio
        )?;
        for (ch, name) in table.channels.names().iter().enumerate() {
            writeln!(
                w,
                "channel {name}: RMS error {:.4e} 1/sr ({:.2}% of the RMS value), max {:.4e} 1/sr",
                err.rms[ch],
                100.0 * err.relative_rms[ch],
                err.max_abs[ch]
            )?;
        }
        w.flush()
    })())
}

/// The correction steps in the order their flags appear on the command line: clap
/// keeps each flag's values in order but not the order across flags.
pub fn ordered_steps(
    raw: &[String],
    reciprocity: &[String],
    energy: &[String],
    isotropy: &[String],
    separable: &[String],
) -> CliResult<Vec<Step>> {
    let mut next = [0usize; 4];
    let mut steps = Vec::new();
    for a in raw {
        let which = ["--reciprocity", "--energy", "--isotropy", "--separable"]
            .iter()
            .position(|f| a == f || a.starts_with(&format!("{f}=")));
        let Some(k) = which else { continue };
        let lists = [reciprocity, energy, isotropy, separable];
        let Some(v) = lists[k].get(next[k]) else {
            continue;
        };
        next[k] += 1;
        let step = match k {
            0 => transform::parse_delta(v).map(Step::Reciprocity),
            1 => Step::parse_energy(v),
            2 => transform::parse_delta(v).map(Step::Isotropy),
            _ => Step::parse_separable(v),
        };
        let flag = ["--reciprocity", "--energy", "--isotropy", "--separable"][k];
        steps.push(step.map_err(|e| CliError::Input(format!("{flag}: {e}")))?);
    }
    Ok(steps)
}
