//! The directions file of `docs/CONVENTIONS.md`: CSV with the header
//! `theta_i,phi_i,theta_o,phi_o` or `theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg`
//! (degrees), one pair of directions a row; and the evaluation result, which repeats
//! those columns with their unit (`theta_i_deg`, …) and adds one column a channel in
//! 1/sr (`f_r_550nm_per_sr`, the sample file's names): pandas reads it with no
//! arguments, and it reads back as directions or as samples.

use std::fmt::Write as _;

use crate::{Channels, Dir, DirPair, SphericalDeg};

/// The four columns a directions file starts with (or [`HEADER_DEG`]'s).
pub const HEADER: [&str; 4] = ["theta_i", "phi_i", "theta_o", "phi_o"];

/// The same columns with their unit: what Gonio writes, and what a directions file
/// may also start with.
pub const HEADER_DEG: [&str; 4] = ["theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg"];

/// The column of a channel's BRDF values in files Gonio writes: `f_r_per_sr` for
/// the single channel `value`, else `f_r_<channel>_per_sr` (1/sr).
pub fn value_column(channel: &str) -> String {
    if channel == "value" {
        "f_r_per_sr".into()
    } else {
        format!("f_r_{channel}_per_sr")
    }
}

/// A row of a directions file: two directions in degrees, as written.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairDeg {
    /// Incident direction (towards the source).
    pub incident: SphericalDeg,
    /// Outgoing direction (towards the detector).
    pub outgoing: SphericalDeg,
}

impl PairDeg {
    /// The directions as unit vectors.
    pub fn to_dirs(&self) -> DirPair {
        DirPair::new(Dir::from(self.incident), Dir::from(self.outgoing))
    }
}

/// A directions file that could not be read: the line (1-based) and column at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("line {line}{}: {message}", column.as_ref().map(|c| format!(", field {c}")).unwrap_or_default())]
pub struct DirFileError {
    /// 1-based line number.
    pub line: usize,
    /// The column name, where one is at fault.
    pub column: Option<String>,
    /// What is wrong.
    pub message: String,
}

fn err(line: usize, column: Option<&str>, message: impl Into<String>) -> DirFileError {
    DirFileError {
        line,
        column: column.map(str::to_string),
        message: message.into(),
    }
}

/// The most bytes a directions file may have: 256 MiB, about four million pairs,
/// four times what a plan may measure (`gonio_plan::MAX_POINTS`).
pub const MAX_BYTES: u64 = 256 << 20;

/// Parses a directions file. Blank lines and lines starting with `#` are skipped;
/// columns after the first four are ignored (so an evaluation result reads back).
/// θ must lie in [0, 90]; φ may be any finite angle. A leading byte order mark is
/// ignored.
pub fn read_pairs(text: &str) -> Result<Vec<PairDeg>, DirFileError> {
    let mut lines = crate::text::strip_bom(text)
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let Some((hline, header)) = lines.next() else {
        return Err(err(
            1,
            None,
            "empty file: expected the header theta_i,phi_i,theta_o,phi_o (or with _deg)",
        ));
    };
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    let named = |k: usize| {
        cols.get(k)
            .is_some_and(|c| *c == HEADER[k] || *c == HEADER_DEG[k])
    };
    if !(0..4).all(named) {
        return Err(err(
            hline,
            None,
            format!(
                "header must start with theta_i,phi_i,theta_o,phi_o (or \
                 theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg); got {header:?}"
            ),
        ));
    }
    let mut out = Vec::new();
    for (n, line) in lines {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() < 4 {
            return Err(err(
                n,
                None,
                format!("expected 4 values, found {}", fields.len()),
            ));
        }
        let mut v = [0.0; 4];
        for k in 0..4 {
            let x: f64 = fields[k]
                .parse()
                .map_err(|_| err(n, Some(cols[k]), format!("{:?} is not a number", fields[k])))?;
            if !x.is_finite() {
                return Err(err(n, Some(cols[k]), "must be finite"));
            }
            if k % 2 == 0 && !(0.0..=90.0).contains(&x) {
                return Err(err(
                    n,
                    Some(cols[k]),
                    format!("{x} is outside [0, 90] degrees"),
                ));
            }
            v[k] = x;
        }
        out.push(PairDeg {
            incident: SphericalDeg::new(v[0], v[1]),
            outgoing: SphericalDeg::new(v[2], v[3]),
        });
    }
    Ok(out)
}

