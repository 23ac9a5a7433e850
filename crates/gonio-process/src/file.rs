//! The sample and table file: CSV in the form of `docs/CONVENTIONS.md` (directions in
//! degrees, then one column a channel), then one `sigma_<channel>` column a channel
//! when uncertainties are known and a `flags` column when any sample has flags.
//! Leading `#` lines carry `key: value` metadata; a table has a `grid:` line, which
//! makes the rows its nodes (each exactly once, in any order):
//!
//! ```text
//! # gonio-table: 1
//! # grid: isotropic=false phi_i=0:30:12 theta_i=5:10:9 phi_o=0:30:12 theta_o=5:10:9
//! theta_i,phi_i,theta_o,phi_o,R,G,B,sigma_R,sigma_G,sigma_B
//! 5,0,5,0,0.123,0.1,0.2,0.001,0.001,0.002
//! ```
//!
//! Axes are `start:step:n` in degrees. Numbers are written in Rust's shortest
//! round-trip form, so write → read is lossless. `numpy.loadtxt(f, delimiter=",",
//! skiprows=…)` and `pandas.read_csv(f, comment="#")` read it as it is.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use gonio_core::dirfile::{HEADER, PairDeg};
use gonio_core::tomlfile::FileError;
use gonio_core::{Channels, SphericalDeg};

use crate::{Axis, Grid, Sample, Samples, Table};

const KIND: &str = "BRDF table";

/// What a table file holds.
#[derive(Clone, Debug, PartialEq)]
pub enum Content {
    /// Values on a grid.
    Table(Table),
    /// Scattered samples.
    Samples(Samples),
}

fn axis_text(a: &Axis) -> String {
    format!("{}:{}:{}", deg(a.start), deg(a.step), a.n)
}

fn grid_line(g: &Grid) -> String {
    format!(
        "isotropic={} phi_i={} theta_i={} phi_o={} theta_o={}",
        g.isotropic,
        axis_text(&g.phi_i),
        axis_text(&g.theta_i),
        axis_text(&g.phi_o),
        axis_text(&g.theta_o)
    )
}

fn header(channels: &Channels, sigma: bool, flags: bool) -> String {
    let mut h = HEADER.join(",");
    for n in channels.names() {
        h.push(',');
        h.push_str(&n);
    }
    if sigma {
        for n in channels.names() {
            let _ = write!(h, ",sigma_{n}");
        }
    }
    if flags {
        h.push_str(",flags");
    }
    h
}

/// Writes samples.
pub fn write_samples(s: &Samples) -> String {
    let sigma = s.samples.iter().all(|x| x.sigma.is_some()) && !s.samples.is_empty();
    let flags = s.samples.iter().any(|x| x.flags != 0);
    let mut out = String::from("# gonio-samples: 1\n");
    if s.isotropic {
        out.push_str("# isotropic: true\n");
    }
    out.push_str(&header(&s.channels, sigma, flags));
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

/// Writes a table, one row a node in grid order.
pub fn write_table(t: &Table) -> String {
    let mut out = format!("# gonio-table: 1\n# grid: {}\n", grid_line(&t.grid));
    out.push_str(&header(&t.channels, t.sigma.is_some(), false));
    out.push('\n');
    let n = t.grid.len();
    let nc = t.channels.len();
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
fn deg(x: f64) -> f64 {
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
pub const EXPECTED_COLUMNS: &str = "theta_i,phi_i,theta_o,phi_o, then one column a channel \
     (value; R,G,B; or wavelengths like 550nm), then optionally sigma_<channel> for each \
     channel and flags";

/// Reads a table or sample file. `path` only labels errors; a leading byte order mark
/// is ignored.
pub fn read(text: &str, path: Option<&Path>) -> Result<Content, FileError> {
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
        if n_sigma != nc || rest[nc..] != want.iter().map(String::as_str).collect::<Vec<_>>()[..] {
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
        let Content::Table(back) = read(&text, None).expect("read") else {
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
            "t.csv:2: expected the columns theta_i,phi_i,theta_o,phi_o, then one column a \
             channel (value; R,G,B; or wavelengths like 550nm), then optionally \
             sigma_<channel> for each channel and flags; found \"theta,phi,theta_o,phi_o,value\""
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
}
