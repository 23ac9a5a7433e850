//! `gonio micro`: the virtual gonioreflectometer — a BRDF table (and optionally the
//! symmetric spherical-harmonic matrix of Westin et al.) predicted by ray tracing a
//! surface file's microgeometry (`gonio-micro`).

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use gonio_micro::{MicroResult, ORDERS, Sample, SimOptions, Simulation};
use gonio_process::{Axis, Grid};
use serde_json::json;

use crate::error::{CliError, CliResult};
use crate::output;
use crate::process_cmd::grid_of;

/// What `gonio micro` was asked for.
pub struct MicroArgs {
    /// The surface file.
    pub surface: PathBuf,
    /// The grid, DTHETA,DPHI degrees.
    pub grid: (f64, f64),
    /// Tabulate the isotropic (θi, φo − φi, θo) form, averaging the sample's turns.
    pub isotropic: bool,
    /// Rays per incident direction of the grid.
    pub rays: usize,
    /// Seed of every random draw.
    pub seed: u64,
    /// The table to write.
    pub out: PathBuf,
    /// Also write one table per bounce order beside `out`.
    pub per_order: bool,
    /// Spherical-harmonic estimate: degree, optional filter degree, file, rays.
    pub sh: Option<(usize, Option<usize>, PathBuf, usize)>,
    /// Bounces after which a ray is stopped.
    pub max_bounces: u32,
    /// JSON instead of text.
    pub json: bool,
}

/// The grid of `--grid`, full or isotropic.
pub fn micro_grid((dt, dp): (f64, f64), isotropic: bool) -> Grid {
    if isotropic {
        let t = Axis::polar_midpoints((90.0 / dt).round() as usize);
        let p = Axis::full_turn((360.0 / dp).round() as usize);
        Grid::isotropic(t, p, t)
    } else {
        grid_of((dt, dp))
    }
}

fn input_err(path: &Path, e: impl std::fmt::Display) -> CliError {
    let msg = e.to_string();
    // Surface-file errors already start with the file's name.
    if msg.starts_with(&path.display().to_string()) {
        CliError::Input(msg)
    } else {
        CliError::Input(format!("{}: {msg}", path.display()))
    }
}

fn write(out: &Path, text: &str) -> CliResult<()> {
    std::fs::write(out, text)
        .map_err(|e| CliError::Input(format!("{}: cannot write output file: {e}", out.display())))
}

/// `OUT` with `.orderK` before its extension: `brdf.csv` → `brdf.order1.csv`.
fn order_path(out: &Path, order: &str) -> PathBuf {
    let tag = order.replace('+', "plus");
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = match out.extension() {
        Some(e) => format!("{stem}.order{tag}.{}", e.to_string_lossy()),
        None => format!("{stem}.order{tag}"),
    };
    out.with_file_name(name)
}

/// Median over the table's positive values of σ/value: the Monte Carlo error a
/// typical bin carries.
fn median_relative_error(r: &MicroResult) -> f64 {
    let Some(sigma) = r.table.sigma.as_ref() else {
        return f64::NAN;
    };
    let mut rel: Vec<f64> = r
        .table
        .values
        .iter()
        .zip(sigma)
        .filter(|(v, _)| **v > 0.0)
        .map(|(v, s)| s / v)
        .collect();
    if rel.is_empty() {
        return f64::NAN;
    }
    rel.sort_by(f64::total_cmp);
    rel[rel.len() / 2]
}

