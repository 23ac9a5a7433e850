//! `gonio instrument check`, `ports`, `selftest`, and `gonio sim`.

use std::io::Write;
use std::path::{Path, PathBuf};

use gonio_driver::config::{ControllerKind, DetectorKind, is_sim_port};
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
    /// List the serial ports this machine has, with the USB vendor, product and serial
    /// number of USB adapters and instruments. A config may name a port
    /// `usb:SERIAL` by that serial number instead of a path that reorders on reboot.
    Ports(PortsArgs),
    /// A first day on the hardware: identify every device, read its configuration
    /// back, home what needs it, run 60 short moves on each APT stage checking every
    /// completion arrives, record the status messages' lengths, time a move per axis
    /// against its trapezoid, and read the detector's noise floor with the beam
    /// blocked. Moves stay inside the soft limits. Exit status 1 when a check fails.
    Selftest(SelftestArgs),
}

/// `gonio instrument selftest`.
#[derive(clap::Args)]
pub struct SelftestArgs {
    /// The instrument config (TOML).
    config: PathBuf,
    /// Write the report (JSON: every check, what the hardware answered and what the
    /// manual says) to this file.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Short moves on each APT stage.
    #[arg(long, default_value_t = 60)]
    apt_moves: usize,
    #[command(flatten)]
    sim: SimFlag,
    #[command(flatten)]
    force: crate::output::ForceFlag,
    #[command(flatten)]
    json: JsonFlag,
}

/// `gonio instrument ports`.
#[derive(clap::Args)]
pub struct PortsArgs {
    #[command(flatten)]
    json: JsonFlag,
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
        Command::Ports(a) => ports(a.json.json),
        Command::Selftest(a) => selftest(&a),
    }
}

/// `gonio instrument selftest CONFIG [--out REPORT.json] [--sim SIM] [--json]`.
fn selftest(a: &SelftestArgs) -> CliResult<()> {
    let path = &a.config;
    let cfg = InstrumentConfig::load(path).map_err(|e| CliError::Input(e.to_string()))?;
    if !(1..=100_000).contains(&a.apt_moves) {
        return Err(CliError::Input(format!(
            "--apt-moves: {} is outside [1, 100000]",
            a.apt_moves
        )));
    }
    // The report's file is checked before anything is opened.
    let target = a
        .out
        .as_deref()
        .map(|o| crate::output::Target::new(o, a.force.force))
        .transpose()?;
    let opts = gonio_driver::selftest::SelftestOptions {
        apt_moves: a.apt_moves,
        ..Default::default()
    };
    let simulated = is_simulated(&cfg, path)?;
    let report = if simulated {
        let scfg = sim_config(a.sim.sim.as_deref())?;
        let (mut g, shared) = gonio_sim::connect(&cfg, &scfg).map_err(|e| match e {
            gonio_sim::SimError::Mismatch(m) => CliError::Input(format!("{}: {m}", path.display())),
            other => CliError::Runtime(other.to_string()),
        })?;
        let mut bench = gonio_sim::SimBench::new(shared, None);
        gonio_driver::selftest::selftest(&mut g, &cfg, &mut bench, &opts)
    } else {
        let mut g = Goniometer::open(&cfg).map_err(|e| CliError::Runtime(e.to_string()))?;
        let mut bench = gonio_driver::OperatorBench::new(
            std::io::BufReader::new(std::io::stdin()),
            std::io::stderr(),
        );
        gonio_driver::selftest::selftest(&mut g, &cfg, &mut bench, &opts)
    };
    let doc = json!({
        "config": path.display().to_string(),
        "name": cfg.name,
        "simulated": simulated,
        "report": report,
    });
    if let Some(t) = &target {
        let mut text = serde_json::to_vec_pretty(&doc)
            .map_err(|e| CliError::Runtime(format!("the report: {e}")))?;
        text.push(b'\n');
        t.write(&text)?;
    }
    if a.json.json {
        output::json(&doc)?;
    } else {
        let mut w = output::stdout();
        output::finish((|| {
            for c in &report.checks {
                writeln!(
                    w,
                    "{} {:<15} {:<12} {}",
                    if c.passed { "pass" } else { "FAIL" },
                    c.check,
                    c.device,
                    c.answered
                )?;
                if !c.passed {
                    writeln!(w, "     expected: {} ({})", c.expected, c.source)?;
                }
            }
            for l in &report.status_lengths {
                writeln!(
                    w,
                    "     {:<15} {:<12} {} {} data bytes ×{}",
                    "status message", l.axis, l.message, l.data_bytes, l.count
                )?;
            }
            for f in &report.unconfirmed {
                writeln!(w, "unconfirmed for {}:", f.family)?;
                for u in f.unconfirmed {
                    writeln!(w, "  - {} (check: {})", u.fact, u.check)?;
                }
            }
            let failed = report.checks.iter().filter(|c| !c.passed).count();
            writeln!(
                w,
                "{}: {} of {} checks passed in {:.1} s of instrument time{}",
                path.display(),
                report.checks.len() - failed,
                report.checks.len(),
                report.duration_s,
                target
                    .as_ref()
                    .map(|t| format!("; report in {}", t.path().display()))
                    .unwrap_or_default()
            )?;
            w.flush()
        })())?;
    }
    if report.passed {
        Ok(())
    } else {
        let failed: Vec<String> = report
            .checks
            .iter()
            .filter(|c| !c.passed)
            .map(|c| format!("{} on {}", c.check, c.device))
            .collect();
        Err(CliError::Runtime(format!(
            "{}: the self-test failed: {}",
            path.display(),
            failed.join(", ")
        )))
    }
}

