//! The sample on the simulated stage, as the sim config gives it: a model file (or the
//! embedded blue paint), a table file, or a microgeometry surface traced into a table;
//! read, traced and loaded once, its text kept for a run file.

use std::path::{Path, PathBuf};

use gonio_brdf::{Brdf, Model};
use serde::Deserialize;

use super::{KIND, SimConfig, SimConfigError};
use crate::twin::ensure;

/// The most bytes a table sample (`[sample] table`) may have: 1 GiB, a 5° × 5° full
/// 4-D RGB table with its uncertainties about twice over. The simulator holds the
/// whole table, and a run file keeps its text.
pub const MAX_TABLE_BYTES: u64 = 1 << 30;

/// The embedded default sample.
const BLUE_PAINT: &str = include_str!("../../../config/models/blue-paint-550nm.toml");

/// The sample on the stage.
#[derive(Clone, Debug, PartialEq, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct SampleConfig {
    /// A model file (relative to the config file's directory).
    pub model: Option<PathBuf>,
    /// The channel the detector sees (a name like `G` or `550nm`); the first if absent.
    pub channel: Option<String>,
    /// A measured or tabulated BRDF instead of a model: a table file of
    /// `docs/processing.md` (CSV with a grid header), interpolated quadrilinearly.
    pub table: Option<PathBuf>,
    /// A microgeometry sample instead of a model: its BRDF is tabulated by ray tracing
    /// (`gonio-micro`) when the sample is first prepared.
    pub micro: Option<MicroSampleConfig>,
}

/// What the sample is, as the config gives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleKind {
    /// A model file (or the embedded blue paint).
    Model,
    /// A table file.
    Table,
    /// A microgeometry surface, tabulated by ray tracing.
    Micro,
}

/// A microgeometry sample (`[sample.micro]`): a `gonio micro` surface file and how to
/// tabulate it. The table is traced once, by [`SimConfig::prepare_sample`] (or when
/// the simulator is built), and its text is what a run file keeps, so a resumed run
/// measures the same table without tracing again.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MicroSampleConfig {
    /// The surface file (relative to the config file's directory).
    pub surface: PathBuf,
    /// The table's grid, [DTHETA, DPHI] degrees (polar band midpoints, a full turn).
    #[serde(default = "default_micro_grid")]
    pub grid: [f64; 2],
    /// Tabulate the isotropic form (θi, φo − φi, θo): right for isotropic surfaces,
    /// and far cheaper.
    #[serde(default = "default_true")]
    pub isotropic: bool,
    /// Rays per incident direction of the grid.
    #[serde(default = "default_micro_rays")]
    pub rays: usize,
    /// Seed of the ray tracer (the same seed, the same table).
    #[serde(default)]
    pub seed: u64,
}

fn default_micro_grid() -> [f64; 2] {
    [10.0, 15.0]
}

fn default_true() -> bool {
    true
}

fn default_micro_rays() -> usize {
    50_000
}

impl MicroSampleConfig {
    /// The surface file's path, resolved against the config file's directory.
    pub fn surface_path(&self, config: Option<&Path>) -> PathBuf {
        match config.and_then(Path::parent) {
            Some(b) if self.surface.is_relative() => b.join(&self.surface),
            _ => self.surface.clone(),
        }
    }
}

/// A sample BRDF prepared outside the simulator (a tabulated microgeometry), shared
/// by every simulator built from the config.
#[derive(Clone)]
pub struct PreparedSample(pub std::sync::Arc<dyn Brdf>);

impl std::fmt::Debug for PreparedSample {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "PreparedSample({})", self.0.channels())
    }
}

impl PartialEq for PreparedSample {
    fn eq(&self, o: &Self) -> bool {
        std::sync::Arc::ptr_eq(&self.0, &o.0)
    }
}

/// A [`PreparedSample`] as the `Box<dyn Brdf>` the optics hold.
struct Shared(std::sync::Arc<dyn Brdf>);

impl Brdf for Shared {
    fn channels(&self) -> &gonio_core::Channels {
        self.0.channels()
    }
    fn eval(&self, wi: gonio_core::Dir, wo: gonio_core::Dir, out: &mut [f64]) {
        self.0.eval(wi, wo, out)
    }
    fn proposals(&self, wi: gonio_core::Dir, out: &mut Vec<gonio_brdf::Weighted>) {
        self.0.proposals(wi, out)
    }
    fn mirror(&self, wi: gonio_core::Dir, out: &mut [f64]) -> bool {
        self.0.mirror(wi, out)
    }
    fn is_reciprocal(&self) -> bool {
        self.0.is_reciprocal()
    }
    fn albedo(&self, wi: gonio_core::Dir, out: &mut [f64]) {
        self.0.albedo(wi, out)
    }
}

