//! `gonio fit`: generalized cosine lobes fitted to a run, a table or samples, with a
//! report, and the comparison table of other models on the same data and metric.

use std::io::Write;
use std::path::{Path, PathBuf};

use gonio_fit::compare::{self, Kind};
use gonio_fit::{DataOptions, Diffuse, FitData, FitOptions, Metric, Objective, Shape, fit_lobes};
use serde_json::json;

use crate::error::{CliError, CliResult};
use crate::flags::{JsonFlag, ReduceFlags};
use crate::output;

/// `gonio fit`: sums of generalized cosine lobes (Lafortune et al. 1997) fitted by
/// Levenberg–Marquardt; writes the model file and reports parameters with standard
/// errors. `--compare` also fits Ward, Blinn-Phong and Cook–Torrance.
#[derive(clap::Args)]
pub struct FitArgs {
    /// The input: a run file, a table or sample CSV, a separable file.
    input: PathBuf,
    /// The model fitted: lafortune.
    #[arg(long, default_value = "lafortune")]
    model: String,
    /// Number of lobes.
    #[arg(long, default_value_t = 3)]
    lobes: usize,
    /// The diffuse term: lambert or minnaert.
    #[arg(long, default_value = "lambert")]
    diffuse: String,
    /// Let Cx and Cy differ.
    #[arg(long)]
    anisotropic: bool,
    /// The error measured: lafortune (f cos θi cos θo) or ngan (f cos θi).
    #[arg(long, default_value = "lafortune")]
    metric: String,
    /// Leave out pairs with θi or θo above this, degrees.
    #[arg(long, default_value_t = 90.0)]
    cutoff: f64,
    /// One set of exponents for all channels.
    #[arg(long)]
    share_exponents: bool,
    /// Hold the directional albedo ≤ 1 at every incident direction of the data (the
    /// constrained optimum; its active set and multipliers are reported).
    #[arg(long)]
    conserve_energy: bool,
    /// What is minimised: cosine (Lafortune et al. Sec. 6: the error times the
    /// metric's cosines), chi2 (the error over σ) or relative (the error over the value,
    /// floored at 1% of the channel's mean |value|). Default: chi2 when every sample has
    /// σ > 0, else cosine.
    #[arg(long)]
    objective: Option<String>,
    /// Ignore the samples' uncertainties: the same as --objective cosine.
    #[arg(long)]
    unweighted: bool,
    /// Also fit Ward, Blinn-Phong and Cook–Torrance on the same data and metric.
    #[arg(long)]
    compare: bool,
    /// The model file to write (TOML).
    #[arg(long)]
    out: Option<PathBuf>,
    #[command(flatten)]
    force: output::ForceFlag,
    #[command(flatten)]
    reduction: ReduceFlags,
    #[command(flatten)]
    json: JsonFlag,
}

/// The rows of a sample CSV that reads and validates cleanly, as columns; `None` for
/// anything else (a run, a table with a `# grid:` line, another format, a file with
/// faults), which goes through `gonio_dataset::open` and its errors. A fit needs the
/// rows, not a grid: the dataset's grid recognition and the table's samples back were
/// a third of `gonio fit`'s time on a 98 000-row CSV, and a `Sample` a row (two `Vec`s
/// each) most of its page faults (BENCHMARKS.md). The columns are parsed on every
/// core (`gonio_process::file::read_columns`) and go to the fit as they are.
fn plain_columns(path: &Path) -> Option<gonio_process::file::Columns> {
    let head = gonio_core::input::read_head(path, 64 << 10).ok()?;
    if gonio_dataset::detect(&head) != Some(gonio_dataset::Kind::Csv) {
        return None;
    }
    // Streamed from the file: the reader's one buffer is the only copy of the text.
    let file = std::fs::File::open(path).ok()?;
    let len = file.metadata().ok().filter(|m| m.is_file())?.len();
    let max = gonio_dataset::MAX_TEXT_BYTES;
    if len > max {
        return None;
    }
    let c =
        gonio_process::file::read_columns(std::io::Read::take(file, max), len, Some(path)).ok()?;
    (c.grid.is_none() && valid(&c)).then_some(c)
}

