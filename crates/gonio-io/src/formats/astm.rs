//! ASTM E1392-style BRDF text, the form of the Cornell gonioreflectometer
//! measurements: a header of keyword lines, then one row a sample.
//!
//! # What Gonio writes
//! ```text
//! # ASTM E1392-style BRDF written by Gonio
//! # angles in degrees (theta from the normal, phi from +x towards +y), BRDF in 1/sr
//! # isotropic: true
//! NUM_POINTS 2
//! VARS theta_i,phi_i,theta_s,phi_s,R,G,B
//! 30,0,30,180,0.1234,0.2,0.30000000000000004
//! 30,0,45,180,0.05,0.06,0.07
//! ```
//! The `# isotropic: true` line appears only for isotropic samples. Angles are in
//! degrees (as the Cornell files and every Gonio file): `theta_i, phi_i` the incident
//! direction (towards the source), `theta_s, phi_s` the scattered one (towards the
//! detector, Gonio's `theta_o, phi_o`). Then one column a channel, named as Gonio
//! names channels (`R,G,B`, `value`, or wavelengths `550nm`). Numbers are written in
//! the shortest form that reads back to the same `f64` (exponent form below 1e-5 and
//! from 1e16), so write → read is lossless. Uncertainties and flags are not part of
//! the format and are not written.
//!
//! # What Gonio reads
//! - Before `VARS`: blank lines; `#` comment lines (`# isotropic: true` sets the
//!   samples' isotropic flag, other comments are ignored); `NUM_POINTS n` (required,
//!   once, a whole number ≤ [`MAX_POINTS`]); any other keyword line (a line starting
//!   with a letter and without commas, e.g. `FORMAT ...`, `SOURCE ...`), ignored.
//! - `VARS` names the columns, separated by commas or whitespace: first
//!   `theta_i phi_i theta_s phi_s` (`theta_o phi_o` accepted for the last two; names
//!   compared without regard to case), then at least one channel: `R G B`, `value`,
//!   wavelengths like `550nm`, or bare numbers (`550`, read as nm). It ends the header.
//! - After `VARS`: one row a sample, its fields separated by commas (spaces around
//!   them allowed) or by whitespace; blank and `#` lines skipped. Every row has one
//!   field a column; every field is a finite number; θ lies in [0, 90].
//! - The number of rows must equal `NUM_POINTS`: more rows is an error at the first
//!   extra row, fewer an error at the `NUM_POINTS` line. No data rows at all is an
//!   error too.
//!
//! Errors name the file, the line and the field (the column's `VARS` name).
//!
//! # Spectral data
//! Several wavelengths are written as a column each, `VARS
//! theta_i,phi_i,theta_s,phi_s,450nm,550nm,650nm`, one row a pair: the layout
//! libbsdf's ASTM reader expects (KimuraRyo/libbsdf, `src/Reader/AstmReader.cpp`: a
//! `VARS` name ending in `nm` is that wavelength). **UNCONFIRMED:** what ASTM E1392
//! itself prescribes for several wavelengths, and whether the Cornell text files put
//! a wavelength in each record instead; a `wavelength` column in `VARS` is not read.

use std::fmt::Write as _;
use std::path::Path;

use gonio_core::dirfile::PairDeg;
use gonio_core::{Channels, SphericalDeg};
use gonio_process::{Sample, Samples};

use super::{Format, FormatError};

/// The most rows `NUM_POINTS` may announce: 50 million, as many as a Gonio CSV may
/// have (`gonio_process::file::MAX_ROWS`), about 3 GB of text. Beyond it a header is
/// refused before any row is read.
pub const MAX_POINTS: usize = 50_000_000;

/// The angle columns Gonio writes.
pub const ANGLES: [&str; 4] = ["theta_i", "phi_i", "theta_s", "phi_s"];

/// The first token of a line: up to the first whitespace or comma.
pub(crate) fn first_token(line: &str) -> &str {
    line.split(|c: char| c.is_whitespace() || c == ',')
        .next()
        .unwrap_or("")
}

/// Whether a token is one of the two keywords that identify the format.
pub(crate) fn is_astm_keyword(token: &str) -> bool {
    token.eq_ignore_ascii_case("NUM_POINTS") || token.eq_ignore_ascii_case("VARS")
}

/// The line after its first token (and the separator after it).
fn rest_after_keyword(line: &str) -> &str {
    let k = first_token(line).len();
    line[k..]
        .trim_start()
        .strip_prefix(',')
        .unwrap_or(line[k..].trim_start())
        .trim()
}

/// The fields of a row or of the `VARS` list: comma-separated when there is a comma,
/// else whitespace-separated.
fn fields(s: &str) -> Vec<&str> {
    if s.contains(',') {
        s.split(',').map(str::trim).collect()
    } else {
        s.split_whitespace().collect()
    }
}

