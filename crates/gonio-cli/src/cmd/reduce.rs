//! `gonio reduce`: a run's readings to BRDF samples with uncertainties (DeYoung Eq.
//! A.15, or relative to the run's reference standard), drift-corrected.

use std::io::Write;
use std::path::{Path, PathBuf};

use gonio_dataset::Kind;
use gonio_process::file::Content;
use gonio_process::samples::{InterpolationReport, Kernel};
use gonio_reduce::Reduction;
use serde_json::json;

use crate::csvout::CsvTarget;
use crate::error::{CliError, CliResult};
use crate::flags::{GridFlag, JsonFlag, ReduceFlags};
use crate::output;

/// `gonio reduce`: writes a table when the samples form a grid, else the samples
/// (CSV).
#[derive(clap::Args)]
pub struct ReduceArgs {
    /// The run file.
    run: PathBuf,
    /// The table or sample file to write (CSV).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    force: output::ForceFlag,
    #[command(flatten)]
    reduction: ReduceFlags,
    #[command(flatten)]
    grid: GridFlag,
    #[command(flatten)]
    json: JsonFlag,
    /// Write the long-form CSV: a row per pair per wavelength, with its σ
    /// (`theta_i_deg,…,wavelength_nm,f_r_per_sr,sigma_per_sr`); wavelength channels
    /// only.
    #[arg(long)]
    long: bool,
    /// The reference standard's relative standard uncertainty (its certificate's),
    /// carried as the budget's `standard` term when the standard calibrates.
    #[arg(long, value_name = "REL", default_value_t = 0.0)]
    standard_sigma: f64,
}

/// The first bytes of a file, for recognising its kind; a FIFO, a device or a
/// directory is refused without being opened.
pub fn head(path: &Path) -> CliResult<Vec<u8>> {
    gonio_core::input::read_head(path, 64 * 1024).map_err(|e| CliError::Input(e.to_string()))
}

pub(crate) fn reduction_json(r: &Reduction) -> serde_json::Value {
    let mut v = serde_json::to_value(&r.report).unwrap_or_default();
    if let Some(o) = v.as_object_mut() {
        o.insert(
            "covariance".into(),
            serde_json::to_value(&r.covariance).unwrap_or_default(),
        );
    }
    v
}

impl ReduceArgs {
    /// Whether `--grid` resamples the samples (the table's nodes are not samples).
    pub(crate) fn resampled(&self) -> bool {
        self.grid.grid.is_some()
    }
}

/// The sidecar `gonio reduce` writes beside the wide CSV of `content`: with the
/// reduction's covariance, unless `resampled` (a `--grid` table's nodes are not the
/// samples the covariance's rows are).
pub(crate) fn sidecar(
    red: &Reduction,
    content: &Content,
    resampled: bool,
) -> gonio_process::file::Meta {
    let mut meta = match content {
        Content::Table(t) => gonio_process::file::Meta::for_table(t),
        Content::Samples(s) => gonio_process::file::Meta::for_samples(s),
    };
    if !resampled {
        meta.covariance = Some(red.covariance.clone());
    }
    meta
}

/// A simulated run against the sample the simulator measured (the run file keeps
/// it): per channel, χ² per sample and against the full covariance, and the shared
/// errors' shifts ([`gonio_reduce::agreement`]). `None` for a laboratory run, or
/// one whose simulated sample is not a model file.
pub(crate) fn agreement(
    run: &Path,
    red: &Reduction,
) -> Option<Vec<gonio_process::covariance::Agreement>> {
    let store = gonio_run::RunStore::open(run).ok()?;
    let meta = store.run_meta().ok()?;
    let model = gonio_reduce::agreement::simulated_sample(meta.sim_sample.as_deref())?;
    let truth = gonio_reduce::agreement::truth(red, &model)?;
    Some(gonio_reduce::agreement::agreements(red, &truth))
}

/// The agreement's `--json` form: each channel's numbers, the shifts named.
pub(crate) fn agreement_json(
    red: &Reduction,
    a: &[gonio_process::covariance::Agreement],
) -> serde_json::Value {
    a.iter()
        .map(|x| {
            json!({
                "channel": red.samples.channels.name(x.channel),
                "samples": x.n,
                "chi2_per_sample": x.chi2_plain,
                "chi2_full_covariance": x.chi2_full,
                "mean_z": x.mean_z,
                "shared_fraction": x.shared_fraction,
                "shifts": x.shifts.iter().map(|(s, e)| json!({
                    "source": red.covariance.sources[*s].label,
                    "term": red.covariance.sources[*s].term,
                    "sigmas": e,
                })).collect::<Vec<_>>(),
            })
        })
        .collect()
}

