//! BRDF files other tools read and write: the MERL binary table, ASTM E1392-style
//! text, and Gonio's own CSV samples and tables.
//!
//! | format | module | holds | reads as |
//! |---|---|---|---|
//! | MERL binary (Matusik et al. 2003) | [`merl`] | isotropic RGB BRDF on 90 × 90 × 180 half/difference bins | [`Data::Merl`] ([`MerlBrdf`]) |
//! | ASTM E1392-style text (the Cornell measurements) | [`astm`] | scattered samples, any channels | [`Data::Samples`] |
//! | CSV samples or table (`gonio_process::file`) | — | samples, or a table on a grid | [`Data::Samples`] or [`Data::Table`] |
//! | long-form spectral CSV (a row per pair per wavelength) | [`long`] | samples with wavelength channels | [`Data::Samples`] |
//! | RGL material `.bsdf` (Dupuy & Jakob 2018; Mitsuba 3's `measured`) | [`rgl`] | a BRDF in the paper's adaptive parameterisation, RGB or spectral | [`Data::Rgl`] ([`RglBsdf`]) |
//!
//! [`detect`] recognises a format from the bytes alone (never from a file name);
//! [`read`] detects and parses, [`read_as`] parses as a given format; [`write()`] and
//! [`write_file`] convert any [`Data`] to any format (resampling onto MERL bins when
//! needed, see [`MerlBrdf::from_table`] and [`MerlBrdf::from_samples`]).
//!
//! **Errors.** Every reader returns a [`FormatError`] that names the file and the
//! place: a line (and field) in text files, a byte offset in MERL files. Malformed,
//! truncated or oversized input is refused before anything is allocated for it: the
//! MERL length is checked before the 35 MB of values are decoded, ASTM `NUM_POINTS`
//! is capped by [`astm::MAX_POINTS`] and checked against the rows actually present,
//! and [`read_file`] refuses files larger than [`MAX_FILE_BYTES`] before reading them.
//! No input makes a reader panic (the [`fuzz`] bodies, run by `fuzz/` and by the
//! tests, check that).
//!
//! ```
//! use gonio_io::formats::{self, Data, Format};
//!
//! let text = "NUM_POINTS 2\nVARS theta_i phi_i theta_s phi_s value\n\
//!             30 0 30 180 0.25\n30 0 40 180 0.125\n";
//! assert_eq!(formats::detect(text.as_bytes()), Some(Format::Astm));
//! let Data::Samples(s) = formats::read(text.as_bytes(), None).unwrap() else { panic!() };
//! assert_eq!(s.samples.len(), 2);
//! assert_eq!(s.samples[1].value, vec![0.125]);
//! ```

use std::fmt;
use std::path::{Path, PathBuf};

use gonio_core::Channels;
use gonio_core::tomlfile::FileError;
use gonio_process::file::{Content, Meta, sidecar_path};
use gonio_process::{Samples, Table};

pub mod astm;
pub mod fuzz;
pub mod long;
pub mod merl;
pub mod rgl;

pub use astm::{read_astm, write_astm};
pub use long::{long_meta, read_long, write_long};
pub use merl::{Bin, FromSamples, MerlBrdf, read_merl, write_merl};
pub use rgl::{RglBsdf, RglOptions};

/// The largest file [`read_file`] reads (4 GiB): far beyond any BRDF Gonio writes
/// (a full CSV of [`gonio_process::file::MAX_ROWS`] rows is about 3 GB), and a
/// guard against reading a device or a runaway file into memory.
pub const MAX_FILE_BYTES: u64 = 1 << 32;

/// How many bytes from the start [`detect`] looks at in a text file.
const DETECT_BYTES: usize = 64 * 1024;

/// A file format this module reads and writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// The MERL binary BRDF ([`merl`]).
    Merl,
    /// ASTM E1392-style text ([`astm`]).
    Astm,
    /// Gonio's CSV samples or table (`gonio_process::file`).
    Csv,
    /// The long-form spectral CSV: a row per pair per wavelength ([`long`]).
    CsvLong,
    /// The RGL material of Mitsuba 3's `measured` plugin ([`rgl`]).
    Rgl,
}

