//! The sample and table file: CSV that `pandas.read_csv(path)` reads with no
//! arguments — one header row, units in the column names, nothing above it:
//!
//! ```text
//! theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,f_r_R_per_sr,f_r_G_per_sr,f_r_B_per_sr,sigma_R_per_sr,sigma_G_per_sr,sigma_B_per_sr
//! 5,0,5,0,0.123,0.1,0.2,0.001,0.001,0.002
//! ```
//!
//! A single channel named `value` has the columns `f_r_per_sr` and `sigma_per_sr`;
//! any other channel `f_r_<channel>_per_sr` and `sigma_<channel>_per_sr`; a `flags`
//! column ends the row when any sample has flags. What a header cannot say goes into
//! a sidecar JSON file beside the CSV ([`sidecar_path`]: `TABLE.csv.json`, a
//! [`Meta`]): the kind of file, the channels, whether the data are isotropic, and a
//! table's grid, which makes the rows its nodes (each exactly once, in any order).
//! Without the sidecar the rows read as samples, which `Samples::to_table`
//! recognises as a table when they form a complete uniform grid.
//!
//! Files of format 1 (before 2026-11) still read: the columns
//! `theta_i,phi_i,theta_o,phi_o`, the channel names and `sigma_<channel>`, and
//! leading `# key: value` lines, of which `# grid: isotropic=false phi_i=0:30:12
//! theta_i=5:10:9 phi_o=0:30:12 theta_o=5:10:9` (axes `start:step:n` in degrees)
//! makes the rows a table's nodes and `# isotropic: true` marks isotropic samples.
//!
//! Numbers are written in Rust's shortest round-trip form, so write → read is
//! lossless. [`read_from`] streams: a table whose grid is known (sidecar or grid line)
//! goes straight into one preallocated array of values, one line buffer reused, no
//! record per row.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::io::BufRead;
use std::path::{Path, PathBuf};

use gonio_core::dirfile::{HEADER, PairDeg};
use gonio_core::tomlfile::FileError;
use gonio_core::{Channels, SphericalDeg};
use serde::{Deserialize, Serialize};

use crate::{Axis, Grid, Sample, Samples, Table};

pub(crate) const KIND: &str = "BRDF table";
const SIDECAR_KIND: &str = "BRDF table sidecar";

/// The direction columns (degrees) of the current format.
pub const DIR_COLUMNS: [&str; 4] = gonio_core::dirfile::HEADER_DEG;

/// The format version files are written in (1 had `#` lines and unitless names).
pub const VERSION: u32 = 2;

/// The longest sidecar read (a sidecar is a few hundred bytes).
pub const MAX_SIDECAR_BYTES: u64 = 1 << 20;

/// The longest line read: a row of a hundred channels with uncertainties is ~5 kB.
const MAX_LINE: usize = 1 << 16;

/// What a table file holds.
#[derive(Clone, Debug, PartialEq)]
pub enum Content {
    /// Values on a grid.
    Table(Table),
    /// Scattered samples.
    Samples(Samples),
}

/// The column of a channel's values: `f_r_per_sr` for the single channel `value`,
/// else `f_r_<channel>_per_sr` (1/sr).
pub fn value_column(channel: &str) -> String {
    gonio_core::dirfile::value_column(channel)
}

/// The column of a channel's standard uncertainty: `sigma_per_sr` or
/// `sigma_<channel>_per_sr` (1/sr).
pub fn sigma_column(channel: &str) -> String {
    if channel == "value" {
        "sigma_per_sr".into()
    } else {
        format!("sigma_{channel}_per_sr")
    }
}

/// The sidecar of a CSV file: `PATH.json` beside it (`table.csv` → `table.csv.json`).
pub fn sidecar_path(csv: &Path) -> PathBuf {
    let mut s = csv.as_os_str().to_os_string();
    s.push(".json");
    PathBuf::from(s)
}

/// One grid axis in the sidecar, in degrees.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AxisMeta {
    /// The first node.
    pub start_deg: f64,
    /// The spacing of the nodes.
    pub step_deg: f64,
    /// How many nodes.
    pub n: usize,
}

/// A table's grid in the sidecar (DeYoung Sec. 3.1: rows (φi, θi), columns (φo, θo)).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GridMeta {
    /// Incident azimuth φi (one node at 0 in the isotropic form).
    pub phi_i: AxisMeta,
    /// Incident polar angle θi.
    pub theta_i: AxisMeta,
    /// Outgoing azimuth φo (φ+ = φo − φi in the isotropic form).
    pub phi_o: AxisMeta,
    /// Outgoing polar angle θo.
    pub theta_o: AxisMeta,
}

/// The sidecar JSON of a table or samples file: what its header cannot say.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Meta {
    /// `gonio-table` or `gonio-samples`.
    pub format: String,
    /// The format version ([`VERSION`]).
    pub version: u32,
    /// The channel names, in column order.
    pub channels: Vec<String>,
    /// Whether the data are isotropic (a table in the isotropic form of Eq. 4.6).
    pub isotropic: bool,
    /// The CSV's columns, as its header has them (a check that the two belong together).
    pub columns: Vec<String>,
    /// A table's grid; none for samples.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grid: Option<GridMeta>,
    /// The symmetry assumed of measured data to make the table
    /// ([`crate::hemisphere::Symmetry::name`]); none when nothing was said.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub symmetry: Option<String>,
    /// The table's nodes that were interpolated, not measured (θi°, φi°, θo°, φo°;
    /// [`crate::hemisphere::Fill`]); none when nothing was said.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interpolated: Option<Vec<[f64; 4]>>,
}

fn axis_meta(a: &Axis) -> AxisMeta {
    AxisMeta {
        start_deg: deg(a.start),
        step_deg: deg(a.step),
        n: a.n,
    }
}

impl Meta {
    /// The sidecar of [`write_table`]'s file.
    pub fn for_table(t: &Table) -> Meta {
        let g = &t.grid;
        Meta {
            format: "gonio-table".into(),
            version: VERSION,
            channels: t.channels.names(),
            isotropic: g.isotropic,
            columns: columns(&t.channels, t.sigma.is_some(), false),
            grid: Some(GridMeta {
                phi_i: axis_meta(&g.phi_i),
                theta_i: axis_meta(&g.theta_i),
                phi_o: axis_meta(&g.phi_o),
                theta_o: axis_meta(&g.theta_o),
            }),
            symmetry: None,
            interpolated: None,
        }
    }

