//! `gonio export`: a run, table, samples or model in the formats other tools read.

use std::io::Write;
use std::path::{Path, PathBuf};

use gonio_dataset::Dataset;
use gonio_io::formats::{self, Format};
use serde_json::json;

use crate::csvout::CsvTarget;
use crate::error::{CliError, CliResult};
use crate::flags::{JsonFlag, ReduceFlags};
use crate::output;

/// `gonio export`: write a run, table, samples or model as MERL binary, ASTM E1392
/// text, CSV or an RGL material (`.bsdf`, Mitsuba 3's `measured`).
#[derive(clap::Args)]
pub struct ExportArgs {
    /// The input.
    input: PathBuf,
    /// merl, astm, csv, csv-long (a row per pair per wavelength: wavelength
    /// channels only) or rgl (the RGL material `.bsdf` Mitsuba 3 renders).
    #[arg(long)]
    format: String,
    /// rgl: incidence angles θi, from 0° to 85°.
    #[arg(long, default_value_t = 8, value_name = "N")]
    rgl_incidences: usize,
    /// rgl: nodes a side of each incidence's sample square (the RGL database has 32
    /// or 64).
    #[arg(long, default_value_t = 32, value_name = "N")]
    rgl_slice: usize,
    /// rgl: nodes a side of each incidence's VNDF.
    #[arg(long, default_value_t = 128, value_name = "N")]
    rgl_vndf: usize,
    /// The file to write.
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    force: output::ForceFlag,
    #[command(flatten)]
    reduction: ReduceFlags,
    /// How wavelength channels become R, G, B for MERL (`docs/colour.md`).
    #[command(flatten)]
    colour: crate::cmd::colour::ConditionFlags,
    #[command(flatten)]
    json: JsonFlag,
}

/// What `gonio export` makes of its input: the file's bytes, and its sidecar for a
/// CSV.
pub(crate) struct Exported {
    /// The file's contents.
    pub bytes: Vec<u8>,
    /// The CSV's sidecar (`PATH.json`); `None` for MERL and ASTM.
    pub sidecar: Option<gonio_process::file::Meta>,
    format: Format,
    from: &'static str,
    symmetry: Option<gonio_process::hemisphere::Symmetry>,
    colour: Option<String>,
    rgl: Option<gonio_io::formats::rgl::InterpolationError>,
}

impl Exported {
    /// The `--json` object; `out` is where the file was written.
    pub(crate) fn json(&self, out: Option<&Path>) -> serde_json::Value {
        let mut v = serde_json::Map::new();
        if let Some(out) = out {
            v.insert("out".into(), json!(out.display().to_string()));
        }
        for (k, x) in [
            ("format", json!(self.format.name())),
            ("from", json!(self.from)),
            ("bytes", json!(self.bytes.len())),
            ("symmetry", json!(self.symmetry.map(|s| s.name()))),
            ("colour", json!(self.colour)),
        ] {
            v.insert(k.into(), x);
        }
        if let Some(r) = &self.rgl {
            v.insert(
                "interpolation".into(),
                json!({
                    "at_nodes": r.at_nodes,
                    "between": r.between,
                    "theta_max_deg": r.theta_max_deg,
                }),
            );
        }
        serde_json::Value::Object(v)
    }
}

impl Exported {
    /// An RGL material made from `from`, with its interpolation error when it was
    /// resampled.
    fn rgl(
        r: &gonio_io::formats::RglBsdf,
        from: &Dataset,
        err: Option<gonio_io::formats::rgl::InterpolationError>,
    ) -> Exported {
        Exported {
            bytes: r.to_bytes(),
            sidecar: None,
            format: Format::Rgl,
            from: from.describe(),
            symmetry: None,
            colour: None,
            rgl: err,
        }
    }
}

/// Where `gonio export` writes: a file, or a CSV and its sidecar.
pub(crate) enum ExportTarget {
    /// MERL or ASTM.
    File(output::Target),
    /// A CSV and its sidecar.
    Csv(CsvTarget),
}