impl Format {
    /// Every format, in the order [`detect`] tries them.
    pub const ALL: [Format; 5] = [
        Format::Merl,
        Format::Rgl,
        Format::Astm,
        Format::Csv,
        Format::CsvLong,
    ];

    /// The short name commands take (`merl`, `astm`, `csv`, `csv-long`, `rgl`).
    pub fn name(self) -> &'static str {
        match self {
            Format::Merl => "merl",
            Format::Astm => "astm",
            Format::Csv => "csv",
            Format::CsvLong => "csv-long",
            Format::Rgl => "rgl",
        }
    }

    /// A longer name for messages.
    pub fn title(self) -> &'static str {
        match self {
            Format::Merl => "MERL BRDF",
            Format::Astm => "ASTM E1392 BRDF",
            Format::Csv => "BRDF table",
            Format::CsvLong => "long-form spectral BRDF CSV",
            Format::Rgl => "RGL material",
        }
    }

    /// The format of a short name (case-insensitive), as [`Format::name`] gives it.
    pub fn from_name(name: &str) -> Option<Format> {
        Format::ALL
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(name.trim()))
    }

    /// The format a file name's extension suggests: `.binary` or `.merl` (MERL),
    /// `.astm` (ASTM), `.csv` (CSV; never the long form, which is asked for by name),
    /// `.bsdf` (RGL).
    /// Only a hint for writing; reading detects the format from the content.
    pub fn from_extension(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "binary" | "merl" => Some(Format::Merl),
            "astm" => Some(Format::Astm),
            "csv" => Some(Format::Csv),
            "bsdf" => Some(Format::Rgl),
            _ => None,
        }
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// What a file holds once read.
#[derive(Clone, Debug, PartialEq)]
pub enum Data {
    /// A MERL table of half/difference bins (a BRDF in its own right).
    Merl(MerlBrdf),
    /// Scattered samples (ASTM, or a CSV without a grid).
    Samples(Samples),
    /// A table on a grid (a CSV with a `grid:` line).
    Table(Table),
    /// An RGL material (a BRDF in its own right).
    Rgl(Box<RglBsdf>),
}

impl Data {
    /// The channels of the data.
    pub fn channels(&self) -> &Channels {
        match self {
            Data::Merl(m) => gonio_brdf::Brdf::channels(m),
            Data::Samples(s) => &s.channels,
            Data::Table(t) => &t.channels,
            Data::Rgl(r) => gonio_brdf::Brdf::channels(r.as_ref()),
        }
    }

    /// A short description of the variant (`MERL table`, `samples`, `table`).
    pub fn kind(&self) -> &'static str {
        match self {
            Data::Merl(_) => "MERL table",
            Data::Samples(_) => "samples",
            Data::Table(_) => "table",
            Data::Rgl(_) => "RGL material",
        }
    }

    /// The data as samples: a MERL table's valid bin centres
    /// ([`MerlBrdf::to_samples`]), a table's nodes, the samples themselves, or an
    /// RGL material's values on the 10° × 10° grid ([`rgl_table`]).
    pub fn to_samples(&self) -> Samples {
        match self {
            Data::Merl(m) => m.to_samples(),
            Data::Samples(s) => s.clone(),
            Data::Table(t) => Samples::from_table(t),
            Data::Rgl(r) => rgl_samples(r),
        }
    }

    /// The data as a BRDF that can be evaluated anywhere, when it is one (a MERL
    /// table, or a table, which interpolates); `None` for scattered samples.
    pub fn as_brdf(&self) -> Option<&dyn gonio_brdf::Brdf> {
        match self {
            Data::Merl(m) => Some(m),
            Data::Table(t) => Some(t),
            Data::Rgl(r) => Some(r.as_ref()),
            Data::Samples(_) => None,
        }
    }
}