    /// The sidecar of [`write_samples`]' file.
    pub fn for_samples(s: &Samples) -> Meta {
        let (sigma, flags) = sample_columns(s);
        Meta {
            format: "gonio-samples".into(),
            version: VERSION,
            channels: s.channels.names(),
            isotropic: s.isotropic,
            columns: columns(&s.channels, sigma, flags),
            grid: None,
            symmetry: None,
            interpolated: None,
        }
    }

    /// The sidecar as JSON text (pretty, ending in a newline).
    pub fn to_json(&self) -> String {
        // A struct of strings, numbers and lists always serialises.
        let mut s = serde_json::to_string_pretty(self).unwrap_or_default();
        s.push('\n');
        s
    }

    /// Parses a sidecar; `path` (the sidecar's) labels errors.
    pub fn from_json(text: &str, path: Option<&Path>) -> Result<Meta, FileError> {
        let text = gonio_core::text::strip_bom(text);
        let m: Meta = serde_json::from_str(text).map_err(|e| FileError {
            kind: SIDECAR_KIND,
            path: path.map(Path::to_path_buf),
            line: Some(e.line()),
            column: Some(e.column()),
            field: None,
            message: e.to_string(),
        })?;
        let bad = |field: &str, msg: String| FileError {
            field: Some(field.into()),
            ..FileError::whole(SIDECAR_KIND, path, msg)
        };
        if !matches!(m.format.as_str(), "gonio-table" | "gonio-samples") {
            return Err(bad(
                "format",
                format!(
                    "expected gonio-table or gonio-samples, found {:?}",
                    m.format
                ),
            ));
        }
        if m.version == 0 || m.version > VERSION {
            return Err(bad(
                "version",
                format!(
                    "version {} (this Gonio reads versions 1 to {VERSION})",
                    m.version
                ),
            ));
        }
        m.grid().transpose().map_err(|e| bad("grid", e))?;
        Ok(m)
    }

    /// The grid the sidecar gives, checked ([`Grid::validate`]).
    fn grid(&self) -> Option<Result<Grid, String>> {
        let gm = self.grid.as_ref()?;
        let ax = |a: &AxisMeta, name: &str| -> Result<Axis, String> {
            if !(a.start_deg.is_finite() && a.step_deg.is_finite()) || a.n == 0 {
                return Err(format!(
                    "axis `{name}` must have a finite start and step and n ≥ 1"
                ));
            }
            Ok(Axis::from_deg(a.start_deg, a.step_deg, a.n))
        };
        let g = (|| {
            let g = Grid {
                phi_i: ax(&gm.phi_i, "phi_i")?,
                theta_i: ax(&gm.theta_i, "theta_i")?,
                phi_o: ax(&gm.phi_o, "phi_o")?,
                theta_o: ax(&gm.theta_o, "theta_o")?,
                isotropic: self.isotropic,
            };
            g.validate().map_err(|e| e.to_string())?;
            Ok(g)
        })();
        Some(g)
    }
}

fn axis_text(a: &Axis) -> String {
    format!("{}:{}:{}", deg(a.start), deg(a.step), a.n)
}

/// The grid line of format 1 (`# grid: …`), for tests and messages.
pub fn grid_line(g: &Grid) -> String {
    format!(
        "isotropic={} phi_i={} theta_i={} phi_o={} theta_o={}",
        g.isotropic,
        axis_text(&g.phi_i),
        axis_text(&g.theta_i),
        axis_text(&g.phi_o),
        axis_text(&g.theta_o)
    )
}

pub(crate) fn columns(channels: &Channels, sigma: bool, flags: bool) -> Vec<String> {
    let mut c: Vec<String> = DIR_COLUMNS.iter().map(|s| s.to_string()).collect();
    let names = channels.names();
    c.extend(names.iter().map(|n| value_column(n)));
    if sigma {
        c.extend(names.iter().map(|n| sigma_column(n)));
    }
    if flags {
        c.push("flags".into());
    }
    c
}

pub(crate) fn sample_columns(s: &Samples) -> (bool, bool) {
    let sigma = s.samples.iter().all(|x| x.sigma.is_some()) && !s.samples.is_empty();
    let flags = s.samples.iter().any(|x| x.flags != 0);
    (sigma, flags)
}

/// Writes a table as text that needs no sidecar: [`write_table`] below the grid
/// line of format 1 (`# grid: …`, which the reader still takes). For tables kept
/// where no file can sit beside them, such as the sample text a run file stores.
/// pandas reads it with `comment="#"`.
pub fn write_table_self_contained(t: &Table) -> String {
    format!("# grid: {}\n{}", grid_line(&t.grid), write_table(t))
}

/// Writes samples: the header row, then one row a sample. [`Meta::for_samples`] is
/// its sidecar.
pub fn write_samples(s: &Samples) -> String {
    let (sigma, flags) = sample_columns(s);
    let mut out = columns(&s.channels, sigma, flags).join(",");
    out.push('\n');
    for x in &s.samples {
        let p = &x.pair;
        let _ = write!(
            out,
            "{},{},{},{}",
            p.incident.theta_deg, p.incident.phi_deg, p.outgoing.theta_deg, p.outgoing.phi_deg
        );
        for v in &x.value {
            let _ = write!(out, ",{v}");
        }
        if sigma && let Some(sg) = &x.sigma {
            for v in sg {
                let _ = write!(out, ",{v}");
            }
        }
        if flags {
            let _ = write!(out, ",{}", x.flags);
        }
        out.push('\n');
    }
    out
}

/// Writes a table, the header row then one row a node in grid order.
/// [`Meta::for_table`] is its sidecar, which carries the grid.
pub fn write_table(t: &Table) -> String {
    let n = t.grid.len();
    let nc = t.channels.len();
    // ~20 bytes a number: one allocation for the whole text.
    let width = 4 + nc * (1 + usize::from(t.sigma.is_some()));
    let mut out = String::with_capacity(n.saturating_mul(width * 20).min(1 << 32));
    out.push_str(&columns(&t.channels, t.sigma.is_some(), false).join(","));
    out.push('\n');
    for i in 0..n {
        let [pi, ti, po, to] = t.grid.angles(i);
        let _ = write!(out, "{},{},{},{}", deg(ti), deg(pi), deg(to), deg(po));
        for ch in 0..nc {
            let _ = write!(out, ",{}", t.values[ch * n + i]);
        }
        if let Some(s) = &t.sigma {
            for ch in 0..nc {
                let _ = write!(out, ",{}", s[ch * n + i]);
            }
        }
        out.push('\n');
    }
    out
}