impl ExportTarget {
    /// Checks `a.out` (and a CSV's sidecar) before any work, as [`output::Target`].
    pub(crate) fn new(a: &ExportArgs) -> CliResult<ExportTarget> {
        Ok(match format_of(a)? {
            Format::Csv | Format::CsvLong => {
                ExportTarget::Csv(CsvTarget::new(&a.out, a.force.force)?)
            }
            _ => ExportTarget::File(output::Target::new(&a.out, a.force.force)?),
        })
    }

    /// Writes what [`compute`] made.
    pub(crate) fn write(&self, e: &Exported) -> CliResult<()> {
        match (self, &e.sidecar) {
            (ExportTarget::Csv(csv), Some(meta)) => csv.write(&e.bytes, meta),
            (ExportTarget::File(t), _) => t.write(&e.bytes),
            (ExportTarget::Csv(csv), None) => Err(CliError::Runtime(format!(
                "{}: a CSV without its sidecar",
                csv.path().display()
            ))),
        }
    }
}

/// The format `--format` names.
fn format_of(a: &ExportArgs) -> CliResult<Format> {
    Format::from_name(&a.format).ok_or_else(|| {
        CliError::Input(format!(
            "--format: merl, astm, csv, csv-long or rgl, got {:?}",
            a.format
        ))
    })
}

/// The file `gonio export` writes, made from its input or from `given` (data already
/// in memory, which the input word then only names in messages). Writes nothing.
pub(crate) fn compute(a: &ExportArgs, given: Option<Dataset>) -> CliResult<Exported> {
    let input = a.input.as_path();
    let colour = a.colour.conversion()?;
    let format = format_of(a)?;
    let dataset = crate::cmd::open_data(input, &a.reduction, given)?;
    if matches!(format, Format::Rgl) {
        return rgl(a, &dataset);
    }
    let mut data = dataset.to_format_data(input)?;
    // MERL holds R, G, B: wavelength channels go through the colour conversion.
    let mut converted = None;
    if matches!(format, Format::Merl)
        && matches!(data.channels(), gonio_core::Channels::Wavelengths(_))
    {
        data = gonio_io::rgb::to_rgb(&data, &colour)
            .map_err(|e| CliError::Input(format!("{}: {e}", input.display())))?;
        converted = Some(colour.describe());
    }
    // A MERL table fills the whole hemisphere: a half turn of an isotropic material
    // is unfolded into it (bilateral symmetry). CSV and ASTM keep the samples as
    // measured.
    let mut symmetry = None;
    if matches!(format, Format::Merl)
        && let formats::Data::Samples(s) = &data
    {
        let (u, sym) = gonio_process::hemisphere::unfold(s);
        symmetry = Some(sym);
        data = formats::Data::Samples(u);
    }
    let bytes = formats::write(format, &data).map_err(|e| CliError::Input(e.to_string()))?;
    let sidecar = match format {
        Format::CsvLong => {
            Some(formats::long_meta(&data).map_err(|e| CliError::Input(e.to_string()))?)
        }
        Format::Csv => Some(formats::csv_meta(&data)),
        _ => None,
    };
    Ok(Exported {
        bytes,
        sidecar,
        format,
        from: data.kind(),
        symmetry,
        colour: converted,
        rgl: None,
    })
}

