//! Flag groups several commands share, defined once and flattened into each
//! command's arguments.

use gonio_dataset::OpenOptions;
use gonio_process::GridStep;
use gonio_reduce::{Calibration, Drift};

use crate::error::{CliError, CliResult};

/// `--json`.
#[derive(Clone, Copy, Debug, clap::Args)]
pub struct JsonFlag {
    /// Print one JSON object on stdout instead of text.
    #[arg(long)]
    pub json: bool,
}

/// How a run file's readings are reduced (`--calibration`, `--drift`).
#[derive(Clone, Debug, clap::Args)]
pub struct ReduceFlags {
    /// The calibration giving the incident flux: auto, incident or standard.
    #[arg(long, default_value = "auto")]
    pub calibration: String,
    /// Drift correction: auto (reference readings), calibrations, none.
    #[arg(long, default_value = "auto")]
    pub drift: String,
}

impl Default for ReduceFlags {
    fn default() -> Self {
        ReduceFlags {
            calibration: "auto".into(),
            drift: "auto".into(),
        }
    }
}

impl ReduceFlags {
    /// The reduction options, checked.
    pub fn options(&self) -> CliResult<gonio_reduce::Options> {
        let calibration = match self.calibration.as_str() {
            "auto" => Calibration::Auto,
            "incident" => Calibration::Incident,
            "standard" => Calibration::Standard,
            x => {
                return Err(CliError::Input(format!(
                    "--calibration: expected auto, incident or standard, got {x:?}"
                )));
            }
        };
        let drift = match self.drift.as_str() {
            "auto" => Drift::Auto,
            "calibrations" => Drift::Calibrations,
            "none" => Drift::None,
            x => {
                return Err(CliError::Input(format!(
                    "--drift: expected auto, calibrations or none, got {x:?}"
                )));
            }
        };
        Ok(gonio_reduce::Options {
            calibration,
            drift,
            ..gonio_reduce::Options::default()
        })
    }

    /// How inputs are opened with these reduction options.
    pub fn open_options(&self) -> CliResult<OpenOptions> {
        Ok(OpenOptions {
            reduce: self.options()?,
        })
    }
}

/// `--grid DTHETA,DPHI`.
#[derive(Clone, Copy, Debug, clap::Args)]
pub struct GridFlag {
    /// Resample (or tabulate a model) on a hemisphere grid of DTHETA,DPHI degrees
    /// (polar band midpoints, a full turn of azimuth; nearest-j kernel for measured
    /// data, DeYoung Sec. 3.2.1).
    #[arg(long, value_parser = parse_grid)]
    pub grid: Option<GridStep>,
}

/// A grid given as `DTHETA,DPHI` in degrees.
pub fn parse_grid(s: &str) -> Result<GridStep, String> {
    s.parse()
}
