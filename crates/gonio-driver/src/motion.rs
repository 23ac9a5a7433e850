//! Every motion axis of an instrument, whatever drives it: [`Motion`].
//!
//! An instrument's axes sit on one or more serial lines (a chain of SMC100s on one
//! RS-232 line, each Thorlabs K-Cube on its own USB line). [`Motion`] holds them all
//! behind one set of operations that the run engine, plans and safety rules use
//! without knowing the families: identify, home, move several axes at once, read a
//! position, stop. Each line's session keeps its own policy (soft limits before any
//! byte, retries, reconnections); a move over several lines runs the lines' operations
//! together on one thread (`pump_many`), and a fault on one line stops the stages on
//! every line.

use std::any::Any;
use std::time::Duration;

use crate::apt::{AptAxis, StageKind};
use crate::clock::Clock;
use crate::heartbeat::Heartbeat;
pub use crate::pump::Slot;
use crate::pump::{AbortFlag, pump_many};
use crate::smc100::{AxisError, MotionError, Smc100Chain};
use crate::transport::Transport;

/// One serial line of motion controllers, whatever their family: what [`Motion`]
/// needs of it. A family plugs in by implementing it over its session's pump
/// ([`Smc100Chain`] for an SMC100 chain, [`AptAxis`] for one APT controller); the
/// engine, plans and safety rules then work for it unchanged. `Motion` hands each
/// line only the axes it has.
pub trait MotionDevice: Send + std::fmt::Debug {
    /// The names of the axes on the line, in config order.
    fn axis_names(&self) -> Vec<String>;
    /// The limits and units of the named axis, when it is on this line.
    fn limits(&self, name: &str) -> Option<(f64, f64, String)>;
    /// Exchanges re-sent after a lost, late or garbled reply.
    fn retried(&self) -> u64;
    /// Takes the motion system's abort flag, read at every abort point.
    fn set_abort_flag(&mut self, flag: AbortFlag);
    /// Joins the instrument's heartbeat: the line's keep-alives, if it has any, go
    /// into it, and its waits keep every line's going.
    fn set_heartbeat(&mut self, beats: Heartbeat);
    /// Identifies (and, where the family needs it, sets up) every controller. Nothing
    /// moves.
    fn identify(&mut self) -> Result<Vec<(String, AxisInfo)>, MotionError>;
    /// Where the named axis stands.
    fn state(&mut self, name: &str) -> Result<AxisState, MotionError>;
    /// The named axis' position, units.
    fn position(&mut self, name: &str) -> Result<f64, MotionError>;
    /// Homes the named axes.
    fn home(&mut self, names: &[&str]) -> Result<(), MotionError>;
    /// Moves the named axes and returns where they ended, in `targets` order.
    fn move_to(&mut self, targets: &[(&str, f64)]) -> Result<Vec<f64>, MotionError>;
    /// The same move, started but not pumped: one slot of a move over several lines.
    fn move_slot<'a>(
        &'a mut self,
        targets: &[(&str, f64)],
    ) -> Slot<'a, Result<Vec<f64>, MotionError>>;
    /// Moves one axis by `delta`; never re-sent.
    fn move_by(&mut self, name: &str, delta: f64) -> Result<f64, MotionError>;
    /// When the line's last move was seen to have ended, before its positions were
    /// read back; `None` where the family does not tell (the move's return is then
    /// taken).
    fn stopped_at(&self) -> Option<Duration> {
        None
    }
    /// Stops every stage on the line.
    fn stop_all(&mut self) -> Result<(), MotionError>;
    /// Resets the named axis' controller where the family can, and homes it.
    fn reset_and_home(&mut self, name: &str) -> Result<(), MotionError>;
    /// The line as `Any`, to reach a family's own operations (an SMC100's
    /// configuration, through `downcast_mut`).
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