/// An RGL material evaluated on the 10° × 10° grid (the grid analytic inputs are
/// tabulated on by default), as a CSV or ASTM export of it holds.
pub fn rgl_table(r: &RglBsdf) -> Result<Table, FormatError> {
    let step = gonio_process::GridStep {
        dtheta_deg: 10.0,
        dphi_deg: 10.0,
    };
    Table::from_brdf(r, step.grid())
        .map_err(|e| FormatError::whole(Some(Format::Rgl), None, e.to_string()))
}

/// [`rgl_table`]'s nodes as samples (none if it cannot be formed, which a material
/// [`RglBsdf::read`] accepted never gives: its values are finite).
pub(crate) fn rgl_samples(r: &RglBsdf) -> Samples {
    match rgl_table(r) {
        Ok(t) => Samples::from_table(&t),
        Err(_) => Samples::from_brdf(r, &[]),
    }
}

/// A file that could not be read or data that could not be written, with where.
///
/// Displays as `FILE:LINE: field `NAME`: MESSAGE` for text files and
/// `FILE: byte OFFSET: MESSAGE` for MERL files, leaving out what is unknown
/// (`<MERL BRDF file>` and the like stand in for a missing file name).
#[derive(Clone, Debug, PartialEq)]
pub struct FormatError {
    /// The format whose rules the input broke; `None` when no format was recognised.
    pub format: Option<Format>,
    /// The file, when known.
    pub path: Option<PathBuf>,
    /// 1-based line (text formats).
    pub line: Option<usize>,
    /// The field or column at fault (`NUM_POINTS`, `theta_i`, `R`, …).
    pub field: Option<String>,
    /// 0-based byte offset (binary formats).
    pub byte: Option<u64>,
    /// What is wrong.
    pub message: String,
}

impl FormatError {
    /// A fault with the file or data as a whole.
    pub fn whole(format: Option<Format>, path: Option<&Path>, message: impl Into<String>) -> Self {
        FormatError {
            format,
            path: path.map(Path::to_path_buf),
            line: None,
            field: None,
            byte: None,
            message: message.into(),
        }
    }

    /// A fault at a line (and field) of a text file.
    pub fn at_line(
        format: Format,
        path: Option<&Path>,
        line: usize,
        field: Option<&str>,
        message: impl Into<String>,
    ) -> Self {
        FormatError {
            line: Some(line),
            field: field.map(str::to_string),
            ..FormatError::whole(Some(format), path, message)
        }
    }

    /// A fault at a byte offset of a binary file.
    pub fn at_byte(
        format: Format,
        path: Option<&Path>,
        byte: u64,
        message: impl Into<String>,
    ) -> Self {
        FormatError {
            byte: Some(byte),
            ..FormatError::whole(Some(format), path, message)
        }
    }

    fn from_file_error(e: FileError) -> Self {
        let message = match e.column {
            Some(c) => format!("column {c}: {}", e.message),
            None => e.message,
        };
        FormatError {
            format: Some(Format::Csv),
            path: e.path,
            line: e.line,
            field: e.field,
            byte: None,
            message,
        }
    }
}

impl fmt::Display for FormatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (&self.path, self.format) {
            (Some(p), _) => write!(f, "{}", p.display())?,
            (None, Some(fmt)) => write!(f, "<{} file>", fmt.title())?,
            (None, None) => f.write_str("<BRDF file>")?,
        }
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        f.write_str(": ")?;
        if let Some(b) = self.byte {
            write!(f, "byte {b}: ")?;
        }
        if let Some(field) = &self.field {
            write!(f, "field `{field}`: ")?;
        }
        f.write_str(&self.message)
    }
}

impl std::error::Error for FormatError {}

