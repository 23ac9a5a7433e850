//! What `gonio-sim` and `gonio sim` run: the simulator on pseudo-terminals, announced
//! by one JSON line on stdout.

use std::io::{Read, Write};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use crate::{PtySim, SimClock, SimConfig, SimConfigError, SimInstrument};

/// Options of the serve command (`gonio-sim` and `gonio sim` share them).
#[derive(Clone, Debug, Default, clap::Args)]
pub struct ServeArgs {
    /// Simulator config (TOML); the embedded default when absent.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Override the config's seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Wall seconds per physical second (> 0; default 1, real time).
    #[arg(long)]
    pub time_scale: Option<f64>,
}

/// Why serving failed.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// Bad config or arguments.
    #[error("{0}")]
    Config(#[from] SimConfigError),
    /// Bad argument.
    #[error("{0}")]
    Argument(String),
    /// The ptys could not be created or stdout written.
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

impl ServeError {
    /// Exit status: 2 for bad input, 1 otherwise.
    pub fn exit_code(&self) -> u8 {
        match self {
            ServeError::Config(_) | ServeError::Argument(_) => 2,
            ServeError::Io(_) => 1,
        }
    }
}

/// Serves the simulator on two ptys until `stdin` reaches end of file.
pub fn serve(args: ServeArgs, stdin: &mut dyn Read) -> Result<(), ServeError> {
    let mut cfg = match &args.config {
        Some(p) => SimConfig::load(p)?,
        None => SimConfig::default_config()?,
    };
    if let Some(s) = args.seed {
        cfg.seed = s;
    }
    if let Some(t) = args.time_scale {
        if !(t.is_finite() && t > 0.0) {
            return Err(ServeError::Argument(format!(
                "--time-scale: {t} must be positive (a simulator in its own process follows the wall clock)"
            )));
        }
        cfg.time_scale = t;
    }
    // Another process drives it through real time: a free-running clock.
    let scale = if cfg.time_scale > 0.0 {
        cfg.time_scale
    } else {
        1.0
    };
    let sim = SimInstrument::new(&cfg, SimClock::free_running(scale))?;
    let pty = PtySim::spawn(Arc::new(Mutex::new(sim)))?;
    let line = serde_json::json!({
        "motion": pty.motion.display().to_string(),
        "detector": pty.detector.display().to_string(),
        "seed": cfg.seed,
        "time_scale": scale,
    });
    let mut out = std::io::stdout().lock();
    writeln!(out, "{line}")?;
    out.flush()?;
    drop(out);
    let mut sink = [0u8; 256];
    while stdin.read(&mut sink)? > 0 {}
    drop(pty);
    Ok(())
}
