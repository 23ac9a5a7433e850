//! `gonio model eval` and `gonio model albedo`.

use std::io::Write;
use std::path::{Path, PathBuf};

use gonio_brdf::{Brdf, Model};
use gonio_core::dirfile::{self, PairDeg};
use gonio_core::{Dir, SphericalDeg};
use serde_json::json;

use crate::error::{CliError, CliResult};
use crate::flags::JsonFlag;
use crate::output;

/// `gonio model`: evaluate and integrate analytic BRDF model files.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Evaluate a model at the direction pairs of a CSV file
    /// (`theta_i,phi_i,theta_o,phi_o`, degrees, or with `_deg`); writes the pairs
    /// (`theta_i_deg,…`) with one column a channel, in 1/sr (`f_r_<channel>_per_sr`).
    Eval(EvalArgs),
    /// Directional–hemispherical reflectance ρ(θi) per channel.
    Albedo(AlbedoArgs),
}

/// `gonio model eval`.
#[derive(clap::Args)]
pub struct EvalArgs {
    /// The model file (TOML).
    model: PathBuf,
    /// The directions file (CSV).
    dirs: PathBuf,
    /// Write the CSV here instead of stdout.
    #[arg(long)]
    out: Option<PathBuf>,
    #[command(flatten)]
    force: output::ForceFlag,
    #[command(flatten)]
    json: JsonFlag,
}

/// `gonio model albedo`.
#[derive(clap::Args)]
pub struct AlbedoArgs {
    /// The model file (TOML).
    model: PathBuf,
    /// Incident polar angles in degrees, comma-separated, each in [0, 90].
    #[arg(long, value_delimiter = ',', default_value = "0,15,30,45,60,75,85",
          value_parser = parse_theta)]
    theta_i: Vec<f64>,
    /// Incident azimuth in degrees (matters for anisotropic models).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    phi_i: f64,
    #[command(flatten)]
    json: JsonFlag,
}

/// Runs `gonio model …`.
pub fn run(c: Command) -> CliResult<()> {
    match c {
        Command::Eval(a) => {
            let out = a
                .out
                .as_deref()
                .map(|p| output::Target::new(p, a.force.force))
                .transpose()?;
            eval(&a.model, &a.dirs, out, a.json.json)
        }
        Command::Albedo(a) => {
            PHI_I
                .check(a.phi_i)
                .map_err(|m| CliError::Input(format!("--phi-i: {m}")))?;
            albedo(&a.model, &a.theta_i, a.phi_i, a.json.json)
        }
    }
}

/// `--phi-i`: a turn either way, degrees.
const PHI_I: gonio_core::limits::Range = gonio_core::limits::Range::closed(-360.0, 360.0, "deg");

/// Parses one `--theta-i` value: degrees in [0, 90].
pub fn parse_theta(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a number of degrees"))?;
    if (0.0..=90.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} is outside [0, 90] degrees"))
    }
}

fn read_pairs(path: &Path) -> CliResult<Vec<PairDeg>> {
    let text = gonio_core::input::read_text(path, dirfile::MAX_BYTES)
        .map_err(|e| CliError::Input(e.to_string()))?;
    dirfile::read_pairs(&text).map_err(|e| {
        let field = e
            .column
            .as_ref()
            .map(|c| format!("field `{c}`: "))
            .unwrap_or_default();
        CliError::Input(format!(
            "{}:{}: {field}{}",
            path.display(),
            e.line,
            e.message
        ))
    })
}

/// `gonio model eval MODEL DIRS [--out FILE] [--json]`.
fn eval(
    model_path: &Path,
    dirs_path: &Path,
    out: Option<output::Target>,
    json: bool,
) -> CliResult<()> {
    let model = Model::load(model_path)?;
    let pairs = read_pairs(dirs_path)?;
    let ch = model.channels().clone();
    let mut values = vec![0.0; ch.len()];
    if json {
        let rows: Vec<_> = pairs
            .iter()
            .map(|p| {
                let d = p.to_dirs();
                model.eval(d.wi, d.wo, &mut values);
                json!({
                    "theta_i": p.incident.theta_deg, "phi_i": p.incident.phi_deg,
                    "theta_o": p.outgoing.theta_deg, "phi_o": p.outgoing.phi_deg,
                    "values": values,
                })
            })
            .collect();
        return output::json(&json!({
            "model": model_path.display().to_string(),
            "kind": model.kind().name(),
            "channels": ch.names(),
            "unit": "1/sr",
            "rows": rows,
        }));
    }
    let mut w = output::Sink::new(out);
    let r = (|| {
        writeln!(w, "{}", dirfile::eval_header(&ch))?;
        for p in &pairs {
            let d = p.to_dirs();
            model.eval(d.wi, d.wo, &mut values);
            writeln!(w, "{}", dirfile::eval_row(p, &values))?;
        }
        Ok(())
    })();
    w.finish(r)
}

/// `gonio model albedo MODEL [--theta-i LIST] [--phi-i DEG] [--json]`.
fn albedo(model_path: &Path, thetas: &[f64], phi_i: f64, json: bool) -> CliResult<()> {
    if !phi_i.is_finite() {
        return Err(CliError::Input(format!(
            "--phi-i: {phi_i} is not a finite angle"
        )));
    }
    let model = Model::load(model_path)?;
    let ch = model.channels().clone();
    let rows: Vec<(f64, Vec<f64>)> = thetas
        .iter()
        .map(|t| {
            let mut a = vec![0.0; ch.len()];
            model.albedo(Dir::from(SphericalDeg::new(*t, phi_i)), &mut a);
            (*t, a)
        })
        .collect();
    if json {
        let rows: Vec<_> = rows
            .iter()
            .map(|(t, a)| json!({"theta_i": t, "values": a}))
            .collect();
        return output::json(&json!({
            "model": model_path.display().to_string(),
            "kind": model.kind().name(),
            "channels": ch.names(),
            "phi_i": phi_i,
            "albedo": rows,
        }));
    }
    let mut w = output::stdout();
    output::finish((|| {
        writeln!(
            w,
            "# directional albedo of {} ({}), phi_i = {phi_i} deg",
            model_path.display(),
            model.kind().name()
        )?;
        write!(w, "{:>8}", "theta_i")?;
        for n in ch.names() {
            write!(w, " {n:>12}")?;
        }
        writeln!(w)?;
        for (t, a) in &rows {
            write!(w, "{t:>8}")?;
            for v in a {
                write!(w, " {v:>12.8}")?;
            }
            writeln!(w)?;
        }
        w.flush()
    })())
}
