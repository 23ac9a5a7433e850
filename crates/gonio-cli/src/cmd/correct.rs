//! `gonio correct`: DeYoung's δ-transforms (Ch. 5) towards reciprocity, energy
//! conservation, isotropy or k-separability, in the order given.

use std::io::Write;
use std::path::PathBuf;

use gonio_process::separable::SeparableBrdf;
use gonio_process::transform::{self, Step};
use gonio_process::{file, measure};
use serde_json::json;

use crate::csvout::CsvTarget;
use crate::error::{CliError, CliResult};
use crate::flags::{GridFlag, JsonFlag, ReduceFlags};
use crate::output;

/// `gonio correct`: transform a table towards reciprocity, energy conservation,
/// isotropy or k-separability (DeYoung Ch. 5), the steps in the order given.
#[derive(clap::Args)]
pub struct CorrectArgs {
    /// The input.
    input: PathBuf,
    /// Reciprocity with δ in [0, 1] (Eq. 5.1–5.2).
    #[arg(long)]
    reciprocity: Vec<String>,
    /// Energy conservation: δ, then optionally :per-direction or :global, and :tau=T
    /// (Eq. 5.4–5.8).
    #[arg(long)]
    energy: Vec<String>,
    /// Isotropy with δ (Eq. 5.9–5.10).
    #[arg(long)]
    isotropy: Vec<String>,
    /// k-separability: k or k:δ (Eq. 5.15); a last step with δ = 1 and a .toml output
    /// writes the k factor pairs.
    #[arg(long)]
    separable: Vec<String>,
    /// The output (CSV table, or TOML factors).
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

/// The four step flags, as clap names them.
const STEP_FLAGS: [(&str, &str); 4] = [
    ("reciprocity", "--reciprocity"),
    ("energy", "--energy"),
    ("isotropy", "--isotropy"),
    ("separable", "--separable"),
];

impl CorrectArgs {
    /// The steps in the order their flags appear on the command line: clap keeps
    /// each flag's values in order, and `matches` (the subcommand's) says where on
    /// the line each value stood. Without `matches`, the flags' own order.
    pub(crate) fn steps(&self, matches: Option<&clap::ArgMatches>) -> CliResult<Vec<Step>> {
        let lists = [
            &self.reciprocity,
            &self.energy,
            &self.isotropy,
            &self.separable,
        ];
        let mut placed: Vec<(usize, usize, &String)> = Vec::new();
        for (k, ((id, _), values)) in STEP_FLAGS.iter().zip(lists).enumerate() {
            let at: Vec<usize> = matches
                .and_then(|m| m.indices_of(id))
                .map(Iterator::collect)
                .unwrap_or_default();
            for (j, v) in values.iter().enumerate() {
                let index = at.get(j).copied().unwrap_or(usize::MAX);
                placed.push((index, k, v));
            }
        }
        placed.sort_by_key(|(index, k, _)| (*index, *k));
        placed
            .into_iter()
            .map(|(_, k, v)| {
                let step = match k {
                    0 => transform::parse_delta(v).map(Step::Reciprocity),
                    1 => Step::parse_energy(v),
                    2 => transform::parse_delta(v).map(Step::Isotropy),
                    _ => Step::parse_separable(v),
                };
                step.map_err(|e| CliError::Input(format!("{}: {e}", STEP_FLAGS[k].1)))
            })
            .collect()
    }
}

/// `gonio correct INPUT --reciprocity δ --energy … --isotropy δ --separable k[:δ]
/// --out OUTPUT`, the steps in the order given.
pub fn run(a: CorrectArgs, matches: Option<&clap::ArgMatches>) -> CliResult<()> {
    let steps = a.steps(matches)?;
    let steps = steps.as_slice();
    let (out, json_out) = (a.out.as_path(), a.json.json);
    require_steps(steps)?;
    // A TOML output holds the separable factors; anything else is a CSV table with its
    // sidecar.
    let toml_out = out.extension().is_some_and(|e| e == "toml");
    let target = if toml_out {
        Ok(output::Target::new(out, a.force.force)?)
    } else {
        Err(CsvTarget::new(out, a.force.force)?)
    };
    let corrected = compute(&a, steps, None, toml_out)?;
    let Corrected {
        tab,
        table,
        before,
        after,
        factors,
        ks,
    } = &corrected;
    match (factors, &target) {
        (Some(f), Ok(t)) => t.write(f.to_toml().as_bytes())?,
        (None, Ok(t)) => t.write(file::write_table(table).as_bytes())?,
        (_, Err(csv)) => {
            csv.write_tabulated(table, tab)?;
        }
    }
    let ratio = factors.as_ref().map(SeparableBrdf::storage_ratio);
    if json_out {
        return output::json(&corrected.json(steps, out));
    }
    let mut w = output::stdout();
    output::finish((|| {
        writeln!(w, "{}: {} step(s) applied", out.display(), steps.len())?;
        super::write_provenance(&mut w, tab)?;
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

/// At least one step is asked for (checked before anything else).
fn require_steps(steps: &[Step]) -> CliResult<()> {
    if steps.is_empty() {
        return Err(CliError::Input(
            "give at least one of --reciprocity, --energy, --isotropy, --separable".into(),
        ));
    }
    Ok(())
}

/// What `gonio correct` made: the table transformed, and the measures before and
/// after.
pub(crate) struct Corrected {
    /// The input's table and what was assumed to make it.
    pub tab: gonio_dataset::Tabulated,
    /// The table after the steps.
    pub table: gonio_process::Table,
    /// The measures before.
    pub before: measure::Report,
    /// The measures after.
    pub after: measure::Report,
    /// The separable factors, when the last step is k-separable with δ = 1 and they
    /// were asked for.
    pub factors: Option<SeparableBrdf>,
    /// The k of P_s^(k) measured (the steps' k, then 1).
    pub ks: Vec<usize>,
}

impl Corrected {
    /// The `--json` object (`out` names the output).
    pub fn json(&self, steps: &[Step], out: &std::path::Path) -> serde_json::Value {
        json!({
            "out": out.display().to_string(),
            "steps": steps,
            "before": self.before,
            "after": self.after,
            "storage_ratio": self.factors.as_ref().map(SeparableBrdf::storage_ratio),
            "symmetry": self.tab.symmetry.name(),
            "grid": super::grid_json(&self.tab.table, &self.tab),
        })
    }
}

/// Applies `steps` to the input's table (or to `given`, data already in memory that
/// `path` names); writes nothing. `factors_wanted`: a last separable step with δ = 1
/// also gives its factors.
pub(crate) fn compute(
    a: &CorrectArgs,
    steps: &[Step],
    given: Option<gonio_dataset::Dataset>,
    factors_wanted: bool,
) -> CliResult<Corrected> {
    let path = a.input.as_path();
    require_steps(steps)?;
    let data = super::open_data(path, &a.reduction, given)?;
    let tab = data.tabulate(a.grid.grid, path)?;
    let mut table = tab.table.clone();
    let ks: Vec<usize> = steps
        .iter()
        .filter_map(|s| match s {
            Step::Separable(k, _) => Some(*k),
            _ => None,
        })
        .chain([1])
        .collect();
    let before = measure::report_with(&table, tab.measured.as_ref(), &ks, 1)
        .map_err(|e| CliError::process(path, e))?;
    for s in steps {
        table = s.apply(&table).map_err(|e| CliError::process(path, e))?;
    }
    let after = measure::report(&table, &ks, 1).map_err(|e| CliError::process(path, e))?;
    // A last separable step with δ = 1 writes its factors when the output is TOML:
    // the compressed representation.
    let factors = match steps.last() {
        Some(Step::Separable(k, d)) if *d == 1.0 && factors_wanted => Some(
            SeparableBrdf::from_table(&table, *k, true).map_err(|e| CliError::process(path, e))?,
        ),
        _ => None,
    };
    Ok(Corrected {
        tab,
        table,
        before,
        after,
        factors,
        ks,
    })
}
