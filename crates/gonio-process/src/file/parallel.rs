//! The table and sample CSV read as columns, in parallel: any tool's file.
//!
//! [`read_columns`] streams the bytes in blocks of [`BLOCK`] bytes (the first a
//! sixteenth of that, each next twice the last), cuts each block at line
//! boundaries into chunks of about [`CHUNK`] bytes, and parses the chunks on rayon,
//! each into its own short columns, which are copied to their places in the whole
//! file's columns (known from the chunks' lengths), on rayon as well. The blocks and
//! chunks depend on the bytes alone, never on the number of threads, and a number's
//! parse does not depend on its neighbours: the columns, and any error
//! (the first in file order), are the same on any number of threads.
//!
//! The header may come from another tool: the columns in any order, the angles as
//! `theta_i`, `theta_i_deg`, `theta_i [deg]` or `theta_i (°)` (degrees; radians are
//! refused rather than guessed), the values as `f_r_<channel>_per_sr`,
//! `f_r_<channel> [1/sr]` or a format-1 channel name, the uncertainties likewise
//! with `sigma`, and `flags`. A name that could mean two columns (two θi, a σ without
//! its channel) is refused, naming the header line.
//!
//! [`Columns::into_content`] makes the table: with a grid (a `# grid:` line or the
//! sidecar) each row goes to its node; without one the grid is recognised from the
//! values themselves, as `Samples::to_table` recognises it, and the table is built
//! straight from the columns when each node is given once (the same table, bit for
//! bit, that the samples would give). Anything else is samples.

use std::io::Read;
use std::path::Path;

use gonio_core::dirfile::PairDeg;
use gonio_core::tomlfile::FileError;
use gonio_core::{Channels, SphericalDeg};
use rayon::prelude::*;

use super::{Content, KIND, MAX_LINE, MAX_ROWS, Meta, SIDECAR_KIND, sidecar_path};
use crate::{Axis, Grid, Sample, Samples, Table};

/// Bytes read at a time: the text held at once.
pub const BLOCK: usize = 16 << 20;

/// Bytes a chunk of a block has (cut at the next line end): the unit of parallel work.
pub const CHUNK: usize = 256 << 10;

/// Rows per unit of parallel work once the columns are read.
const ROW_CHUNK: usize = 1 << 16;

/// What each column of the header is.
#[derive(Clone, Debug, PartialEq)]
pub struct Roles {
    /// The header's names, trimmed, in file order.
    pub names: Vec<String>,
    /// The columns (0-based) of θi, φi, θo, φo.
    pub angles: [usize; 4],
    /// The channels, in the order of their value columns.
    pub channels: Channels,
    /// Each channel's value column.
    pub values: Vec<usize>,
    /// Each channel's uncertainty column, when the file has them.
    pub sigma: Option<Vec<usize>>,
    /// The flags column.
    pub flags: Option<usize>,
}

impl Roles {
    /// The slots parsed as numbers: angles, values, uncertainties, in that order, as
    /// file columns.
    fn slots(&self) -> Vec<usize> {
        let mut s: Vec<usize> = self.angles.to_vec();
        s.extend(&self.values);
        if let Some(sg) = &self.sigma {
            s.extend(sg);
        }
        s
    }
}

/// What a column's name says it is.
enum Role {
    Angle(usize),
    Value(String),
    Sigma(String),
    Flags,
}

/// A name and the unit written after it in brackets (`theta_i [deg]`, `f_r (1/sr)`).
fn split_unit(c: &str) -> (&str, Option<&str>) {
    for (open, close) in [('[', ']'), ('(', ')')] {
        if let Some(s) = c.strip_suffix(close)
            && let Some(i) = s.rfind(open)
        {
            return (s[..i].trim(), Some(s[i + 1..].trim()));
        }
    }
    (c, None)
}

/// The role of one header name, or why it has none.
fn role_of(col: &str) -> Result<Role, String> {
    let (base, unit) = split_unit(col);
    const ANGLES: [&str; 4] = ["theta_i", "phi_i", "theta_o", "phi_o"];
    let lower = base.to_ascii_lowercase();
    let (stem, suffix_unit) = match lower.rsplit_once('_') {
        Some((s, u @ ("deg" | "rad"))) if ANGLES.contains(&s) => (s.to_string(), Some(u)),
        _ => (lower.clone(), None),
    };
    if let Some(k) = ANGLES.iter().position(|a| *a == stem) {
        return match unit.or(suffix_unit) {
            None | Some("deg" | "degree" | "degrees" | "°") => Ok(Role::Angle(k)),
            Some("rad" | "radian" | "radians") => Err(format!(
                "column {col:?} is in radians; the angles are read in degrees"
            )),
            Some(u) => Err(format!(
                "column {col:?}: {u:?} is not an angle unit (degrees: deg or °)"
            )),
        };
    }
    if base == "flags" && unit.is_none() {
        return Ok(Role::Flags);
    }
    let per_sr = |u: Option<&str>| matches!(u, Some("1/sr" | "sr^-1" | "sr-1" | "per sr"));
    for (prefix, sigma) in [("f_r", false), ("sigma", true)] {
        let channel = if let Some(rest) = base.strip_prefix(prefix) {
            let rest = match rest.strip_suffix("_per_sr") {
                Some(r) if unit.is_none() => Some(r),
                None if per_sr(unit) => Some(rest),
                _ => None,
            };
            match rest {
                Some("") => Some("value".to_string()),
                Some(r) => r
                    .strip_prefix('_')
                    .filter(|c| !c.is_empty())
                    .map(str::to_string),
                None => None,
            }
        } else {
            None
        };
        if let Some(c) = channel {
            return Ok(if sigma {
                Role::Sigma(c)
            } else {
                Role::Value(c)
            });
        }
    }
    if unit.is_none() {
        // Format 1: `sigma_<channel>` and the bare channel names.
        if let Some(c) = base.strip_prefix("sigma_").filter(|c| !c.is_empty()) {
            return Ok(Role::Sigma(c.to_string()));
        }
        if !base.is_empty() {
            return Ok(Role::Value(base.to_string()));
        }
    }
    Err(format!("column {col:?} is not one Gonio reads"))
}

