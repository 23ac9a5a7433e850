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

/// `gonio export`: write a run, table or samples as MERL binary, ASTM E1392 text or
/// CSV.
#[derive(clap::Args)]
pub struct ExportArgs {
    /// The input.
    input: PathBuf,
    /// merl, astm, csv or csv-long (a row per pair per wavelength: wavelength
    /// channels only).
    #[arg(long)]
    format: String,
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
        serde_json::Value::Object(v)
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
            "--format: merl, astm, csv or csv-long, got {:?}",
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
    })
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
        if let Some(c) = converted {
            writeln!(
                w,
                "colour: wavelength channels as linear sRGB R, G, B ({c})"
            )?;
        }
        w.flush()
    })())
}