/// Degrees of a node angle, as [`crate::Axis::node_deg`] prints them.
pub(crate) fn deg(x: f64) -> f64 {
    crate::grid::clean_deg(x.to_degrees())
}

fn parse_axis(s: &str) -> Option<Axis> {
    let mut it = s.split(':');
    let start: f64 = it.next()?.trim().parse().ok()?;
    let step: f64 = it.next()?.trim().parse().ok()?;
    let n: usize = it.next()?.trim().parse().ok()?;
    if it.next().is_some() {
        return None;
    }
    Some(Axis::from_deg(start, step, n))
}

fn parse_grid(s: &str) -> Result<Grid, String> {
    let mut map = HashMap::new();
    for part in s.split_whitespace() {
        let (k, v) = part
            .split_once('=')
            .ok_or_else(|| format!("expected key=value, found {part:?}"))?;
        if map.insert(k, v).is_some() {
            return Err(format!("`{k}` given twice"));
        }
    }
    let isotropic = match map.remove("isotropic") {
        None | Some("false") => false,
        Some("true") => true,
        Some(x) => return Err(format!("isotropic must be true or false, found {x:?}")),
    };
    let mut axis = |name: &str| -> Result<Axis, String> {
        let v = map
            .remove(name)
            .ok_or_else(|| format!("no `{name}` axis"))?;
        parse_axis(v)
            .ok_or_else(|| format!("`{name}` must be start:step:n in degrees, found {v:?}"))
    };
    let g = Grid {
        phi_i: axis("phi_i")?,
        theta_i: axis("theta_i")?,
        phi_o: axis("phi_o")?,
        theta_o: axis("theta_o")?,
        isotropic,
    };
    if let Some(k) = map.keys().next() {
        return Err(format!("unknown key `{k}`"));
    }
    g.validate().map_err(|e| e.to_string())?;
    Ok(g)
}

/// The most rows a file may have: a 1° full 4D grid of three channels is 2.1 billion
/// values, far beyond memory; this cap (≈ 2 GB of values) keeps a corrupted or hostile
/// header from asking for more than a workstation has.
pub const MAX_ROWS: usize = 50_000_000;

/// The columns a table or sample file has, for messages about a wrong header.
pub const EXPECTED_COLUMNS: &str = "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg, then one \
     column a channel (f_r_per_sr; f_r_R_per_sr,f_r_G_per_sr,f_r_B_per_sr; or wavelengths \
     like f_r_550nm_per_sr), then optionally sigma_<channel>_per_sr for each channel and \
     flags (or the older theta_i,phi_i,theta_o,phi_o, channel names and sigma_<channel>)";

/// What a header row says.
pub(crate) struct Header {
    pub(crate) cols: Vec<String>,
    pub(crate) channels: Channels,
    pub(crate) sigma: bool,
    pub(crate) flags: bool,
}

/// The channel a column of the current format names (`f_r_R_per_sr` → `R`).
fn channel_of(col: &str, prefix: &str) -> Option<String> {
    if col == format!("{prefix}_per_sr") {
        return Some("value".into());
    }
    let c = col
        .strip_prefix(prefix)?
        .strip_prefix('_')?
        .strip_suffix("_per_sr")?;
    (!c.is_empty()).then(|| c.to_string())
}

pub(crate) fn parse_header(head: &str) -> Result<Header, String> {
    let cols: Vec<&str> = head.split(',').map(str::trim).collect();
    let wrong = || format!("expected the columns {EXPECTED_COLUMNS}; found {head:?}");
    if cols.len() < 5 {
        return Err(wrong());
    }
    let current = cols[..4] == DIR_COLUMNS;
    if !current && cols[..4] != HEADER {
        return Err(wrong());
    }
    let rest = &cols[4..];
    let flags = rest.last() == Some(&"flags");
    let rest = if flags { &rest[..rest.len() - 1] } else { rest };
    let is_sigma = |c: &&&str| {
        if current {
            c.starts_with("sigma_") && c.ends_with("_per_sr")
        } else {
            c.starts_with("sigma_")
        }
    };
    let n_sigma = rest.iter().filter(is_sigma).count();
    let value_cols = &rest[..rest.len() - n_sigma];
    let names: Vec<String> = if current {
        value_cols
            .iter()
            .map(|c| {
                channel_of(c, "f_r").ok_or_else(|| {
                    format!("column {c:?} is not f_r_<channel>_per_sr; expected the columns {EXPECTED_COLUMNS}")
                })
            })
            .collect::<Result<_, _>>()?
    } else {
        value_cols.iter().map(|c| c.to_string()).collect()
    };
    let channels = Channels::from_names(&names)
        .map_err(|e| format!("channels: {e} (expected the columns {EXPECTED_COLUMNS})"))?;
    if n_sigma != 0 {
        let want: Vec<String> = names
            .iter()
            .map(|n| {
                if current {
                    sigma_column(n)
                } else {
                    format!("sigma_{n}")
                }
            })
            .collect();
        if n_sigma != names.len()
            || rest[names.len()..] != want.iter().map(String::as_str).collect::<Vec<_>>()[..]
        {
            return Err(format!(
                "uncertainty columns must be {} in that order",
                want.join(",")
            ));
        }
    }
    Ok(Header {
        cols: cols.iter().map(|c| c.to_string()).collect(),
        channels,
        sigma: n_sigma > 0,
        flags,
    })
}

/// Reads a table or sample file from text (no sidecar). `path` only labels errors; a
/// leading byte order mark is ignored.
pub fn read(text: &str, path: Option<&Path>) -> Result<Content, FileError> {
    read_from(text.as_bytes(), text.len() as u64, None, path)
}

/// Where the grid of a table comes from, for messages.
enum GridFrom {
    Line(usize),
    Sidecar,
}