/// The roles of a header row's columns, in any order; an error names what is
/// missing, given twice or not understood.
pub fn header_roles(head: &str) -> Result<Roles, String> {
    let names: Vec<String> = head
        .split(',')
        .map(|c| c.trim().trim_matches('"').trim().to_string())
        .collect();
    let mut angles = [None::<usize>; 4];
    let mut values: Vec<(String, usize)> = Vec::new();
    let mut sigmas: Vec<(String, usize)> = Vec::new();
    let mut flags = None;
    let twice = |a: usize, b: usize| {
        format!(
            "columns {} ({:?}) and {} ({:?}) both name the same quantity",
            a + 1,
            names[a],
            b + 1,
            names[b]
        )
    };
    for (j, c) in names.iter().enumerate() {
        match role_of(c)? {
            Role::Angle(k) => {
                if let Some(a) = angles[k] {
                    return Err(twice(a, j));
                }
                angles[k] = Some(j);
            }
            Role::Flags => {
                if let Some(a) = flags {
                    return Err(twice(a, j));
                }
                flags = Some(j);
            }
            Role::Value(ch) => {
                if let Some((_, a)) = values.iter().find(|(c, _)| *c == ch) {
                    return Err(twice(*a, j));
                }
                values.push((ch, j));
            }
            Role::Sigma(ch) => {
                if let Some((_, a)) = sigmas.iter().find(|(c, _)| *c == ch) {
                    return Err(twice(*a, j));
                }
                sigmas.push((ch, j));
            }
        }
    }
    let [Some(ti), Some(pi), Some(to), Some(po)] = angles else {
        return Err(format!(
            "no column for {}; expected theta_i_deg, phi_i_deg, theta_o_deg and phi_o_deg \
             (in any order; theta_i, theta_i [deg] and the like also read)",
            ["θi", "φi", "θo", "φo"]
                .iter()
                .zip(angles)
                .filter(|(_, a)| a.is_none())
                .map(|(n, _)| *n)
                .collect::<Vec<_>>()
                .join(", ")
        ));
    };
    let chans: Vec<&str> = values.iter().map(|(c, _)| c.as_str()).collect();
    let channels = Channels::from_names(&chans).map_err(|e| format!("channels: {e}"))?;
    let sigma = if sigmas.is_empty() {
        None
    } else {
        if let Some((ch, j)) = sigmas.iter().find(|(c, _)| !chans.contains(&c.as_str())) {
            return Err(format!(
                "column {} ({:?}) is the uncertainty of {ch:?}, which has no value column",
                j + 1,
                names[*j]
            ));
        }
        let mut s = Vec::with_capacity(values.len());
        for (ch, _) in &values {
            let Some((_, j)) = sigmas.iter().find(|(c, _)| c == ch) else {
                return Err(format!(
                    "the uncertainty of channel {ch:?} is missing: either every channel \
                     has one or none"
                ));
            };
            s.push(*j);
        }
        Some(s)
    };
    Ok(Roles {
        angles: [ti, pi, to, po],
        values: values.iter().map(|v| v.1).collect(),
        channels,
        sigma,
        flags,
        names,
    })
}

/// A table or sample file as columns ([`read_columns`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Columns {
    /// What each column is.
    pub roles: Roles,
    /// θi, φi, θo, φo (degrees), one entry a row, whatever the file's column order.
    pub angles: [Vec<f64>; 4],
    /// Each channel's values (1/sr), in the order of `roles.channels`.
    pub values: Vec<Vec<f64>>,
    /// Each channel's standard uncertainties (1/sr), when the file has them.
    pub sigma: Option<Vec<Vec<f64>>>,
    /// Each row's flags, when the file has the column.
    pub flags: Option<Vec<u32>>,
    /// `# isotropic: true` above the header.
    pub isotropic: bool,
    /// A `# grid:` line above the header, and its line number.
    pub grid: Option<(usize, Grid)>,
    /// The header's line number (1-based).
    pub header_line: usize,
    /// Lines after the header that are blank or comments, ascending: row r is on
    /// line `header_line + 1 + r` plus those of them before it.
    skipped: Vec<usize>,
}

