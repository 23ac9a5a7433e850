//! `gonio harmonics`: a table as real spherical harmonics with a symmetric
//! coefficient matrix (Westin et al. 1992), exactly reciprocal.

use std::io::Write;
use std::path::PathBuf;

use gonio_process::sh::{ShBrdf, ShOptions};
use serde_json::json;

use crate::error::{CliError, CliResult};
use crate::flags::{GridFlag, JsonFlag, ReduceFlags};
use crate::output;

/// `gonio harmonics`: represent a table by real spherical harmonics with a symmetric
/// coefficient matrix; reports the truncation error.
#[derive(clap::Args)]
pub struct HarmonicsArgs {
    /// The input.
    input: PathBuf,
    /// The truncation order l_max.
    #[arg(long)]
    order: usize,
    /// Attenuate orders above this one (against ringing); none by default.
    #[arg(long)]
    filter: Option<usize>,
    /// The coefficient file to write (TOML).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    force: output::ForceFlag,
    #[command(flatten)]
    grid: GridFlag,
    #[command(flatten)]
    reduction: ReduceFlags,
    #[command(flatten)]
    json: JsonFlag,
}

/// `gonio harmonics INPUT --order L [--filter LF] --out SH.toml`.
pub fn run(a: HarmonicsArgs) -> CliResult<()> {
    let (order, out, json_out) = (a.order, a.out.as_path(), a.json.json);
    check_degrees(&a)?;
    let target = output::Target::new(out, a.force.force)?;
    let h = compute(&a, None)?;
    target.write(h.file.as_bytes())?;
    let (tab, sh, err) = (&h.tab, &h.sh, &h.error);
    let table = &tab.table;
    let ratio = h.storage_ratio();
    if json_out {
        return output::json(&h.json(order, out));
    }
    let mut w = output::stdout();
    output::finish((|| {
        writeln!(
            w,
            "{}: spherical harmonics to order {order}, {} coefficients ({:.2}% of the table), exactly reciprocal",
            out.display(),
            sh.coefficient_count(),
            100.0 * ratio
        )?;
        super::write_provenance(&mut w, tab)?;
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

/// A table as harmonics, as `gonio harmonics` makes it.
pub(crate) struct Harmonics {
    /// The input's table and what was assumed to make it.
    pub tab: gonio_dataset::Tabulated,
    /// The representation.
    pub sh: ShBrdf,
    /// Its error against the table.
    pub error: gonio_process::sh::ShError,
    /// The file `--out` receives: comments on what was assumed, then the
    /// coefficients.
    pub file: String,
}

impl Harmonics {
    /// Coefficients over table values.
    pub fn storage_ratio(&self) -> f64 {
        self.sh.coefficient_count() as f64 / self.tab.table.values.len() as f64
    }

    /// The `--json` object (`out` names the output).
    pub fn json(&self, order: usize, out: &std::path::Path) -> serde_json::Value {
        let err = &self.error;
        json!({
            "out": out.display().to_string(),
            "order": order,
            "coefficients": self.sh.coefficient_count(),
            "storage_ratio": self.storage_ratio(),
            "rms": err.rms,
            "relative_rms": err.relative_rms,
            "max_abs": err.max_abs,
            "symmetry": self.tab.symmetry.name(),
            "grid": super::grid_json(&self.tab.table, &self.tab),
        })
    }
}

/// The degrees, checked before the input is read: a bad one is refused at once.
fn check_degrees(a: &HarmonicsArgs) -> CliResult<()> {
    let degree = |name: &str, v: usize, max: usize| {
        gonio_core::limits::count(v as u64, 0, max as u64, "")
            .map(|_| ())
            .map_err(|m| CliError::Input(format!("{name}: {m}")))
    };
    degree("--order", a.order, gonio_process::sh::MAX_L_MAX)?;
    if let Some(f) = a.filter {
        degree("--filter", f, a.order)?;
    }
    Ok(())
}

/// Represents the input's table (or `given`, data already in memory that
/// `a.input` names); writes nothing.
pub(crate) fn compute(
    a: &HarmonicsArgs,
    given: Option<gonio_dataset::Dataset>,
) -> CliResult<Harmonics> {
    let (path, order, filter) = (a.input.as_path(), a.order, a.filter);
    check_degrees(a)?;
    let data = super::open_data(path, &a.reduction, given)?;
    let tab = data.tabulate(a.grid.grid, path)?;
    let table = &tab.table;
    let opts = ShOptions {
        l_max: order,
        l_filter: filter,
        quadrature: None,
    };
    let sh = ShBrdf::from_table(table, &opts).map_err(|e| CliError::process(path, e))?;
    let err = sh
        .error_against(table)
        .map_err(|e| CliError::process(path, e))?;
    // What was assumed of measured data travels with the coefficients (a comment:
    // readers of the file need nothing new).
    let mut text = String::new();
    if tab.measured.is_some() {
        text.push_str(&format!(
            "# symmetry assumed: {} ({})\n",
            tab.symmetry.name(),
            tab.symmetry.describe()
        ));
        if let Some(f) = &tab.fill {
            text.push_str(&format!(
                "# grid: the data's own, {} of {} nodes interpolated (not measured)\n",
                f.interpolated.len(),
                f.nodes
            ));
        }
    }
    text.push_str(&sh.to_toml());
    Ok(Harmonics {
        tab,
        sh,
        error: err,
        file: text,
    })
}
