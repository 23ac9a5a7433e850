//! Checking a plan as read: every field in its range, and the whole within
//! [`MAX_POINTS`] pairs and [`MAX_READINGS`] readings.

use super::{
    Adaptive, BUDGET, Budget, MAX_POINTS, MAX_READINGS, PHI, Plan, Points, STAGE_POSITION, Values,
};

/// The four angles of a pair, checked: θ in [0, 90], φ in [`PHI`], everything finite.
fn check_pair(p: &[f64; 4]) -> Result<(), String> {
    if p.iter().any(|x| !x.is_finite()) {
        return Err("angles must be finite".into());
    }
    for (name, t) in [("theta_i", p[0]), ("theta_o", p[2])] {
        if !(0.0..=90.0).contains(&t) {
            return Err(format!("{name} = {t} is outside [0, 90]"));
        }
    }
    for (name, f) in [("phi_i", p[1]), ("phi_o", p[3])] {
        PHI.check(f).map_err(|m| format!("{name} {m}"))?;
    }
    Ok(())
}

/// The fault of `field`, for `return bad(…)`.
fn bad<T>(field: &str, message: String) -> Result<T, (String, String)> {
    Err((field.to_string(), message))
}

impl Plan {
    /// Checks every field, in the order a reader fixes them: the bands, the points,
    /// their count, then the drift, calibration, ordering and reading tables.
    pub(super) fn validate(&self) -> Result<(), (String, String)> {
        self.validate_bands()?;
        let mut total = self.validate_angles()?;
        if let Points::Isotropic { phi_i, .. }
        | Points::InPlane { phi_i, .. }
        | Points::Adaptive(Adaptive { phi_i, .. }) = &self.points
        {
            PHI.at("points.phi_i", *phi_i)?;
        }
        if let Points::Adaptive(a) = &self.points {
            if let Budget::Points(p) = a.budget {
                total = p;
            }
            self.validate_adaptive_calibration()?;
        }
        if total > MAX_POINTS {
            return bad(
                "points",
                format!("expands to {total} pairs, more than {MAX_POINTS}"),
            );
        }
        // A list plan's pairs are counted when its file is read (`pairs`).
        if !matches!(self.points, Points::List { .. }) {
            self.check_readings(total)?;
        }
        if let Some(d) = &self.drift {
            if d.every == 0 {
                return bad("drift.every", "must be at least 1".into());
            }
            if let Some(at) = &d.at {
                check_pair(at).map_err(|m| ("drift.at".to_string(), m))?;
            }
        }
        self.validate_calibration()?;
        BUDGET.at("order.budget_s", self.order.budget_s)?;
        if let Some(r) = &self.reading {
            r.validate()?;
        }
        Ok(())
    }

    /// Checks the repeats and the bands: `channels` distinct and non-empty, or
    /// `wavelengths` (not both) that expand and name their channels.
    fn validate_bands(&self) -> Result<(), (String, String)> {
        if self.repeats == 0 || self.repeats > 10_000 {
            return bad("repeats", format!("{} is not in 1..=10000", self.repeats));
        }
        if let Some(ch) = &self.channels {
            if ch.is_empty() {
                return bad(
                    "channels",
                    "name at least one channel, or leave it out".into(),
                );
            }
            for (i, c) in ch.iter().enumerate() {
                if c.trim().is_empty() || ch[..i].contains(c) {
                    return bad(
                        &format!("channels[{i}]"),
                        format!("{c:?} is empty or repeated"),
                    );
                }
            }
        }
        if let Some(w) = &self.wavelengths {
            if self.channels.is_some() {
                return bad(
                    "wavelengths",
                    "`wavelengths` and `channels` both name the bands; give one of them".into(),
                );
            }
            w.names()?;
        }
        Ok(())
    }