/// `gonio instrument ports [--json]`.
fn ports(json: bool) -> CliResult<()> {
    let ports = gonio_driver::ports::list().map_err(CliError::Runtime)?;
    let rows: Vec<serde_json::Value> = ports
        .iter()
        .map(|p| {
            let u = p.usb.as_ref();
            json!({
                "path": p.path,
                "bus": p.bus,
                "vid": u.map(|u| format!("{:04x}", u.vid)),
                "pid": u.map(|u| format!("{:04x}", u.pid)),
                "serial_number": u.and_then(|u| u.serial_number.clone()),
                "manufacturer": u.and_then(|u| u.manufacturer.clone()),
                "product": u.and_then(|u| u.product.clone()),
                "name": u
                    .and_then(|u| u.serial_number.as_ref())
                    .map(|s| format!("{}{s}", gonio_driver::ports::USB_PREFIX)),
            })
        })
        .collect();
    if json {
        return output::json(&json!({ "ports": rows }));
    }
    let mut w = output::stdout();
    output::finish((|| {
        if ports.is_empty() {
            writeln!(w, "no serial ports")?;
        }
        for p in &ports {
            match &p.usb {
                Some(u) => writeln!(
                    w,
                    "{}  usb {:04x}:{:04x}  {}  {}  {}",
                    p.path,
                    u.vid,
                    u.pid,
                    u.serial_number
                        .as_ref()
                        .map_or("(no serial number)".to_string(), |s| {
                            format!("{}{s}", gonio_driver::ports::USB_PREFIX)
                        }),
                    u.manufacturer.as_deref().unwrap_or("-"),
                    u.product.as_deref().unwrap_or("-"),
                )?,
                None => writeln!(w, "{}  {}", p.path, p.bus)?,
            }
        }
        w.flush()
    })())
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
    if let Some(m) = &cfg.monochromator {
        ports.push(&m.port);
    }
    if let Some(w) = &cfg.filter_wheel {
        ports.push(&w.port);
    }
    let sim = ports.iter().filter(|p| is_sim_port(p)).count();
    if sim == 0 {
        Ok(false)
    } else if sim == ports.len() {
        Ok(true)
    } else {
        Err(CliError::Input(format!(
            "{}: field `motion.port`/`detector.port`/`monochromator.port`/`filter_wheel.port`: either every port is \"sim\" or none",
            path.display()
        )))
    }
}

impl CheckArgs {
    /// What `gonio instrument check` finds, printing nothing: its `--json` object.
    pub(crate) fn report(&self) -> CliResult<serde_json::Value> {
        check_report(&self.config, self.connect, self.sim.sim.as_deref()).map(|(_, r)| r)
    }
}

/// `gonio instrument check CONFIG [--connect] [--sim SIM] [--json]`.
fn check(path: &Path, connect: bool, sim: Option<&Path>, json: bool) -> CliResult<()> {
    let (cfg, report) = check_report(path, connect, sim)?;
    if json {
        return output::json(&report);
    }
    print_check(path, &cfg, &report)
}