/// The format of a file, from its content alone:
///
/// - **MERL**: exactly [`merl::FILE_BYTES`] (34 992 012) bytes starting with the
///   little-endian `int32`s 90, 90, 180;
/// - **ASTM**: text whose header (before any data row) has a `NUM_POINTS` or `VARS`
///   keyword line, after any blank lines, `#` comments and other keyword lines;
/// - **CSV**: text whose first line that is neither blank nor a `#` line starts with
///   the `docs/CONVENTIONS.md` header `theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg`
///   (or `theta_i,phi_i,theta_o,phi_o`, as files before format 2 have it);
/// - **long-form CSV**: the same, with `wavelength_nm` for the fifth column.
///
/// `None` for anything else, including a MERL file of the wrong length (which
/// [`read`] still reads as MERL, to say what is wrong with it). Looks at no more
/// than the first 64 KiB of a text file.
pub fn detect(bytes: &[u8]) -> Option<Format> {
    if merl::is_merl(bytes) {
        return Some(Format::Merl);
    }
    if rgl::tensor::is_tensor_file(bytes) {
        return Some(Format::Rgl);
    }
    detect_text(bytes).ok()
}

/// Why a text file's format was not recognised.
enum Unrecognised {
    /// Not text at all.
    NotText,
    /// Recognition failed at this 1-based line.
    At(usize),
    /// This 1-based line has commas, so it is most likely a CSV header gone wrong.
    CsvHeader(usize, String),
}

/// The text format of `bytes` (after any byte order mark), or why there is none.
fn detect_text(bytes: &[u8]) -> Result<Format, Unrecognised> {
    let bytes = gonio_core::text::strip_bom_bytes(bytes);
    let head = &bytes[..bytes.len().min(DETECT_BYTES)];
    // Recognised from the valid UTF-8 prefix: a text file with a bad byte further on
    // is still that format, and its reader names the bad byte.
    let text = match std::str::from_utf8(head) {
        Ok(t) => t,
        Err(e) if e.valid_up_to() > 0 => {
            std::str::from_utf8(&head[..e.valid_up_to()]).map_err(|_| Unrecognised::NotText)?
        }
        Err(_) => return Err(Unrecognised::NotText),
    };
    if text.contains('\0') {
        return Err(Unrecognised::NotText);
    }
    let mut last = 0;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        last = i + 1;
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if long::is_long_header(&fields) {
            return Ok(Format::CsvLong);
        }
        if fields.len() >= 4
            && (fields[..4] == gonio_core::dirfile::HEADER
                || fields[..4] == gonio_process::file::DIR_COLUMNS)
        {
            return Ok(Format::Csv);
        }
        let first = astm::first_token(line);
        if astm::is_astm_keyword(first) {
            return Ok(Format::Astm);
        }
        if first.starts_with(|c: char| c.is_ascii_alphabetic()) && !line.contains(',') {
            // Another keyword line of an ASTM header (FORMAT, SOURCE, …): keep looking.
            continue;
        }
        // Names separated by commas from the first word on: a CSV header gone wrong
        // (an ASTM keyword line has a space after its keyword).
        let csv_like = line[first.len()..].trim_start().starts_with(',') && fields.len() >= 4;
        if csv_like && first.starts_with(|c: char| c.is_alphabetic()) {
            return Err(Unrecognised::CsvHeader(i + 1, line.to_string()));
        }
        return Err(Unrecognised::At(i + 1));
    }
    Err(Unrecognised::At(last.max(1)))
}