impl SimConfig {
    /// What the sample is: a model, a table or a microgeometry.
    pub fn sample_kind(&self) -> SampleKind {
        if self.sample.micro.is_some() {
            SampleKind::Micro
        } else if self.sample.table.is_some() {
            SampleKind::Table
        } else {
            SampleKind::Model
        }
    }

    fn sample_error(&self, field: &str, message: String) -> SimConfigError {
        SimConfigError {
            field: Some(field.into()),
            ..SimConfigError::whole(KIND, self.source.as_deref(), message)
        }
    }

    /// A path from the config, resolved against the config file's directory.
    fn resolve(&self, p: &Path) -> PathBuf {
        match self.source.as_deref().and_then(Path::parent) {
            Some(b) if p.is_relative() => b.join(p),
            _ => p.to_path_buf(),
        }
    }

    /// The sample as text, as a run file keeps it: [`sample_text`](Self::sample_text)
    /// when set; else the model file `sample.model` names (the embedded blue paint
    /// without one), the table file `sample.table` names, or the table a
    /// `[sample.micro]` surface traces to (tracing it: prefer
    /// [`prepare_sample`](Self::prepare_sample), which keeps the result).
    pub fn sample_model_text(&self) -> Result<String, SimConfigError> {
        if let Some(t) = &self.sample_text {
            return Ok(t.clone());
        }
        match self.sample_kind() {
            SampleKind::Micro => Ok(self.trace_micro()?.1),
            SampleKind::Table => {
                let p = self.sample.table.as_deref().unwrap_or(Path::new(""));
                let path = self.resolve(p);
                let text = gonio_core::input::read_text(&path, MAX_TABLE_BYTES)
                    .map_err(|e| self.sample_error("sample.table", e.to_string()))?;
                // A table file of format 2 keeps its grid in a sidecar; the run file
                // keeps one text, so the grid is written into it.
                let side = gonio_process::file::sidecar_path(&path);
                if !side.exists() {
                    return Ok(text);
                }
                let err =
                    |e: &dyn std::fmt::Display| self.sample_error("sample.table", e.to_string());
                let meta_text =
                    gonio_core::input::read_text(&side, gonio_core::input::MAX_CONFIG_BYTES)
                        .map_err(|e| err(&e))?;
                let meta = gonio_process::file::Meta::from_json(&meta_text, Some(&side))
                    .map_err(|e| err(&e))?;
                match gonio_process::file::read_from(
                    text.as_bytes(),
                    text.len() as u64,
                    Some(&meta),
                    Some(&path),
                )
                .map_err(|e| err(&e))?
                {
                    gonio_process::file::Content::Table(t) => {
                        Ok(gonio_process::file::write_table_self_contained(&t))
                    }
                    gonio_process::file::Content::Samples(_) => Ok(text),
                }
            }
            SampleKind::Model => match &self.sample.model {
                Some(p) => {
                    let path = self.resolve(p);
                    gonio_core::input::read_text(&path, gonio_core::input::MAX_CONFIG_BYTES)
                        .map_err(|e| self.sample_error("sample.model", e.to_string()))
                }
                None => Ok(BLUE_PAINT.to_string()),
            },
        }
    }

    /// Traces a `[sample.micro]` surface into its table: the BRDF and its text.
    fn trace_micro(&self) -> Result<(std::sync::Arc<dyn Brdf>, String), SimConfigError> {
        let Some(m) = &self.sample.micro else {
            return Err(self.sample_error("sample.micro", "no microgeometry sample".into()));
        };
        let surface = m.surface_path(self.source.as_deref());
        let err = |e: &dyn std::fmt::Display| {
            let msg = e.to_string();
            // Surface-file errors already start with the file's name.
            if msg.starts_with(&surface.display().to_string()) {
                self.sample_error("sample.micro.surface", msg)
            } else {
                self.sample_error(
                    "sample.micro.surface",
                    format!("{}: {msg}", surface.display()),
                )
            }
        };
        let sample = gonio_micro::Sample::load(&surface).map_err(|e| err(&e))?;
        let sim = gonio_micro::Simulation::new(sample, gonio_micro::SimOptions::default())
            .map_err(|e| err(&e))?;
        let step = gonio_process::GridStep::new(m.grid[0], m.grid[1])
            .map_err(|e| self.sample_error("sample.micro.grid", e))?;
        let grid = if m.isotropic {
            step.isotropic_grid()
        } else {
            step.grid()
        };
        tracing::info!(
            surface = %surface.display(),
            rays = m.rays,
            seed = m.seed,
            "tracing the microgeometry sample"
        );
        let r = sim.to_table(&grid, m.rays, m.seed).map_err(|e| err(&e))?;
        // The run file keeps this text alone, with no sidecar: the grid goes in it.
        let text = gonio_process::file::write_table_self_contained(&r.table);
        Ok((std::sync::Arc::new(r.table), text))
    }