/// Writes what a simulated run's agreement with its truth says, a line a channel.
pub(crate) fn print_agreement(
    w: &mut dyn Write,
    red: &Reduction,
    a: &[gonio_process::covariance::Agreement],
) -> std::io::Result<()> {
    for x in a {
        let shifts: Vec<String> = x
            .shifts
            .iter()
            .take(2)
            .map(|(s, e)| format!("{} {e:+.2}σ", red.covariance.sources[*s].label))
            .collect();
        writeln!(
            w,
            "against the simulated sample, channel {}: χ²/n {:.3} with the full covariance \
             ({:.3} per sample), mean z {:+.2} (its shared terms allow ±{:.2}); moved most by {}",
            red.samples.channels.name(x.channel),
            x.chi2_full,
            x.chi2_plain,
            x.mean_z,
            2.5 * x.shared_fraction,
            if shifts.is_empty() {
                "nothing shared".to_string()
            } else {
                shifts.join(", ")
            }
        )?;
    }
    Ok(())
}

/// Checks every flag's value without reading the run: what a batch does before it
/// starts any task.
pub(crate) fn check_values(a: &ReduceArgs) -> CliResult<()> {
    if !(0.0..=1.0).contains(&a.standard_sigma) {
        return Err(CliError::Input(format!(
            "--standard-sigma {}: must be a relative uncertainty in [0, 1]",
            a.standard_sigma
        )));
    }
    a.reduction.options().map(drop)
}

/// A run reduced as `gonio reduce` reduces it: the reduction, what it writes (a table
/// when the samples form a grid or `--grid` asks for one, else the samples), and with
/// `--grid` the resampling's noise and interpolation error.
pub(crate) fn compute(
    a: &ReduceArgs,
) -> CliResult<(Reduction, Content, Option<InterpolationReport>)> {
    let (path, grid) = (a.run.as_path(), a.grid.grid);
    if gonio_dataset::detect(&head(path)?) != Some(Kind::Run) {
        return Err(CliError::Input(format!(
            "{}: not a run file (.gonio, SQLite)",
            path.display()
        )));
    }
    check_values(a)?;
    let mut options = a.reduction.open_options()?;
    options.reduce.standard_rel_sigma = a.standard_sigma;
    let opened = gonio_dataset::open(path, &options)?;
    let Some(red) = opened.reduction else {
        return Err(CliError::Runtime(format!(
            "{}: not reduced",
            path.display()
        )));
    };
    let (content, interpolation) = match (red.samples.to_table(), grid) {
        (Some(t), None) => (Content::Table(t), None),
        (_, Some(g)) => {
            let r = red
                .samples
                .resample_step_detailed(g, Kernel::default())
                .map_err(|e| CliError::process(path, e))?;
            let report = r.report();
            (Content::Table(r.table), Some(report))
        }
        (None, None) => (Content::Samples(red.samples.clone()), None),
    };
    Ok((red, content, interpolation))
}

/// The resampling's account for `--json`: the nodes interpolated and on a sample,
/// and per channel the relative interpolation error beside the relative noise.
fn interpolation_json(r: &InterpolationReport) -> serde_json::Value {
    serde_json::to_value(r).unwrap_or_default()
}

/// The resampling's account in text: the interpolation error stated apart from the
/// noise (the table's σ is the two in quadrature).
fn print_interpolation(w: &mut dyn Write, r: &InterpolationReport) -> std::io::Result<()> {
    writeln!(
        w,
        "resampled onto {} nodes: {} interpolated, {} on a sample (there σ is the noise alone)",
        r.nodes, r.interpolated, r.exact
    )?;
    for c in &r.channels {
        let noise = match (c.noise_rel_median, c.noise_rel_max) {
            (Some(m), Some(x)) => format!("σ noise rel. median {m:.2e}, max {x:.2e}"),
            _ => "σ noise unknown".into(),
        };
        writeln!(
            w,
            "  channel {}: σ interpolation rel. median {:.2e}, max {:.2e}; {noise}; \
             the table's σ is the two in quadrature",
            c.channel, c.rel_median, c.rel_max
        )?;
    }
    Ok(())
}