/// A number in the shortest form that reads back to the same `f64`.
fn num(out: &mut String, x: f64) {
    let a = x.abs();
    if a == 0.0 || (1e-5..1e16).contains(&a) {
        let _ = write!(out, "{x}");
    } else {
        let _ = write!(out, "{x:e}");
    }
}

/// Writes samples as ASTM E1392-style text (module docs for the exact form).
pub fn write_astm(s: &Samples) -> String {
    let mut out = String::from(
        "# ASTM E1392-style BRDF written by Gonio\n\
         # angles in degrees (theta from the normal, phi from +x towards +y), BRDF in 1/sr\n",
    );
    if s.isotropic {
        out.push_str("# isotropic: true\n");
    }
    let _ = writeln!(out, "NUM_POINTS {}", s.samples.len());
    out.push_str("VARS ");
    out.push_str(&ANGLES.join(","));
    for n in s.channels.names() {
        out.push(',');
        out.push_str(&n);
    }
    out.push('\n');
    for x in &s.samples {
        let p = &x.pair;
        for (k, a) in [
            p.incident.theta_deg,
            p.incident.phi_deg,
            p.outgoing.theta_deg,
            p.outgoing.phi_deg,
        ]
        .into_iter()
        .enumerate()
        {
            if k > 0 {
                out.push(',');
            }
            num(&mut out, a);
        }
        for v in &x.value {
            out.push(',');
            num(&mut out, *v);
        }
        out.push('\n');
    }
    out
}

/// The channels a `VARS` list names after the angles.
fn channels_of(names: &[&str]) -> Result<Channels, String> {
    let mapped: Vec<String> = names
        .iter()
        .map(|n| match n.parse::<f64>() {
            Ok(w) => format!("{w}nm"),
            Err(_) => n.to_string(),
        })
        .collect();
    Channels::from_names(&mapped).map_err(|e| e.to_string())
}

/// Reads ASTM E1392-style text into samples (module docs for what is accepted).
/// `path` only labels errors; a leading byte order mark is ignored.
pub fn read_astm(text: &str, path: Option<&Path>) -> Result<Samples, FormatError> {
    let text = gonio_core::text::strip_bom(text);
    let at = |line: usize, field: Option<&str>, msg: String| {
        FormatError::at_line(Format::Astm, path, line, field, msg)
    };
    let mut lines = text.split('\n').enumerate().map(|(i, l)| (i + 1, l.trim()));
    let Header {
        isotropic,
        num_points,
        vline,
        names,
    } = header(&mut lines, &at, path)?;
    let Some((nline, n)) = num_points else {
        return Err(at(
            vline,
            Some("NUM_POINTS"),
            "no NUM_POINTS line before VARS".into(),
        ));
    };
    let channels = columns(&names, vline, &at)?;
    let nc = channels.len();
    let width = 4 + nc;
    // Each row takes at least 2·width bytes (a digit and a separator a field).
    let mut samples = Vec::with_capacity(n.min(text.len() / (2 * width) + 1));
    for (ln, l) in lines {
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        if samples.len() == n {
            return Err(at(
                ln,
                None,
                format!("more rows than NUM_POINTS (line {nline}) announces: {n}"),
            ));
        }
        let key = first_token(l);
        if is_astm_keyword(key) {
            return Err(at(
                ln,
                Some(key),
                "a header keyword among the data: NUM_POINTS and VARS come once, \
                 NUM_POINTS first, before the rows"
                    .into(),
            ));
        }
        let f = fields(l);
        if f.len() != width {
            return Err(at(
                ln,
                None,
                format!("{} fields, VARS names {width} columns", f.len()),
            ));
        }
        samples.push(row(ln, &f, &names, nc, &at)?);
    }
    if samples.len() < n {
        return Err(at(
            nline,
            Some("NUM_POINTS"),
            format!(
                "NUM_POINTS announces {n} rows, the file has {} (truncated?)",
                samples.len()
            ),
        ));
    }
    if samples.is_empty() {
        return Err(at(nline, Some("NUM_POINTS"), "no data rows".into()));
    }
    Ok(Samples {
        channels,
        samples,
        isotropic,
    })
}

/// What the header says, up to and including its `VARS` line.
struct Header<'a> {
    isotropic: bool,
    /// The `NUM_POINTS` line and its count, when there is one.
    num_points: Option<(usize, usize)>,
    /// The `VARS` line and the columns it names.
    vline: usize,
    names: Vec<&'a str>,
}