/// Reads a file of any format, detected from its content ([`detect`]). `path` only
/// labels errors.
///
/// A file that looks like MERL but is not quite (the right header with the wrong
/// length, or the right length with a wrong header) is read as MERL so that the
/// error says what is wrong; a text file of no recognised format is refused with
/// the line where recognition failed.
pub fn read(bytes: &[u8], path: Option<&Path>) -> Result<Data, FormatError> {
    if bytes.is_empty() {
        return Err(FormatError::whole(None, path, "empty file"));
    }
    if let Some(f) = detect(bytes) {
        return read_as(f, bytes, path);
    }
    if merl::looks_like_merl(bytes) {
        return read_as(Format::Merl, bytes, path);
    }
    match detect_text(bytes) {
        Ok(f) => read_as(f, bytes, path),
        Err(Unrecognised::NotText) => Err(FormatError::whole(
            None,
            path,
            format!(
                "not a BRDF file Gonio reads: not text, and not a MERL binary \
                 ({} bytes; a MERL file has exactly {} bytes and starts with the \
                 int32s 90, 90, 180)",
                bytes.len(),
                merl::FILE_BYTES
            ),
        )),
        Err(Unrecognised::CsvHeader(line, found)) => Err(FormatError {
            line: Some(line),
            ..FormatError::whole(
                Some(Format::Csv),
                path,
                format!(
                    "not a CSV header Gonio reads: expected the columns {}; found {found:?}",
                    gonio_process::file::EXPECTED_COLUMNS
                ),
            )
        }),
        Err(Unrecognised::At(line)) => Err(FormatError {
            line: Some(line),
            ..FormatError::whole(
                None,
                path,
                "not a BRDF file Gonio reads: expected an ASTM E1392 header (NUM_POINTS \
                 and VARS lines) or the CSV header theta_i,phi_i,theta_o,phi_o,<channels>",
            )
        }),
    }
}

/// Reads `bytes` as the given format, whatever [`detect`] would say.
pub fn read_as(format: Format, bytes: &[u8], path: Option<&Path>) -> Result<Data, FormatError> {
    match format {
        Format::Merl => read_merl(bytes, path).map(Data::Merl),
        Format::Astm => read_astm(utf8(format, bytes, path)?, path).map(Data::Samples),
        Format::Csv => read_csv(utf8(format, bytes, path)?, path),
        Format::CsvLong => read_long(utf8(format, bytes, path)?, None, path),
        Format::Rgl => RglBsdf::read(bytes, path).map(|r| Data::Rgl(Box::new(r))),
    }
}

/// The bytes as UTF-8 text, or an error at the first invalid byte.
fn utf8<'a>(format: Format, bytes: &'a [u8], path: Option<&Path>) -> Result<&'a str, FormatError> {
    std::str::from_utf8(bytes).map_err(|e| {
        let at = e.valid_up_to();
        let line = bytes[..at].iter().filter(|b| **b == b'\n').count() + 1;
        FormatError {
            line: Some(line),
            byte: Some(at as u64),
            ..FormatError::whole(Some(format), path, "not UTF-8 text")
        }
    })
}

/// Reads a CSV sample or table file from its text alone (`gonio_process::file::read`):
/// without its sidecar, a table of format 2 reads as samples (a table of format 1 has
/// its grid line).
pub fn read_csv(text: &str, path: Option<&Path>) -> Result<Data, FormatError> {
    read_csv_from(text.as_bytes(), text.len() as u64, None, path)
}

/// Reads a CSV sample or table file of at most `len` bytes line by line, with its
/// sidecar when there is one (`gonio_process::file::read_from`).
pub fn read_csv_from(
    r: impl std::io::BufRead,
    len: u64,
    meta: Option<&Meta>,
    path: Option<&Path>,
) -> Result<Data, FormatError> {
    match gonio_process::file::read_from(r, len, meta, path) {
        Ok(Content::Samples(s)) => Ok(Data::Samples(s)),
        Ok(Content::Table(t)) => Ok(Data::Table(t)),
        Err(e) => Err(FormatError::from_file_error(e)),
    }
}

/// The sidecar of the CSV file `csv` (`CSV.json`), when there is one: none when no
/// such file exists, an error when it cannot be read or does not parse.
pub fn read_sidecar(csv: &Path) -> Result<Option<Meta>, FormatError> {
    let side = sidecar_path(csv);
    if let Err(e) = std::fs::symlink_metadata(&side)
        && e.kind() == std::io::ErrorKind::NotFound
    {
        return Ok(None);
    }
    let text = gonio_core::input::read_text(&side, gonio_process::file::MAX_SIDECAR_BYTES)
        .map_err(|e| {
            FormatError::whole(
                Some(Format::Csv),
                Some(&side),
                format!("cannot read the sidecar: {}", e.reason()),
            )
        })?;
    Meta::from_json(&text, Some(&side))
        .map(Some)
        .map_err(FormatError::from_file_error)
}

