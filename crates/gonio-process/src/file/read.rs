//! Reading tables and samples, of either format, streamed.

use std::collections::HashMap;
use std::io::BufRead;
use std::path::Path;

use gonio_core::dirfile::{HEADER, PairDeg};
use gonio_core::tomlfile::FileError;
use gonio_core::{Channels, SphericalDeg};

use super::{Content, DIR_COLUMNS, KIND, MAX_LINE, Meta, SIDECAR_KIND, sidecar_path, sigma_column};
use crate::{Axis, Grid, Sample, Samples, Table};

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

pub(super) fn parse_grid(s: &str) -> Result<Grid, String> {
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
    let at = |line: usize, field: Option<&str>, msg: String| {
        FileError::at_line(KIND, path, line, field, msg)
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
    let Preamble {
        head,
        mut grid,
        mut isotropic,
    } = preamble(&mut next, &mut buf, &mut ln, &at, path)?;
    let hline = ln;
    let h = parse_header(&head).map_err(|m| at(hline, None, m))?;
    let side = |field: &str, msg: String| FileError {
        field: Some(field.into()),
        ..FileError::whole(SIDECAR_KIND, path.map(sidecar_path).as_deref(), msg)
    };
    if let Some(m) = meta {
        isotropic = sidecar(m, &h, &mut grid, &side)?;
    }
    let table = grid.as_ref().and_then(|(_, g)| storage(g, &h, len));
    let lines = Lines { next, buf, ln };
    let filled = read_rows(lines, &at, &side, &h, &grid, table)?;
    finish(h, grid, filled, isotropic, &at, &side, path)
}

/// What the lines up to the header row say.
struct Preamble {
    /// The header row, trimmed.
    head: String,
    /// A `# grid:` line's grid, which makes the file a table.
    grid: Option<(GridFrom, Grid)>,
    /// `# isotropic: true`.
    isotropic: bool,
}

/// Reads the lines up to the header row: blank lines are passed over, comments
/// read for a grid or isotropy; no header row is an error.
fn preamble(
    next: &mut impl FnMut(&mut Vec<u8>, &mut usize) -> Result<bool, FileError>,
    buf: &mut Vec<u8>,
    ln: &mut usize,
    at: &impl Fn(usize, Option<&str>, String) -> FileError,
    path: Option<&Path>,
) -> Result<Preamble, FileError> {
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
        if !next(buf, ln)? {
            return Err(FileError::whole(KIND, path, "no header row"));
        }
        let l = text_of(buf, *ln)?;
        if l.is_empty() {
            continue;
        }
        if let Some(c) = l.strip_prefix('#') {
            if let Some((k, v)) = c.split_once(':') {
                match k.trim() {
                    "grid" => {
                        let g = parse_grid(v.trim()).map_err(|m| at(*ln, Some("grid"), m))?;
                        grid = Some((GridFrom::Line(*ln), g));
                    }
                    "isotropic" => isotropic = v.trim() == "true",
                    _ => {}
                }
            }
            continue;
        }
        break l;
    };
    Ok(Preamble {
        head,
        grid,
        isotropic,
    })
}

/// Checks the sidecar against the header (the same columns) and takes what it
/// adds: whether the rows are isotropic, which it returns, and its grid when the
/// file has no grid line.
fn sidecar(
    m: &Meta,
    h: &Header,
    grid: &mut Option<(GridFrom, Grid)>,
    side: &impl Fn(&str, String) -> FileError,
) -> Result<bool, FileError> {
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
    if grid.is_none()
        && let Some(g) = m.grid()
    {
        *grid = Some((GridFrom::Sidecar, g.map_err(|e| side("grid", e))?));
    }
    Ok(m.isotropic)
}

/// A table's storage as the rows fill it: the values by channel, their
/// uncertainties when the file has them, and which nodes were given.
type TableFill = (Vec<f64>, Option<Vec<f64>>, Vec<bool>);