/// `gonio reduce RUN --out TABLE`.
pub fn run(a: ReduceArgs) -> CliResult<()> {
    let (out, grid, json_out) = (a.out.as_path(), a.grid.grid, a.json.json);
    let target = CsvTarget::new(out, a.force.force)?;
    let (red, content, interpolation) = compute(&a)?;
    let what = match (&content, grid) {
        _ if a.long => {
            let data = match &content {
                Content::Table(t) => gonio_io::formats::Data::Table(t.clone()),
                Content::Samples(s) => gonio_io::formats::Data::Samples(s.clone()),
            };
            let bad = |e: gonio_io::formats::FormatError| CliError::Input(e.to_string());
            let text = gonio_io::formats::write_long(&data).map_err(bad)?;
            target.write(
                text.as_bytes(),
                &gonio_io::formats::long_meta(&data).map_err(bad)?,
            )?;
            format!(
                "{} rows (long form, {} wavelengths)",
                text.lines().count() - 1,
                data.channels().len()
            )
        }
        (Content::Table(t), None) => {
            let meta = sidecar(&red, &content, false);
            target.write(gonio_process::file::write_table(t).as_bytes(), &meta)?;
            format!("a table of {} nodes", t.grid.len())
        }
        (Content::Table(t), Some(_)) => {
            target.write_table(t)?;
            format!("a table of {} nodes (resampled)", t.grid.len())
        }
        (Content::Samples(s), _) => {
            target.write_samples(s, Some(&red.covariance))?;
            format!("{} samples", s.samples.len())
        }
    };
    if json_out {
        let mut v = json!({
            "out": out.display().to_string(),
            "wrote": what,
            "samples": red.samples.samples.len(),
            "channels": red.samples.channels.names(),
            "reduction": reduction_json(&red),
        });
        if let (Some(a), Some(o)) = (agreement(&a.run, &red), v.as_object_mut()) {
            o.insert("agreement".into(), agreement_json(&red, &a));
        }
        // The channels' wavelengths (nm), in the order of `channels`; only for
        // wavelength channels, so that other runs' output stays as it was.
        if let (gonio_core::Channels::Wavelengths(w), Some(o)) =
            (&red.samples.channels, v.as_object_mut())
        {
            o.insert("wavelengths_nm".into(), json!(w.to_vec()));
        }
        // With `--grid` only, so that other runs' output stays as it was.
        if let (Some(r), Some(o)) = (&interpolation, v.as_object_mut()) {
            o.insert("interpolation".into(), interpolation_json(r));
        }
        return output::json(&v);
    }
    let mut w = output::stdout();
    output::finish((|| {
        writeln!(
            w,
            "{}: {} from {} samples",
            out.display(),
            what,
            red.samples.samples.len()
        )?;
        print_reduction(&mut w, &red)?;
        if let Some(ag) = agreement(&a.run, &red) {
            print_agreement(&mut w, &red, &ag)?;
        }
        if let Some(r) = &interpolation {
            print_interpolation(&mut w, r)?;
        }
        w.flush()
    })())
}

pub fn print_reduction(w: &mut dyn Write, red: &Reduction) -> std::io::Result<()> {
    let r = &red.report;
    writeln!(w, "detector solid angle {:.4e} sr", r.solid_angle_sr)?;
    for c in &r.channels {
        writeln!(
            w,
            "channel {}: {} calibration ({} readings), incident {:.6e} {} ± {:.2e} (rel.), dark ({:.2e}, {:.2e}) {}, drift {} references, max |g−1| {:.3}%",
            c.channel,
            c.calibration,
            c.calibration_readings,
            c.incident_v,
            c.unit,
            c.incident_rel_sigma,
            c.dark_v[0],
            c.dark_v[1],
            c.unit,
            c.drift_readings,
            100.0 * c.drift_max
        )?;
        for t in &c.budget {
            writeln!(
                w,
                "  σ {:<11} rel. median {:.2e}, max {:.2e} ({}): {}",
                t.term, t.rel_median, t.rel_max, t.correlation, t.source
            )?;
        }
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
