//! `gonio export`: a run, table, samples or model in the formats other tools read.

use std::io::Write;
use std::path::PathBuf;

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

/// `gonio export INPUT --format merl|astm|csv --out FILE`.
pub fn run(a: ExportArgs) -> CliResult<()> {
    let (input, out, json_out) = (a.input.as_path(), a.out.as_path(), a.json.json);
    let colour = a.colour.conversion()?;
    let format = Format::from_name(&a.format).ok_or_else(|| {
        CliError::Input(format!(
            "--format: merl, astm, csv or csv-long, got {:?}",
            a.format
        ))
    })?;
    // A CSV goes with its sidecar (the grid, isotropy), both checked before any work.
    let target = match format {
        Format::Csv | Format::CsvLong => Err(CsvTarget::new(out, a.force.force)?),
        _ => Ok(output::Target::new(out, a.force.force)?),
    };
    let opened = gonio_dataset::open(input, &a.reduction.open_options()?)?;
    let mut data = opened.data.to_format_data(input)?;
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
    match &target {
        Ok(t) => t.write(&bytes)?,
        Err(csv) if format == Format::CsvLong => csv.write(
            &bytes,
            &formats::long_meta(&data).map_err(|e| CliError::Input(e.to_string()))?,
        )?,
        Err(csv) => csv.write(&bytes, &formats::csv_meta(&data))?,
    }
    let bytes = bytes.len();
    if json_out {
        return output::json(&json!({
            "out": out.display().to_string(),
            "format": format.name(),
            "from": data.kind(),
            "bytes": bytes,
            "symmetry": symmetry.map(|s| s.name()),
            "colour": converted,
        }));
    }
    let mut w = output::stdout();
    output::finish((|| {
        writeln!(
            w,
            "{}: {} ({} bytes) from {}",
            out.display(),
            format.title(),
            bytes,
            data.kind()
        )?;
        if let Some(s) = symmetry {
            writeln!(w, "symmetry: {}", s.describe())?;
        }
        if let Some(c) = &converted {
            writeln!(
                w,
                "colour: wavelength channels as linear sRGB R, G, B ({c})"
            )?;
        }
        w.flush()
    })())
}
