//! `gonio instrument check` and `gonio sim`.

use std::io::Write;
use std::path::{Path, PathBuf};

use gonio_driver::config::is_sim_port;
use gonio_driver::{Goniometer, InstrumentConfig};
use serde_json::json;

use crate::error::{CliError, CliResult};
use crate::flags::JsonFlag;
use crate::output;

/// `gonio instrument`: check an instrument config, and optionally talk to it.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Validate an instrument config (ports, axes, limits, detector settings); with
    /// `--connect`, open the ports, identify every controller and set the lock-in up.
    /// Nothing moves.
    Check(CheckArgs),
}

/// `gonio instrument check`.
#[derive(clap::Args)]
pub struct CheckArgs {
    /// The instrument config (TOML).
    config: PathBuf,
    /// Open the ports and identify the instruments.
    #[arg(long)]
    connect: bool,
    #[command(flatten)]
    sim: SimFlag,
    #[command(flatten)]
    json: JsonFlag,
}

/// `--sim`: the simulator behind ports named "sim".
#[derive(Clone, Debug, clap::Args)]
pub struct SimFlag {
    /// Simulator config for ports named "sim" (the embedded default otherwise).
    #[arg(long)]
    pub sim: Option<PathBuf>,
}

/// Runs `gonio instrument …`.
pub fn run(c: Command) -> CliResult<()> {
    match c {
        Command::Check(a) => check(&a.config, a.connect, a.sim.sim.as_deref(), a.json.json),
    }
}

/// `gonio sim`: the simulated goniometer on two pseudo-terminals.
#[derive(clap::Args)]
pub struct SimArgs {
    /// Simulator config (TOML); the embedded default when absent.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Override the config's seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Wall seconds per physical second (> 0; default 1, real time).
    #[arg(long)]
    time_scale: Option<f64>,
}

/// The simulator config for ports named `"sim"`: the file given, or the default.
pub fn sim_config(path: Option<&Path>) -> CliResult<gonio_sim::SimConfig> {
    let mut cfg = match path {
        Some(p) => gonio_sim::SimConfig::load(p).map_err(|e| CliError::Input(e.to_string()))?,
        None => gonio_sim::SimConfig::default_config()
            .map_err(|e| CliError::Runtime(format!("embedded simulator config: {e}")))?,
    };
    cfg.prepare_sample()?;
    Ok(cfg)
}

/// Ports named `"sim"` mean the in-process simulator; every line must be simulated,
/// or none.
pub fn is_simulated(cfg: &InstrumentConfig, path: &Path) -> CliResult<bool> {
    let mut ports = cfg.motion.ports();
    ports.push(&cfg.detector.port);
    let sim = ports.iter().filter(|p| is_sim_port(p)).count();
    if sim == 0 {
        Ok(false)
    } else if sim == ports.len() {
        Ok(true)
    } else {
        Err(CliError::Input(format!(
            "{}: field `motion.port`/`detector.port`: either every port is \"sim\" or none",
            path.display()
        )))
    }
}

/// `gonio instrument check CONFIG [--connect] [--sim SIM] [--json]`.
fn check(path: &Path, connect: bool, sim: Option<&Path>, json: bool) -> CliResult<()> {
    let cfg = InstrumentConfig::load(path).map_err(|e| CliError::Input(e.to_string()))?;
    let axes: Vec<_> = cfg
        .motion
        .axes
        .iter()
        .map(|a| {
            json!({
                "name": a.name, "address": a.address, "units": a.units,
                "min": a.min, "max": a.max, "velocity": a.velocity,
                "acceleration": a.acceleration, "tolerance": a.tolerance,
            })
        })
        .collect();
    let lockin = &cfg.detector.lockin;
    let mut report = json!({
        "config": path.display().to_string(),
        "name": cfg.name,
        "motion": {"port": cfg.motion.port, "baud": cfg.motion.baud, "axes": axes},
        "detector": {
            "port": cfg.detector.port, "baud": cfg.detector.baud,
            "sensitivity_v": lockin.sensitivity.volts(),
            "time_constant_s": lockin.time_constant.seconds(),
            "slope_db": lockin.slope.db_per_octave(),
            "samples": lockin.samples,
        },
    });
    if connect {
        let start = if is_simulated(&cfg, path)? {
            let scfg = sim_config(sim)?;
            let (mut g, _) = gonio_sim::connect(&cfg, &scfg).map_err(|e| match e {
                gonio_sim::SimError::Mismatch(m) => {
                    CliError::Input(format!("{}: {m}", path.display()))
                }
                other => CliError::Runtime(other.to_string()),
            })?;
            g.start().map_err(|e| CliError::Runtime(e.to_string()))?
        } else {
            let mut g = Goniometer::open(&cfg).map_err(|e| CliError::Runtime(e.to_string()))?;
            g.start().map_err(|e| CliError::Runtime(e.to_string()))?
        };
        report["connected"] = json!({
            "controllers": start.axes.iter().map(|(n, i)| json!({
                "axis": n, "version": i.version, "stage": i.stage,
                "state": i.state_code, "family": i.family,
            })).collect::<Vec<_>>(),
            "detector": start.detector,
        });
    }
    if json {
        return output::json(&report);
    }
    let mut w = output::stdout();
    output::finish((|| {
        writeln!(w, "{}: valid", path.display())?;
        writeln!(
            w,
            "motion: {} at {} baud, {} axes",
            cfg.motion.port,
            cfg.motion.baud,
            cfg.motion.axes.len()
        )?;
        for a in &cfg.motion.axes {
            writeln!(
                w,
                "  {:<12} address {:>2}  limits [{}, {}] {}",
                a.name, a.address, a.min, a.max, a.units
            )?;
        }
        writeln!(
            w,
            "detector: {} at {} baud; {} V full scale, {} s, {} dB/oct, {} samples",
            cfg.detector.port,
            cfg.detector.baud,
            lockin.sensitivity.volts(),
            lockin.time_constant.seconds(),
            lockin.slope.db_per_octave(),
            lockin.samples
        )?;
        if let Some(c) = report.get("connected") {
            writeln!(w, "connected: {c}")?;
        }
        w.flush()
    })())
}

/// `gonio sim`: the simulator on two pseudo-terminals, announced by one JSON line on
/// stdout, served until a stop signal (SIGINT, SIGTERM, SIGHUP): standard input is
/// left alone, so that `gonio sim &` and service managers work.
pub fn sim(a: SimArgs) -> CliResult<()> {
    let waiter = crate::signals::Waiter::new()
        .map_err(|e| CliError::Runtime(format!("catching the stop signals: {e}")))?;
    let served = gonio_sim::serve::serve(&gonio_sim::serve::ServeOptions {
        config: a.config,
        seed: a.seed,
        time_scale: a.time_scale,
    })?;
    output::finish((|| {
        let mut out = std::io::stdout().lock();
        writeln!(out, "{}", served.announcement())?;
        out.flush()
    })())?;
    let sig = waiter.wait();
    tracing::info!(signal = sig, "simulator stopped");
    Ok(())
}
