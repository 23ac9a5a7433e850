//! Every input Gonio takes, opened one way.
//!
//! [`detect`] recognises a file's [`Kind`] from its content alone (never its name):
//! a run file (SQLite with Gonio's header), a MERL binary, an RGL material
//! (`.bsdf`, Mitsuba 3's `measured`), ASTM text, Gonio's CSV
//! (a table when it has a grid line, else samples), or a TOML file — a separable
//! representation, spherical harmonics, or else an analytic model. [`open`] reads
//! it into a [`Dataset`], reducing a run file on the way (its
//! [`gonio_reduce::Reduction`] account is kept), and every command takes
//! the dataset from there: as a table on a grid ([`Dataset::to_table`]), as samples
//! ([`Dataset::to_samples`]), as a BRDF to evaluate ([`Dataset::brdf`]), or as what
//! an export format holds ([`Dataset::to_format_data`]).

use std::path::{Path, PathBuf};

use gonio_brdf::{Brdf, Model};
use gonio_core::Channels;
use gonio_io::formats::{self, Data, FormatError, MerlBrdf, RglBsdf};
use gonio_process::hemisphere::{self, Fill, Symmetry};
use gonio_process::samples::Kernel;
use gonio_process::separable::SeparableBrdf;
use gonio_process::sh::ShBrdf;
use gonio_process::{GridStep, ProcessError, Samples, Table};
use gonio_reduce::{ReduceError, Reduction};
use gonio_run::{RunStore, StoreError};

/// The largest text input read (a 5° full 4-D RGB table with uncertainties is
/// ~0.5 GB of text; anything past this is refused rather than read into memory).
pub const MAX_TEXT_BYTES: u64 = 4 << 30;

/// The grid analytic inputs (models, harmonics) are tabulated on when a command
/// needs a table and none is given: 10° × 10°.
pub const DEFAULT_STEP: GridStep = GridStep {
    dtheta_deg: 10.0,
    dphi_deg: 10.0,
};

/// What a file is, from its content.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A run file (`.gonio`, SQLite).
    Run,
    /// A MERL binary table.
    Merl,
    /// An RGL material (a tensor file, `.bsdf`).
    Rgl,
    /// ASTM E1392-style text.
    Astm,
    /// Gonio's CSV: a table or samples, wide (a column a channel) or long (a row a
    /// wavelength, `gonio_io::formats::long`).
    Csv,
    /// A k-separable representation (TOML, `kind = "separable"`).
    Separable,
    /// Spherical harmonics (TOML, `kind = "spherical-harmonics"`).
    Harmonics,
    /// An analytic model file (TOML).
    Model,
}

impl Kind {
    /// A name for messages and JSON.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Run => "run",
            Kind::Merl => "merl",
            Kind::Rgl => "rgl",
            Kind::Astm => "astm",
            Kind::Csv => "csv",
            Kind::Separable => "separable",
            Kind::Harmonics => "harmonics",
            Kind::Model => "model",
        }
    }
}

/// Why an input could not be opened or used.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// Larger than [`MAX_TEXT_BYTES`].
    #[error("{}: larger than {MAX_TEXT_BYTES} bytes, the most an input may have", .0.display())]
    TooLarge(PathBuf),
    /// Not a regular file (a directory, a FIFO, a device): refused without being read.
    #[error("{0}")]
    NotRegular(gonio_core::input::InputError),
    /// Not a format Gonio reads, or malformed in it.
    #[error("{0}")]
    Format(#[from] FormatError),
    /// A model, separable or harmonics file that does not parse.
    #[error("{0}")]
    File(#[from] gonio_core::tomlfile::FileError),
    /// A model file that does not parse.
    #[error("{0}")]
    Model(#[from] gonio_brdf::ModelError),
    /// The run file.
    #[error("{0}")]
    Run(#[from] StoreError),
    /// The run file's reduction.
    #[error("{0}")]
    Reduce(#[from] ReduceError),
    /// Processing refused the data (a grid it cannot support, bad values).
    #[error("{path}: {source}")]
    Process {
        /// The input.
        path: PathBuf,
        /// The cause.
        #[source]
        source: ProcessError,
    },
    /// Samples that cover no area of the outgoing hemisphere at any incidence (an
    /// in-plane scan) where a table is needed: no grid can be made of them.
    #[error(
        "{}: its {samples} samples cover no area of the outgoing hemisphere at any incident \
         direction (an in-plane scan): DeYoung's measures and transforms need data over the \
         hemisphere; fit, export and the polar plot take the samples as they are",
        .path.display()
    )]
    NotHemisphere {
        /// The input.
        path: PathBuf,
        /// How many samples.
        samples: usize,
    },
    /// Scattered samples where a table is needed, no grid was given, and the
    /// samples form no grid of their own.
    #[error(
        "{}: its {samples} samples do not form a grid of their own ({why}); pass --grid \
         DTHETA,DPHI to resample them (nearest-j Gaussian kernel, DeYoung Sec. 3.2.1)",
        .path.display()
    )]
    NotOnGrid {
        /// The input.
        path: PathBuf,
        /// How many samples.
        samples: usize,
        /// Why not.
        why: String,
    },
}