/// What `Samples::validate` asks of samples, asked of columns: rows within
/// `MAX_ROWS`, finite values, finite non-negative σ, directions in the upper
/// hemisphere. A file that fails is left to the dataset's reading, which names the
/// fault.
fn valid(c: &gonio_process::file::Columns) -> bool {
    let n = c.rows();
    let finite = |v: &Vec<f64>| v.iter().all(|x| x.is_finite());
    let [ti, pi, to, po] = &c.angles;
    n > 0
        && n <= gonio_process::file::MAX_ROWS
        && c.values.iter().all(finite)
        && c.sigma
            .as_ref()
            .is_none_or(|s| s.iter().flatten().all(|x| x.is_finite() && *x >= 0.0))
        && ti.iter().chain(to).all(|t| (0.0..=90.0).contains(t))
        && finite(pi)
        && finite(po)
}

/// The fit's view of a file's columns.
fn fit_columns(
    c: &gonio_process::file::Columns,
    opts: &DataOptions,
) -> Result<FitData, gonio_fit::FitError> {
    let values: Vec<&[f64]> = c.values.iter().map(Vec::as_slice).collect();
    let sigma: Option<Vec<&[f64]>> = c
        .sigma
        .as_ref()
        .map(|s| s.iter().map(Vec::as_slice).collect());
    let [theta_i, phi_i, theta_o, phi_o] = &c.angles;
    FitData::from_columns(
        &gonio_fit::Columns {
            channels: &c.roles.channels,
            theta_i,
            phi_i,
            theta_o,
            phi_o,
            values: &values,
            sigma: sigma.as_deref(),
        },
        opts,
    )
}

fn input_err(path: &Path, e: impl std::fmt::Display) -> CliError {
    CliError::Input(format!("{}: {e}", path.display()))
}

/// A fit as `gonio fit` makes it: the data fitted, the lobes, and the comparison
/// models when asked for.
pub(crate) struct Fitted {
    /// The data, as fitted.
    pub data: FitData,
    /// The lobes.
    pub fit: gonio_fit::LobeFit,
    /// Ward, Blinn-Phong and Cook–Torrance on the same data (`--compare`).
    pub comparison: Option<Vec<compare::Compared>>,
    /// The diffuse term.
    pub diffuse: Diffuse,
    /// The error measured.
    pub metric: Metric,
}

impl Fitted {
    /// The model file `--out` receives: a comment line saying how it was made, then
    /// the model.
    pub fn model_file(&self, a: &FitArgs) -> String {
        format!(
            "# gonio fit {}: {} lobe(s), {:?} diffuse, metric {:?}, objective {}, {} pairs\n{}",
            a.input.display(),
            a.lobes,
            self.diffuse,
            self.metric,
            self.data.objective.name(),
            self.data.len(),
            self.fit.model_toml
        )
    }

    /// The `--json` object.
    pub fn json(&self, a: &FitArgs) -> serde_json::Value {
        let mut v = json!({
            "out": a.out.as_ref().map(|p| p.display().to_string()),
            "fit": self.fit,
            "comparison": self.comparison,
            "cut_by_angle": self.data.cut,
        });
        // The channels' wavelengths (nm), in the order of `fit.channels`; only for
        // wavelength channels, so that other data's output stays as it was.
        if let (gonio_core::Channels::Wavelengths(w), Some(o)) =
            (&self.data.channels, v.as_object_mut())
        {
            o.insert("wavelengths_nm".into(), json!(w.to_vec()));
        }
        v
    }
}

/// The model and the lobe count, checked before anything else (the output, the
/// input).
fn check_model(a: &FitArgs) -> CliResult<()> {
    if a.model != "lafortune" {
        return Err(CliError::Input(format!(
            "--model: only `lafortune` lobes are fitted as the result (got {:?}); use --compare \
             for Ward, Blinn-Phong and Cook-Torrance",
            a.model
        )));
    }
    // Checked before the input is read: a bad count is refused at once.
    if a.lobes > gonio_fit::MAX_LOBES {
        return Err(CliError::Input(format!(
            "--lobes: must be at most {}, got {}",
            gonio_fit::MAX_LOBES,
            a.lobes
        )));
    }
    Ok(())
}

/// Fits the input (or `given`, samples already in memory that `a.input` names), as
/// `a` says; writes nothing.
/// What the flags choose, checked: the diffuse term, the metric, the objective.
struct Settings {
    diffuse: Diffuse,
    metric: Metric,
    objective: Option<Objective>,
}

