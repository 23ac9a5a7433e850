//! `gonio micro`: the virtual gonioreflectometer — a BRDF table (and optionally the
//! symmetric spherical-harmonic matrix of Westin et al.) predicted by ray tracing a
//! surface file's microgeometry (`gonio-micro`).

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use gonio_micro::{MicroResult, ORDERS, Sample, SimOptions, Simulation};
use gonio_process::GridStep;
use serde_json::json;

use crate::csvout::CsvTarget;
use crate::error::{CliError, CliResult};
use crate::flags::{JsonFlag, parse_grid};
use crate::output;

/// `gonio micro`: predict a BRDF from microgeometry (the virtual gonioreflectometer of
/// Westin et al. 1992): trace rays through every bounce on a surface file's height
/// field and tabulate f_r with its Monte Carlo error (and, with --sh, the symmetric
/// spherical-harmonic matrix).
#[derive(clap::Args)]
pub struct MicroArgs {
    /// The surface file (TOML; docs/micro.md).
    surface: PathBuf,
    /// The grid, DTHETA,DPHI in degrees (polar band midpoints, a full turn).
    #[arg(long, value_parser = parse_grid, default_value = "10,15")]
    grid: GridStep,
    /// Tabulate the isotropic form (θi, φo − φi, θo), averaging over the sample's
    /// turns; for anisotropic surfaces leave it off.
    #[arg(long)]
    isotropic: bool,
    /// Rays per incident direction of the grid.
    #[arg(long, default_value_t = 100_000)]
    rays: usize,
    /// Seed of every random draw: the same seed gives the same table bytes.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The table to write (CSV with a grid header, sigma columns = Monte Carlo
    /// standard errors).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    force: output::ForceFlag,
    /// Also write one table per bounce order (1, 2, 3+) beside OUT.
    #[arg(long)]
    per_order: bool,
    /// Also estimate the spherical-harmonic matrix to this degree from its own rays.
    #[arg(long)]
    sh: Option<usize>,
    /// Taper SH degrees above this one (Westin et al.'s filtering).
    #[arg(long, requires = "sh")]
    sh_filter: Option<usize>,
    /// Where to write the SH file (TOML); required with --sh.
    #[arg(long, requires = "sh")]
    sh_out: Option<PathBuf>,
    /// Rays of the SH estimate (incident directions drawn over the hemisphere).
    #[arg(long, default_value_t = 1_000_000, requires = "sh")]
    sh_rays: usize,
    /// Bounces after which a ray is stopped (its energy is reported).
    #[arg(long, default_value_t = 100)]
    max_bounces: u32,
    #[command(flatten)]
    json: JsonFlag,
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

/// The counts of the flags against the library's caps, before the surface is read:
/// an absurd `--rays` is refused at once rather than after a surface is generated.
pub(crate) fn check_counts(a: &MicroArgs) -> CliResult<()> {
    use gonio_core::limits::count;
    let flag = |name: &str, r: Result<u64, String>| {
        r.map(|_| ())
            .map_err(|m| CliError::Input(format!("{name}: {m}")))
    };
    let max_rays = gonio_micro::MAX_RAYS as u64;
    flag("--rays", count(a.rays as u64, 2, max_rays, "rays"))?;
    flag(
        "--max-bounces",
        count(
            a.max_bounces.into(),
            1,
            gonio_micro::MAX_BOUNCES.into(),
            "bounces",
        ),
    )?;
    if let Some(l) = a.sh {
        let max_l = gonio_process::sh::MAX_L_MAX as u64;
        flag("--sh", count(l as u64, 0, max_l, ""))?;
        flag("--sh-rays", count(a.sh_rays as u64, 2, max_rays, "rays"))?;
        if let Some(f) = a.sh_filter {
            flag("--sh-filter", count(f as u64, 0, l as u64, ""))?;
        }
    }
    Ok(())
}

/// `gonio micro SURFACE --grid DT,DP --rays N --out TABLE`.
pub fn run(a: MicroArgs) -> CliResult<()> {
    let sh_request = match (a.sh, &a.sh_out) {
        (Some(l), Some(p)) => Some((l, a.sh_filter, p.clone(), a.sh_rays)),
        (Some(_), None) => {
            return Err(CliError::Input("--sh needs --sh-out FILE".into()));
        }
        _ => None,
    };
    check_counts(&a)?;
    // Every output is checked before the rays are traced.
    let force = a.force.force;
    let out = CsvTarget::new(&a.out, force)?;
    let order_targets = if a.per_order {
        ORDERS
            .iter()
            .map(|name| CsvTarget::new(&order_path(&a.out, name), force))
            .collect::<CliResult<Vec<_>>>()?
    } else {
        Vec::new()
    };
    let sh_target = match &sh_request {
        Some((_, _, p, _)) => Some(output::Target::new(p, force)?),
        None => None,
    };
    let started = Instant::now();
    let (sim, grid) = load(&a)?;
    let r = trace(&a, &sim, &grid)?;
    out.write_table(&r.table)?;
    let mut order_files = Vec::new();
    for (t, target) in r.per_order.iter().zip(&order_targets) {
        target.write_table(t)?;
        order_files.push(target.path().to_path_buf());
    }
    let sh = match (&sh_request, &sh_target) {
        (Some((l_max, l_filter, path, rays)), Some(target)) => {
            let e = sim
                .estimate_sh(*l_max, *l_filter, *rays, a.seed)
                .map_err(|e| input_err(&a.surface, e))?;
            target.write(e.sh.to_toml().as_bytes())?;
            Some((path.clone(), e))
        }
        _ => None,
    };
    let channels = r.table.channels.names();
    let seconds = started.elapsed().as_secs_f64();
    let s = &r.stats;
    let mc = median_relative_error(&r);
    if a.json.json {
        return output::json(&json(&a, &r, &order_files, sh.as_ref(), seconds));
    }
    let mut w = output::stdout();
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

impl MicroArgs {
    /// Rays per incident direction.
    pub(crate) fn rays(&self) -> usize {
        self.rays
    }
}

/// The surface's simulation and the grid `a` asks for; nothing traced yet.
pub(crate) fn load(a: &MicroArgs) -> CliResult<(Simulation, gonio_process::Grid)> {
    load_from(a, None)
}

/// [`load`], the surface file's text given as `text` when it is (a sweep's edited
/// copy: the file's path still names it in messages and anchors its relative
/// files).
pub(crate) fn load_from(
    a: &MicroArgs,
    text: Option<&str>,
) -> CliResult<(Simulation, gonio_process::Grid)> {
    check_counts(a)?;
    let sample = match text {
        Some(t) => Sample::from_toml(t, Some(&a.surface)),
        None => Sample::load(&a.surface),
    }
    .map_err(|e| input_err(&a.surface, e))?;
    let opts = SimOptions {
        max_bounces: a.max_bounces,
        ..SimOptions::default()
    };
    let sim = Simulation::new(sample, opts).map_err(|e| input_err(&a.surface, e))?;
    let grid = if a.isotropic {
        a.grid.isotropic_grid()
    } else {
        a.grid.grid()
    };
    Ok((sim, grid))
}

/// Traces `a.rays` rays an incident node of `grid`.
pub(crate) fn trace(
    a: &MicroArgs,
    sim: &Simulation,
    grid: &gonio_process::Grid,
) -> CliResult<MicroResult> {
    sim.to_table(grid, a.rays, a.seed)
        .map_err(|e| input_err(&a.surface, e))
}

/// Segments `segs` of incident node `incident` of the table [`trace`] makes.
pub(crate) fn part(
    a: &MicroArgs,
    sim: &Simulation,
    grid: &gonio_process::Grid,
    incident: usize,
    segs: std::ops::Range<usize>,
) -> CliResult<gonio_micro::TablePart> {
    sim.table_part(grid, a.rays, a.seed, incident, segs)
        .map_err(|e| input_err(&a.surface, e))
}

/// The table [`trace`] makes, from its parts.
pub(crate) fn merge(
    a: &MicroArgs,
    sim: &Simulation,
    grid: &gonio_process::Grid,
    parts: &[gonio_micro::TablePart],
) -> CliResult<MicroResult> {
    sim.table_from_parts(grid, a.rays, a.seed, parts)
        .map_err(|e| CliError::Input(format!("{}: {e}", a.surface.display())))
}

/// The `--json` object.
pub(crate) fn json(
    a: &MicroArgs,
    r: &MicroResult,
    order_files: &[PathBuf],
    sh: Option<&(PathBuf, gonio_micro::ShEstimate)>,
    seconds: f64,
) -> serde_json::Value {
    let channels = r.table.channels.names();
    let s = &r.stats;
    let mc = median_relative_error(r);
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
    json!({
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
    })
}
