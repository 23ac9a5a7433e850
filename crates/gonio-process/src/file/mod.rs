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

use std::path::{Path, PathBuf};

use gonio_core::Channels;

use crate::{Samples, Table};

mod parallel;
mod read;
mod sidecar;
mod write;

pub use parallel::{
    BLOCK, CHUNK, Columns, Roles, header_roles, is_columns_header, read_columns, read_columns_in,
};
pub(crate) use read::parse_header;
pub use read::{EXPECTED_COLUMNS, MAX_ROWS, read, read_from};
pub use sidecar::{AxisMeta, GridMeta, Meta};
pub use write::{grid_line, write_samples, write_table, write_table_self_contained};

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

/// Degrees of a node angle, as [`crate::Axis::node_deg`] prints them.
pub(crate) fn deg(x: f64) -> f64 {
    crate::grid::clean_deg(x.to_degrees())
}

#[cfg(test)]
mod tests {
    use super::read::parse_grid;
    use super::*;
    use crate::{Axis, Grid, Sample};
    use gonio_core::SphericalDeg;
    use gonio_core::dirfile::{HEADER, PairDeg};
    use gonio_core::tomlfile::FileError;

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
        let at = |line: usize, field: Option<&str>, msg: String| {
            FileError::at_line(KIND, path, line, field, msg)
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