/// Every flag checked (the input not read): a bad value is refused at once.
fn settings(a: &FitArgs) -> CliResult<Settings> {
    check_model(a)?;
    if !(a.cutoff > 0.0 && a.cutoff <= 90.0) {
        return Err(CliError::Input(format!(
            "--cutoff must lie in (0, 90] degrees, got {}",
            a.cutoff
        )));
    }
    let diffuse = match a.diffuse.as_str() {
        "lambert" => Diffuse::Lambert,
        "minnaert" => Diffuse::Minnaert,
        x => {
            return Err(CliError::Input(format!(
                "--diffuse: lambert or minnaert, got {x:?}"
            )));
        }
    };
    let metric = match a.metric.as_str() {
        "lafortune" => Metric::Lafortune,
        "ngan" => Metric::Ngan,
        x => {
            return Err(CliError::Input(format!(
                "--metric: lafortune or ngan, got {x:?}"
            )));
        }
    };
    let objective = match a.objective.as_deref() {
        None => None,
        Some(x) => Some(Objective::from_name(x).ok_or_else(|| {
            CliError::Input(format!("--objective: cosine, chi2 or relative, got {x:?}"))
        })?),
    };
    if a.unweighted && objective.is_some_and(|o| o != Objective::Cosine) {
        return Err(CliError::Input(
            "--unweighted is --objective cosine: it cannot be combined with another objective"
                .into(),
        ));
    }
    Ok(Settings {
        diffuse,
        metric,
        objective,
    })
}

/// Checks every flag's value, the reduction's included, without reading the input:
/// what a batch does before it starts any task.
pub(crate) fn check_values(a: &FitArgs) -> CliResult<()> {
    settings(a)?;
    a.reduction.options().map(drop)
}

pub(crate) fn compute(a: &FitArgs, given: Option<gonio_process::Samples>) -> CliResult<Fitted> {
    let Settings {
        diffuse,
        metric,
        objective,
    } = settings(a)?;
    let data_opts = DataOptions {
        metric,
        cutoff_deg: a.cutoff,
        use_sigma: !a.unweighted,
        objective,
    };
    let columns = if given.is_none() {
        plain_columns(&a.input)
    } else {
        None
    };
    let data = if let Some(c) = columns {
        let data = fit_columns(&c, &data_opts);
        // Not needed again, and the process ends with this command.
        std::mem::forget(c);
        data
    } else {
        let samples = match given {
            Some(s) => s,
            None => {
                let opened = gonio_dataset::open(&a.input, &a.reduction.open_options()?)?;
                // A MERL table is fitted on at most 200 000 of its valid bins (evenly
                // strided).
                opened.data.to_samples(200_000, &a.input)?
            }
        };
        let data = FitData::from_samples(&samples, &data_opts);
        // Freeing a sample's two small allocations one by one is milliseconds on a
        // 100 000-row input, and the process ends with this command.
        std::mem::forget(samples);
        data
    }
    .map_err(|e| input_err(&a.input, e))?;
    let opts = FitOptions {
        shape: Shape {
            lobes: a.lobes,
            anisotropic: a.anisotropic,
            diffuse,
        },
        share_exponents: a.share_exponents,
        conserve_energy: a.conserve_energy,
        ..FitOptions::default()
    };
    let fit = fit_lobes(&data, &opts).map_err(|e| {
        CliError::classify(
            matches!(e, gonio_fit::FitError::Options(_)),
            format!("{}: {e}", a.input.display()),
        )
    })?;
    let comparison = if a.compare {
        let mut rows = Vec::new();
        for k in Kind::ALL {
            rows.extend(
                compare::fit_model(k, &data)
                    .map_err(|e| CliError::Runtime(format!("{}: {e}", a.input.display())))?,
            );
        }
        Some(rows)
    } else {
        None
    };
    Ok(Fitted {
        data,
        fit,
        comparison,
        diffuse,
        metric,
    })
}

/// `gonio fit INPUT --model lafortune --lobes 3 … --out FIT.toml`.
pub fn run(a: FitArgs) -> CliResult<()> {
    check_model(&a)?;
    if a.out.is_none() && !a.compare {
        return Err(CliError::Input("give --out FIT.toml (or --compare)".into()));
    }
    let target = a
        .out
        .as_deref()
        .map(|p| output::Target::new(p, a.force.force))
        .transpose()?;
    let fitted = compute(&a, None)?;
    if let Some(target) = &target {
        target.write(fitted.model_file(&a).as_bytes())?;
    }
    if a.json.json {
        return output::json(&fitted.json(&a));
    }
    let mut w = output::stdout();
    output::finish(write_report(&mut w, &a, &fitted))
}