/// Reads the CSV file `path` with its sidecar ([`read_sidecar`]), streaming: a table
/// goes straight into its array of values, and the file's text is never held whole.
/// Only a regular file of at most `max_bytes` is read.
pub fn read_csv_file(path: &Path, max_bytes: u64) -> Result<Data, FormatError> {
    let meta = read_sidecar(path)?;
    let cannot = |why: String| FormatError::whole(Some(Format::Csv), Some(path), why);
    let len = gonio_core::input::regular_file(path)
        .map_err(|e| cannot(format!("cannot read: {}", e.reason())))?
        .len();
    if len > max_bytes {
        return Err(cannot(format!(
            "more than the {max_bytes} bytes a BRDF file may have"
        )));
    }
    let file = std::fs::File::open(path).map_err(|e| cannot(format!("cannot read: {e}")))?;
    // Looked at again through the handle: a FIFO swapped in after the first look.
    if !file.metadata().is_ok_and(|m| m.is_file()) {
        return Err(cannot("cannot read: not a regular file".into()));
    }
    let r = std::io::BufReader::with_capacity(1 << 20, std::io::Read::take(file, max_bytes));
    read_csv_from(r, len, meta.as_ref(), Some(path))
}

/// Writes data as CSV: a table (`gonio_process::file::write_table`), samples as they
/// are, a MERL table as the samples of its valid bins
/// (`gonio_process::file::write_samples`). [`csv_meta`] is the sidecar that goes
/// beside it.
pub fn write_csv(data: &Data) -> String {
    match data {
        Data::Table(t) => gonio_process::file::write_table(t),
        Data::Samples(s) => gonio_process::file::write_samples(s),
        Data::Merl(m) => gonio_process::file::write_samples(&m.to_samples()),
        Data::Rgl(r) => match rgl_table(r) {
            Ok(t) => gonio_process::file::write_table(&t),
            Err(_) => gonio_process::file::write_samples(&rgl_samples(r)),
        },
    }
}

/// The sidecar of [`write_csv`]'s file: the kind, channels, isotropy and a table's grid.
pub fn csv_meta(data: &Data) -> Meta {
    match data {
        Data::Table(t) => Meta::for_table(t),
        Data::Samples(s) => Meta::for_samples(s),
        Data::Merl(m) => Meta::for_samples(&m.to_samples()),
        Data::Rgl(r) => match rgl_table(r) {
            Ok(t) => Meta::for_table(&t),
            Err(_) => Meta::for_samples(&rgl_samples(r)),
        },
    }
}

/// Writes data in a format, converting when the format cannot hold it as it is:
///
/// - MERL from a table ([`MerlBrdf::from_table`]) or samples
///   ([`MerlBrdf::from_samples`] with the default [`FromSamples`]);
/// - ASTM from a table's nodes or a MERL table's valid bin centres (ASTM holds
///   samples only; uncertainties and flags are not part of it and are dropped);
/// - CSV as [`write_csv`];
/// - the long-form CSV ([`write_long`]) from any data with wavelength channels (a
///   table's nodes, a MERL table's valid bins), refused for other channels.
///
/// Errors (channels MERL cannot hold, samples that cannot be interpolated) carry no
/// file name; [`write_file`] adds it.
pub fn write(format: Format, data: &Data) -> Result<Vec<u8>, FormatError> {
    Ok(match (format, data) {
        (Format::Merl, Data::Merl(m)) => write_merl(m),
        // Evaluated exactly at the bin centres, as the plugin would.
        (Format::Merl, Data::Rgl(r)) => write_merl(&MerlBrdf::from_brdf(r.as_ref())?),
        (Format::Merl, Data::Table(t)) => write_merl(&MerlBrdf::from_table(t)?),
        (Format::Merl, Data::Samples(s)) => {
            write_merl(&MerlBrdf::from_samples(s, &FromSamples::default())?)
        }
        (Format::Astm, Data::Samples(s)) => write_astm(s).into_bytes(),
        (Format::Astm, d) => write_astm(&d.to_samples()).into_bytes(),
        (Format::Csv, d) => write_csv(d).into_bytes(),
        (Format::CsvLong, d) => write_long(d)?.into_bytes(),
        (Format::Rgl, Data::Rgl(r)) => r.to_bytes(),
        (Format::Rgl, Data::Samples(_)) => {
            return Err(FormatError::whole(
                Some(Format::Rgl),
                None,
                "scattered samples: tabulate them first (`gonio export` does)",
            ));
        }
        (Format::Rgl, d) => {
            let b = d.as_brdf().ok_or_else(|| {
                FormatError::whole(Some(Format::Rgl), None, "nothing to evaluate")
            })?;
            RglBsdf::from_brdf(b, &RglOptions::default(), "written by Gonio", &|_, _| true)?
                .to_bytes()
        }
    })
}