/// The header line of an evaluation result: the four direction columns in degrees
/// and one column a channel in 1/sr ([`value_column`]: `f_r_R_per_sr`,
/// `f_r_550nm_per_sr`, or `f_r_per_sr`).
pub fn eval_header(channels: &Channels) -> String {
    let mut h = HEADER_DEG.join(",");
    for n in channels.names() {
        h.push(',');
        h.push_str(&value_column(&n));
    }
    h
}

/// One row of an evaluation result. Numbers are written in the shortest form that
/// reads back to the same `f64`.
pub fn eval_row(pair: &PairDeg, values: &[f64]) -> String {
    let mut s = String::new();
    let _ = write!(
        s,
        "{},{},{},{}",
        pair.incident.theta_deg,
        pair.incident.phi_deg,
        pair.outgoing.theta_deg,
        pair.outgoing.phi_deg
    );
    for v in values {
        let _ = write!(s, ",{v}");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_pairs_and_skips_comments() {
        let t = "# measured grid\ntheta_i,phi_i,theta_o,phi_o\n0,0,30,180\n\n45, 90 ,60,270\n";
        let p = read_pairs(t).expect("valid");
        assert_eq!(p.len(), 2);
        assert_eq!(p[1].incident, SphericalDeg::new(45.0, 90.0));
        assert_eq!(p[1].outgoing, SphericalDeg::new(60.0, 270.0));
    }

    #[test]
    fn errors_name_line_and_column() {
        let e = read_pairs("theta_i,phi_i,theta_o,phi_o\n0,0,30,0\n0,0,x,0\n").unwrap_err();
        assert_eq!(e.line, 3);
        assert_eq!(e.column.as_deref(), Some("theta_o"));
        assert_eq!(
            e.to_string(),
            "line 3, field theta_o: \"x\" is not a number"
        );
        let e = read_pairs("theta_i,phi_i,theta_o,phi_o\n95,0,30,0\n").unwrap_err();
        assert_eq!(e.column.as_deref(), Some("theta_i"));
        let e = read_pairs("ti,pi,to,po\n").unwrap_err();
        assert_eq!(e.line, 1);
        assert_eq!(
            e.to_string(),
            "line 1: header must start with theta_i,phi_i,theta_o,phi_o (or \
             theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg); got \"ti,pi,to,po\""
        );
        let e = read_pairs("theta_i,phi_i,theta_o,phi_o\n1,2,3\n").unwrap_err();
        assert!(e.message.contains("expected 4 values"));
        assert!(read_pairs("").is_err());
    }

    #[test]
    fn a_byte_order_mark_is_not_part_of_the_header() {
        let p = read_pairs("\u{feff}theta_i,phi_i,theta_o,phi_o\n10,0,20,180\n").expect("BOM");
        assert_eq!(p[0].incident, SphericalDeg::new(10.0, 0.0));
        assert_eq!(p[0].outgoing, SphericalDeg::new(20.0, 180.0));
    }

    #[test]
    fn eval_rows_read_back() {
        let p = PairDeg {
            incident: SphericalDeg::new(10.5, 0.0),
            outgoing: SphericalDeg::new(20.0, 180.0),
        };
        let text = format!(
            "{}\n{}\n",
            eval_header(&Channels::Rgb),
            eval_row(&p, &[0.1, 0.2, 1.0 / 3.0])
        );
        assert!(text.starts_with(
            "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,f_r_R_per_sr,f_r_G_per_sr,f_r_B_per_sr\n\
             10.5,0,20,180,0.1,0.2,0.3333333333333333\n"
        ));
        assert_eq!(read_pairs(&text).expect("reads back")[0], p);
    }

    #[test]
    fn units_in_the_header_read_and_name_the_field() {
        let t = "theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg\n10,0,20,180\n0,0,x,0\n";
        let e = read_pairs(t).unwrap_err();
        assert_eq!(
            e.to_string(),
            "line 3, field theta_o_deg: \"x\" is not a number"
        );
        let p = read_pairs("theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg\n10,0,20,180\n");
        assert_eq!(
            p.expect("valid")[0].outgoing,
            SphericalDeg::new(20.0, 180.0)
        );
        assert_eq!(value_column("value"), "f_r_per_sr");
        assert_eq!(value_column("550nm"), "f_r_550nm_per_sr");
    }
}