/// The text `gonio fit` prints.
pub(crate) fn write_report(w: &mut dyn Write, a: &FitArgs, f: &Fitted) -> std::io::Result<()> {
    let Fitted {
        data,
        fit,
        comparison,
        diffuse,
        metric,
    } = f;
    let (diffuse, metric) = (*diffuse, *metric);
    writeln!(
        w,
        "{}: {} pairs ({} above the {}° cutoff left out), {} fit, metric {:?}",
        a.input.display(),
        data.len(),
        data.cut,
        a.cutoff,
        if data.chi_square {
            "χ² (1/σ weights)"
        } else {
            "unweighted"
        },
        metric
    )?;
    writeln!(
        w,
        "objective {} ({}): minimises the {}",
        fit.objective.name, fit.objective.chosen, fit.objective.formula
    )?;
    for c in &fit.channels {
        write_channel(w, c, diffuse)?;
    }
    writeln!(
        w,
        "{} evaluations, {:.3} s; largest directional albedo {:.4}{}",
        fit.evaluations,
        fit.seconds,
        fit.max_albedo,
        match (&fit.energy, fit.max_albedo > 1.0) {
            (None, true) => " — exceeds 1: --conserve-energy fits under albedo ≤ 1",
            (Some(_), true) => {
                " — above 1 beyond the data's incident directions, which the constraint holds"
            }
            _ => "",
        }
    )?;
    if let Some(e) = &fit.energy {
        write_energy(w, e)?;
    }
    if let Some(out) = &a.out {
        writeln!(w, "model: {}", out.display())?;
    }
    if let Some(rows) = &comparison {
        write_comparison(w, a, fit, rows)?;
    }
    w.flush()
}

/// One channel's lines: its errors, the diffuse term, each lobe with its standard
/// errors, and the relative error by incidence angle.
fn write_channel(
    w: &mut dyn Write,
    c: &gonio_fit::fit::ChannelFit,
    diffuse: Diffuse,
) -> std::io::Result<()> {
    writeln!(
        w,
        "channel {}: RMS {:.4e} 1/sr ({:.3}% of the data's RMS), reduced χ² {:.3}",
        c.channel,
        c.rms,
        100.0 * c.relative_rms,
        c.reduced_chi2
    )?;
    writeln!(
        w,
        "  diffuse ρd = {:.6} ± {:.2e}",
        c.params.rho_d, c.std_err.rho_d
    )?;
    if diffuse == Diffuse::Minnaert {
        writeln!(w, "  Minnaert m = {:.4} ± {:.2e}", c.params.m, c.std_err.m)?;
    }
    for (j, (l, s)) in c.params.lobes.iter().zip(&c.std_err.lobes).enumerate() {
        writeln!(
            w,
            "  lobe {}: Cx {:+.5} ± {:.1e}  Cy {:+.5} ± {:.1e}  Cz {:+.5} ± {:.1e}  n {:.4} ± {:.1e}",
            j + 1,
            l[0],
            s[0],
            l[1],
            s[1],
            l[2],
            s[2],
            l[3],
            s[3]
        )?;
    }
    let per: Vec<String> = c
        .per_theta_i
        .iter()
        .map(|(t, _, rel)| format!("{t:.0}°: {:.2}%", 100.0 * rel))
        .collect();
    writeln!(w, "  relative error by θi: {}", per.join(", "))?;
    Ok(())
}

/// The energy constraint's account: where albedo ≤ 1 was held, and per channel
/// the largest albedo and objective with and without it, and the active limits.
fn write_energy(w: &mut dyn Write, e: &gonio_fit::fit::EnergyReport) -> std::io::Result<()> {
    writeln!(
        w,
        "energy: directional albedo ≤ 1 at the data's {} incident directions — {}",
        e.directions,
        if e.constrained {
            "the constrained optimum"
        } else {
            "the unconstrained optimum already meets it, unchanged"
        }
    )?;
    for c in &e.channels {
        writeln!(
            w,
            "  channel {}: largest albedo {:.6} (unconstrained {:.6}); objective {:.6e} \
                 (unconstrained {:.6e}); active: {}",
            c.channel,
            c.max_albedo,
            c.unconstrained_max_albedo,
            c.cost,
            c.unconstrained_cost,
            if c.active.is_empty() {
                "none".to_string()
            } else {
                c.active
                    .iter()
                    .map(|x| {
                        format!(
                            "θi {:.2}° φi {:.1}° (albedo {:.6}, multiplier {:.4e})",
                            x.theta_i_deg, x.phi_i_deg, x.albedo, x.multiplier
                        )
                    })
                    .collect::<Vec<_>>()
                    .join(", ")
            }
        )?;
    }
    Ok(())
}

