//! What `gonio-sim` and `gonio sim` run: the simulator on pseudo-terminals, on a
//! free-running clock, announced by one JSON line.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use crate::{PtySim, SimClock, SimConfig, SimConfigError, SimInstrument};

/// What to serve (`gonio-sim` and `gonio sim` take the same options).
#[derive(Clone, Debug, Default)]
pub struct ServeOptions {
    /// Simulator config (TOML); the embedded default when absent.
    pub config: Option<PathBuf>,
    /// Override the config's seed.
    pub seed: Option<u64>,
    /// Wall seconds per physical second (> 0; default 1, real time).
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
    /// The ptys could not be created.
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

/// A simulator being served on two pseudo-terminals; dropping it stops serving.
#[derive(Debug)]
pub struct Served {
    /// The ptys.
    pub pty: PtySim,
    /// The seed in use.
    pub seed: u64,
    /// The time scale in use.
    pub time_scale: f64,
}

impl Served {
    /// The one JSON line that announces the ports: `{"motion": …, "detector": …,
    /// "seed": …, "time_scale": …}`.
    pub fn announcement(&self) -> String {
        serde_json::json!({
            "motion": self.pty.motion.display().to_string(),
            "detector": self.pty.detector.display().to_string(),
            "apt": self.pty.apt.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
            "monochromator": self.pty.monochromator.as_ref().map(|p| p.display().to_string()),
            "filter_wheel": self.pty.filter_wheel.as_ref().map(|p| p.display().to_string()),
            "seed": self.seed,
            "time_scale": self.time_scale,
        })
        .to_string()
    }
}

/// Starts serving the simulator `opts` describes on two ptys, on a free-running
/// clock (another process drives it through real time).
pub fn serve(opts: &ServeOptions) -> Result<Served, ServeError> {
    let mut cfg = match &opts.config {
        Some(p) => SimConfig::load(p)?,
        None => SimConfig::default_config()?,
    };
    if let Some(s) = opts.seed {
        cfg.seed = s;
    }
    if let Some(t) = opts.time_scale {
        if !(t.is_finite() && t > 0.0) {
            return Err(ServeError::Argument(format!(
                "--time-scale: {t} must be positive (a simulator in its own process follows the wall clock)"
            )));
        }
        if let Err(m) = crate::config::limits::TIME_SCALE.check(t) {
            return Err(ServeError::Argument(format!("--time-scale: {m}")));
        }
        cfg.time_scale = t;
    }
    let scale = if cfg.time_scale > 0.0 {
        cfg.time_scale
    } else {
        1.0
    };
    cfg.prepare_sample()?;
    let sim = SimInstrument::new(&cfg, SimClock::free_running(scale))?;
    let pty = PtySim::spawn(Arc::new(Mutex::new(sim)))?;
    tracing::info!(
        motion = %pty.motion.display(),
        detector = %pty.detector.display(),
        seed = cfg.seed,
        "simulator serving"
    );
    Ok(Served {
        pty,
        seed: cfg.seed,
        time_scale: scale,
    })
}
