//! The instrument config's validation: every value a driver will rely on, checked
//! against its range ([`limits`]) before any port is opened — the motion line,
//! each axis, the kinematics' roles, the spectral devices and the detector.

use gonio_proto::apt::StageKind;

use super::{
    ControllerKind, DetectorKind, InstrumentConfig, KinematicsConfig, is_sim_port, limits,
};
use crate::sr830::Sr830Config;

impl InstrumentConfig {
    /// The `[monochromator]` and `[filter_wheel]` sections.
    fn validate_spectral(&self) -> Result<(), (String, String)> {
        use gonio_core::limits::count_at;
        if self.monochromator.is_some() && self.filter_wheel.is_some() {
            return Err((
                "filter_wheel".into(),
                "one device selects the wavelength: give [monochromator] or [filter_wheel], not both"
                    .into(),
            ));
        }
        if let Some(m) = &self.monochromator {
            if m.port.trim().is_empty() {
                return Err(("monochromator.port".into(), "must name a port".into()));
            }
            count_at(
                "monochromator.baud",
                m.baud.into(),
                limits::MIN_BAUD,
                limits::MAX_BAUD,
                "baud",
            )?;
            m.cs130
                .validate()
                .map_err(|e| (format!("monochromator.cs130.{}", e.field), e.reason))?;
            m.timing.validate("monochromator.timing")?;
            for (f, v) in [
                ("wavelength_uncertainty_nm", m.wavelength_uncertainty_nm),
                ("bandwidth_nm", m.bandwidth_nm),
            ] {
                if let Some(v) = v {
                    crate::spectral::BANDWIDTH
                        .check(v)
                        .map_err(|e| (format!("monochromator.{f}"), e))?;
                }
            }
        }
        if let Some(w) = &self.filter_wheel {
            if w.port.trim().is_empty() {
                return Err(("filter_wheel.port".into(), "must name a port".into()));
            }
            count_at(
                "filter_wheel.baud",
                w.baud.into(),
                limits::MIN_BAUD,
                limits::MAX_BAUD,
                "baud",
            )?;
            w.fw102c
                .validate()
                .map_err(|e| (format!("filter_wheel.fw102c.{}", e.field), e.reason))?;
            crate::spectral::CHANGE_TIME
                .check(w.change_s)
                .map_err(|m| ("filter_wheel.change_s".to_string(), m))?;
            if let Some(v) = w.wavelength_uncertainty_nm {
                crate::spectral::BANDWIDTH
                    .check(v)
                    .map_err(|e| ("filter_wheel.wavelength_uncertainty_nm".to_string(), e))?;
            }
        }
        Ok(())
    }

    /// Checks every value a driver will rely on against its range ([`limits`]); the
    /// first bad one is named by its path.
    pub fn validate(&self) -> Result<(), (String, String)> {
        self.validate_motion_line()?;
        for i in 0..self.motion.axes.len() {
            self.validate_axis(i)?;
        }
        if let Some(k) = &self.kinematics {
            self.validate_kinematics(k)?;
        }
        self.geometry.validate("geometry")?;
        self.validate_spectral()?;
        self.validate_detector()
    }

    /// The motion line's port, speed, waits and retries, and that there are axes.
    fn validate_motion_line(&self) -> Result<(), (String, String)> {
        use gonio_core::limits::count_at;
        let err = |f: String, m: &str| Err((f, m.to_string()));
        let m = &self.motion;
        if m.port.trim().is_empty() && m.axes.iter().all(|a| a.port.is_none()) {
            return err("motion.port".into(), "must name a port");
        }
        count_at(
            "motion.baud",
            m.baud.into(),
            limits::MIN_BAUD,
            limits::MAX_BAUD,
            "baud",
        )?;
        count_at(
            "motion.reply_timeout_ms",
            m.reply_timeout_ms,
            1,
            limits::MAX_WAIT_MS,
            "ms",
        )?;
        count_at(
            "motion.poll_interval_ms",
            m.poll_interval_ms,
            1,
            limits::MAX_WAIT_MS,
            "ms",
        )?;
        count_at(
            "motion.retries",
            m.retries as u64,
            0,
            limits::MAX_RETRIES,
            "",
        )?;
        count_at(
            "motion.reconnect_attempts",
            m.reconnect_attempts as u64,
            0,
            limits::MAX_RECONNECTS,
            "",
        )?;
        count_at(
            "motion.reconnect_delay_ms",
            m.reconnect_delay_ms,
            0,
            limits::MAX_WAIT_MS,
            "ms",
        )?;
        if m.axes.is_empty() {
            return err("motion.axes".into(), "at least one axis is needed");
        }
        Ok(())
    }