/// The comparison table (`--compare`): relative RMS per channel, the lobes' then
/// each other model's.
fn write_comparison(
    w: &mut dyn Write,
    a: &FitArgs,
    fit: &gonio_fit::LobeFit,
    rows: &[compare::Compared],
) -> std::io::Result<()> {
    writeln!(
        w,
        "\nthe same data, the same metric (relative RMS per channel):"
    )?;
    writeln!(
        w,
        "{:<28}{}",
        "model",
        fit.channels
            .iter()
            .map(|c| format!("{:>12}", c.channel))
            .collect::<String>()
    )?;
    writeln!(
        w,
        "{:<28}{}",
        format!("Lafortune, {} lobe(s)", a.lobes),
        fit.channels
            .iter()
            .map(|c| format!("{:>11.3}%", 100.0 * c.relative_rms))
            .collect::<String>()
    )?;
    for k in Kind::ALL {
        let v: String = rows
            .iter()
            .filter(|r| r.model == k.name())
            .map(|r| format!("{:>11.3}%", 100.0 * r.relative_rms))
            .collect();
        writeln!(w, "{:<28}{v}", k.name())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sample file of `rows` rows with comments in its header and in its body.
    fn text(rows: usize, newline: &str) -> String {
        let mut t = format!(
            "# isotropic: true{newline}# note: x{newline}\
             theta_i,phi_i,theta_o,phi_o,R,G,B,sigma_R,sigma_G,sigma_B{newline}"
        );
        for i in 0..rows {
            if i == rows / 2 {
                t.push_str(&format!("# a comment in the body{newline}"));
            }
            t.push_str(&format!(
                "{},0,{},{},{},{},0.3,0.01,0.02,0.03{newline}",
                (i % 80) as f64,
                (i / 80 % 89) as f64,
                (i % 360) as f64,
                0.1 + i as f64 * 1e-6,
                0.2 - i as f64 * 1e-6
            ));
        }
        t
    }

    #[test]
    fn the_columns_give_the_data_the_samples_give() {
        let dir = std::env::temp_dir().join(format!("gonio-fit-columns-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("s.csv");
        let opts = DataOptions {
            metric: Metric::Lafortune,
            cutoff_deg: 80.0,
            use_sigma: true,
            objective: None,
        };
        for nl in ["\n", "\r\n"] {
            for rows in [30_001, 100] {
                let t = text(rows, nl);
                std::fs::write(&path, &t).expect("write");
                let samples = match gonio_process::file::read(&t, Some(&path)).expect("reads") {
                    gonio_process::file::Content::Samples(s) => s,
                    gonio_process::file::Content::Table(_) => panic!("samples"),
                };
                let c = plain_columns(&path).expect("columns");
                assert!(c.isotropic && c.rows() == rows);
                let (a, b) = (
                    fit_columns(&c, &opts).expect("fits"),
                    FitData::from_samples(&samples, &opts).expect("fits"),
                );
                assert_eq!((a.y, a.weight, a.wi, a.wo), (b.y, b.weight, b.wi, b.wo));
            }
        }
        // A fault is left to the dataset's reading, which names it.
        let t = text(300, "\n");
        let row = t.lines().nth(3 + 100).expect("a row").to_string();
        for bad in [
            row.replace("0.03", "x"),
            row.replace("0.03", "-0.03"),
            format!("95{}", &row[row.find(',').expect("comma")..]),
        ] {
            std::fs::write(&path, t.replacen(&row, &bad, 1)).expect("write");
            assert!(plain_columns(&path).is_none(), "{bad}");
        }
        // A table is not read as rows.
        std::fs::write(
            &path,
            format!("# grid: isotropic=false phi_i=0:90:1 theta_i=0:45:1 phi_o=0:90:1 theta_o=0:45:2\n{t}"),
        )
        .expect("write");
        assert!(plain_columns(&path).is_none());
        std::fs::remove_dir_all(&dir).expect("clean");
    }
}