/// A chunk's rows as parsed: numbers by slot, flags, and the first error. Its
/// buffers serve the chunk at the same place in the next block.
#[derive(Default)]
struct Parsed {
    slots: Vec<Vec<f64>>,
    flags: Vec<u32>,
    /// Lines in the chunk (its newlines, or one more for an unterminated last line).
    lines: usize,
    /// Blank and comment lines, 0-based within the chunk.
    skipped: Vec<usize>,
    /// The first bad line (0-based within the chunk), the column, the message.
    error: Option<(usize, Option<usize>, String)>,
}

/// Trims ASCII whitespace (and a line's `\r`) from both ends.
fn trim(b: &[u8]) -> &[u8] {
    b.trim_ascii()
}

/// A field's number: std's correctly rounded parse, finite only.
fn number(f: &[u8]) -> Option<f64> {
    std::str::from_utf8(f)
        .ok()?
        .parse::<f64>()
        .ok()
        .filter(|x| x.is_finite())
}

/// Parses the lines of one chunk (whole lines, the last maybe unterminated) into
/// `out`, whose buffers are reused.
fn parse_chunk(text: &[u8], roles: &Roles, slots: &[usize], out: &mut Parsed) {
    let width = roles.names.len();
    let nc = roles.values.len();
    // At most a row a line: the chunk's columns are allocated once.
    let guess = text.iter().filter(|b| **b == b'\n').count() + 1;
    out.slots.resize_with(slots.len(), Vec::new);
    for c in &mut out.slots {
        c.clear();
        c.reserve(guess);
    }
    out.flags.clear();
    if roles.flags.is_some() {
        out.flags.reserve(guess);
    }
    out.lines = 0;
    out.skipped.clear();
    out.error = None;
    let mut fields: Vec<(usize, usize)> = Vec::with_capacity(width);
    // The angles repeat from row to row: a field equal to the last row's keeps its value.
    let mut last: [(&[u8], f64); 4] = [(&[][..], 0.0); 4];
    for (k, line) in text.split_inclusive(|b| *b == b'\n').enumerate() {
        out.lines += 1;
        if line.len() > MAX_LINE {
            out.error = Some((k, None, format!("longer than {MAX_LINE} bytes")));
            return;
        }
        let l = trim(line);
        if l.is_empty() || l[0] == b'#' {
            out.skipped.push(k);
            continue;
        }
        fields.clear();
        let mut s = 0;
        for (i, b) in l.iter().enumerate() {
            if *b == b',' {
                fields.push((s, i));
                s = i + 1;
            }
        }
        fields.push((s, l.len()));
        if fields.len() != width {
            out.error = Some((
                k,
                None,
                format!("{} fields, the header has {width}", fields.len()),
            ));
            return;
        }
        let field = |j: usize| trim(&l[fields[j].0..fields[j].1]);
        let bad = |j: usize| {
            let f = String::from_utf8_lossy(field(j)).into_owned();
            (k, Some(j), format!("not a finite number: {f:?}"))
        };
        for (slot, &j) in slots.iter().enumerate() {
            let f = field(j);
            let x = if slot < 4 {
                let (text, x) = &mut last[slot];
                if *text != f {
                    match number(f) {
                        Some(v) => (*text, *x) = (f, v),
                        None => {
                            out.error = Some(bad(j));
                            return;
                        }
                    }
                }
                let x = *x;
                if slot % 2 == 0 && !(0.0..=90.0).contains(&x) {
                    out.error = Some((k, Some(j), format!("θ must lie in [0, 90], got {x}")));
                    return;
                }
                x
            } else {
                match number(f) {
                    Some(v) if slot >= 4 + nc && v < 0.0 => {
                        out.error = Some((k, Some(j), "uncertainty is negative".into()));
                        return;
                    }
                    Some(v) => v,
                    None => {
                        out.error = Some(bad(j));
                        return;
                    }
                }
            };
            out.slots[slot].push(x);
        }
        if let Some(j) = roles.flags {
            let f = field(j);
            match std::str::from_utf8(f)
                .ok()
                .and_then(|s| s.parse::<u32>().ok())
            {
                Some(v) => out.flags.push(v),
                None => {
                    let f = String::from_utf8_lossy(f).into_owned();
                    out.error = Some((k, Some(j), format!("not a whole number: {f:?}")));
                    return;
                }
            }
        }
    }
}

/// Cuts `text` into chunks of about `size` bytes, each ending at a line end (the
/// last maybe not).
fn chunks(text: &[u8], size: usize) -> Vec<&[u8]> {
    let mut out = Vec::with_capacity(text.len() / size + 1);
    let mut rest = text;
    while !rest.is_empty() {
        let cut = if rest.len() <= size {
            rest.len()
        } else {
            match rest[size - 1..].iter().position(|b| *b == b'\n') {
                Some(i) => size + i,
                None => rest.len(),
            }
        };
        let (a, b) = rest.split_at(cut);
        out.push(a);
        rest = b;
    }
    out
}