impl DatasetError {
    /// True for faults of the input (exit status 2), false for failures of the
    /// machine or the numerics (exit status 1).
    pub fn is_bad_input(&self) -> bool {
        match self {
            DatasetError::Run(e) => e.is_bad_input(),
            DatasetError::Reduce(ReduceError::Store(e)) => e.is_bad_input(),
            DatasetError::Process { source, .. } => !matches!(source, ProcessError::Numerics(_)),
            _ => true,
        }
    }

    /// An input the reading helper refused, as the variant that says why.
    fn input(e: gonio_core::input::InputError) -> DatasetError {
        use gonio_core::input::InputError;
        match e {
            InputError::Io { path, source } => DatasetError::Io { path, source },
            InputError::TooLarge { path, .. } => DatasetError::TooLarge(path),
            other => DatasetError::NotRegular(other),
        }
    }

    fn process(path: &Path, source: ProcessError) -> DatasetError {
        DatasetError::Process {
            path: path.to_path_buf(),
            source,
        }
    }
}

/// The data of an input.
#[derive(Clone, Debug)]
pub enum Dataset {
    /// Values on a grid (a table file, a run or CSV whose samples form a grid).
    Table(Table),
    /// Scattered samples.
    Samples(Samples),
    /// A MERL table of half/difference bins.
    Merl(Box<MerlBrdf>),
    /// An RGL material, evaluated as Mitsuba 3's `measured` plugin does.
    Rgl(Box<RglBsdf>),
    /// An analytic model.
    Model(Box<Model>),
    /// A k-separable representation.
    Separable(Box<SeparableBrdf>),
    /// Spherical harmonics.
    Harmonics(Box<ShBrdf>),
}

/// A table made from an input ([`Dataset::tabulate`]) and what was assumed on the way.
#[derive(Clone, Debug)]
pub struct Tabulated {
    /// The table.
    pub table: Table,
    /// The symmetry assumed of measured data (none for analytic inputs).
    pub symmetry: Symmetry,
    /// For samples tabulated on their own grid: which nodes were interpolated.
    pub fill: Option<Fill>,
    /// The samples a table of measured data was formed from (unfolded when the
    /// symmetry says so); none for tables and analytic inputs.
    pub measured: Option<Samples>,
}

/// An opened input: what it was, its data, and, for a run file, the reduction's
/// account.
#[derive(Clone, Debug)]
pub struct Opened {
    /// The file.
    pub path: PathBuf,
    /// What it was.
    pub kind: Kind,
    /// Its data.
    pub data: Dataset,
    /// The reduction, for a run file.
    pub reduction: Option<Reduction>,
}

/// How inputs are opened.
#[derive(Clone, Debug, Default)]
pub struct OpenOptions {
    /// How a run file's readings are reduced.
    pub reduce: gonio_reduce::Options,
}

/// The first bytes of a run file (any SQLite database).
const SQLITE_MAGIC: &[u8; 16] = b"SQLite format 3\0";