    /// Axis `i` of `motion.axes`: its name, port and address, what its controller
    /// kind allows, its limits, and that no earlier axis has its name or address.
    fn validate_axis(&self, i: usize) -> Result<(), (String, String)> {
        let err = |f: String, m: &str| Err((f, m.to_string()));
        let m = &self.motion;
        let a = &m.axes[i];
        let f = |k: &str| format!("motion.axes[{i}].{k}");
        if a.name.trim().is_empty() {
            return err(f("name"), "must not be empty");
        }
        match &a.port {
            Some(p) if p.trim().is_empty() => return err(f("port"), "must name a port"),
            None if m.port.trim().is_empty() => {
                return err(f("port"), "must name a port (there is no `motion.port`)");
            }
            _ => {}
        }
        if a.kind == ControllerKind::Smc100
            && !(1..=gonio_proto::smc100::MAX_ADDRESS).contains(&a.address)
        {
            return err(f("address"), "must be in 1..=31");
        }
        if let Some(stage) = a.apt_stage() {
            if a.address != 0 {
                return err(
                    f("address"),
                    "an APT controller has no chain address; leave it out",
                );
            }
            if a.units != "deg" {
                return err(f("units"), "APT rotation stages move in `deg`");
            }
            if a.kind == ControllerKind::K10cr1 && a.stage.is_some_and(|s| s != stage) {
                return err(f("stage"), "a K10CR1 is its own stage; leave it out");
            }
            if a.kind == ControllerKind::Kdc101 && stage != StageKind::Prm1Z8 {
                return err(f("stage"), "a KDC101 drives a `prm1z8` here");
            }
            a.apt(stage).validate().map_err(|(k, why)| (f(k), why))?;
            if let Some(j) = m.axes[..i]
                .iter()
                .position(|b| m.port_of(b) == m.port_of(a) && !is_sim_port(m.port_of(a)))
            {
                return Err((
                    f("port"),
                    format!(
                        "an APT controller needs a line of its own; motion.axes[{j}] is on {:?} too",
                        m.port_of(a)
                    ),
                ));
            }
        } else {
            if a.stage.is_some()
                || a.serial_number.is_some()
                || a.backlash_deg.is_some()
                || !a.keepalive
            {
                return err(
                    f("kind"),
                    "`stage`, `serial_number`, `backlash_deg` and `keepalive` are for APT axes (kind = \"kdc101\" or \"k10cr1\")",
                );
            }
            if let Some(j) = m.axes[..i].iter().position(|b| {
                b.apt_stage().is_some()
                    && m.port_of(b) == m.port_of(a)
                    && !is_sim_port(m.port_of(a))
            }) {
                return Err((
                    f("port"),
                    format!("motion.axes[{j}], an APT controller, holds this line"),
                ));
            }
        }
        limits::POSITION.at(f("min"), a.min)?;
        limits::POSITION.at(f("max"), a.max)?;
        if a.max <= a.min {
            return err(f("max"), "must be finite and greater than `min`");
        }
        if let Some(v) = a.velocity {
            limits::VELOCITY.at(f("velocity"), v)?;
        }
        if let Some(v) = a.acceleration {
            limits::ACCELERATION.at(f("acceleration"), v)?;
        }
        limits::TOLERANCE.at(f("tolerance"), a.tolerance)?;
        limits::HOME_TIMEOUT.at(f("home_timeout_s"), a.home_timeout_s)?;
        if let Some(j) = m.axes[..i].iter().position(|b| b.name == a.name) {
            return Err((f("name"), format!("repeats the name of motion.axes[{j}]")));
        }
        if let Some(j) = m.axes[..i].iter().position(|b| {
            b.kind == a.kind && m.port_of(b) == m.port_of(a) && b.address == a.address
        }) {
            return Err((
                f("address"),
                format!("repeats the address of motion.axes[{j}]"),
            ));
        }
        Ok(())
    }

    /// The kinematics' roles: each one of the layout's, on an axis that exists.
    fn validate_kinematics(&self, k: &KinematicsConfig) -> Result<(), (String, String)> {
        let m = &self.motion;
        for role in k.axes.keys() {
            if !k.layout.roles().contains(&role.as_str()) {
                return Err((
                    format!("kinematics.axes.{role}"),
                    format!(
                        "not a role of this layout ({})",
                        k.layout.roles().join(", ")
                    ),
                ));
            }
        }
        for (role, axis) in k.layout.roles().iter().zip(k.role_axes()) {
            if !m.axes.iter().any(|a| a.name == axis) {
                return Err((
                    format!("kinematics.axes.{role}"),
                    format!("no axis named {axis:?} in motion.axes"),
                ));
            }
        }
        Ok(())
    }

    /// The detector's port and speed, and the settings of its kind (and none of the
    /// other kind's).
    fn validate_detector(&self) -> Result<(), (String, String)> {
        use gonio_core::limits::count_at;
        let err = |f: String, m: &str| Err((f, m.to_string()));
        let d = &self.detector;
        if d.port.trim().is_empty() {
            return err("detector.port".into(), "must name a port");
        }
        count_at(
            "detector.baud",
            d.baud.into(),
            limits::MIN_BAUD,
            limits::MAX_BAUD,
            "baud",
        )?;
        match d.kind {
            DetectorKind::Sr830 => {
                if d.picoammeter.is_some() {
                    return err(
                        "detector.picoammeter".into(),
                        "is for kind = \"k6485\"; an SR830 takes [detector.lockin]",
                    );
                }
                d.lockin
                    .validate()
                    .map_err(|e| (format!("detector.lockin.{}", e.field), e.reason))
            }
            DetectorKind::K6485 => {
                if d.lockin != Sr830Config::default() {
                    return err(
                        "detector.lockin".into(),
                        "is for kind = \"sr830\"; a K6485 takes [detector.picoammeter]",
                    );
                }
                d.picoammeter()
                    .validate()
                    .map_err(|e| (format!("detector.picoammeter.{}", e.field), e.reason))
            }
        }
    }
}