/// The storage for a grid's values, or `None` for a grid with more nodes than the
/// input can hold rows for. A row has at least one character a field and a
/// separator after each: a grid with more nodes than that many rows fits in the
/// input cannot match it, and its values are never allocated (the rows are only
/// checked and counted, and the count is refused at the end, as for any grid the
/// rows do not fill).
fn storage(g: &Grid, h: &Header, len: u64) -> Option<TableFill> {
    let nc = h.channels.len();
    let width = h.cols.len();
    let fits = g.len() <= (len.saturating_add(1) / (2 * width as u64)) as usize;
    fits.then(|| {
        let n = g.len();
        (
            vec![f64::NAN; n * nc],
            h.sigma.then(|| vec![0.0; n * nc]),
            vec![false; n],
        )
    })
}

/// The line reader after the header: the read of the next line into `buf`, and the
/// number of the line last read.
struct Lines<N> {
    next: N,
    buf: Vec<u8>,
    ln: usize,
}

/// What the data rows gave: how many there were, the samples (without a grid), and
/// the table's storage filled (with one).
struct Filled {
    rows: usize,
    samples: Vec<Sample>,
    table: Option<TableFill>,
}

/// One data row's numbers, parsed into buffers reused from row to row.
struct Row {
    /// Positions of the fields of the current line.
    fields: Vec<(usize, usize)>,
    /// The text and value of each angle in the last row: the angles repeat from row
    /// to row (a table's rows run through the grid), so a field equal to the last
    /// row's keeps its parsed value.
    last_angle: [(String, f64); 4],
    /// θi, φi, θo, φo, degrees.
    angles: [f64; 4],
    value: Vec<f64>,
    sigma: Vec<f64>,
    flags: u32,
}

impl Row {
    fn new(h: &Header) -> Row {
        let nc = h.channels.len();
        Row {
            fields: Vec::with_capacity(h.cols.len()),
            last_angle: Default::default(),
            angles: [0.0; 4],
            value: vec![0.0; nc],
            sigma: vec![0.0; nc],
            flags: 0,
        }
    }