/// The kind of `bytes` (a whole file, or at least its first 64 KiB), or `None` when
/// Gonio reads no such file.
pub fn detect(bytes: &[u8]) -> Option<Kind> {
    if bytes.starts_with(SQLITE_MAGIC) {
        return Some(Kind::Run);
    }
    if let Some(k) = toml_kind(bytes) {
        return Some(k);
    }
    formats::detect(bytes).map(|f| match f {
        formats::Format::Merl => Kind::Merl,
        formats::Format::Rgl => Kind::Rgl,
        formats::Format::Astm => Kind::Astm,
        formats::Format::Csv | formats::Format::CsvLong => Kind::Csv,
    })
}

/// A TOML file's kind: its first line that is neither blank nor a comment starts
/// with `kind` or a `[table]` (after any byte order mark); `kind = "separable"` and
/// `kind = "spherical-harmonics"` name the representations, anything else is a model.
fn toml_kind(bytes: &[u8]) -> Option<Kind> {
    let bytes = gonio_core::text::strip_bom_bytes(bytes);
    let text = match std::str::from_utf8(bytes) {
        Ok(t) => t,
        Err(e) => std::str::from_utf8(&bytes[..e.valid_up_to()]).ok()?,
    };
    let first = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))?;
    if !(first.starts_with("kind") || first.starts_with('[')) {
        return None;
    }
    let kind = text
        .lines()
        .map(str::trim)
        .find(|l| l.starts_with("kind"))
        .and_then(|l| l.split_once('='))
        .map(|(_, v)| v.trim().trim_matches('"').to_string());
    Some(match kind.as_deref() {
        Some("separable") => Kind::Separable,
        Some("spherical-harmonics") => Kind::Harmonics,
        _ => Kind::Model,
    })
}

/// Opens any input: a run file (reduced with `opts`), a table or samples CSV, a MERL
/// or ASTM file, a separable or harmonics file, or a model file.
pub fn open(path: &Path, opts: &OpenOptions) -> Result<Opened, DatasetError> {
    let _span = tracing::debug_span!("open", path = %path.display()).entered();
    // Examined before anything is opened: a FIFO, a device or a directory is refused
    // here, and nothing longer than the cap is read (gonio_core::input).
    let head = gonio_core::input::read_head(path, 16).map_err(DatasetError::input)?;
    if head.as_slice() == SQLITE_MAGIC {
        let (data, red) = open_run(path, opts)?;
        tracing::debug!(kind = "run", samples = red.samples.samples.len(), "opened");
        return Ok(Opened {
            path: path.to_path_buf(),
            kind: Kind::Run,
            data,
            reduction: Some(red),
        });
    }
    let (kind, data) = if let Some(f) = csv_format(path)? {
        // With its sidecar; the wide form streamed, so a large table is never held as
        // text.
        let data = match f {
            formats::Format::CsvLong => formats::read_long_file(path, MAX_TEXT_BYTES)?,
            _ => read_wide_csv(path)?,
        };
        (Kind::Csv, from_data(data, path)?)
    } else {
        let bytes =
            gonio_core::input::read_bounded(path, MAX_TEXT_BYTES).map_err(DatasetError::input)?;
        open_bytes(&bytes, path)?
    };
    tracing::debug!(kind = kind.name(), "opened");
    Ok(Opened {
        path: path.to_path_buf(),
        kind,
        data,
        reduction: None,
    })
}

/// Reduces a run file into samples (a table when they form a grid).
fn open_run(path: &Path, opts: &OpenOptions) -> Result<(Dataset, Reduction), DatasetError> {
    let store = RunStore::open_read_only(path)?;
    let red = gonio_reduce::reduce(&store, &opts.reduce)?;
    let data = match red.samples.to_table() {
        Some(t) => Dataset::Table(t),
        None => Dataset::Samples(red.samples.clone()),
    };
    Ok((data, red))
}