impl<T: Transport + 'static, C: Clock + 'static> MotionDevice for Smc100Chain<T, C> {
    fn axis_names(&self) -> Vec<String> {
        self.axes().iter().map(|a| a.name.clone()).collect()
    }
    fn limits(&self, name: &str) -> Option<(f64, f64, String)> {
        self.axes()
            .iter()
            .find(|a| a.name == name)
            .map(|a| (a.min, a.max, a.units.clone()))
    }
    fn retried(&self) -> u64 {
        Smc100Chain::retried(self)
    }
    fn set_abort_flag(&mut self, flag: AbortFlag) {
        Smc100Chain::set_abort_flag(self, flag);
    }
    fn set_heartbeat(&mut self, beats: Heartbeat) {
        Smc100Chain::set_heartbeat(self, beats);
    }
    fn identify(&mut self) -> Result<Vec<(String, AxisInfo)>, MotionError> {
        let infos = Smc100Chain::identify(self)?;
        Ok(self
            .axes()
            .iter()
            .zip(infos)
            .map(|(a, i)| {
                (
                    a.name.clone(),
                    AxisInfo {
                        family: "smc100",
                        version: i.version.clone(),
                        stage: i.stage.clone(),
                        state_code: format!("{:02X}", i.state.code()),
                        state: i.state.to_string(),
                        referenced: i.state.is_ready(),
                    },
                )
            })
            .collect())
    }
    fn state(&mut self, name: &str) -> Result<AxisState, MotionError> {
        let s = self.status(name)?;
        Ok(if s.state.is_moving() {
            AxisState::Moving
        } else if s.state.is_ready() {
            AxisState::Referenced
        } else {
            AxisState::Unreferenced
        })
    }
    fn position(&mut self, name: &str) -> Result<f64, MotionError> {
        Smc100Chain::position(self, name)
    }
    fn home(&mut self, names: &[&str]) -> Result<(), MotionError> {
        Smc100Chain::home(self, names)
    }
    fn move_to(&mut self, targets: &[(&str, f64)]) -> Result<Vec<f64>, MotionError> {
        Smc100Chain::move_to(self, targets)
    }
    fn move_slot<'a>(
        &'a mut self,
        targets: &[(&str, f64)],
    ) -> Slot<'a, Result<Vec<f64>, MotionError>> {
        Smc100Chain::move_slot(self, targets)
    }
    fn move_by(&mut self, name: &str, delta: f64) -> Result<f64, MotionError> {
        Smc100Chain::move_by(self, name, delta)
    }
    fn stopped_at(&self) -> Option<Duration> {
        Smc100Chain::stopped_at(self)
    }
    fn stop_all(&mut self) -> Result<(), MotionError> {
        Smc100Chain::stop_all(self)
    }
    fn reset_and_home(&mut self, name: &str) -> Result<(), MotionError> {
        Smc100Chain::reset_and_home(self, name)
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

impl<T: Transport + 'static, C: Clock + 'static> MotionDevice for AptAxis<T, C> {
    fn axis_names(&self) -> Vec<String> {
        vec![self.axis().name.clone()]
    }
    fn limits(&self, name: &str) -> Option<(f64, f64, String)> {
        let x = self.axis();
        (x.name == name).then(|| (x.min, x.max, "deg".to_string()))
    }
    fn retried(&self) -> u64 {
        AptAxis::retried(self)
    }
    fn set_abort_flag(&mut self, flag: AbortFlag) {
        AptAxis::set_abort_flag(self, flag);
    }
    fn set_heartbeat(&mut self, beats: Heartbeat) {
        AptAxis::set_heartbeat(self, beats);
    }
    fn identify(&mut self) -> Result<Vec<(String, AxisInfo)>, MotionError> {
        let info = AptAxis::identify(self)?;
        let status = self.status()?;
        let homed = status.is_homed();
        let [ma, it, mi] = info.firmware;
        Ok(vec![(
            self.axis().name.clone(),
            AxisInfo {
                family: match self.axis().stage {
                    StageKind::K10cr1 => "k10cr1",
                    StageKind::Prm1Z8 => "kdc101",
                },
                version: format!("{ma}.{it}.{mi}"),
                stage: format!(
                    "{} s/n {} ({:?})",
                    info.model,
                    info.serial,
                    self.axis().stage
                ),
                state_code: format!("{:08X}", status.bits),
                state: if homed { "homed" } else { "not homed" }.to_string(),
                referenced: homed,
            },
        )])
    }
    fn state(&mut self, _name: &str) -> Result<AxisState, MotionError> {
        let s = self.status()?;
        Ok(if s.is_moving() {
            AxisState::Moving
        } else if s.is_homed() {
            AxisState::Referenced
        } else {
            AxisState::Unreferenced
        })
    }
    fn position(&mut self, _name: &str) -> Result<f64, MotionError> {
        AptAxis::position(self)
    }
    fn home(&mut self, _names: &[&str]) -> Result<(), MotionError> {
        AptAxis::home(self).map(|_| ())
    }
    fn move_to(&mut self, targets: &[(&str, f64)]) -> Result<Vec<f64>, MotionError> {
        targets
            .iter()
            .map(|(_, t)| AptAxis::move_to(self, *t))
            .collect()
    }
    fn move_slot<'a>(
        &'a mut self,
        targets: &[(&str, f64)],
    ) -> Slot<'a, Result<Vec<f64>, MotionError>> {
        // One axis on the line: one target (a missing one is refused by the limits).
        let target = targets.first().map_or(f64::NAN, |(_, t)| *t);
        AptAxis::move_slot(self, target)
    }
    fn move_by(&mut self, _name: &str, delta: f64) -> Result<f64, MotionError> {
        AptAxis::move_by(self, delta)
    }
    fn stop_all(&mut self) -> Result<(), MotionError> {
        self.stop(true)
    }
    fn reset_and_home(&mut self, _name: &str) -> Result<(), MotionError> {
        // An APT controller has no reset command: homing restores its reference.
        AptAxis::home(self).map(|_| ())
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

/// What start-up learnt about an axis' controller.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisInfo {
    /// The controller family (`smc100`, `kdc101`, `k10cr1`).
    pub family: &'static str,
    /// The controller's firmware version as it reports it (an SMC100's `VE` text).
    pub version: String,
    /// The stage as the controller names it (an SMC100's `ID?`; an APT model).
    pub stage: String,
    /// The controller's state code (an SMC100's two hex digits).
    pub state_code: String,
    /// The state, for people (`32 (ReadyFromHoming)`, `homed`).
    pub state: String,
    /// Whether the axis has its reference (homed) already.
    pub referenced: bool,
}

