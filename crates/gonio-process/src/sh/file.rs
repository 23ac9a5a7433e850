//! The TOML file of an [`ShBrdf`]: [`ShBrdf::to_toml`] and [`ShBrdf::from_toml`].

use std::fmt::Write as _;

use gonio_core::Channels;
use serde::Deserialize;

use super::{FILE_KIND, MAX_L_MAX, ShBrdf, basis, basis_len};

impl ShBrdf {
    /// The representation as a TOML file (see the module docs); floats are written
    /// in their shortest exact form, so [`from_toml`](ShBrdf::from_toml) gives back
    /// the same matrices bit for bit.
    pub fn to_toml(&self) -> String {
        let k = self.basis.len();
        let names = self.channels.names();
        let mut s = String::new();
        // Writing to a String cannot fail; the results are ignored for that reason.
        let _ = writeln!(
            s,
            "# f_r(wi, wo) = sum_jk M_jk Y_j(wi) Y_k(wo), M symmetric (Westin et al. 1992, Eq. 8-10)"
        );
        let _ = writeln!(
            s,
            "# basis: l = 0..=l_max, m = -l..=l with l + m even (DeYoung Eq. 3.4-3.6);"
        );
        let _ = writeln!(
            s,
            "# upper: the upper triangle of M, row j from column j, one row a line"
        );
        let _ = writeln!(s, "kind = {}", toml::Value::from(FILE_KIND));
        let chans = toml::Value::Array(
            names
                .iter()
                .map(|n| toml::Value::from(n.as_str()))
                .collect(),
        );
        let _ = writeln!(s, "channels = {chans}");
        let _ = writeln!(s, "l_max = {}", self.l_max);
        let _ = writeln!(s, "l_filter = {}", self.l_filter);
        for (name, m) in names.iter().zip(&self.matrices) {
            let _ = writeln!(s, "\n[[matrices]]");
            let _ = writeln!(s, "channel = {}", toml::Value::from(name.as_str()));
            let _ = writeln!(s, "upper = [");
            for j in 0..k {
                s.push(' ');
                for v in &m[j * k + j..(j + 1) * k] {
                    // Debug is Rust's shortest round-trip form, and always TOML: `1.0`,
                    // `-2.5e-7`, `3e20`.
                    let _ = write!(s, " {v:?},");
                }
                s.push('\n');
            }
            let _ = writeln!(s, "]");
        }
        s
    }

    /// Reads [`to_toml`](ShBrdf::to_toml)'s format strictly (unknown keys are errors);
    /// errors name the line and field (`matrices[1].upper`).
    /// `path` only labels errors.
    pub fn from_toml(
        text: &str,
        path: Option<&std::path::Path>,
    ) -> Result<ShBrdf, gonio_core::tomlfile::FileError> {
        const KIND: &str = "spherical-harmonics file";
        let file: ShFile = gonio_core::tomlfile::parse(KIND, text, path, ShFile::check)?;
        let k = basis_len(file.l_max);
        let matrices = file
            .matrices
            .iter()
            .map(|mf| {
                let mut m = vec![0.0; k * k];
                let mut it = mf.upper.iter();
                for j in 0..k {
                    for i in j..k {
                        let v = it.next().copied().unwrap_or(f64::NAN);
                        m[j * k + i] = v;
                        m[i * k + j] = v;
                    }
                }
                m
            })
            .collect();
        let sh = ShBrdf {
            channels: file.channels,
            l_max: file.l_max,
            l_filter: file.l_filter,
            basis: basis(file.l_max),
            matrices,
        };
        sh.validate()
            .map_err(|e| gonio_core::tomlfile::FileError::whole(KIND, path, e.to_string()))?;
        Ok(sh)
    }
}

/// The TOML file of an [`ShBrdf`].
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ShFile {
    kind: String,
    channels: Channels,
    l_max: usize,
    l_filter: usize,
    matrices: Vec<ShFileMatrix>,
}

/// One channel's `[[matrices]]` table.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ShFileMatrix {
    channel: String,
    upper: Vec<f64>,
}

impl ShFile {
    /// The faults serde cannot see, as (field, why).
    fn check(&self) -> Result<(), (String, String)> {
        let fault = |field: &str, why: String| Err((field.to_string(), why));
        if self.kind != FILE_KIND {
            return fault(
                "kind",
                format!("expected \"{FILE_KIND}\", got \"{}\"", self.kind),
            );
        }
        if self.l_max > MAX_L_MAX {
            return fault(
                "l_max",
                format!("{} exceeds the supported {MAX_L_MAX}", self.l_max),
            );
        }
        if self.l_filter > self.l_max {
            return fault(
                "l_filter",
                format!("{} exceeds l_max = {}", self.l_filter, self.l_max),
            );
        }
        if self.matrices.len() != self.channels.len() {
            return fault(
                "matrices",
                format!(
                    "{} [[matrices]] tables for {} channels",
                    self.matrices.len(),
                    self.channels.len()
                ),
            );
        }
        let k = basis_len(self.l_max);
        let want = k * (k + 1) / 2;
        for (i, m) in self.matrices.iter().enumerate() {
            let name = self.channels.name(i);
            if m.channel != name {
                return fault(
                    &format!("matrices[{i}].channel"),
                    format!("expected \"{name}\" (channel {i}), got \"{}\"", m.channel),
                );
            }
            if m.upper.len() != want {
                return fault(
                    &format!("matrices[{i}].upper"),
                    format!(
                        "{} values; the upper triangle for l_max = {} has {want}",
                        m.upper.len(),
                        self.l_max
                    ),
                );
            }
            if let Some(j) = m.upper.iter().position(|v| !v.is_finite()) {
                return fault(
                    &format!("matrices[{i}].upper"),
                    format!("value {j} is not finite ({})", m.upper[j]),
                );
            }
            if let Some(j) = m.upper.iter().position(|v| v.abs() > crate::MAX_MAGNITUDE) {
                return fault(
                    &format!("matrices[{i}].upper"),
                    format!(
                        "value {j} ({:e}) is larger in magnitude than {:e}",
                        m.upper[j],
                        crate::MAX_MAGNITUDE
                    ),
                );
            }
        }
        Ok(())
    }
}