/// Reads a table or sample file line by line from `r`, at most `len` bytes long, with
/// its sidecar when there is one (`meta`, from [`Meta::from_json`]). A grid line or
/// the sidecar's grid makes the rows a table's nodes, parsed straight into the
/// table's values; otherwise the rows are samples. A grid with more nodes than `len`
/// bytes can hold rows for is refused before its values are allocated. `path` only
/// labels errors; a leading byte order mark is ignored.
pub fn read_from<R: BufRead>(
    mut r: R,
    len: u64,
    meta: Option<&Meta>,
    path: Option<&Path>,
) -> Result<Content, FileError> {
    let at = |line: usize, field: Option<&str>, msg: String| FileError {
        kind: KIND,
        path: path.map(Path::to_path_buf),
        line: Some(line),
        column: None,
        field: field.map(str::to_string),
        message: msg,
    };
    let mut buf: Vec<u8> = Vec::with_capacity(256);
    let mut ln = 0usize;
    // The next line, trimmed; None at the end of the input.
    let mut next = |buf: &mut Vec<u8>, ln: &mut usize| -> Result<bool, FileError> {
        buf.clear();
        let n = std::io::Read::take(&mut r, MAX_LINE as u64 + 1)
            .read_until(b'\n', buf)
            .map_err(|e| FileError::whole(KIND, path, format!("cannot read: {e}")))?;
        if n == 0 {
            return Ok(false);
        }
        *ln += 1;
        if buf.len() > MAX_LINE {
            return Err(at(*ln, None, format!("longer than {MAX_LINE} bytes")));
        }
        Ok(true)
    };
    let text_of = |buf: &[u8], ln: usize| -> Result<String, FileError> {
        let b = if ln == 1 {
            gonio_core::text::strip_bom_bytes(buf)
        } else {
            buf
        };
        std::str::from_utf8(b)
            .map(|s| s.trim().to_string())
            .map_err(|_| at(ln, None, "not UTF-8 text".into()))
    };
    let mut grid: Option<(GridFrom, Grid)> = None;
    let mut isotropic = false;
    let head = loop {
        if !next(&mut buf, &mut ln)? {
            return Err(FileError::whole(KIND, path, "no header row"));
        }
        let l = text_of(&buf, ln)?;
        if l.is_empty() {
            continue;
        }
        if let Some(c) = l.strip_prefix('#') {
            if let Some((k, v)) = c.split_once(':') {
                match k.trim() {
                    "grid" => {
                        let g = parse_grid(v.trim()).map_err(|m| at(ln, Some("grid"), m))?;
                        grid = Some((GridFrom::Line(ln), g));
                    }
                    "isotropic" => isotropic = v.trim() == "true",
                    _ => {}
                }
            }
            continue;
        }
        break l;
    };
    let hline = ln;
    let h = parse_header(&head).map_err(|m| at(hline, None, m))?;
    let side = |field: &str, msg: String| FileError {
        field: Some(field.into()),
        ..FileError::whole(SIDECAR_KIND, path.map(sidecar_path).as_deref(), msg)
    };
    if let Some(m) = meta {
        if m.columns != h.cols {
            return Err(side(
                "columns",
                format!(
                    "describes the columns {}, the CSV has {}; the two do not belong together",
                    m.columns.join(","),
                    h.cols.join(",")
                ),
            ));
        }
        isotropic = m.isotropic;
        if grid.is_none()
            && let Some(g) = m.grid()
        {
            grid = Some((GridFrom::Sidecar, g.map_err(|e| side("grid", e))?));
        }
    }
    let nc = h.channels.len();
    let width = h.cols.len();
    let cols = &h.cols;
    // A row has at least one character a field and a separator after each: a grid
    // with more nodes than that many rows fits in the input cannot match it, and its
    // values are never allocated (the rows are only checked and counted, and the
    // count is refused at the end, as for any grid the rows do not fill).
    let fits = |g: &Grid| g.len() <= (len.saturating_add(1) / (2 * width as u64)) as usize;
    // Positions of the fields of the current line, reused.
    let mut fields: Vec<(usize, usize)> = Vec::with_capacity(width);
    let mut rows = 0usize;
    let mut samples: Vec<Sample> = Vec::new();
    let mut table = grid.as_ref().filter(|(_, g)| fits(g)).map(|(_, g)| {
        let n = g.len();
        (
            vec![f64::NAN; n * nc],
            h.sigma.then(|| vec![0.0; n * nc]),
            vec![false; n],
        )
    });
    let mut value = vec![0.0; nc];
    let mut sigma = vec![0.0; nc];
    let mut last_angle: [(String, f64); 4] = Default::default();
    // The last node found on each axis, by angle: most rows repeat three of them.
    let mut last_node: [(f64, usize); 4] = [(f64::NAN, 0); 4];
    while next(&mut buf, &mut ln)? {
        let l = std::str::from_utf8(&buf)
            .map_err(|_| at(ln, None, "not UTF-8 text".into()))?
            .trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        if rows >= MAX_ROWS {
            return Err(at(ln, None, format!("more than {MAX_ROWS} rows")));
        }
        rows += 1;
        fields.clear();
        let mut s = 0;
        for (i, b) in l.bytes().enumerate() {
            if b == b',' {
                fields.push((s, i));
                s = i + 1;
            }
        }
        fields.push((s, l.len()));
        if fields.len() != width {
            return Err(at(
                ln,
                None,
                format!("{} fields, the header has {width}", fields.len()),
            ));
        }
        // Every field lies on char boundaries of the line (split at ASCII commas).
        let field = |k: usize| -> &str {
            let (a, b) = fields[k];
            let f = l.get(a..b).unwrap_or("");
            let edge = |c: Option<&u8>| c.is_some_and(|c| c.is_ascii_whitespace() || *c >= 0x80);
            if edge(f.as_bytes().first()) || edge(f.as_bytes().last()) {
                f.trim()
            } else {
                f
            }
        };
        let num = |k: usize| -> Result<f64, FileError> {
            let f = field(k);
            f.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| at(ln, Some(&cols[k]), format!("not a finite number: {f:?}")))
        };
        // The angles repeat from row to row (a table's rows run through the grid):
        // a field equal to the last row's keeps its parsed value.
        let mut angle = |k: usize| -> Result<f64, FileError> {
            let f = field(k);
            let (text, x) = &mut last_angle[k];
            if text.as_str() != f {
                *x = num(k)?;
                text.clear();
                text.push_str(f);
            }
            Ok(*x)
        };
        let (ti, pi, to, po) = (angle(0)?, angle(1)?, angle(2)?, angle(3)?);
        for (k, th) in [(0, ti), (2, to)] {
            if !(0.0..=90.0).contains(&th) {
                return Err(at(
                    ln,
                    Some(&cols[k]),
                    format!("θ must lie in [0, 90], got {th}"),
                ));
            }
        }
        for (c, v) in value.iter_mut().enumerate() {
            *v = num(4 + c)?;
        }
        if h.sigma {
            for (c, v) in sigma.iter_mut().enumerate() {
                *v = num(4 + nc + c)?;
                if *v < 0.0 {
                    return Err(at(
                        ln,
                        Some(&cols[4 + nc + c]),
                        "uncertainty is negative".into(),
                    ));
                }
            }
        }
        let flags = if h.flags {
            let f = field(width - 1);
            f.parse::<u32>()
                .map_err(|_| at(ln, Some("flags"), format!("not a whole number: {f:?}")))?
        } else {
            0
        };
        if grid.is_some() && table.is_none() {
            continue;
        }
        let (Some((from, g)), Some((values, sig, seen))) = (grid.as_ref(), table.as_mut()) else {
            samples.push(Sample {
                pair: PairDeg {
                    incident: SphericalDeg::new(ti, pi),
                    outgoing: SphericalDeg::new(to, po),
                },
                value: value.clone(),
                sigma: h.sigma.then(|| sigma.clone()),
                flags,
            });
            continue;
        };
        let n = g.len();
        if rows > n {
            return Err(grid_count(at, side, from, n, rows, ln));
        }
        let (pi, po) = if g.isotropic {
            (0.0, po - pi)
        } else {
            (pi, po)
        };
        let mut node = |slot: usize, ax: &Axis, x: f64, name: &str| {
            let (lx, li) = &mut last_node[slot];
            if *lx == x {
                return Ok(*li);
            }
            let i = ax
                .node_at(x.to_radians())
                .ok_or_else(|| at(ln, Some(name), format!("{x} is not a node of the grid")))?;
            (*lx, *li) = (x, i);
            Ok::<usize, FileError>(i)
        };
        let i = g.index(
            node(0, &g.phi_i, pi, "phi_i")?,
            node(1, &g.theta_i, ti, "theta_i")?,
            node(2, &g.phi_o, po, "phi_o")?,
            node(3, &g.theta_o, to, "theta_o")?,
        );
        if std::mem::replace(&mut seen[i], true) {
            return Err(at(ln, None, "this node was already given".into()));
        }
        for ch in 0..nc {
            values[ch * n + i] = value[ch];
        }
        if let Some(out) = sig.as_mut() {
            for ch in 0..nc {
                out[ch * n + i] = sigma[ch];
            }
        }
    }
    if rows == 0 {
        return Err(FileError::whole(KIND, path, "no data rows"));
    }
    if let (Some((from, g)), None) = (&grid, &table) {
        return Err(grid_count(at, side, from, g.len(), rows, 0));
    }
    let (Some((from, g)), Some((values, sig, _))) = (grid, table) else {
        return Ok(Content::Samples(Samples {
            channels: h.channels,
            samples,
            isotropic,
        }));
    };
    if rows != g.len() {
        return Err(grid_count(at, side, &from, g.len(), rows, 0));
    }
    Table::new(h.channels, g, values, sig)
        .map(Content::Table)
        .map_err(|e| FileError::whole(KIND, path, e.to_string()))
}