/// Reads the lines up to the header: the header row (trimmed), its line number, a
/// grid line, `# isotropic: true`, and the byte offset of the first data line.
struct Head {
    text: String,
    line: usize,
    grid: Option<(usize, Grid)>,
    isotropic: bool,
    end: usize,
}

/// The head of the text in `buf` (which starts at the file's first byte), or `None`
/// when `buf` ends before the header row's line does.
fn head(buf: &[u8], eof: bool, path: Option<&Path>) -> Result<Option<Head>, FileError> {
    let at = |line: usize, field: Option<&str>, msg: String| {
        FileError::at_line(KIND, path, line, field, msg)
    };
    let mut pos = 0;
    let mut line = 0;
    let mut grid = None;
    let mut isotropic = false;
    loop {
        let Some(len) = buf[pos..]
            .iter()
            .position(|b| *b == b'\n')
            .map(|i| i + 1)
            .or((eof && pos < buf.len()).then_some(buf.len() - pos))
        else {
            if eof {
                return Err(FileError::whole(KIND, path, "no header row"));
            }
            if buf.len() - pos > MAX_LINE {
                return Err(at(line + 1, None, format!("longer than {MAX_LINE} bytes")));
            }
            return Ok(None);
        };
        line += 1;
        let mut raw = &buf[pos..pos + len];
        pos += len;
        if line == 1 {
            raw = gonio_core::text::strip_bom_bytes(raw);
        }
        if raw.len() > MAX_LINE {
            return Err(at(line, None, format!("longer than {MAX_LINE} bytes")));
        }
        let l = std::str::from_utf8(raw)
            .map_err(|_| at(line, None, "not UTF-8 text".into()))?
            .trim();
        if l.is_empty() {
            continue;
        }
        if let Some(c) = l.strip_prefix('#') {
            if let Some((k, v)) = c.split_once(':') {
                match k.trim() {
                    "grid" => {
                        let g = super::read::parse_grid(v.trim())
                            .map_err(|m| at(line, Some("grid"), m))?;
                        grid = Some((line, g));
                    }
                    "isotropic" => isotropic = v.trim() == "true",
                    _ => {}
                }
            }
            continue;
        }
        return Ok(Some(Head {
            text: l.to_string(),
            line,
            grid,
            isotropic,
            end: pos,
        }));
    }
}

/// Whether `bytes` (a file's first bytes) start, after blank and `#` lines, with a
/// header row [`header_roles`] reads: a table or sample file in any column order.
pub fn is_columns_header(bytes: &[u8]) -> bool {
    let bytes = gonio_core::text::strip_bom_bytes(bytes);
    let text = match std::str::from_utf8(bytes) {
        Ok(t) => t,
        Err(e) => std::str::from_utf8(&bytes[..e.valid_up_to()]).unwrap_or(""),
    };
    text.lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .is_some_and(|h| h.contains(',') && header_roles(h).is_ok())
}

/// Reads a table or sample file of at most `len` bytes from `r` as columns: the
/// header in any column order ([`header_roles`]), the rows parsed in parallel, block
/// by block (module docs). Errors name `path`, the line and the column.
pub fn read_columns<R: Read>(r: R, len: u64, path: Option<&Path>) -> Result<Columns, FileError> {
    read_columns_in(r, len, path, BLOCK, CHUNK)
}