    /// Reads a table sample's text: a table (its grid line), or rows that form a
    /// complete uniform grid.
    fn table_of(&self, text: &str, field: &str) -> Result<gonio_process::Table, SimConfigError> {
        match gonio_process::file::read(text, None) {
            Ok(gonio_process::file::Content::Table(t)) => Ok(t),
            Ok(gonio_process::file::Content::Samples(s)) => s.to_table().ok_or_else(|| {
                self.sample_error(
                    field,
                    "the sample's text holds scattered samples, not a table".into(),
                )
            }),
            Err(e) => Err(self.sample_error(field, format!("sample table: {e}"))),
        }
    }

    /// Loads (or traces) the sample once and keeps it with its text, so that every
    /// simulator built from this config, and the run file, share it. Nothing to do
    /// when it is already prepared.
    pub fn prepare_sample(&mut self) -> Result<(), SimConfigError> {
        if self.prepared.is_some() {
            return Ok(());
        }
        let (brdf, text): (std::sync::Arc<dyn Brdf>, String) = match self.sample_kind() {
            SampleKind::Micro if self.sample_text.is_none() => self.trace_micro()?,
            SampleKind::Micro | SampleKind::Table => {
                let field = if self.sample_kind() == SampleKind::Micro {
                    "sample.micro"
                } else {
                    "sample.table"
                };
                let text = self.sample_model_text()?;
                (std::sync::Arc::new(self.table_of(&text, field)?), text)
            }
            SampleKind::Model => {
                let text = self.sample_model_text()?;
                let m = Model::from_toml(&text, self.sample.model.as_deref())
                    .map_err(|e| self.sample_error("sample.model", e.to_string()))?;
                (std::sync::Arc::new(m), text)
            }
        };
        self.set_sample(brdf, text);
        Ok(())
    }

    /// Hands over a sample prepared outside the simulator (any `Brdf`) and the text a
    /// run file keeps for it.
    pub fn set_sample(&mut self, brdf: std::sync::Arc<dyn Brdf>, text: String) {
        self.prepared = Some(PreparedSample(brdf));
        self.sample_text = Some(text);
    }

    /// Loads the sample (preparing it if needed) and finds the measured channel.
    pub fn load_sample(&self) -> Result<(Box<dyn Brdf>, usize), SimConfigError> {
        let model: Box<dyn Brdf> = match &self.prepared {
            Some(p) => Box::new(Shared(p.0.clone())),
            None => {
                let mut c = self.clone();
                c.prepare_sample()?;
                match c.prepared {
                    Some(p) => Box::new(Shared(p.0)),
                    None => {
                        return Err(self.sample_error("sample", "not prepared".into()));
                    }
                }
            }
        };
        let channel = match &self.sample.channel {
            None => 0,
            Some(name) => model.channels().index_of(name).ok_or_else(|| {
                self.sample_error(
                    "sample.channel",
                    format!("the sample has channels {}, not {name:?}", model.channels()),
                )
            })?,
        };
        Ok((model, channel))
    }

    /// The sample's fields: one kind of sample, and a microgeometry's grid and rays.
    pub(crate) fn validate_sample(&self) -> Result<(), (String, String)> {
        let s = &self.sample;
        let m = "a sample is a model or a table, not both (remove sample.model)";
        ensure!(s.table.is_none() || s.model.is_none(); "sample.table", "{m}");
        if let Some(m) = &s.micro {
            let why = "a sample is a model, a table or a microgeometry, not more than one";
            let ok = s.model.is_none() && s.table.is_none();
            ensure!(ok; "sample.micro", "{why} (remove sample.model or sample.table)");
            let [dt, dp] = m.grid;
            let divides = |step: f64, of: f64| step > 0.0 && (of / step).fract().abs() < 1e-9;
            let ok = divides(dt, 90.0) && divides(dp, 360.0);
            let why = "[DTHETA, DPHI] must divide 90° and 360°";
            ensure!(ok; "sample.micro.grid", "{why}, got {:?}", m.grid);
            // The node cap of a grid (gonio_process::MAX_GRID_NODES).
            gonio_process::GridStep::new(dt, dp).map_err(|e| ("sample.micro.grid".into(), e))?;
            gonio_core::limits::count_at(
                "sample.micro.rays",
                m.rays as u64,
                2,
                gonio_micro::MAX_RAYS as u64,
                "rays",
            )?;
        }
        Ok(())
    }
}