impl AxisInfo {
    /// `stage (state)`, for the run log.
    pub fn description(&self) -> String {
        format!("{} ({})", self.stage, self.state)
    }
}

/// Where an axis stands, as the engine's recovery needs to know it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AxisState {
    /// Still moving (stopping after a fault, or homing).
    Moving,
    /// At rest, with its reference.
    Referenced,
    /// At rest, without a reference: it must be homed.
    Unreferenced,
}

/// Every motion axis of an instrument, on however many lines of whichever families.
#[derive(Debug)]
pub struct Motion<C: Clock + Clone> {
    lines: Vec<Box<dyn MotionDevice>>,
    /// Each axis' name and line, in config order.
    axes: Vec<(String, usize)>,
    clock: C,
    abort: AbortFlag,
    beats: Heartbeat,
    /// When the last move's stages had all stopped, as the controllers told it.
    stopped: Option<Duration>,
}

impl<C: Clock + Clone> Motion<C> {
    /// The motion system of `lines`, waiting on `clock`. Every line takes the one abort
    /// flag and joins one heartbeat. Axis names must be distinct across lines.
    pub fn new(mut lines: Vec<Box<dyn MotionDevice>>, clock: C) -> Result<Self, MotionError> {
        let abort = AbortFlag::new();
        let beats = Heartbeat::new();
        for l in &mut lines {
            l.set_abort_flag(abort.clone());
            l.set_heartbeat(beats.clone());
        }
        let mut axes: Vec<(String, usize)> = Vec::new();
        for (i, l) in lines.iter().enumerate() {
            for name in l.axis_names() {
                if axes.iter().any(|(n, _)| *n == name) {
                    return Err(MotionError::Config(format!("two axes are named {name:?}")));
                }
                axes.push((name, i));
            }
        }
        Ok(Motion {
            lines,
            axes,
            clock,
            abort,
            beats,
            stopped: None,
        })
    }