/// Opens the bytes of any input but a run file; `path` names it in errors.
pub fn open_bytes(bytes: &[u8], path: &Path) -> Result<(Kind, Dataset), DatasetError> {
    let text = std::str::from_utf8(bytes).unwrap_or("");
    match toml_kind(bytes) {
        Some(Kind::Separable) => {
            let s = SeparableBrdf::from_toml(text, Some(path))?;
            return Ok((Kind::Separable, Dataset::Separable(Box::new(s))));
        }
        Some(Kind::Harmonics) => {
            let sh = ShBrdf::from_toml(text, Some(path))?;
            return Ok((Kind::Harmonics, Dataset::Harmonics(Box::new(sh))));
        }
        Some(_) => {
            let m = Model::from_toml(text, Some(path))?;
            return Ok((Kind::Model, Dataset::Model(Box::new(m))));
        }
        None => {}
    }
    // Recognised once: a format detected is read as that format; anything else goes
    // to the reader that says best what is wrong with it.
    let detected = formats::detect(bytes);
    let kind = match detected {
        Some(formats::Format::Astm) => Kind::Astm,
        Some(formats::Format::Csv | formats::Format::CsvLong) => Kind::Csv,
        Some(formats::Format::Rgl) => Kind::Rgl,
        _ => Kind::Merl,
    };
    let read = match detected {
        Some(f) => formats::read_as(f, bytes, Some(path)),
        None => formats::read(bytes, Some(path)),
    };
    Ok((kind, from_data(read?, path)?))
}

/// Which of Gonio's CSV forms `path` holds (wide or long), if either, from its
/// first 64 KiB.
fn csv_format(path: &Path) -> Result<Option<formats::Format>, DatasetError> {
    let head = gonio_core::input::read_head(path, 64 << 10).map_err(DatasetError::input)?;
    if toml_kind(&head).is_some() {
        return Ok(None);
    }
    match formats::detect(&head) {
        Some(f @ (formats::Format::Csv | formats::Format::CsvLong)) => Ok(Some(f)),
        // Another tool's table: the columns in another order, units in the names.
        None if gonio_process::file::is_columns_header(&head) => Ok(Some(formats::Format::Csv)),
        _ => Ok(None),
    }
}

/// Reads a wide CSV table or sample file with its sidecar, in parallel and in any
/// column order (`gonio_process::file::read_columns`). A file in Gonio's own column
/// order that this refuses is read again by the streaming reader, so that its
/// errors stay word for word what they were.
fn read_wide_csv(path: &Path) -> Result<Data, DatasetError> {
    let columns = || -> Result<Data, DatasetError> {
        let meta = formats::read_sidecar(path)?;
        let whole =
            |why: String| gonio_core::tomlfile::FileError::whole("BRDF table", Some(path), why);
        let len = gonio_core::input::regular_file(path)
            .map_err(|e| whole(format!("cannot read: {}", e.reason())))?
            .len();
        if len > MAX_TEXT_BYTES {
            return Err(DatasetError::TooLarge(path.to_path_buf()));
        }
        let file = std::fs::File::open(path).map_err(|e| whole(format!("cannot read: {e}")))?;
        if !file.metadata().is_ok_and(|m| m.is_file()) {
            return Err(whole("cannot read: not a regular file".into()).into());
        }
        let cols = gonio_process::file::read_columns(
            std::io::Read::take(file, MAX_TEXT_BYTES),
            len,
            Some(path),
        )?;
        Ok(match cols.into_content(meta.as_ref(), Some(path))? {
            gonio_process::file::Content::Table(t) => Data::Table(t),
            gonio_process::file::Content::Samples(s) => Data::Samples(s),
        })
    };
    match columns() {
        Ok(d) => Ok(d),
        Err(e) => {
            let head = gonio_core::input::read_head(path, 64 << 10).unwrap_or_default();
            if formats::detect(&head) == Some(formats::Format::Csv) {
                Ok(formats::read_csv_file(path, MAX_TEXT_BYTES)?)
            } else {
                Err(e)
            }
        }
    }
}

/// What a format reader gave, as a dataset: samples that form a complete uniform grid
/// become its table (`Samples::to_table`), which is how a CSV table without its
/// sidecar is recognised.
fn from_data(data: Data, path: &Path) -> Result<Dataset, DatasetError> {
    Ok(match data {
        Data::Table(t) => Dataset::Table(t),
        Data::Merl(m) => Dataset::Merl(Box::new(m)),
        Data::Rgl(r) => Dataset::Rgl(r),
        Data::Samples(s) => {
            s.validate().map_err(|e| DatasetError::process(path, e))?;
            match s.to_table() {
                Some(t) => Dataset::Table(t),
                None => Dataset::Samples(s),
            }
        }
    })
}