    /// Parses line `ln`'s text `l` (trimmed, not blank, not a comment): every field
    /// checked, the first bad one named.
    fn parse(
        &mut self,
        l: &str,
        ln: usize,
        h: &Header,
        at: &impl Fn(usize, Option<&str>, String) -> FileError,
    ) -> Result<(), FileError> {
        let (nc, width, cols) = (h.channels.len(), h.cols.len(), &h.cols);
        self.fields.clear();
        let mut s = 0;
        for (i, b) in l.bytes().enumerate() {
            if b == b',' {
                self.fields.push((s, i));
                s = i + 1;
            }
        }
        self.fields.push((s, l.len()));
        if self.fields.len() != width {
            return Err(at(
                ln,
                None,
                format!("{} fields, the header has {width}", self.fields.len()),
            ));
        }
        let fields = &self.fields;
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
        for k in 0..4 {
            let f = field(k);
            let (text, x) = &mut self.last_angle[k];
            if text.as_str() != f {
                *x = num(k)?;
                text.clear();
                text.push_str(f);
            }
            self.angles[k] = *x;
        }
        for k in [0, 2] {
            let th = self.angles[k];
            if !(0.0..=90.0).contains(&th) {
                return Err(at(
                    ln,
                    Some(&cols[k]),
                    format!("θ must lie in [0, 90], got {th}"),
                ));
            }
        }
        for (c, v) in self.value.iter_mut().enumerate() {
            *v = num(4 + c)?;
        }
        if h.sigma {
            for (c, v) in self.sigma.iter_mut().enumerate() {
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
        self.flags = if h.flags {
            let f = field(width - 1);
            f.parse::<u32>()
                .map_err(|_| at(ln, Some("flags"), format!("not a whole number: {f:?}")))?
        } else {
            0
        };
        Ok(())
    }

    /// The row as a sample.
    fn sample(&self, h: &Header) -> Sample {
        let [ti, pi, to, po] = self.angles;
        Sample {
            pair: PairDeg {
                incident: SphericalDeg::new(ti, pi),
                outgoing: SphericalDeg::new(to, po),
            },
            value: self.value.clone(),
            sigma: h.sigma.then(|| self.sigma.clone()),
            flags: self.flags,
        }
    }
}

/// The grid's node of a row's directions, remembering the last node found on each
/// axis by angle: most rows repeat three of them.
struct Nodes([(f64, usize); 4]);

impl Nodes {
    /// The node index of `row` in `g` (in the frame φi = 0 for an isotropic grid).
    fn index(
        &mut self,
        g: &Grid,
        row: &Row,
        ln: usize,
        at: &impl Fn(usize, Option<&str>, String) -> FileError,
    ) -> Result<usize, FileError> {
        let [ti, pi, to, po] = row.angles;
        let (pi, po) = if g.isotropic {
            (0.0, po - pi)
        } else {
            (pi, po)
        };
        let mut node = |slot: usize, ax: &Axis, x: f64, name: &str| {
            let (lx, li) = &mut self.0[slot];
            if *lx == x {
                return Ok(*li);
            }
            let i = ax
                .node_at(x.to_radians())
                .ok_or_else(|| at(ln, Some(name), format!("{x} is not a node of the grid")))?;
            (*lx, *li) = (x, i);
            Ok::<usize, FileError>(i)
        };
        Ok(g.index(
            node(0, &g.phi_i, pi, "phi_i")?,
            node(1, &g.theta_i, ti, "theta_i")?,
            node(2, &g.phi_o, po, "phi_o")?,
            node(3, &g.theta_o, to, "theta_o")?,
        ))
    }
}

/// Reads the data rows, each checked and parsed straight into the table's storage
/// at its node, or into a sample without a grid. This is the reader's hot loop.
fn read_rows<N>(
    lines: Lines<N>,
    at: &impl Fn(usize, Option<&str>, String) -> FileError,
    side: &impl Fn(&str, String) -> FileError,
    h: &Header,
    grid: &Option<(GridFrom, Grid)>,
    mut table: Option<TableFill>,
) -> Result<Filled, FileError>
where
    N: FnMut(&mut Vec<u8>, &mut usize) -> Result<bool, FileError>,
{
    let Lines {
        mut next,
        mut buf,
        mut ln,
    } = lines;
    let nc = h.channels.len();
    let mut rows = 0usize;
    let mut samples: Vec<Sample> = Vec::new();
    let mut row = Row::new(h);
    let mut nodes = Nodes([(f64::NAN, 0); 4]);
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
        row.parse(l, ln, h, at)?;
        if grid.is_some() && table.is_none() {
            continue;
        }
        let (Some((from, g)), Some((values, sig, seen))) = (grid.as_ref(), table.as_mut()) else {
            samples.push(row.sample(h));
            continue;
        };
        let n = g.len();
        if rows > n {
            return Err(grid_count(at, side, from, n, rows, ln));
        }
        let i = nodes.index(g, &row, ln, at)?;
        if std::mem::replace(&mut seen[i], true) {
            return Err(at(ln, None, "this node was already given".into()));
        }
        for ch in 0..nc {
            values[ch * n + i] = row.value[ch];
        }
        if let Some(out) = sig.as_mut() {
            for ch in 0..nc {
                out[ch * n + i] = row.sigma[ch];
            }
        }
    }
    Ok(Filled {
        rows,
        samples,
        table,
    })
}

/// The content once every row is read: the samples, or the table when its grid's
/// nodes were each given once (no rows, or a count other than the grid's, is an
/// error).
fn finish(
    h: Header,
    grid: Option<(GridFrom, Grid)>,
    filled: Filled,
    isotropic: bool,
    at: &impl Fn(usize, Option<&str>, String) -> FileError,
    side: &impl Fn(&str, String) -> FileError,
    path: Option<&Path>,
) -> Result<Content, FileError> {
    let Filled {
        rows,
        samples,
        table,
    } = filled;
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
