//! One module a command (or a group of subcommands): each defines its arguments as
//! one `clap::Args` struct and a `run` that takes it.

pub mod acquire;
pub mod check;
pub mod colour;
pub mod compare;
pub mod correct;
pub mod demo;
pub mod estimate;
pub mod export;
pub mod fit;
pub mod harmonics;
pub mod instrument;
pub mod micro;
pub mod model;
pub mod plan;
pub mod plot;
pub mod prepare;
pub mod reading_time;
pub mod reduce;
pub mod report;
pub mod runs;
pub mod verify;
pub mod view;

/// The data of `path`, opened as the reduction flags say, or `given`: data already in
/// memory (from the Python package) that `path` names in messages.
pub(crate) fn open_data(
    path: &std::path::Path,
    reduction: &crate::flags::ReduceFlags,
    given: Option<gonio_dataset::Dataset>,
) -> crate::error::CliResult<gonio_dataset::Dataset> {
    match given {
        Some(d) => Ok(d),
        None => Ok(gonio_dataset::open(path, &reduction.open_options()?)?.data),
    }
}

/// Writes what a command assumed to make a table of its input: the symmetry, and
/// the nodes of the data's own grid that were interpolated rather than measured.
pub(crate) fn write_provenance(
    w: &mut dyn std::io::Write,
    tab: &gonio_dataset::Tabulated,
) -> std::io::Result<()> {
    if tab.measured.is_some() || tab.symmetry != gonio_process::hemisphere::Symmetry::None {
        writeln!(w, "symmetry: {}", tab.symmetry.describe())?;
    }
    if let Some(f) = &tab.fill {
        writeln!(
            w,
            "grid: the samples' own ({} nodes, {} measured); {} not measured, interpolated \
             from their neighbours (nearest-j kernel, DeYoung Sec. 3.2.1){}",
            f.nodes,
            f.measured,
            f.interpolated.len(),
            match f.interpolated.first() {
                Some(n) => format!(", e.g. θi {}°, θo {}°, Δφ {}°", n[0], n[2], n[3] - n[1]),
                None => String::new(),
            }
        )?;
    }
    Ok(())
}

/// The table's grid and how it was filled, for `--json`.
pub(crate) fn grid_json(
    table: &gonio_process::Table,
    tab: &gonio_dataset::Tabulated,
) -> serde_json::Value {
    let g = &table.grid;
    let axis = |a: &gonio_process::Axis| serde_json::json!({"start_deg": a.node_deg(0), "step_deg": gonio_process::grid::clean_deg(a.step.to_degrees()), "n": a.n});
    serde_json::json!({
        "isotropic": g.isotropic,
        "phi_i": axis(&g.phi_i),
        "theta_i": axis(&g.theta_i),
        "phi_o": axis(&g.phi_o),
        "theta_o": axis(&g.theta_o),
        "own": tab.fill.is_some(),
        "measured_nodes": tab.fill.as_ref().map(|f| f.measured),
        "interpolated": tab.fill.as_ref().map(|f| &f.interpolated),
    })
}
