//! The sidecar JSON beside a table or samples file (`TABLE.csv.json`): what the CSV's
//! header cannot say.

use std::path::Path;

use gonio_core::tomlfile::FileError;
use serde::{Deserialize, Serialize};

use super::{SIDECAR_KIND, VERSION, columns, deg, sample_columns};
use crate::{Axis, Grid, Samples, Table};

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
    /// Reduced samples' covariance, rows in the CSV's order: each sample's
    /// independent σ and its coefficient on every shared error
    /// ([`crate::covariance`]), so that a user can form the full χ²; none when
    /// nothing was said (a table, samples not from a reduction).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub covariance: Option<crate::covariance::Covariance>,
}

fn axis_meta(a: &Axis) -> AxisMeta {
    AxisMeta {
        start_deg: deg(a.start),
        step_deg: deg(a.step),
        n: a.n,
    }
}

impl Meta {
    /// The sidecar of [`write_table`](super::write_table)'s file.
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
            covariance: None,
        }
    }

    /// The sidecar of [`write_samples`](super::write_samples)' file.
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
            covariance: None,
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
    pub(super) fn grid(&self) -> Option<Result<Grid, String>> {
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
