//! Expanding a plan's points into direction pairs.

use gonio_core::SphericalDeg;
use gonio_core::dirfile::{self, PairDeg};
use gonio_core::tomlfile::FileError;

use super::{Budget, KIND, MAX_POINTS, Plan, Points, Values};

impl Plan {
    /// Reads the directions file of a `list` plan.
    pub fn pairs(&self) -> Result<Vec<PairDeg>, FileError> {
        let pair = |ti: f64, pi: f64, to: f64, po: f64| PairDeg {
            incident: SphericalDeg::new(ti, pi),
            outgoing: SphericalDeg::new(to, po),
        };
        // Validated by `validate`: expansion cannot fail here; an error is reported
        // anyway rather than unwrapped.
        let ex = |name: &str, v: &Values| {
            v.expand().map_err(|m| FileError {
                field: Some(format!("points.{name}")),
                ..FileError::whole(KIND, self.source.as_deref(), m)
            })
        };
        let mut out = Vec::new();
        match &self.points {
            Points::Grid {
                theta_i,
                phi_i,
                theta_o,
                phi_o,
            } => {
                let (a, b, c, d) = (
                    ex("theta_i", theta_i)?,
                    ex("phi_i", phi_i)?,
                    ex("theta_o", theta_o)?,
                    ex("phi_o", phi_o)?,
                );
                for &ti in &a {
                    for &pi in &b {
                        for &to in &c {
                            for &po in &d {
                                out.push(pair(ti, pi, to, po));
                            }
                        }
                    }
                }
            }
            Points::Isotropic {
                phi_i,
                theta_i,
                theta_o,
                delta_phi,
            } => {
                let (a, c, d) = (
                    ex("theta_i", theta_i)?,
                    ex("theta_o", theta_o)?,
                    ex("delta_phi", delta_phi)?,
                );
                for &ti in &a {
                    for &to in &c {
                        for &dp in &d {
                            out.push(pair(ti, *phi_i, to, phi_i + dp));
                        }
                    }
                }
            }
            Points::InPlane {
                phi_i,
                theta_i,
                theta_o,
            } => {
                let (a, c) = (ex("theta_i", theta_i)?, ex("theta_o", theta_o)?);
                for &ti in &a {
                    for &to in &c {
                        let po = if to > 0.0 { phi_i + 180.0 } else { *phi_i };
                        out.push(pair(ti, *phi_i, to.abs(), po));
                    }
                }
            }
            Points::Adaptive(a) => {
                let at = |m: String| FileError {
                    field: Some("points".into()),
                    ..FileError::whole(KIND, self.source.as_deref(), m)
                };
                match a.budget {
                    Budget::Points(p) => {
                        out = a
                            .coarse_per_incidence(p)
                            .and_then(|n| a.coarse_pairs(n))
                            .map_err(at)?;
                    }
                    Budget::Hours(_) => {
                        return Err(at(
                            "an adaptive plan with a budget in hours is expanded on an \
                             instrument (its coarse pass depends on the time a point takes)"
                                .into(),
                        ));
                    }
                }
            }
            Points::List { file } => {
                let path = self.resolve(file);
                // A regular file of bounded size: a FIFO or a device named here is
                // refused without being read.
                let text =
                    gonio_core::input::read_text(&path, dirfile::MAX_BYTES).map_err(|e| {
                        FileError {
                            field: Some("points.file".into()),
                            ..FileError::whole(KIND, self.source.as_deref(), e.to_string())
                        }
                    })?;
                out = dirfile::read_pairs(&text).map_err(|e| FileError {
                    line: Some(e.line),
                    field: e.column.clone(),
                    ..FileError::whole("directions file", Some(&path), e.message.clone())
                })?;
                if out.len() > MAX_POINTS {
                    return Err(FileError::whole(
                        "directions file",
                        Some(&path),
                        format!("{} pairs, more than {MAX_POINTS}", out.len()),
                    ));
                }
                self.check_readings(out.len())
                    .map_err(|(field, m)| FileError {
                        field: Some(field),
                        ..FileError::whole(KIND, self.source.as_deref(), m)
                    })?;
            }
        }
        Ok(out)
    }
}