/// [`read_columns`] with other block and chunk sizes (bytes, at least 1): the same
/// columns and errors for any sizes, which is what the tests vary.
pub fn read_columns_in<R: Read>(
    mut r: R,
    len: u64,
    path: Option<&Path>,
    block: usize,
    chunk: usize,
) -> Result<Columns, FileError> {
    let (block, chunk) = (block.max(1), chunk.max(1));
    let _span = tracing::debug_span!("read_columns", bytes = len).entered();
    let at = |line: usize, field: Option<&str>, msg: String| {
        FileError::at_line(KIND, path, line, field, msg)
    };
    let mut buf: Vec<u8> = Vec::with_capacity(block.min(len as usize + 1).min(BLOCK) + 1);
    let mut eof = false;
    // The first block is a sixteenth of `block`, and each next one twice the last up
    // to `block`: the parse starts (on rayon) while the calling thread would still
    // be reading a whole block, and each read is hidden behind the parse before it.
    let first = (block / 16).max(1);
    // Reads up to `size` bytes more (to `size` when short of it).
    let mut fill = |buf: &mut Vec<u8>, eof: &mut bool, size: usize| -> Result<(), FileError> {
        let want = if buf.len() < size {
            size - buf.len()
        } else {
            size
        };
        let got = std::io::Read::take(&mut r, want as u64)
            .read_to_end(buf)
            .map_err(|e| FileError::whole(KIND, path, format!("cannot read: {e}")))?;
        *eof = got < want;
        Ok(())
    };
    let h = loop {
        fill(&mut buf, &mut eof, first)?;
        if let Some(h) = head(&buf, eof, path)? {
            break h;
        }
    };
    let roles = header_roles(&h.text).map_err(|m| at(h.line, None, m))?;
    buf.drain(..h.end);
    let slots = roles.slots();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); slots.len()];
    let mut flags: Vec<u32> = Vec::new();
    let mut skipped = Vec::new();
    let mut line = h.line;
    let mut rows = 0usize;
    // The buffer the next block is read into: the last block's, whose pages are
    // already the process's (a fresh one a block costs the reading thread a page
    // fault every 4 KiB, beside the parse).
    let mut spare: Vec<u8> = Vec::new();
    let mut parsed: Vec<Parsed> = Vec::new();
    let mut size = first;
    loop {
        if !eof && buf.len() < size {
            fill(&mut buf, &mut eof, size)?;
        }
        // Whole lines only, but for the file's last.
        let end = if eof {
            buf.len()
        } else {
            match buf.iter().rposition(|b| *b == b'\n') {
                Some(i) => i + 1,
                None if buf.len() > MAX_LINE => {
                    return Err(at(line + 1, None, format!("longer than {MAX_LINE} bytes")));
                }
                None => {
                    fill(&mut buf, &mut eof, size)?;
                    continue;
                }
            }
        };
        // This block's whole lines are parsed (on rayon, from a scoped thread) while
        // this thread reads the next block behind the rest of its last line: the
        // same reads, so the same blocks, as one after the other.
        size = (2 * size).min(block);
        let mut next = std::mem::take(&mut spare);
        next.clear();
        next.reserve(buf.capacity());
        next.extend_from_slice(&buf[end..]);
        let pieces = chunks(&buf[..end], chunk);
        // The last block's chunk buffers parse this one's (their pages are the
        // process's already: fresh ones a block page-fault anew).
        parsed.resize_with(pieces.len(), Parsed::default);
        let (done, read) = std::thread::scope(|s| {
            let parse = s.spawn(|| {
                pieces
                    .par_iter()
                    .zip(parsed.par_iter_mut())
                    .for_each(|(c, p)| parse_chunk(c, &roles, &slots, p))
            });
            let read = if eof {
                Ok(())
            } else {
                fill(&mut next, &mut eof, size)
            };
            (parse.join(), read)
        });
        done.unwrap_or_else(|e| std::panic::resume_unwind(e));
        if rows == 0 && !parsed.is_empty() {
            // Columns for the whole file from the first block's density, zeroed by
            // the allocator (fresh pages: touched first by the copies below, on
            // rayon).
            let (n, bytes) = (parsed.iter().map(|p| p.slots[0].len()).sum::<usize>(), end);
            let est = ((len as f64 / bytes.max(1) as f64) * n as f64 * 1.01) as usize + 16;
            let est = est.min(MAX_ROWS);
            cols.iter_mut().for_each(|c| *c = vec![0.0; est]);
            if roles.flags.is_some() {
                flags.reserve_exact(est);
            }
        }
        let first = rows;
        for p in &parsed {
            if let Some((k, col, msg)) = &p.error {
                let field = col.map(|j| roles.names[j].as_str());
                return Err(at(line + 1 + k, field, msg.clone()));
            }
            let got = p.slots[0].len();
            if rows + got > MAX_ROWS {
                let k = (0..p.lines)
                    .filter(|k| p.skipped.binary_search(k).is_err())
                    .nth(MAX_ROWS - rows)
                    .unwrap_or(0);
                return Err(at(line + 1 + k, None, format!("more than {MAX_ROWS} rows")));
            }
            rows += got;
            flags.extend_from_slice(&p.flags);
            skipped.extend(p.skipped.iter().map(|k| line + 1 + k));
            line += p.lines;
        }
        // The chunks' columns copied to their places (known from their lengths) on
        // rayon, rather than appended one after the other.
        for c in cols.iter_mut() {
            if c.len() < rows {
                // More rows than the first block's density promised.
                c.resize(rows.max(c.len() + c.len() / 2), 0.0);
            }
        }
        let mut copies: Vec<(&mut [f64], &[f64])> = Vec::new();
        for (j, c) in cols.iter_mut().enumerate() {
            let mut rest = &mut c[first..rows];
            for p in &parsed {
                let (here, after) = rest.split_at_mut(p.slots[j].len());
                copies.push((here, &p.slots[j]));
                rest = after;
            }
        }
        copies
            .into_par_iter()
            .for_each(|(to, from)| to.copy_from_slice(from));
        // A read's error after this block's own (the order of one after the other).
        read?;
        spare = std::mem::replace(&mut buf, next);
        if eof && buf.is_empty() {
            break;
        }
    }
    if rows == 0 {
        return Err(FileError::whole(KIND, path, "no data rows"));
    }
    // The read buffers are freed on rayon, beside what follows (unmapping them is
    // a pass over their pages).
    rayon::spawn(move || drop((buf, spare, parsed)));
    cols.iter_mut().for_each(|c| c.truncate(rows));
    let nc = roles.values.len();
    let mut it = cols.into_iter();
    let angles = [(); 4].map(|_| it.next().unwrap_or_default());
    let values: Vec<Vec<f64>> = it.by_ref().take(nc).collect();
    let sigma = roles.sigma.is_some().then(|| it.collect());
    tracing::debug!(rows, channels = nc, "read as columns");
    Ok(Columns {
        flags: roles.flags.is_some().then_some(flags),
        roles,
        angles,
        values,
        sigma,
        isotropic: h.isotropic,
        grid: h.grid,
        header_line: h.line,
        skipped,
    })
}