/// Reads the header up to and including `VARS`: the `# isotropic:` comment,
/// `NUM_POINTS` (once, within [`MAX_POINTS`]) and other keywords, refusing data
/// before `VARS`.
fn header<'a>(
    lines: &mut impl Iterator<Item = (usize, &'a str)>,
    at: &impl Fn(usize, Option<&str>, String) -> FormatError,
    path: Option<&Path>,
) -> Result<Header<'a>, FormatError> {
    let mut isotropic = false;
    let mut num_points: Option<(usize, usize)> = None;
    // The header, up to and including VARS.
    let (vline, names) = loop {
        let Some((ln, l)) = lines.next() else {
            return Err(FormatError::whole(
                Some(Format::Astm),
                path,
                "no VARS line: the header must name the columns",
            ));
        };
        if l.is_empty() {
            continue;
        }
        if let Some(c) = l.strip_prefix('#') {
            if let Some((k, v)) = c.split_once(':')
                && k.trim().eq_ignore_ascii_case("isotropic")
            {
                isotropic = match v.trim() {
                    "true" => true,
                    "false" => false,
                    x => {
                        return Err(at(
                            ln,
                            Some("isotropic"),
                            format!("must be true or false, found {x:?}"),
                        ));
                    }
                };
            }
            continue;
        }
        let key = first_token(l);
        if key.eq_ignore_ascii_case("NUM_POINTS") {
            if num_points.is_some() {
                return Err(at(ln, Some("NUM_POINTS"), "given twice".into()));
            }
            let v = rest_after_keyword(l);
            let n: usize = v
                .parse()
                .map_err(|_| at(ln, Some("NUM_POINTS"), format!("not a whole number: {v:?}")))?;
            if n > MAX_POINTS {
                return Err(at(
                    ln,
                    Some("NUM_POINTS"),
                    format!("{n} points, more than the {MAX_POINTS} a file may have"),
                ));
            }
            num_points = Some((ln, n));
            continue;
        }
        if key.eq_ignore_ascii_case("VARS") {
            break (ln, fields(rest_after_keyword(l)));
        }
        if key.starts_with(|c: char| c.is_ascii_alphabetic()) && !l.contains(',') {
            continue;
        }
        return Err(at(
            ln,
            None,
            format!(
                "expected a header line (NUM_POINTS, VARS, another keyword or a # \
                 comment) before the data, found {:?}",
                clip(l)
            ),
        ));
    };
    Ok(Header {
        isotropic,
        num_points,
        vline,
        names,
    })
}

/// The channels of the columns `VARS` names (on line `vline`): the four angles
/// first, in order, then at least one channel.
fn columns(
    names: &[&str],
    vline: usize,
    at: &impl Fn(usize, Option<&str>, String) -> FormatError,
) -> Result<Channels, FormatError> {
    if names.len() < 5 {
        return Err(at(
            vline,
            Some("VARS"),
            format!(
                "{} columns: expected theta_i phi_i theta_s phi_s and at least one channel",
                names.len()
            ),
        ));
    }
    let accepted: [&[&str]; 4] = [
        &["theta_i"],
        &["phi_i"],
        &["theta_s", "theta_o"],
        &["phi_s", "phi_o"],
    ];
    for (k, ok) in accepted.iter().enumerate() {
        if !ok.iter().any(|a| a.eq_ignore_ascii_case(names[k])) {
            return Err(at(
                vline,
                Some("VARS"),
                format!(
                    "column {} is {:?}, expected {}",
                    k + 1,
                    names[k],
                    ok.join(" or ")
                ),
            ));
        }
    }
    channels_of(&names[4..]).map_err(|e| {
        at(
            vline,
            Some("VARS"),
            format!("channels: {e} (bare numbers are wavelengths in nm)"),
        )
    })
}

/// One data row's sample from its fields (on line `ln`): each a finite number,
/// the θs within [0, 90] degrees.
fn row(
    ln: usize,
    f: &[&str],
    names: &[&str],
    nc: usize,
    at: &impl Fn(usize, Option<&str>, String) -> FormatError,
) -> Result<Sample, FormatError> {
    let mut x = [0.0; 4];
    let mut value = Vec::with_capacity(nc);
    for (k, s) in f.iter().enumerate() {
        let v = s
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| {
                at(
                    ln,
                    Some(names[k]),
                    format!("not a finite number: {:?}", clip(s)),
                )
            })?;
        if k < 4 {
            x[k] = v;
        } else {
            value.push(v);
        }
    }
    for k in [0, 2] {
        if !(0.0..=90.0).contains(&x[k]) {
            return Err(at(
                ln,
                Some(names[k]),
                format!("θ must lie in [0, 90] degrees, got {}", x[k]),
            ));
        }
    }
    Ok(Sample {
        pair: PairDeg {
            incident: SphericalDeg::new(x[0], x[1]),
            outgoing: SphericalDeg::new(x[2], x[3]),
        },
        value,
        sigma: None,
        flags: 0,
    })
}

/// At most 40 characters of a field or line, for messages.
fn clip(s: &str) -> String {
    match s.char_indices().nth(40) {
        Some((i, _)) => format!("{}…", &s[..i]),
        None => s.to_string(),
    }
}