    /// The heartbeat every line's waits keep going: hand it to the instrument's other
    /// devices ([`Goniometer`](crate::Goniometer) does).
    pub fn heartbeat(&self) -> &Heartbeat {
        &self.beats
    }

    /// The flag that aborts waits on every line; clone it to raise it from elsewhere.
    pub fn abort_flag(&self) -> AbortFlag {
        self.abort.clone()
    }

    /// The clock the lines wait on.
    pub fn clock(&self) -> &C {
        &self.clock
    }

    /// The axes' names, in config order.
    pub fn axis_names(&self) -> Vec<String> {
        self.axes.iter().map(|(n, _)| n.clone()).collect()
    }

    /// The lines.
    pub fn lines(&self) -> &[Box<dyn MotionDevice>] {
        &self.lines
    }

    /// The lines, to reach a family's own operations (an SMC100's configuration).
    pub fn lines_mut(&mut self) -> &mut [Box<dyn MotionDevice>] {
        &mut self.lines
    }

    /// Exchanges re-sent after a lost, late or garbled reply, on every line.
    pub fn retried(&self) -> u64 {
        self.lines.iter().map(|l| l.retried()).sum()
    }

    fn line_of(&mut self, name: &str) -> Result<&mut Box<dyn MotionDevice>, MotionError> {
        let i = self
            .axes
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, i)| *i)
            .ok_or_else(|| MotionError::UnknownAxis(name.to_string()))?;
        Ok(&mut self.lines[i])
    }

    /// Identifies every controller: what runs before anything moves. Proves each one
    /// answers, and says which axes need homing.
    pub fn identify(&mut self) -> Result<Vec<(String, AxisInfo)>, MotionError> {
        let mut out = Vec::new();
        for line in &mut self.lines {
            out.extend(line.identify()?);
        }
        // Config order, whatever the lines' order.
        out.sort_by_key(|(n, _)| self.axes.iter().position(|(m, _)| m == n));
        Ok(out)
    }

    /// Where the named axis stands: moving, referenced or not.
    pub fn state(&mut self, name: &str) -> Result<AxisState, MotionError> {
        self.line_of(name)?.state(name)
    }

    /// The named axis' position, units.
    pub fn position(&mut self, name: &str) -> Result<f64, MotionError> {
        self.line_of(name)?.position(name)
    }

    /// Homes the named axes, line by line (concurrently within an SMC100 chain).
    pub fn home(&mut self, names: &[&str]) -> Result<(), MotionError> {
        for i in 0..self.lines.len() {
            let here: Vec<&str> = names
                .iter()
                .copied()
                .filter(|n| self.axes.iter().any(|(m, l)| m == n && *l == i))
                .collect();
            if here.is_empty() {
                continue;
            }
            self.lines[i].home(&here)?;
        }
        if let Some(n) = names
            .iter()
            .find(|n| !self.axes.iter().any(|(m, _)| m == *n))
        {
            return Err(MotionError::UnknownAxis(n.to_string()));
        }
        Ok(())
    }

    /// Homes every axis.
    pub fn home_all(&mut self) -> Result<(), MotionError> {
        let names = self.axis_names();
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        self.home(&refs)
    }

    /// Moves the named axes to their targets, all at once, and returns where each
    /// ended, in `targets` order. Every target is checked against its axis' limits
    /// before any byte goes out on any line. A fault on one line stops every stage and
    /// is the error returned.
    pub fn move_to(&mut self, targets: &[(&str, f64)]) -> Result<Vec<f64>, MotionError> {
        let mut per_line: Vec<Vec<(&str, f64)>> = vec![Vec::new(); self.lines.len()];
        for &(name, target) in targets {
            let line = self
                .axes
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, i)| *i)
                .ok_or_else(|| MotionError::UnknownAxis(name.to_string()))?;
            per_line[line].push((name, target));
        }
        self.check_limits(targets)?;
        self.stopped = None;
        let used: Vec<usize> = (0..self.lines.len())
            .filter(|i| !per_line[*i].is_empty())
            .collect();
        let mut ended: Vec<(String, f64)> = Vec::new();
        if let [only] = used.as_slice() {
            // One line: its own pump, exchange for exchange as a chain alone.
            let got = self.lines[*only].move_to(&per_line[*only])?;
            ended.extend(per_line[*only].iter().map(|(n, _)| n.to_string()).zip(got));
        } else {
            let mut slots = Vec::new();
            let mut names = Vec::new();
            for (i, line) in self.lines.iter_mut().enumerate() {
                if per_line[i].is_empty() {
                    continue;
                }
                names.push(
                    per_line[i]
                        .iter()
                        .map(|(n, _)| n.to_string())
                        .collect::<Vec<_>>(),
                );
                slots.push(line.move_slot(&per_line[i]));
            }
            let results = pump_many(
                slots,
                &self.clock,
                &self.beats,
                Some(&self.abort),
                Result::is_err,
            );
            let mut errors = Vec::new();
            for (names, r) in names.into_iter().zip(results) {
                match r {
                    Ok(got) => ended.extend(names.into_iter().zip(got)),
                    Err(e) => errors.push(e),
                }
            }
            // A line aborted because another failed reports the other's fault, not
            // its own abort.
            let raised = self.abort.is_raised();
            let induced = |e: &MotionError| {
                !raised
                    && matches!(
                        e,
                        MotionError::AtAxis {
                            source: AxisError::Aborted,
                            ..
                        }
                    )
            };
            if let Some(k) =
                (!errors.is_empty()).then(|| errors.iter().position(|e| !induced(e)).unwrap_or(0))
            {
                return Err(errors.swap_remove(k));
            }
        }
        // The light is final once the last line's stages stopped; a line that does
        // not tell is taken as stopped now.
        let now = self.clock.now();
        self.stopped = used
            .iter()
            .map(|i| self.lines[*i].stopped_at().unwrap_or(now).min(now))
            .max()
            .or(Some(now));
        Ok(targets
            .iter()
            .map(|(n, t)| ended.iter().find(|(m, _)| m == n).map_or(*t, |(_, p)| *p))
            .collect())
    }

    /// When the last successful [`move_to`](Self::move_to) had every stage stopped, as
    /// the controllers told it (the status reply that found the last one READY), before
    /// the positions were read back: from then on the light on the detector is the
    /// new point's. `None` before the first move and after a failed one.
    pub fn stopped_at(&self) -> Option<Duration> {
        self.stopped
    }

    /// Refuses the whole move if any target is outside its axis' limits, before any
    /// line sends a byte.
    fn check_limits(&self, targets: &[(&str, f64)]) -> Result<(), MotionError> {
        for &(name, target) in targets {
            for line in &self.lines {
                if let Some((min, max, units)) = line.limits(name)
                    && !(target.is_finite() && target >= min && target <= max)
                {
                    return Err(MotionError::AtAxis {
                        axis: name.to_string(),
                        source: AxisError::OutOfLimits {
                            target,
                            min,
                            max,
                            units,
                        },
                    });
                }
            }
        }
        Ok(())
    }

    /// Moves one axis by `delta` from its current target; never re-sent.
    pub fn move_by(&mut self, name: &str, delta: f64) -> Result<f64, MotionError> {
        self.line_of(name)?.move_by(name, delta)
    }

    /// Stops every stage on every line. Every line gets its stop; the first error is
    /// returned.
    pub fn stop_all(&mut self) -> Result<(), MotionError> {
        let mut first = None;
        for line in &mut self.lines {
            if let Err(e) = line.stop_all() {
                first.get_or_insert(e);
            }
        }
        first.map_or(Ok(()), Err)
    }

    /// Resets the named axis' controller where the family can (an SMC100's `RS`),
    /// waits for it, and homes it.
    pub fn reset_and_home(&mut self, name: &str) -> Result<(), MotionError> {
        self.line_of(name)?.reset_and_home(name)
    }
}