/// The instrument config at `path` checked (and, with `connect`, the instruments
/// identified): the config, and the `--json` object.
fn check_report(
    path: &Path,
    connect: bool,
    sim: Option<&Path>,
) -> CliResult<(InstrumentConfig, serde_json::Value)> {
    let cfg = InstrumentConfig::load(path).map_err(|e| CliError::Input(e.to_string()))?;
    let axes: Vec<_> = cfg
        .motion
        .axes
        .iter()
        .map(|a| {
            json!({
                "name": a.name, "kind": a.kind.as_str(), "port": cfg.motion.port_of(a),
                "address": a.address, "units": a.units,
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
            "kind": match cfg.detector.kind {
                DetectorKind::Sr830 => "sr830",
                DetectorKind::K6485 => "k6485",
            },
            "port": cfg.detector.port, "baud": cfg.detector.baud,
            "sensitivity_v": lockin.sensitivity.volts(),
            "time_constant_s": lockin.time_constant.seconds(),
            "slope_db": lockin.slope.db_per_octave(),
            "samples": lockin.samples,
        },
    });
    if let Some(m) = &cfg.monochromator {
        report["monochromator"] = json!({
            "kind": "cs130", "port": m.port, "baud": m.baud,
            "gratings": m.cs130.gratings.iter().map(|g| json!({
                "index": g.index, "lines_per_mm": g.lines_per_mm,
                "min_nm": g.min_nm, "max_nm": g.max_nm,
            })).collect::<Vec<_>>(),
            "order_filters": m.cs130.filters.iter().map(|f| json!({
                "position": f.position, "cut_on_nm": f.cut_on_nm,
            })).collect::<Vec<_>>(),
            "auto_order_filter": m.cs130.auto_order_filter,
            "approach_nm": m.cs130.approach_nm,
        });
    }
    if let Some(wh) = &cfg.filter_wheel {
        report["filter_wheel"] = json!({
            "kind": "fw102c", "port": wh.port, "baud": wh.baud,
            "positions": wh.fw102c.positions,
            "filters": wh.fw102c.filters.iter().map(|f| json!({
                "position": f.position(), "kind": f.kind(),
            })).collect::<Vec<_>>(),
        });
    }
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
        let mut families: Vec<&str> = start.axes.iter().map(|(_, i)| i.family).collect();
        families.push(match cfg.detector.kind {
            DetectorKind::Sr830 => "sr830",
            DetectorKind::K6485 => "k6485",
        });
        if cfg.monochromator.is_some() {
            families.push("cs130");
        }
        if cfg.filter_wheel.is_some() {
            families.push("fw102c");
        }
        let mut unconfirmed: Vec<gonio_driver::selftest::FamilyFacts> = Vec::new();
        for f in families
            .iter()
            .filter_map(|f| gonio_driver::selftest::unconfirmed(f))
        {
            if !unconfirmed.iter().any(|u| u.family == f.family) {
                unconfirmed.push(f);
            }
        }
        report["connected"] = json!({
            "controllers": start.axes.iter().map(|(n, i)| json!({
                "axis": n, "version": i.version, "stage": i.stage,
                "state": i.state_code, "family": i.family,
            })).collect::<Vec<_>>(),
            "detector": start.detector,
            "wavelength": start.spectral,
            "unconfirmed": unconfirmed,
        });
    }
    Ok((cfg, report))
}

/// What `instrument check` prints without `--json`.
fn print_check(path: &Path, cfg: &InstrumentConfig, report: &serde_json::Value) -> CliResult<()> {
    let lockin = &cfg.detector.lockin;
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
            if a.kind == ControllerKind::Smc100 && a.port.is_none() {
                writeln!(
                    w,
                    "  {:<12} address {:>2}  limits [{}, {}] {}",
                    a.name, a.address, a.min, a.max, a.units
                )?;
            } else {
                writeln!(
                    w,
                    "  {:<12} {} on {}  limits [{}, {}] {}",
                    a.name,
                    a.kind.as_str(),
                    cfg.motion.port_of(a),
                    a.min,
                    a.max,
                    a.units
                )?;
            }
        }
        match cfg.detector.kind {
            DetectorKind::Sr830 => writeln!(
                w,
                "detector: {} at {} baud; {} V full scale, {} s, {} dB/oct, {} samples",
                cfg.detector.port,
                cfg.detector.baud,
                lockin.sensitivity.volts(),
                lockin.time_constant.seconds(),
                lockin.slope.db_per_octave(),
                lockin.samples
            )?,
            DetectorKind::K6485 => {
                let p = cfg.detector.picoammeter();
                writeln!(
                    w,
                    "detector: K6485 on {} at {} baud; {}{}, {} PLC at {} Hz, {} samples",
                    cfg.detector.port,
                    cfg.detector.baud,
                    p.range,
                    if p.autorange { " (autorange)" } else { "" },
                    p.nplc,
                    p.line_frequency_hz,
                    p.samples
                )?;
            }
        }
        if let Some(m) = &cfg.monochromator {
            let c = &m.cs130;
            writeln!(
                w,
                "monochromator: CS130 on {} at {} baud; {} grating(s) over {}–{} nm, order filters {}",
                m.port,
                m.baud,
                c.gratings.len(),
                c.gratings
                    .iter()
                    .map(|g| g.min_nm)
                    .fold(f64::INFINITY, f64::min),
                c.gratings.iter().map(|g| g.max_nm).fold(0.0, f64::max),
                if c.auto_order_filter {
                    "chosen by wavelength"
                } else {
                    "left as they are"
                }
            )?;
        }
        if let Some(wh) = &cfg.filter_wheel {
            writeln!(
                w,
                "filter wheel: FW102C on {} at {} baud; {} positions, {} filter(s)",
                wh.port,
                wh.baud,
                wh.fw102c.positions,
                wh.fw102c.filters.len()
            )?;
        }
        if let Some(c) = report.get("connected") {
            let mut shown = c.clone();
            if let Some(o) = shown.as_object_mut() {
                o.remove("unconfirmed");
            }
            writeln!(w, "connected: {shown}")?;
            for f in c["unconfirmed"].as_array().into_iter().flatten() {
                writeln!(
                    w,
                    "unconfirmed for {} (check these on the hardware; docs/instruments/):",
                    f["family"].as_str().unwrap_or("?")
                )?;
                for u in f["unconfirmed"].as_array().into_iter().flatten() {
                    writeln!(
                        w,
                        "  - {} (check: {})",
                        u["fact"].as_str().unwrap_or(""),
                        u["check"].as_str().unwrap_or("")
                    )?;
                }
            }
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