/// A small direct-mapped memo of a function of one or two angles (keyed by their
/// bits): rows repeat and cycle through few angles, so that most rows find their
/// axis keys here rather than forming them anew. Exact: a miss forms the value.
struct Memo<V> {
    slots: Vec<Option<(u64, u64, V)>>,
}

impl<V: Clone> Default for Memo<V> {
    fn default() -> Self {
        Memo {
            slots: vec![None; 256],
        }
    }
}

impl<V: Clone> Memo<V> {
    /// The value kept for `(x, y)`, else `f()`'s, kept.
    fn get_or(&mut self, (x, y): (f64, f64), f: impl FnOnce() -> V) -> V {
        let (x, y) = (x.to_bits(), y.to_bits());
        let h = ((x ^ y.rotate_left(29)).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 56) as usize;
        match &self.slots[h] {
            Some((a, b, v)) if *a == x && *b == y => v.clone(),
            _ => {
                let v = f();
                self.slots[h] = Some((x, y, v.clone()));
                v
            }
        }
    }
}

/// A row off a grid: its index, the axis and the angle.
type OffGrid = (usize, &'static str, f64);

/// Micro-degrees: angles keyed exactly for any grid a plan or file writes (as
/// `Samples::to_table` keys them).
fn q(x: f64) -> i64 {
    (x * 1e6).round() as i64
}

/// An azimuth's key in [0°, 360°).
fn wrap(x: f64) -> i64 {
    q(x.rem_euclid(360.0)) % 360_000_000
}

impl Columns {
    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.angles[0].len()
    }

    /// The line (1-based) of row `r` (0-based).
    pub fn line_of(&self, r: usize) -> usize {
        let mut line = self.header_line + 1 + r;
        for s in &self.skipped {
            if *s <= line {
                line += 1;
            } else {
                break;
            }
        }
        line
    }

    /// The rows as samples, one a row.
    pub fn to_samples(&self) -> Samples {
        let nc = self.values.len();
        let samples = (0..self.rows())
            .map(|r| Sample {
                pair: PairDeg {
                    incident: SphericalDeg::new(self.angles[0][r], self.angles[1][r]),
                    outgoing: SphericalDeg::new(self.angles[2][r], self.angles[3][r]),
                },
                value: (0..nc).map(|c| self.values[c][r]).collect(),
                sigma: self
                    .sigma
                    .as_ref()
                    .map(|s| (0..nc).map(|c| s[c][r]).collect()),
                flags: self.flags.as_ref().map_or(0, |f| f[r]),
            })
            .collect();
        Samples {
            channels: self.roles.channels.clone(),
            samples,
            isotropic: self.isotropic,
        }
    }

    /// The content: a table when a grid is given (the `# grid:` line, else the
    /// sidecar `meta`, whose columns must be the header's) and the rows are its
    /// nodes; without one, a table when the values form a complete uniform grid with
    /// each node once (module docs); else samples. `path` names the CSV in errors.
    pub fn into_content(
        self,
        meta: Option<&Meta>,
        path: Option<&Path>,
    ) -> Result<Content, FileError> {
        let side = |field: &str, msg: String| FileError {
            field: Some(field.into()),
            ..FileError::whole(SIDECAR_KIND, path.map(sidecar_path).as_deref(), msg)
        };
        let mut this = self;
        let mut from_sidecar = false;
        if let Some(m) = meta {
            if m.columns != this.roles.names {
                return Err(side(
                    "columns",
                    format!(
                        "describes the columns {}, the CSV has {}; the two do not belong together",
                        m.columns.join(","),
                        this.roles.names.join(",")
                    ),
                ));
            }
            this.isotropic = m.isotropic;
            if this.grid.is_none()
                && let Some(g) = m.grid()
            {
                this.grid = Some((0, g.map_err(|e| side("grid", e))?));
                from_sidecar = true;
            }
        }
        let Some((gline, g)) = this.grid else {
            return match this.recognise() {
                Some((g, idx)) => this.place(g, idx.as_deref(), path),
                None => Ok(Content::Samples(this.to_samples())),
            };
        };
        let (n, rows) = (g.len(), this.rows());
        if rows != n {
            let msg = |what: &str| format!("the grid has {n} nodes, the {what} {rows} rows");
            return Err(if from_sidecar {
                side("grid", msg("CSV"))
            } else {
                FileError::at_line(KIND, path, gline, Some("grid"), msg("file"))
            });
        }
        let idx = this.nodes_on(&g, path)?;
        this.place(g, idx.as_deref(), path)
    }

    /// The node of each row on a given grid, in parallel over fixed runs of rows;
    /// none when every row is at its own index (the rows in the grid's order: no
    /// index is formed then). The first row (in file order) off the grid is an error.
    fn nodes_on(&self, g: &Grid, path: Option<&Path>) -> Result<Option<Vec<u32>>, FileError> {
        let [ti, pi, to, po] = &self.angles;
        let rows = self.rows();
        // Rows `start..end`'s nodes, each given to `put`; the first off the grid
        // ends the run.
        let run = |start: usize, end: usize, put: &mut dyn FnMut(usize, u32)| {
            let mut cache = [(f64::NAN, 0usize); 4];
            for r in start..end {
                let (a, c) = if g.isotropic {
                    (0.0, po[r] - pi[r])
                } else {
                    (pi[r], po[r])
                };
                let mut node = |slot: usize, ax: &Axis, x: f64, name: &'static str| {
                    let (lx, li) = &mut cache[slot];
                    if *lx == x {
                        return Ok(*li);
                    }
                    let i = ax.node_at(x.to_radians()).ok_or((r, name, x))?;
                    (*lx, *li) = (x, i);
                    Ok(i)
                };
                let i = g.index(
                    node(0, &g.phi_i, a, "phi_i")?,
                    node(1, &g.theta_i, ti[r], "theta_i")?,
                    node(2, &g.phi_o, c, "phi_o")?,
                    node(3, &g.theta_o, to[r], "theta_o")?,
                );
                put(r, i as u32);
            }
            Ok::<(), OffGrid>(())
        };
        // First whether every row is on the grid, and at its own index.
        let runs: Vec<Result<bool, OffGrid>> = (0..rows.div_ceil(ROW_CHUNK))
            .into_par_iter()
            .map(|b| {
                let mut in_order = true;
                let start = b * ROW_CHUNK;
                run(start, (start + ROW_CHUNK).min(rows), &mut |r, i| {
                    in_order &= i as usize == r;
                })?;
                Ok(in_order)
            })
            .collect();
        let mut in_order = true;
        for x in runs {
            match x {
                Ok(o) => in_order &= o,
                Err((r, name, x)) => {
                    return Err(FileError::at_line(
                        KIND,
                        path,
                        self.line_of(r),
                        Some(name),
                        format!("{x} is not a node of the grid"),
                    ));
                }
            }
        }
        if in_order {
            return Ok(None);
        }
        // Each fixed run of rows writes its nodes in place, on rayon (every row is
        // on the grid: the pass above found none off it).
        let mut idx = vec![0u32; rows];
        idx.par_chunks_mut(ROW_CHUNK)
            .enumerate()
            .for_each(|(b, out)| {
                let start = b * ROW_CHUNK;
                let _ = run(start, start + out.len(), &mut |r, i| out[r - start] = i);
            });
        Ok(Some(idx))
    }

    /// The table of rows placed at their nodes `idx` (each node once, else an error
    /// at the repeat's line; none: each row at its own index).
    fn place(
        self,
        g: Grid,
        idx: Option<&[u32]>,
        path: Option<&Path>,
    ) -> Result<Content, FileError> {
        let n = g.len();
        let in_order = idx.is_none();
        if let Some(idx) = idx {
            let mut seen = vec![false; n];
            for (r, i) in idx.iter().enumerate() {
                if std::mem::replace(&mut seen[*i as usize], true) {
                    return Err(FileError::at_line(
                        KIND,
                        path,
                        self.line_of(r),
                        None,
                        "this node was already given",
                    ));
                }
            }
        }
        let gather = |cols: Vec<Vec<f64>>| -> Vec<f64> {
            if in_order && cols.len() == 1 {
                // One channel in grid order: the column is the table's array.
                return cols.into_iter().next().unwrap_or_default();
            }
            // Zeroed by the allocator (fresh pages, touched first by the copies, on
            // rayon); each column freed once copied, so that at most one column is
            // held twice.
            let mut out = vec![0.0; n * cols.len()];
            for (c, dst) in cols.into_iter().zip(out.chunks_mut(n.max(1))) {
                if in_order {
                    dst.par_chunks_mut(ROW_CHUNK)
                        .zip(c.par_chunks(ROW_CHUNK))
                        .for_each(|(d, s)| d.copy_from_slice(s));
                } else if let Some(idx) = idx {
                    for (r, i) in idx.iter().enumerate() {
                        dst[*i as usize] = c[r];
                    }
                }
            }
            out
        };
        let Columns {
            roles,
            values,
            sigma,
            angles,
            ..
        } = self;
        // The angles are the grid's now. A single column in grid order is the table
        // as it is: the angles are freed on rayon beside what follows. Else they are
        // freed, side by side, before the table is gathered (each free unmaps a
        // column's pages).
        if in_order && values.len() == 1 && sigma.is_none() {
            rayon::spawn(move || drop(angles));
        } else {
            angles.into_par_iter().for_each(drop);
        }
        let values = gather(values);
        let sigma = sigma.map(gather);
        Table::new(roles.channels, g, values, sigma)
            .map(Content::Table)
            .map_err(|e| FileError::whole(KIND, path, e.to_string()))
    }

    /// The grid the rows form without a given one, and each row's node (none when
    /// every row is at its own index), when their angles make a complete uniform
    /// grid with each node once: the grid `Samples::to_table` recognises. None
    /// otherwise (repeats, gaps, uneven steps).
    fn recognise(&self) -> Option<(Grid, Option<Vec<u32>>)> {
        let rows = self.rows();
        let iso = self.isotropic;
        if self
            .values
            .iter()
            .chain(self.sigma.iter().flatten())
            .any(|c| c.len() != rows)
        {
            return None;
        }
        // Axis a's key of a row (φi, θi, φo, θo as `Samples::to_table` makes them)
        // is a function of one or two of its angles, `inputs(r, a)`.
        let inputs = |r: usize, a: usize| -> (f64, f64) {
            let at = |k: usize| self.angles[k][r];
            match (a, iso) {
                (0, true) => (0.0, 0.0),
                (0, false) => (at(1), 0.0),
                (1, _) => (at(0), 0.0),
                (2, true) => (at(3), at(1)),
                (2, false) => (at(3), 0.0),
                _ => (at(2), 0.0),
            }
        };
        let key_of = |a: usize, (x, y): (f64, f64)| -> i64 {
            match (a, iso) {
                (0, true) => 0,
                (0, false) | (2, false) => wrap(x),
                (2, true) => wrap(x - y),
                _ => q(x),
            }
        };
        let starts: Vec<usize> = (0..rows).step_by(ROW_CHUNK).collect();
        let sets: Vec<[std::collections::BTreeSet<i64>; 4]> = starts
            .par_iter()
            .map(|&s| {
                let mut sets: [std::collections::BTreeSet<i64>; 4] = Default::default();
                // The angles met in this run: a key is formed and kept once for each.
                let mut memo: [Memo<()>; 4] = Default::default();
                for r in s..(s + ROW_CHUNK).min(rows) {
                    for (a, set) in sets.iter_mut().enumerate() {
                        let xy = inputs(r, a);
                        memo[a].get_or(xy, || {
                            set.insert(key_of(a, xy));
                        });
                    }
                }
                sets
            })
            .collect();
        let mut all: [std::collections::BTreeSet<i64>; 4] = Default::default();
        for s in sets {
            for (a, b) in all.iter_mut().zip(s) {
                a.extend(b);
            }
        }
        let keys: [Vec<i64>; 4] = all.map(|s| s.into_iter().collect());
        let axes: Vec<Axis> = keys
            .iter()
            .map(|k| crate::samples::axis_of_keys(k))
            .collect::<Option<_>>()?;
        let grid = Grid {
            phi_i: axes[0],
            theta_i: axes[1],
            phi_o: axes[2],
            theta_o: axes[3],
            isotropic: iso,
        };
        grid.validate().ok()?;
        if grid.len() != rows {
            return None;
        }
        // Row r's node, each axis's node index kept for the angles met.
        let node = |memo: &mut [Memo<usize>; 4], r: usize| {
            let mut at = |a: usize| {
                let xy = inputs(r, a);
                memo[a].get_or(xy, || keys[a].binary_search(&key_of(a, xy)).unwrap_or(0))
            };
            grid.index(at(0), at(1), at(2), at(3))
        };
        // Rows in the grid's order are each node once, with no index to form.
        if (0..rows)
            .into_par_iter()
            .with_min_len(ROW_CHUNK)
            .map_init(<[Memo<usize>; 4]>::default, |m, r| node(m, r) == r)
            .all(|x| x)
        {
            return Some((grid, None));
        }
        // Each row's node, written in place on rayon.
        let mut idx = vec![0u32; rows];
        idx.par_chunks_mut(ROW_CHUNK)
            .enumerate()
            .for_each(|(b, out)| {
                let mut memo = Default::default();
                for (o, r) in out.iter_mut().zip(b * ROW_CHUNK..) {
                    *o = node(&mut memo, r) as u32;
                }
            });
        // Each node once: whether any is repeated does not depend on the order the
        // rows are marked in, so they are marked on rayon, a bit a node.
        use std::sync::atomic::{AtomicU64, Ordering};
        let seen: Vec<AtomicU64> = (0..rows.div_ceil(64)).map(|_| AtomicU64::new(0)).collect();
        let repeat = idx.par_iter().any(|&i| {
            let bit = 1u64 << (i % 64);
            seen[i as usize / 64].fetch_or(bit, Ordering::Relaxed) & bit != 0
        });
        (!repeat).then_some((grid, Some(idx)))
    }
}