/// `gonio micro SURFACE --grid DT,DP --rays N --out TABLE`.
pub fn micro(a: MicroArgs) -> CliResult<()> {
    let started = Instant::now();
    let sample = Sample::load(&a.surface).map_err(|e| input_err(&a.surface, e))?;
    let opts = SimOptions {
        max_bounces: a.max_bounces,
        ..SimOptions::default()
    };
    let sim = Simulation::new(sample, opts).map_err(|e| input_err(&a.surface, e))?;
    let grid = micro_grid(a.grid, a.isotropic);
    let r = sim
        .to_table(&grid, a.rays, a.seed)
        .map_err(|e| input_err(&a.surface, e))?;
    write(&a.out, &gonio_process::file::write_table(&r.table))?;
    let mut order_files = Vec::new();
    if a.per_order {
        for (t, name) in r.per_order.iter().zip(ORDERS) {
            let p = order_path(&a.out, name);
            write(&p, &gonio_process::file::write_table(t))?;
            order_files.push(p);
        }
    }
    let sh = match &a.sh {
        Some((l_max, l_filter, path, rays)) => {
            let e = sim
                .estimate_sh(*l_max, *l_filter, *rays, a.seed)
                .map_err(|e| input_err(&a.surface, e))?;
            write(path, &e.sh.to_toml())?;
            Some((path.clone(), e))
        }
        None => None,
    };
    let channels = r.table.channels.names();
    let seconds = started.elapsed().as_secs_f64();
    let s = &r.stats;
    let mc = median_relative_error(&r);
    if a.json {
        let albedo: Vec<_> = r
            .albedo
            .iter()
            .map(|x| {
                json!({
                    "phi_i_deg": x.phi_i.to_degrees(),
                    "theta_i_deg": x.theta_i.to_degrees(),
                    "albedo": x.albedo,
                    "sigma": x.sigma,
                    "per_order": x.per_order,
                    "in_table": x.in_table,
                })
            })
            .collect();
        return output::json(&json!({
            "out": a.out.display().to_string(),
            "order_files": order_files.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
            "channels": channels,
            "nodes": r.table.grid.len(),
            "rays_per_direction": a.rays,
            "seed": a.seed,
            "rays": s.rays,
            "exits": s.exits,
            "absorbed": s.absorbed,
            "capped": s.capped,
            "capped_energy_fraction": s.capped_fraction(),
            "leaked": s.leaked,
            "horizon": s.horizon,
            "hits": s.hits,
            "max_order": s.max_order,
            "median_relative_error": mc,
            "albedo": albedo,
            "sh": sh.as_ref().map(|(p, e)| json!({
                "out": p.display().to_string(),
                "l_max": e.sh.l_max,
                "l_filter": e.sh.l_filter,
                "coefficients": e.sh.coefficient_count(),
                "rays": e.stats.rays,
            })),
            "seconds": seconds,
        }));
    }
    let mut w = output::open(None)?;
    output::finish((|| {
        writeln!(
            w,
            "{}: {} nodes × {} channel(s) ({}), {} rays a direction, seed {}",
            a.out.display(),
            r.table.grid.len(),
            channels.len(),
            channels.join(", "),
            a.rays,
            a.seed
        )?;
        writeln!(
            w,
            "rays: {} shot, {} left, {} absorbed, {} stopped at {} bounces ({:.2e} of the energy), {} lost; {:.2} hits a ray; highest order {}",
            s.rays,
            s.exits,
            s.absorbed,
            s.capped,
            a.max_bounces,
            s.capped_fraction(),
            s.leaked + s.horizon,
            s.hits as f64 / (s.rays.max(1)) as f64,
            s.max_order
        )?;
        writeln!(
            w,
            "Monte Carlo error: median {:.2}% of a bin's value (the table's sigma columns hold every bin's)",
            100.0 * mc
        )?;
        writeln!(
            w,
            "albedo (± standard error) and its share by bounce order {}:",
            ORDERS.join("/")
        )?;
        for x in &r.albedo {
            let per: Vec<String> = (0..channels.len())
                .map(|ch| {
                    let orders: Vec<String> = x
                        .per_order
                        .iter()
                        .map(|o| format!("{:.3}", o[ch]))
                        .collect();
                    format!(
                        "{} {:.4} ± {:.4} ({})",
                        channels[ch],
                        x.albedo[ch],
                        x.sigma[ch],
                        orders.join("/")
                    )
                })
                .collect();
            writeln!(
                w,
                "  θi {:5.1}° φi {:5.1}°: {}",
                x.theta_i.to_degrees(),
                x.phi_i.to_degrees(),
                per.join("; ")
            )?;
        }
        for p in &order_files {
            writeln!(w, "per-order table: {}", p.display())?;
        }
        if let Some((p, e)) = &sh {
            writeln!(
                w,
                "{}: spherical harmonics to degree {} (filtered above {}), {} coefficients from {} rays, exactly reciprocal",
                p.display(),
                e.sh.l_max,
                e.sh.l_filter,
                e.sh.coefficient_count(),
                e.stats.rays
            )?;
        }
        writeln!(w, "{seconds:.2} s")?;
        w.flush()
    })())
}