/// Reads a file from disk ([`read`]): only a regular file (a FIFO, a device or a
/// directory is refused without being read), and no more than [`MAX_FILE_BYTES`] of
/// it (`gonio_core::input::read_bounded`). A CSV file is streamed with its sidecar
/// ([`read_csv_file`]).
pub fn read_file(path: &Path) -> Result<Data, FormatError> {
    let head = gonio_core::input::read_head(path, DETECT_BYTES as u64).map_err(|e| {
        FormatError::whole(None, Some(path), format!("cannot read: {}", e.reason()))
    })?;
    if !merl::looks_like_merl(&head) {
        match detect_text(&head) {
            Ok(Format::Csv) => return read_csv_file(path, MAX_FILE_BYTES),
            Ok(Format::CsvLong) => return read_long_file(path, MAX_FILE_BYTES),
            _ => {}
        }
    }
    let bytes = gonio_core::input::read_bounded(path, MAX_FILE_BYTES).map_err(|e| match e {
        gonio_core::input::InputError::TooLarge { max, .. } => FormatError::whole(
            None,
            Some(path),
            format!("more than the {max} bytes a BRDF file may have"),
        ),
        e => FormatError::whole(None, Some(path), format!("cannot read: {}", e.reason())),
    })?;
    read(&bytes, Some(path))
}

/// Writes data to a file in a format ([`write()`]), and a CSV file's sidecar beside
/// it ([`csv_meta`]); errors name the file.
pub fn write_file(format: Format, data: &Data, path: &Path) -> Result<(), FormatError> {
    let bytes = write(format, data).map_err(|mut e| {
        e.path = Some(path.to_path_buf());
        e
    })?;
    let fail = |p: &Path, e: std::io::Error| {
        FormatError::whole(Some(format), Some(p), format!("cannot write: {e}"))
    };
    std::fs::write(path, bytes).map_err(|e| fail(path, e))?;
    let meta = match format {
        Format::Csv => Some(csv_meta(data)),
        Format::CsvLong => Some(long_meta(data)?),
        _ => None,
    };
    if let Some(meta) = meta {
        let side = sidecar_path(path);
        std::fs::write(&side, meta.to_json()).map_err(|e| fail(&side, e))?;
    }
    Ok(())
}

/// Reads the long-form CSV file `path` ([`read_long`]) with its sidecar when there
/// is one ([`read_sidecar`]), which gives the isotropy. Only a regular file of at
/// most `max_bytes` is read.
pub fn read_long_file(path: &Path, max_bytes: u64) -> Result<Data, FormatError> {
    let meta = read_sidecar(path)?;
    let bytes = gonio_core::input::read_bounded(path, max_bytes).map_err(|e| {
        FormatError::whole(
            Some(Format::CsvLong),
            Some(path),
            format!("cannot read: {}", e.reason()),
        )
    })?;
    read_long(
        utf8(Format::CsvLong, &bytes, Some(path))?,
        meta.as_ref(),
        Some(path),
    )
}