/// The error for a file whose rows do not match its grid's node count; `rows` so far
/// (at line `ln`) when there are too many, all of them when too few.
fn grid_count(
    at: impl Fn(usize, Option<&str>, String) -> FileError,
    side: impl Fn(&str, String) -> FileError,
    from: &GridFrom,
    n: usize,
    rows: usize,
    ln: usize,
) -> FileError {
    let more = if rows > n { "more than " } else { "" };
    let shown = if rows > n { n } else { rows };
    match from {
        GridFrom::Line(gl) => at(
            *gl,
            Some("grid"),
            format!("the grid has {n} nodes, the file {more}{shown} rows"),
        ),
        GridFrom::Sidecar => {
            let at_line = if ln > 0 {
                format!(" (line {ln})")
            } else {
                String::new()
            };
            side(
                "grid",
                format!("the grid has {n} nodes, the CSV {more}{shown} rows{at_line}"),
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_round_trip_is_lossless() {
        let g = Grid::full(
            Axis::full_turn(4),
            Axis::polar_midpoints(3),
            Axis::full_turn(6),
            Axis::from_deg(0.0, 30.0, 4),
        );
        let n = g.len();
        let values: Vec<f64> = (0..2 * n)
            .map(|i| (i as f64 * 0.737).sin().abs() / 3.0)
            .collect();
        let sigma: Vec<f64> = values.iter().map(|v| v * 0.01 + 1e-17).collect();
        let t = Table::new(
            Channels::from_names(&["450nm", "550nm"]).expect("names"),
            g,
            values,
            Some(sigma),
        )
        .expect("table");
        let text = write_table(&t);
        let meta = Meta::from_json(&Meta::for_table(&t).to_json(), None).expect("sidecar");
        let Content::Table(back) =
            read_from(text.as_bytes(), text.len() as u64, Some(&meta), None).expect("read")
        else {
            panic!("not a table");
        };
        assert_eq!(back.values, t.values);
        assert_eq!(back.sigma, t.sigma);
        assert_eq!(back.channels, t.channels);
        assert!(
            back.grid.phi_o.same_as(&t.grid.phi_o) && back.grid.theta_o.same_as(&t.grid.theta_o)
        );
    }

    #[test]
    fn a_wrong_header_names_the_columns_expected() {
        let e = read(
            "# a table\ntheta,phi,theta_o,phi_o,value\n0,0,0,0,1\n",
            Some(Path::new("t.csv")),
        )
        .expect_err("header");
        assert_eq!(
            e.to_string(),
            format!(
                "t.csv:2: expected the columns {EXPECTED_COLUMNS}; found \"theta,phi,theta_o,phi_o,value\""
            )
        );
        let e = read("theta_i,phi_i,theta_o,phi_o,red\n0,0,0,0,1\n", None).expect_err("channel");
        assert_eq!(e.line, Some(1));
        assert!(
            e.message.starts_with("channels: ")
                && e.message
                    .ends_with(&format!("(expected the columns {EXPECTED_COLUMNS})")),
            "{e}"
        );
        let e = read(
            "theta_i,phi_i,theta_o,phi_o,R,G,B,sigma_R\n0,0,0,0,1,1,1,0\n",
            None,
        )
        .expect_err("sigma");
        assert_eq!(
            e.message,
            "uncertainty columns must be sigma_R,sigma_G,sigma_B in that order"
        );
    }

    #[test]
    fn a_byte_order_mark_is_ignored() {
        let text = "# isotropic: true\ntheta_i,phi_i,theta_o,phi_o,value\n10,0,20,180,0.25\n";
        let plain = read(text, None).expect("plain");
        assert_eq!(read(&format!("\u{feff}{text}"), None).expect("BOM"), plain);
        let Content::Samples(s) = plain else {
            panic!("no grid line: samples");
        };
        assert!(s.isotropic);
        assert_eq!(s.samples[0].value, [0.25]);
        // A mark before the header itself, with no comment line above it.
        let text = "\u{feff}theta_i,phi_i,theta_o,phi_o,value\n10,0,20,180,0.25\n";
        assert!(read(text, None).is_ok());
    }

    #[test]
    fn errors_name_line_and_field() {
        let text = "# grid: isotropic=false phi_i=0:90:4 theta_i=0:45:3 phi_o=0:90:4 theta_o=0:45:3\n\
                    theta_i,phi_i,theta_o,phi_o,value\n0,0,0,0,nan\n";
        let e = read(text, Some(Path::new("t.csv"))).expect_err("nan");
        assert_eq!(e.line, Some(3));
        assert_eq!(e.field.as_deref(), Some("value"));
        let e = read(
            "# grid: phi_i=0:90:4\ntheta_i,phi_i,theta_o,phi_o,value\n0,0,0,0,1\n",
            None,
        )
        .expect_err("axes");
        assert_eq!((e.line, e.field.as_deref()), (Some(1), Some("grid")));
        let e = read("theta_i,phi_i,theta_o,phi_o,value\n95,0,0,0,1\n", None).expect_err("theta");
        assert_eq!((e.line, e.field.as_deref()), (Some(2), Some("theta_i")));
        let e = read(
            "# grid: isotropic=false phi_i=0:90:1 theta_i=0:45:1 phi_o=0:90:1 theta_o=0:45:2\n\
             theta_i,phi_i,theta_o,phi_o,value\n0,0,0,0,1\n0,0,0,0,1\n",
            None,
        )
        .expect_err("dup");
        assert_eq!(e.line, Some(4));
    }

    /// The reader of format 1 as it was before the streaming reader: an independent
    /// implementation the streaming reader must agree with on format-1 files.
    fn read_reference(text: &str, path: Option<&Path>) -> Result<Content, FileError> {
        let text = gonio_core::text::strip_bom(text);
        let at = |line: usize, field: Option<&str>, msg: String| FileError {
            kind: KIND,
            path: path.map(Path::to_path_buf),
            line: Some(line),
            column: None,
            field: field.map(str::to_string),
            message: msg,
        };
        let mut grid: Option<(usize, Grid)> = None;
        let mut isotropic = false;
        let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim()));
        let (hline, head) = loop {
            let Some((ln, l)) = lines.next() else {
                return Err(FileError::whole(KIND, path, "no header row"));
            };
            if l.is_empty() {
                continue;
            }
            if let Some(c) = l.strip_prefix('#') {
                if let Some((k, v)) = c.split_once(':') {
                    match k.trim() {
                        "grid" => {
                            let g = parse_grid(v.trim()).map_err(|m| at(ln, Some("grid"), m))?;
                            grid = Some((ln, g));
                        }
                        "isotropic" => isotropic = v.trim() == "true",
                        _ => {}
                    }
                }
                continue;
            }
            break (ln, l);
        };
        let cols: Vec<&str> = head.split(',').map(str::trim).collect();
        if cols.len() < 5 || cols[..4] != HEADER {
            return Err(at(
                hline,
                None,
                format!("expected the columns {EXPECTED_COLUMNS}; found {head:?}"),
            ));
        }
        let rest = &cols[4..];
        let has_flags = rest.last() == Some(&"flags");
        let rest = if has_flags {
            &rest[..rest.len() - 1]
        } else {
            rest
        };
        let n_sigma = rest.iter().filter(|c| c.starts_with("sigma_")).count();
        let names: Vec<&str> = rest[..rest.len() - n_sigma].to_vec();
        let channels = Channels::from_names(&names).map_err(|e| {
            at(
                hline,
                None,
                format!("channels: {e} (expected the columns {EXPECTED_COLUMNS})"),
            )
        })?;
        let nc = channels.len();
        if n_sigma != 0 {
            let want: Vec<String> = names.iter().map(|n| format!("sigma_{n}")).collect();
            if n_sigma != nc
                || rest[nc..] != want.iter().map(String::as_str).collect::<Vec<_>>()[..]
            {
                return Err(at(
                    hline,
                    None,
                    format!(
                        "uncertainty columns must be {} in that order",
                        want.join(",")
                    ),
                ));
            }
        }
        let width = cols.len();
        let mut samples = Vec::new();
        for (ln, l) in lines {
            if l.is_empty() || l.starts_with('#') {
                continue;
            }
            if samples.len() >= MAX_ROWS {
                return Err(at(ln, None, format!("more than {MAX_ROWS} rows")));
            }
            let f: Vec<&str> = l.split(',').map(str::trim).collect();
            if f.len() != width {
                return Err(at(
                    ln,
                    None,
                    format!("{} fields, the header has {width}", f.len()),
                ));
            }
            let num = |k: usize| -> Result<f64, FileError> {
                f[k].parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| {
                        at(
                            ln,
                            Some(cols[k]),
                            format!("not a finite number: {:?}", f[k]),
                        )
                    })
            };
            let (ti, pi, to, po) = (num(0)?, num(1)?, num(2)?, num(3)?);
            for (k, th) in [(0, ti), (2, to)] {
                if !(0.0..=90.0).contains(&th) {
                    return Err(at(
                        ln,
                        Some(cols[k]),
                        format!("θ must lie in [0, 90], got {th}"),
                    ));
                }
            }
            let value = (0..nc).map(|c| num(4 + c)).collect::<Result<Vec<_>, _>>()?;
            let sigma = if n_sigma > 0 {
                let s = (0..nc)
                    .map(|c| num(4 + nc + c))
                    .collect::<Result<Vec<_>, _>>()?;
                if let Some(c) = s.iter().position(|x| *x < 0.0) {
                    return Err(at(
                        ln,
                        Some(cols[4 + nc + c]),
                        "uncertainty is negative".into(),
                    ));
                }
                Some(s)
            } else {
                None
            };
            let flags = if has_flags {
                f[width - 1].parse::<u32>().map_err(|_| {
                    at(
                        ln,
                        Some("flags"),
                        format!("not a whole number: {:?}", f[width - 1]),
                    )
                })?
            } else {
                0
            };
            samples.push((
                ln,
                Sample {
                    pair: PairDeg {
                        incident: SphericalDeg::new(ti, pi),
                        outgoing: SphericalDeg::new(to, po),
                    },
                    value,
                    sigma,
                    flags,
                },
            ));
        }
        if samples.is_empty() {
            return Err(FileError::whole(KIND, path, "no data rows"));
        }
        let Some((gline, g)) = grid else {
            return Ok(Content::Samples(Samples {
                channels,
                samples: samples.into_iter().map(|s| s.1).collect(),
                isotropic,
            }));
        };
        let n = g.len();
        if samples.len() != n {
            return Err(at(
                gline,
                Some("grid"),
                format!("the grid has {n} nodes, the file {} rows", samples.len()),
            ));
        }
        let mut values = vec![f64::NAN; n * nc];
        let mut sigma = (n_sigma > 0).then(|| vec![0.0; n * nc]);
        let mut seen = vec![false; n];
        for (ln, s) in samples {
            let p = &s.pair;
            let (pi, po) = if g.isotropic {
                (0.0, p.outgoing.phi_deg - p.incident.phi_deg)
            } else {
                (p.incident.phi_deg, p.outgoing.phi_deg)
            };
            let node = |ax: &Axis, x: f64, name: &str| {
                ax.node_at(x.to_radians())
                    .ok_or_else(|| at(ln, Some(name), format!("{x} is not a node of the grid")))
            };
            let i = g.index(
                node(&g.phi_i, pi, "phi_i")?,
                node(&g.theta_i, p.incident.theta_deg, "theta_i")?,
                node(&g.phi_o, po, "phi_o")?,
                node(&g.theta_o, p.outgoing.theta_deg, "theta_o")?,
            );
            if std::mem::replace(&mut seen[i], true) {
                return Err(at(ln, None, "this node was already given".into()));
            }
            for ch in 0..nc {
                values[ch * n + i] = s.value[ch];
                if let (Some(out), Some(sg)) = (sigma.as_mut(), s.sigma.as_ref()) {
                    out[ch * n + i] = sg[ch];
                }
            }
        }
        Table::new(channels, g, values, sigma)
            .map(Content::Table)
            .map_err(|e| FileError::whole(KIND, path, e.to_string()))
    }

    /// A table of two channels with uncertainties on a small full grid.
    fn small_table() -> Table {
        let g = Grid::full(
            Axis::full_turn(4),
            Axis::polar_midpoints(3),
            Axis::full_turn(6),
            Axis::from_deg(0.0, 30.0, 4),
        );
        let n = g.len();
        let values: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.37).cos().abs()).collect();
        let sigma: Vec<f64> = values.iter().map(|v| v * 0.02).collect();
        Table::new(
            Channels::from_names(&["450nm", "550nm"]).expect("names"),
            g,
            values,
            Some(sigma),
        )
        .expect("table")
    }

    /// Format 1 as Gonio wrote it: `#` lines above a header of unitless names.
    fn format1_table(t: &Table) -> String {
        let new = write_table(t);
        let mut lines = new.lines();
        let _ = lines.next();
        let names = t.channels.names();
        let mut head: Vec<String> = HEADER.iter().map(|s| s.to_string()).collect();
        head.extend(names.iter().cloned());
        if t.sigma.is_some() {
            head.extend(names.iter().map(|n| format!("sigma_{n}")));
        }
        let mut out = format!(
            "# gonio-table: 1\n# grid: {}\n{}\n",
            grid_line(&t.grid),
            head.join(",")
        );
        for l in lines {
            out.push_str(l);
            out.push('\n');
        }
        out
    }

    #[test]
    fn streaming_reads_format_1_as_the_old_reader_did() {
        let t = small_table();
        let text = format1_table(&t);
        assert!(text.starts_with("# gonio-table: 1\n# grid: isotropic=false"));
        let new = read(&text, None).expect("streaming");
        assert_eq!(new, read_reference(&text, None).expect("reference"));
        assert_eq!(new, Content::Table(t.clone()));
        // Samples with flags and isotropic marking, and comment and blank lines among rows.
        let samples = "# gonio-samples: 1\n# isotropic: true\n\
                       theta_i,phi_i,theta_o,phi_o,R,G,B,sigma_R,sigma_G,sigma_B,flags\n\
                       10,0,20,180,0.25,0.5,1e-3,0.01,0.02,0.003,4\n\n# note\n\
                       \u{20}30 , 5 ,40,175.5,1,2,3,0,0,0,0\r\n";
        let new = read(samples, None).expect("streaming");
        assert_eq!(new, read_reference(samples, None).expect("reference"));
        let Content::Samples(s) = new else {
            panic!("samples");
        };
        assert!(s.isotropic);
        assert_eq!(s.samples[0].flags, 4);
        assert_eq!(s.samples[1].pair.outgoing.phi_deg, 175.5);
        // The same errors at the same lines.
        let row = |k: usize, field: usize, with: &str| {
            let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
            let mut f: Vec<&str> = lines[k].split(',').collect();
            f[field] = with;
            lines[k] = f.join(",");
            lines.join("\n")
        };
        for bad in [
            row(3, 4, "x"),
            row(7, 0, "95"),
            row(9, 6, "-1"),
            row(5, 3, "7"),
            format!("{text}15,0,0,0,1,1,1,1\n"),
        ] {
            let (a, b) = (read(&bad, None), read_reference(&bad, None));
            let (a, b) = (a.expect_err("bad"), b.expect_err("bad"));
            assert_eq!(
                (a.line.is_some(), &a.field),
                (b.line.is_some(), &b.field),
                "{a} / {b}"
            );
        }
    }

    #[test]
    fn a_table_reads_from_its_sidecar_or_as_samples_that_form_it() {
        let t = small_table();
        let text = write_table(&t);
        let meta = Meta::for_table(&t);
        let back =
            read_from(text.as_bytes(), text.len() as u64, Some(&meta), None).expect("with sidecar");
        assert_eq!(back, Content::Table(t.clone()));
        let Content::Samples(s) = read(&text, None).expect("without") else {
            panic!("no grid without the sidecar: samples");
        };
        assert_eq!(s.samples.len(), t.grid.len());
        let rec = s.to_table().expect("a complete uniform grid");
        // Samples::to_table takes the inverse-variance mean of each node's samples,
        // which for one sample is its value to within rounding.
        let close = |a: &[f64], b: &[f64]| {
            a.iter()
                .zip(b)
                .all(|(x, y)| (x - y).abs() <= 1e-15 * y.abs())
        };
        assert!(close(&rec.values, &t.values));
        // A node measured once keeps its σ (through 1/√(1/σ²), to the last bit or so).
        let (a, b) = (rec.sigma.expect("σ"), t.sigma.clone().expect("σ"));
        assert!(close(&a, &b));
        // An isotropic table keeps its form only through the sidecar.
        let iso = Table::new(
            Channels::Single,
            Grid::isotropic(
                Axis::polar_midpoints(3),
                Axis::full_turn(8),
                Axis::polar_midpoints(3),
            ),
            (0..72).map(|i| 0.1 + f64::from(i) * 0.01).collect(),
            None,
        )
        .expect("isotropic");
        let text = write_table(&iso);
        let back = read_from(
            text.as_bytes(),
            text.len() as u64,
            Some(&Meta::for_table(&iso)),
            None,
        )
        .expect("isotropic");
        assert_eq!(back, Content::Table(iso));
    }

    #[test]
    fn the_csv_is_what_pandas_reads_without_arguments() {
        // pandas.read_csv(path): the first line is the header, every row has as many
        // fields as it, every field a number, names unique and free of spaces.
        let t = small_table();
        let mut s = Samples::from_table(&t);
        s.samples[3].flags = 2;
        for text in [write_table(&t), write_samples(&s)] {
            let mut lines = text.lines();
            let head: Vec<&str> = lines.next().expect("header").split(',').collect();
            assert_eq!(head[..4], DIR_COLUMNS);
            let mut uniq = head.clone();
            uniq.sort_unstable();
            uniq.dedup();
            assert_eq!(uniq.len(), head.len());
            assert!(
                head.iter()
                    .all(|c| c.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_'))
            );
            let mut rows = 0;
            for l in lines {
                let f: Vec<&str> = l.split(',').collect();
                assert_eq!(f.len(), head.len(), "{l}");
                assert!(f.iter().all(|x| x.parse::<f64>().is_ok()), "{l}");
                rows += 1;
            }
            assert_eq!(rows, t.grid.len());
        }
        assert_eq!(
            write_table(&t).lines().next(),
            Some(
                "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,f_r_450nm_per_sr,f_r_550nm_per_sr,\
                 sigma_450nm_per_sr,sigma_550nm_per_sr"
            )
        );
        let single = Samples {
            channels: Channels::Single,
            samples: vec![Sample {
                pair: PairDeg {
                    incident: SphericalDeg::new(10.0, 0.0),
                    outgoing: SphericalDeg::new(20.0, 180.0),
                },
                value: vec![0.25],
                sigma: Some(vec![0.5]),
                flags: 1,
            }],
            isotropic: false,
        };
        assert_eq!(
            write_samples(&single),
            "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,f_r_per_sr,sigma_per_sr,flags\n\
             10,0,20,180,0.25,0.5,1\n"
        );
        assert_eq!(
            read(&write_samples(&single), None).expect("reads"),
            Content::Samples(single)
        );
    }

    #[test]
    fn a_sidecar_that_does_not_belong_is_refused() {
        let t = small_table();
        let text = write_table(&t);
        let mut meta = Meta::for_table(&t);
        meta.columns.pop();
        let e = read_from(
            text.as_bytes(),
            text.len() as u64,
            Some(&meta),
            Some(Path::new("t.csv")),
        )
        .expect_err("columns");
        assert_eq!(e.path.as_deref(), Some(Path::new("t.csv.json")));
        assert_eq!(e.field.as_deref(), Some("columns"));
        let short = &text[..text.trim_end().rfind('\n').expect("rows")];
        let e = read_from(
            short.as_bytes(),
            short.len() as u64,
            Some(&Meta::for_table(&t)),
            Some(Path::new("t.csv")),
        )
        .expect_err("grid");
        assert_eq!(
            e.to_string(),
            format!(
                "t.csv.json: field `grid`: the grid has {n} nodes, the CSV {m} rows",
                n = t.grid.len(),
                m = t.grid.len() - 1
            )
        );
        // A grid of 33 M nodes (near MAX_GRID_NODES) claimed for a few rows: refused
        // without allocating its values.
        let mut big = Meta::for_table(&t);
        if let Some(g) = big.grid.as_mut() {
            g.phi_i.n = 128;
            g.phi_i.step_deg = 360.0 / 128.0;
            g.phi_o = g.phi_i;
            (g.theta_i.n, g.theta_i.step_deg, g.theta_i.start_deg) = (45, 2.0, 1.0);
            g.theta_o = g.theta_i;
        }
        let e = read_from(
            text.as_bytes(),
            text.len() as u64,
            Some(&big),
            Some(Path::new("t.csv")),
        )
        .expect_err("too many nodes");
        assert_eq!(
            e.to_string(),
            format!(
                "t.csv.json: field `grid`: the grid has 33177600 nodes, the CSV {} rows",
                t.grid.len()
            )
        );
        let json = Meta::for_table(&t)
            .to_json()
            .replace("\"version\": 2", "\"version\": 9");
        let e = Meta::from_json(&json, Some(Path::new("t.csv.json"))).expect_err("version");
        assert_eq!(e.field.as_deref(), Some("version"));
        let e = Meta::from_json("{\"format\": ", None).expect_err("json");
        assert_eq!(e.line, Some(1));
    }
}