/// The RGL material of the input: a BRDF evaluated exactly at the format's nodes,
/// a table (samples tabulated on their own grid first) through its interpolation,
/// with the nodes beyond the table's θ marked not valid; an RGL material as it is.
fn rgl(a: &ExportArgs, dataset: &Dataset) -> CliResult<Exported> {
    let input = a.input.as_path();
    // An RGL material is written as it was read: resampling it would only lose.
    if let Dataset::Rgl(r) = dataset {
        return Ok(Exported::rgl(r, dataset, None));
    }
    let opts = gonio_io::formats::RglOptions {
        incidences: a.rgl_incidences,
        slice: a.rgl_slice,
        vndf: a.rgl_vndf,
        ..Default::default()
    };
    let tab;
    let (src, reach): (&dyn gonio_brdf::Brdf, Option<(f64, f64)>) = match dataset {
        Dataset::Table(t) => (t, Some(theta_reach(t))),
        Dataset::Samples(_) => {
            tab = dataset.to_table(None, input)?;
            (&tab, Some(theta_reach(&tab)))
        }
        d => match d.brdf() {
            Some(b) => (b, None),
            None => {
                return Err(CliError::Input(format!(
                    "{}: nothing to evaluate",
                    input.display()
                )));
            }
        },
    };
    let valid = move |wi: gonio_core::Dir, wo: gonio_core::Dir| match reach {
        Some((ti, to)) => wi.theta() <= ti && wo.theta() <= to,
        None => true,
    };
    let description = format!(
        "Gonio {}: {} from {}",
        env!("CARGO_PKG_VERSION"),
        dataset.describe(),
        input.display()
    );
    let r = gonio_io::formats::RglBsdf::from_brdf(src, &opts, &description, &valid)
        .map_err(|e| CliError::Input(format!("{}: {e}", input.display())))?;
    let err = r.interpolation_error(src, 75.0);
    tracing::debug!(
        at_nodes = err.at_nodes,
        between = err.between,
        "rgl interpolation error"
    );
    Ok(Exported::rgl(&r, dataset, Some(err)))
}

/// The largest θi and θo a table holds (radians, with a 1e-9 margin).
fn theta_reach(t: &gonio_process::Table) -> (f64, f64) {
    let max = |a: &gonio_process::grid::Axis| a.node(a.n.saturating_sub(1));
    (max(&t.grid.theta_i) + 1e-9, max(&t.grid.theta_o) + 1e-9)
}

/// `gonio export` of its input or of `given` data: with `write`, the file written
/// as the command writes it (its target checked before any work); without, nothing
/// written. What it made and the `--json` object (`out` only when written).
pub(crate) fn export(
    a: &ExportArgs,
    given: Option<Dataset>,
    write: bool,
) -> CliResult<(Exported, serde_json::Value)> {
    a.colour.conversion()?;
    // A CSV goes with its sidecar (the grid, isotropy), both checked before any work.
    let target = if write {
        Some(ExportTarget::new(a)?)
    } else {
        None
    };
    let e = compute(a, given)?;
    if let Some(t) = &target {
        t.write(&e)?;
    }
    let json = e.json(target.as_ref().map(|_| a.out.as_path()));
    Ok((e, json))
}

/// `gonio export INPUT --format merl|astm|csv --out FILE`.
pub fn run(a: ExportArgs) -> CliResult<()> {
    let (out, json_out) = (a.out.as_path(), a.json.json);
    let (e, json) = export(&a, None, true)?;
    if json_out {
        return output::json(&json);
    }
    let (format, bytes, symmetry, converted) = (e.format, e.bytes.len(), e.symmetry, &e.colour);
    let mut w = output::stdout();
    output::finish((|| {
        writeln!(
            w,
            "{}: {} ({} bytes) from {}",
            out.display(),
            format.title(),
            bytes,
            e.from
        )?;
        if let Some(s) = symmetry {
            writeln!(w, "symmetry: {}", s.describe())?;
        }
        if let Some(r) = &e.rgl {
            writeln!(
                w,
                "interpolation error (f_r cos θo, relative RMS): {:.3}% at the file's nodes, \
                 {:.2}% between them (θi, θo ≤ {}°)",
                100.0 * r.at_nodes,
                100.0 * r.between,
                r.theta_max_deg
            )?;
        }
        if let Some(c) = converted {
            writeln!(
                w,
                "colour: wavelength channels as linear sRGB R, G, B ({c})"
            )?;
        }
        w.flush()
    })())
}