    /// Expands each angle of the points (an adaptive table's other fields checked
    /// first) and checks it in its range; returns the product of their counts, the
    /// pairs they expand to (1 for a list, whose file is counted when read).
    fn validate_angles(&self) -> Result<usize, (String, String)> {
        let fields: Vec<(&str, &Values)> = match &self.points {
            Points::Grid {
                theta_i,
                phi_i,
                theta_o,
                phi_o,
            } => vec![
                ("theta_i", theta_i),
                ("phi_i", phi_i),
                ("theta_o", theta_o),
                ("phi_o", phi_o),
            ],
            Points::Isotropic {
                theta_i,
                theta_o,
                delta_phi,
                ..
            } => vec![
                ("theta_i", theta_i),
                ("theta_o", theta_o),
                ("delta_phi", delta_phi),
            ],
            Points::InPlane {
                theta_i, theta_o, ..
            } => vec![("theta_i", theta_i), ("theta_o", theta_o)],
            Points::List { .. } => vec![],
            Points::Adaptive(a) => {
                a.validate()?;
                vec![("theta_i", &a.theta_i)]
            }
        };
        let mut total = 1usize;
        for (name, v) in fields {
            let values = v.expand().map_err(|m| (format!("points.{name}"), m))?;
            let (lo, hi) = match name {
                "theta_i" => (0.0, 90.0),
                "theta_o" if matches!(self.points, Points::InPlane { .. }) => (-90.0, 90.0),
                "theta_o" => (0.0, 90.0),
                _ => (PHI.min, PHI.max),
            };
            if let Some(x) = values.iter().find(|x| !(lo..=hi).contains(*x)) {
                let num = gonio_core::limits::num;
                return bad(
                    &format!("points.{name}"),
                    format!("{} is outside [{}, {}]", num(*x), num(lo), num(hi)),
                );
            }
            total = total.saturating_mul(values.len());
        }
        Ok(total)
    }

    /// An adaptive plan's calibrations: an absolute one to reduce its batches with,
    /// and none at the end, which is decided during the run.
    fn validate_adaptive_calibration(&self) -> Result<(), (String, String)> {
        if self.calibration.incident.is_none() && self.calibration.standard.is_none() {
            return bad(
                "calibration",
                "an adaptive plan chooses its points from the reduced BRDF: it needs \
                 `calibration.incident` or `calibration.standard`"
                    .into(),
            );
        }
        if self.calibration.repeat_at_end {
            return bad(
                "calibration.repeat_at_end",
                "an adaptive run's end is decided during the run: its calibrations are \
                 taken once, before the coarse pass"
                    .into(),
            );
        }
        Ok(())
    }

    /// Checks the incident beam's transmittance and stage positions, and the
    /// standard's pairs.
    fn validate_calibration(&self) -> Result<(), (String, String)> {
        let c = &self.calibration;
        if let Some(n) = c.dark_readings
            && !(1..=1000).contains(&n)
        {
            return bad(
                "calibration.dark_readings",
                format!("{n} is not in 1..=1000"),
            );
        }
        if let Some(i) = &c.incident {
            if !(i.transmittance > 0.0 && i.transmittance <= 1.0) {
                return bad(
                    "calibration.incident.transmittance",
                    format!("{} is not in (0, 1]", i.transmittance),
                );
            }
            if let Some(s) = &i.stages {
                for (k, x) in s.iter().enumerate() {
                    STAGE_POSITION.at(format!("calibration.incident.stages[{k}]"), *x)?;
                }
            }
        }
        if let Some(s) = &c.standard {
            if s.at.is_empty() {
                return bad("calibration.standard.at", "name at least one pair".into());
            }
            for (k, p) in s.at.iter().enumerate() {
                check_pair(p).map_err(|m| (format!("calibration.standard.at[{k}]"), m))?;
            }
        }
        Ok(())
    }

    /// Checks that `pairs` pairs, with the calibrations, repeats and channels, stay
    /// within [`MAX_READINGS`]; the fault names the field that multiplies them.
    pub(super) fn check_readings(&self, pairs: usize) -> Result<(), (String, String)> {
        let passes = self.band_count();
        let standards = self.calibration.standard.as_ref().map_or(0, |s| s.at.len());
        // Dark and incident readings, the standard's pairs, and the pairs themselves.
        let per_pass = pairs.saturating_add(standards).saturating_add(2);
        let n = per_pass
            .saturating_mul(self.repeats as usize)
            .saturating_mul(passes);
        if n <= MAX_READINGS {
            return Ok(());
        }
        let field = if self.repeats > 1 {
            "repeats"
        } else if passes > 1 && self.wavelengths.is_some() {
            "wavelengths"
        } else if passes > 1 {
            "channels"
        } else {
            "points"
        };
        Err((
            field.into(),
            format!(
                "{pairs} pairs and {standards} standard pairs × {} repeats × {passes} channels \
                 is about {n} readings, more than the {MAX_READINGS} a plan may take",
                self.repeats
            ),
        ))
    }

    /// How many bands the plan measures in (1 without `channels` or `wavelengths`).
    fn band_count(&self) -> usize {
        match (&self.channels, &self.wavelengths) {
            (Some(c), _) => c.len().max(1),
            (None, Some(w)) => w.expand().map_or(1, |v| v.len()),
            (None, None) => 1,
        }
    }
}
