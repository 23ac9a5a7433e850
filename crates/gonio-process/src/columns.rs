//! Tables and samples as named columns of numbers: what a table or sample file
//! holds (`file`), without the text. The Python package hands these to numpy and
//! pandas, and takes samples back from them, so a DataFrame has exactly the columns,
//! units and values of the CSV the command line writes.

use std::path::Path;

use gonio_core::SphericalDeg;
use gonio_core::dirfile::PairDeg;
use gonio_core::tomlfile::FileError;

use crate::file::{self, KIND};
use crate::{Sample, Samples, Table};

/// One column's numbers.
#[derive(Clone, Debug, PartialEq)]
pub enum Column {
    /// Angles (degrees), values and uncertainties (1/sr).
    F64(Vec<f64>),
    /// Reading flags (`gonio_run::flags` bits).
    U32(Vec<u32>),
}

impl Column {
    /// Number of rows.
    pub fn len(&self) -> usize {
        match self {
            Column::F64(v) => v.len(),
            Column::U32(v) => v.len(),
        }
    }

    /// Whether it has no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A table's columns, named and ordered as [`file::write_table`] writes them: one row
/// a node in grid order.
pub fn of_table(t: &Table) -> Vec<(String, Column)> {
    let n = t.grid.len();
    let names = file::columns(&t.channels, t.sigma.is_some(), false);
    let mut angles = [(); 4].map(|_| Vec::with_capacity(n));
    for i in 0..n {
        let [pi, ti, po, to] = t.grid.angles(i);
        for (col, x) in angles.iter_mut().zip([ti, pi, to, po]) {
            col.push(file::deg(x));
        }
    }
    let mut cols: Vec<Column> = angles.into_iter().map(Column::F64).collect();
    let nc = t.channels.len();
    cols.extend((0..nc).map(|ch| Column::F64(t.values[ch * n..(ch + 1) * n].to_vec())));
    if let Some(s) = &t.sigma {
        cols.extend((0..nc).map(|ch| Column::F64(s[ch * n..(ch + 1) * n].to_vec())));
    }
    names.into_iter().zip(cols).collect()
}

/// Samples' columns, named and ordered as [`file::write_samples`] writes them: one
/// row a sample; the uncertainties when every sample has them, the flags when any is
/// flagged.
pub fn of_samples(s: &Samples) -> Vec<(String, Column)> {
    let (sigma, flags) = file::sample_columns(s);
    let names = file::columns(&s.channels, sigma, flags);
    let n = s.samples.len();
    let nc = s.channels.len();
    let mut cols: Vec<Vec<f64>> = (0..4 + nc * (1 + usize::from(sigma)))
        .map(|_| Vec::with_capacity(n))
        .collect();
    for x in &s.samples {
        let p = &x.pair;
        let angles = [
            p.incident.theta_deg,
            p.incident.phi_deg,
            p.outgoing.theta_deg,
            p.outgoing.phi_deg,
        ];
        for (c, v) in cols.iter_mut().zip(angles) {
            c.push(v);
        }
        for (c, v) in cols[4..].iter_mut().zip(&x.value) {
            c.push(*v);
        }
        if sigma && let Some(sg) = &x.sigma {
            for (c, v) in cols[4 + nc..].iter_mut().zip(sg) {
                c.push(*v);
            }
        }
    }
    let mut out: Vec<Column> = cols.into_iter().map(Column::F64).collect();
    if flags {
        out.push(Column::U32(s.samples.iter().map(|x| x.flags).collect()));
    }
    names.into_iter().zip(out).collect()
}

/// Samples from named columns of numbers (a DataFrame's), read as the header and rows
/// of a sample file would be: the same column names (either format), the same checks.
/// `label` names the data in errors, which name the column or the row (1-based).
pub fn to_samples(
    columns: &[(String, Vec<f64>)],
    isotropic: bool,
    label: &Path,
) -> Result<Samples, FileError> {
    let whole = |msg: String| FileError::whole(KIND, Some(label), msg);
    let head: Vec<&str> = columns.iter().map(|(n, _)| n.as_str()).collect();
    let header = file::parse_header(&head.join(",")).map_err(whole)?;
    let n = columns.first().map_or(0, |(_, c)| c.len());
    if let Some((name, c)) = columns.iter().find(|(_, c)| c.len() != n) {
        return Err(whole(format!(
            "column {name:?} has {} rows, the first column {n}",
            c.len()
        )));
    }
    if n > file::MAX_ROWS {
        return Err(whole(format!(
            "{n} rows: at most {} are read",
            file::MAX_ROWS
        )));
    }
    let nc = header.channels.len();
    let col = |j: usize| columns[j].1.as_slice();
    let mut samples = Vec::with_capacity(n);
    for row in 0..n {
        let at = |j: usize, msg: String| FileError {
            line: Some(row + 1),
            field: Some(columns[j].0.clone()),
            ..whole(msg)
        };
        for j in 0..columns.len() {
            if !col(j)[row].is_finite() {
                return Err(at(j, format!("{} is not a finite number", col(j)[row])));
            }
        }
        let flags = if header.flags {
            let j = columns.len() - 1;
            let f = col(j)[row];
            if !(f >= 0.0 && f <= f64::from(u32::MAX) && f.fract() == 0.0) {
                return Err(at(j, format!("{f} is not a flags word (0 to 2^32 − 1)")));
            }
            f as u32
        } else {
            0
        };
        samples.push(Sample {
            pair: PairDeg {
                incident: SphericalDeg::new(col(0)[row], col(1)[row]),
                outgoing: SphericalDeg::new(col(2)[row], col(3)[row]),
            },
            value: (0..nc).map(|c| col(4 + c)[row]).collect(),
            sigma: header
                .sigma
                .then(|| (0..nc).map(|c| col(4 + nc + c)[row]).collect()),
            flags,
        });
    }
    let s = Samples {
        channels: header.channels,
        samples,
        isotropic,
    };
    s.validate().map_err(|e| whole(e.to_string()))?;
    Ok(s)
}