impl Dataset {
    /// The channels.
    pub fn channels(&self) -> &Channels {
        match self {
            Dataset::Table(t) => &t.channels,
            Dataset::Samples(s) => &s.channels,
            Dataset::Merl(m) => m.channels(),
            Dataset::Rgl(r) => r.channels(),
            Dataset::Model(m) => m.channels(),
            Dataset::Separable(s) => s.channels(),
            Dataset::Harmonics(h) => &h.channels,
        }
    }

    /// A short description (`table`, `samples`, `MERL table`, `model`, …).
    pub fn describe(&self) -> &'static str {
        match self {
            Dataset::Table(_) => "table",
            Dataset::Samples(_) => "samples",
            Dataset::Merl(_) => "MERL table",
            Dataset::Rgl(_) => "RGL material",
            Dataset::Model(_) => "model",
            Dataset::Separable(_) => "separable representation",
            Dataset::Harmonics(_) => "spherical harmonics",
        }
    }

    /// The data as a BRDF that can be evaluated anywhere, when it is one; `None` for
    /// scattered samples.
    pub fn brdf(&self) -> Option<&dyn Brdf> {
        match self {
            Dataset::Table(t) => Some(t),
            Dataset::Samples(_) => None,
            Dataset::Merl(m) => Some(m.as_ref()),
            Dataset::Rgl(r) => Some(r.as_ref()),
            Dataset::Model(m) => Some(m.as_ref()),
            Dataset::Separable(s) => Some(s.as_ref()),
            Dataset::Harmonics(h) => Some(h.as_ref()),
        }
    }

    /// True for data defined everywhere by a formula or factors (a model, a
    /// separable or harmonics representation, a MERL table, an RGL material), which a grid samples
    /// exactly rather than resamples.
    pub fn is_analytic(&self) -> bool {
        matches!(
            self,
            Dataset::Merl(_)
                | Dataset::Rgl(_)
                | Dataset::Model(_)
                | Dataset::Separable(_)
                | Dataset::Harmonics(_)
        )
    }

    /// The data as a table: a table as it is (resampled onto `step` when one is
    /// given, with the nearest-j kernel), scattered samples on their own grid or
    /// resampled onto `step`, anything analytic evaluated on `step` (its own grid
    /// for a separable representation, [`DEFAULT_STEP`] otherwise, when none is
    /// given). Isotropic data measured over a half turn of Δφ are unfolded first
    /// ([`gonio_process::hemisphere::unfold`]). `path` names the input in errors.
    pub fn to_table(&self, step: Option<GridStep>, path: &Path) -> Result<Table, DatasetError> {
        Ok(self.tabulate(step, path)?.table)
    }

    /// [`Dataset::tabulate`] of data no longer needed: a table used as it is moves
    /// into the result instead of being copied (a large table's copy is a serial
    /// pass over all its values and as much memory again).
    pub fn into_tabulated(
        self,
        step: Option<GridStep>,
        path: &Path,
    ) -> Result<Tabulated, DatasetError> {
        match self {
            Dataset::Table(t) if step.is_none() && !hemisphere::half_turn(&t.grid) => {
                let symmetry = if t.grid.isotropic {
                    Symmetry::Isotropic
                } else {
                    Symmetry::None
                };
                Ok(Tabulated {
                    table: t,
                    symmetry,
                    fill: None,
                    measured: None,
                })
            }
            d => d.tabulate(step, path),
        }
    }

    /// [`Dataset::to_table`], with what was assumed and done on the way: the
    /// symmetry, the nodes of the data's own grid that were interpolated, and the
    /// (unfolded) samples of measured data, which the energy measure integrates
    /// where they are ([`gonio_process::measure::report_with`]).
    pub fn tabulate(&self, step: Option<GridStep>, path: &Path) -> Result<Tabulated, DatasetError> {
        let p = |e| DatasetError::process(path, e);
        let analytic = |table| Tabulated {
            table,
            symmetry: Symmetry::None,
            fill: None,
            measured: None,
        };
        match self {
            Dataset::Table(t) => {
                // Told from the axes: a table is turned into samples only when it
                // must be (unfolded or resampled), never for a table used as it is.
                let half = hemisphere::half_turn(&t.grid);
                let symmetry = match (half, t.grid.isotropic) {
                    (true, _) => Symmetry::IsotropicBilateral,
                    (false, true) => Symmetry::Isotropic,
                    (false, false) => Symmetry::None,
                };
                let samples = || hemisphere::unfold(&Samples::from_table(t)).0;
                let table = match step {
                    Some(g) => samples().resample_step(g, Kernel::default()).map_err(p)?,
                    None if half => samples().to_table().ok_or_else(|| {
                        p(ProcessError::Unsupported(
                            "the unfolded half turn forms no complete grid".into(),
                        ))
                    })?,
                    None => t.clone(),
                };
                Ok(Tabulated {
                    table,
                    symmetry,
                    fill: None,
                    measured: None,
                })
            }
            Dataset::Samples(s) => {
                let (s, symmetry) = hemisphere::unfold(s);
                let (table, fill) = match step {
                    Some(g) => (s.resample_step(g, Kernel::default()).map_err(p)?, None),
                    None => match s.to_table() {
                        Some(t) => (t, None),
                        None => {
                            let (t, f) = hemisphere::own_table(&s, Kernel::default()).map_err(
                                |e| match e {
                                    // Say what no grid can fix: a scan in a plane.
                                    ProcessError::Grid { .. } | ProcessError::Unsupported(_)
                                        if hemisphere::albedos(&s).is_err() =>
                                    {
                                        DatasetError::NotHemisphere {
                                            path: path.to_path_buf(),
                                            samples: s.samples.len(),
                                        }
                                    }
                                    ProcessError::Grid { .. } | ProcessError::Unsupported(_) => {
                                        DatasetError::NotOnGrid {
                                            path: path.to_path_buf(),
                                            samples: s.samples.len(),
                                            why: e.to_string(),
                                        }
                                    }
                                    e => p(e),
                                },
                            )?;
                            (t, Some(f))
                        }
                    },
                };
                Ok(Tabulated {
                    table,
                    symmetry,
                    fill,
                    measured: Some(s),
                })
            }
            Dataset::Separable(s) if step.is_none() => Ok(analytic(s.to_table().map_err(p)?)),
            d => {
                let g = step.unwrap_or(DEFAULT_STEP).grid();
                let Some(b) = d.brdf() else {
                    return Err(DatasetError::NotOnGrid {
                        path: path.to_path_buf(),
                        samples: 0,
                        why: "nothing to evaluate".into(),
                    });
                };
                Ok(analytic(Table::from_brdf(b, g).map_err(p)?))
            }
        }
    }

    /// The data as samples: a table's nodes, the samples themselves, a MERL table's
    /// valid bins thinned to at most `max`, an analytic BRDF's values on
    /// [`DEFAULT_STEP`].
    pub fn to_samples(&self, max: usize, path: &Path) -> Result<Samples, DatasetError> {
        Ok(match self {
            Dataset::Table(t) => Samples::from_table(t),
            Dataset::Samples(s) => s.clone(),
            Dataset::Merl(m) => m.to_samples_strided(MerlBrdf::stride_for(max)),
            d => Samples::from_table(&d.to_table(None, path)?),
        })
    }

    /// What an export format holds: a table, samples or a MERL table; anything
    /// analytic is tabulated on its own grid or [`DEFAULT_STEP`].
    pub fn to_format_data(&self, path: &Path) -> Result<Data, DatasetError> {
        Ok(match self {
            Dataset::Table(t) => Data::Table(t.clone()),
            Dataset::Samples(s) => Data::Samples(s.clone()),
            Dataset::Merl(m) => Data::Merl(m.as_ref().clone()),
            Dataset::Rgl(r) => Data::Rgl(r.clone()),
            d => Data::Table(d.to_table(None, path)?),
        })
    }
}
