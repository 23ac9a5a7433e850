//! A chain of Newport SMC100 controllers on one serial line, one rotation stage each.
//!
//! [`Smc100Chain`] owns the transport and the axes' configurations and turns
//! goniometer-level requests into the manual's exchanges:
//! - every set or action command is followed by `TE`, and a letter other than `@` is a
//!   typed [`AxisError::Controller`];
//! - soft limits are checked before any byte of a move goes out, so no plan can move a
//!   stage outside them;
//! - moves complete by polling `TS` until READY; DISABLE, NOT REFERENCED, a vanished
//!   port or a deadline stop every stage and return the cause;
//! - only idempotent commands are re-sent after a lost reply: an absolute move may be,
//!   a relative move never (its fate is reported as [`AxisError::Ambiguous`]);
//! - a reply line with a NUL byte means the controller lost power; the state `0A`
//!   mid-run means it was reset; both are errors, and [`Smc100Chain::home`] recovers;
//! - dropping the chain, or raising its [`AbortFlag`], stops every stage.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

pub use gonio_proto::smc100::{
    AxisConfig, AxisError, ChainPolicy, ControllerInfo, MotionError, describe_errors,
};
use gonio_proto::smc100::{
    Command, ControllerState, ErrorCode, Frame, Param, Reply, ReplyBody, Status,
};

use crate::clock::Clock;
use crate::transport::{Transport, TransportError};

/// A flag that, once raised from anywhere (a signal handler, a UI thread), makes the
/// running and every later wait stop all stages and return [`AxisError::Aborted`].
#[derive(Clone, Debug, Default)]
pub struct AbortFlag(Arc<AtomicBool>);

impl AbortFlag {
    /// A lowered flag.
    pub fn new() -> Self {
        Self::default()
    }
    /// Raises it.
    pub fn raise(&self) {
        self.0.store(true, Ordering::SeqCst);
    }
    /// Lowers it again (after the operator acknowledged).
    pub fn clear(&self) {
        self.0.store(false, Ordering::SeqCst);
    }
    /// True when raised.
    pub fn is_raised(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }
}

/// A chain of SMC100 controllers sharing one serial line.
pub struct Smc100Chain<T: Transport, C: Clock> {
    transport: T,
    clock: C,
    axes: Vec<AxisConfig>,
    policy: ChainPolicy,
    abort: AbortFlag,
    buf: Vec<u8>,
    retried: u64,
}

impl<T: Transport, C: Clock> std::fmt::Debug for Smc100Chain<T, C> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Smc100Chain")
            .field("port", &self.transport.name())
            .field("axes", &self.axes)
            .finish()
    }
}

fn line_text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes)
        .trim_end_matches(['\r', '\n'])
        .to_string()
}

impl<T: Transport, C: Clock> Smc100Chain<T, C> {
    /// A chain over `transport`. Axes must have distinct names and addresses 1–31, and
    /// `min < max`.
    pub fn new(
        transport: T,
        clock: C,
        axes: Vec<AxisConfig>,
        policy: ChainPolicy,
    ) -> Result<Self, MotionError> {
        for (i, a) in axes.iter().enumerate() {
            if !(1..=gonio_proto::smc100::MAX_ADDRESS).contains(&a.address) {
                return Err(MotionError::Config(format!(
                    "axis {:?}: address {} is outside 1..=31",
                    a.name, a.address
                )));
            }
            if !(a.min.is_finite() && a.max.is_finite() && a.min < a.max) {
                return Err(MotionError::Config(format!(
                    "axis {:?}: limits [{}, {}] must be finite with min < max",
                    a.name, a.min, a.max
                )));
            }
            if let Some(b) = axes[..i]
                .iter()
                .find(|b| b.name == a.name || b.address == a.address)
            {
                return Err(MotionError::Config(format!(
                    "axes {:?} and {:?} share a name or the address {}",
                    b.name, a.name, a.address
                )));
            }
        }
        Ok(Smc100Chain {
            transport,
            clock,
            axes,
            policy,
            abort: AbortFlag::new(),
            buf: Vec::with_capacity(32),
            retried: 0,
        })
    }

    /// The flag that aborts waits; clone it to raise it from elsewhere.
    pub fn abort_flag(&self) -> AbortFlag {
        self.abort.clone()
    }

    /// Exchanges sent again after a lost, late or garbled reply since the chain was
    /// built: what a run log reports as retries.
    pub fn retried(&self) -> u64 {
        self.retried
    }

    /// The axes, in configuration order.
    pub fn axes(&self) -> &[AxisConfig] {
        &self.axes
    }

    /// The clock the chain waits on.
    pub fn clock(&self) -> &C {
        &self.clock
    }

    fn index(&self, name: &str) -> Result<usize, MotionError> {
        self.axes
            .iter()
            .position(|a| a.name == name)
            .ok_or_else(|| MotionError::UnknownAxis(name.to_string()))
    }

    fn at(&self, i: usize, source: AxisError) -> MotionError {
        MotionError::AtAxis {
            axis: self.axes[i].name.clone(),
            source,
        }
    }

    /// Sends a frame; after a vanished port, reopens it first (bounded attempts).
    fn send_frame(&mut self, frame: &Frame) -> Result<(), AxisError> {
        self.buf.clear();
        frame.encode(&mut self.buf);
        match self.transport.send(&self.buf) {
            Err(TransportError::Disconnected { .. }) => {
                self.reconnect()?;
                self.transport.send(&self.buf).map_err(AxisError::from)
            }
            r => r.map_err(AxisError::from),
        }
    }

    fn reconnect(&mut self) -> Result<(), AxisError> {
        let mut last = None;
        for attempt in 0..=self.policy.reconnect_attempts {
            if attempt > 0 {
                self.clock.sleep(self.policy.reconnect_delay);
            }
            match self.transport.reconnect() {
                Ok(()) => return Ok(()),
                Err(e) => last = Some(e),
            }
        }
        Err(AxisError::Transport(last.unwrap_or(
            TransportError::Disconnected {
                port: self.transport.name(),
                reason: "no reconnection attempt allowed".into(),
            },
        )))
    }

    /// Reads lines until one answers `frame`, discarding stale replies to earlier
    /// commands (a late answer after a timeout).
    fn read_reply(&mut self, frame: &Frame) -> Result<ReplyBody, AxisError> {
        let sent = line_text(&frame.to_bytes());
        let start = self.clock.now();
        loop {
            let left = self
                .policy
                .reply_timeout
                .saturating_sub(self.clock.now().saturating_sub(start));
            let line = match self.transport.receive_line(left) {
                Ok(l) => l,
                Err(TransportError::Nul) => return Err(AxisError::ControllerReset),
                Err(e) => return Err(e.into()),
            };
            match Reply::parse(&line) {
                Ok(r) if r.answers(frame) => return Ok(r.body),
                // Another controller's or an earlier command's late answer: skip it.
                Ok(_) if self.clock.now().saturating_sub(start) < self.policy.reply_timeout => {
                    continue;
                }
                Ok(_) => {
                    return Err(AxisError::Protocol {
                        sent,
                        reply: line_text(&line),
                        reason: "answers another command".into(),
                    });
                }
                Err(e) => {
                    return Err(AxisError::Protocol {
                        sent,
                        reply: line_text(&line),
                        reason: e.to_string(),
                    });
                }
            }
        }
    }

    /// One query with its reply. Re-sent after a lost or garbled reply when `retry`.
    fn query(&mut self, i: usize, command: Command, retry: bool) -> Result<ReplyBody, AxisError> {
        let frame = Frame::addressed(self.axes[i].address, command);
        let attempts = if retry { self.policy.retries + 1 } else { 1 };
        let mut last = None;
        for attempt in 0..attempts {
            if attempt > 0 {
                self.retried += 1;
            }
            self.send_frame(&frame)?;
            match self.read_reply(&frame) {
                Ok(b) => return Ok(b),
                Err(
                    e @ (AxisError::Transport(TransportError::Timeout(_))
                    | AxisError::Transport(TransportError::LineTooLong)
                    | AxisError::Protocol { .. }),
                ) => {
                    let _ = self.transport.clear_input();
                    last = Some(e);
                }
                Err(e) => return Err(e),
            }
        }
        Err(last.unwrap_or(AxisError::Aborted))
    }

    /// A set or action command, then `TE`. An idempotent command whose `TE` answer is
    /// lost is sent again with a new `TE`; any other is [`AxisError::Ambiguous`].
    fn command(&mut self, i: usize, command: Command) -> Result<(), AxisError> {
        let frame = Frame::addressed(self.axes[i].address, command.clone());
        let attempts = if command.is_idempotent() {
            self.policy.retries + 1
        } else {
            1
        };
        let mut last = None;
        for attempt in 0..attempts {
            if attempt > 0 {
                self.retried += 1;
            }
            self.send_frame(&frame)?;
            match self.query(i, Command::TellError, false) {
                Ok(ReplyBody::Error(ErrorCode::None)) => return Ok(()),
                // The first PA was accepted and the stage is already moving (a PA in
                // MOVING is refused): fine if it is moving to this very target.
                Ok(ReplyBody::Error(ErrorCode::InMoving))
                    if attempt > 0 && self.moving_to(i, &command)? =>
                {
                    return Ok(());
                }
                Ok(ReplyBody::Error(code)) => {
                    return Err(AxisError::Controller {
                        command: line_text(&frame.to_bytes()),
                        code,
                    });
                }
                Ok(other) => {
                    return Err(AxisError::Protocol {
                        sent: format!("{}TE", self.axes[i].address),
                        reply: format!("{other:?}"),
                        reason: "not an error letter".into(),
                    });
                }
                Err(
                    e @ (AxisError::Transport(TransportError::Timeout(_))
                    | AxisError::Transport(TransportError::LineTooLong)
                    | AxisError::Protocol { .. }),
                ) => last = Some(e),
                Err(e) => return Err(e),
            }
        }
        if command.is_idempotent() {
            Err(last.unwrap_or(AxisError::Aborted))
        } else {
            Err(AxisError::Ambiguous {
                command: line_text(&frame.to_bytes()),
            })
        }
    }

    /// True when `command` is an absolute move to the target the controller holds.
    fn moving_to(&mut self, i: usize, command: &Command) -> Result<bool, AxisError> {
        let Command::MoveAbsolute(t) = command else {
            return Ok(false);
        };
        let held = self.number(i, Command::Query(Param::AbsoluteTarget))?;
        Ok((held - t).abs() <= self.axes[i].tolerance)
    }

    fn status_of(&mut self, i: usize) -> Result<Status, AxisError> {
        // A lost TS reply loses its latched error bits, but the state it re-reads is
        // current, which is what polling needs: TS is retried.
        match self.query(i, Command::TellStatus, true)? {
            ReplyBody::Status(s) => Ok(s),
            other => Err(AxisError::Protocol {
                sent: format!("{}TS", self.axes[i].address),
                reply: format!("{other:?}"),
                reason: "not a status".into(),
            }),
        }
    }

    fn number(&mut self, i: usize, command: Command) -> Result<f64, AxisError> {
        let code = command.code();
        match self.query(i, command, true)? {
            ReplyBody::Position(v)
            | ReplyBody::Setpoint(v)
            | ReplyBody::MotionTime(v)
            | ReplyBody::Value(_, v) => Ok(v),
            other => Err(AxisError::Protocol {
                sent: format!("{}{code}", self.axes[i].address),
                reply: format!("{other:?}"),
                reason: "not a number".into(),
            }),
        }
    }

    /// Status of the named axis (`TS`).
    pub fn status(&mut self, name: &str) -> Result<Status, MotionError> {
        let i = self.index(name)?;
        self.status_of(i).map_err(|e| self.at(i, e))
    }

    /// Encoder position of the named axis (`TP`), units.
    pub fn position(&mut self, name: &str) -> Result<f64, MotionError> {
        let i = self.index(name)?;
        self.number(i, Command::TellPosition)
            .map_err(|e| self.at(i, e))
    }

    /// Reads every controller's version, stage name and state (`VE`, `ID?`, `TS`):
    /// what Gonio sends at start-up. Proves each address answers.
    pub fn identify(&mut self) -> Result<Vec<ControllerInfo>, MotionError> {
        (0..self.axes.len())
            .map(|i| {
                let info = (|| -> Result<ControllerInfo, AxisError> {
                    let version = match self.query(i, Command::Version, true)? {
                        ReplyBody::Version(v) => v,
                        other => format!("{other:?}"),
                    };
                    let stage = match self.query(i, Command::Query(Param::StageId), true)? {
                        ReplyBody::StageId(s) => s,
                        other => format!("{other:?}"),
                    };
                    let state = self.status_of(i)?.state;
                    Ok(ControllerInfo {
                        version,
                        stage,
                        state,
                    })
                })();
                info.map_err(|e| self.at(i, e))
            })
            .collect()
    }

    /// Stops every stage: the broadcast `ST`, then each controller's own `ST` if the
    /// broadcast could not be sent. Errors are collected, not early-returned: every
    /// stage gets its stop.
    pub fn stop_all(&mut self) -> Result<(), MotionError> {
        if self.send_frame(&Frame::broadcast(Command::Stop)).is_ok() {
            return Ok(());
        }
        let mut first = None;
        for i in 0..self.axes.len() {
            let f = Frame::addressed(self.axes[i].address, Command::Stop);
            if let Err(e) = self.send_frame(&f) {
                first.get_or_insert(self.at(i, e));
            }
        }
        first.map_or(Ok(()), Err)
    }

    /// Stops one stage (`ST`, then `TE`).
    pub fn stop(&mut self, name: &str) -> Result<(), MotionError> {
        let i = self.index(name)?;
        self.command(i, Command::Stop).map_err(|e| self.at(i, e))
    }

    /// Fails `i` with `e` after stopping every stage.
    fn fail(&mut self, i: usize, e: AxisError) -> MotionError {
        let _ = self.stop_all();
        self.at(i, e)
    }

    /// Brings the named axes to READY with a reference: a home search (`OR`) from NOT
    /// REFERENCED, `MM1` from DISABLE, nothing when already READY; then applies the
    /// configured velocity and acceleration. Home searches run concurrently.
    pub fn home(&mut self, names: &[&str]) -> Result<(), MotionError> {
        let idx: Vec<usize> = names
            .iter()
            .map(|n| self.index(n))
            .collect::<Result<_, _>>()?;
        let mut searching = Vec::new();
        for &i in &idx {
            let s = self.status_of(i).map_err(|e| self.fail(i, e))?;
            let st = s.state;
            if st.is_not_referenced() {
                self.start_home(i)?;
                searching.push(i);
            } else if st.is_homing() {
                searching.push(i);
            } else if st.is_disabled() {
                self.command(i, Command::Enable(true))
                    .map_err(|e| self.fail(i, e))?;
            } else if st.is_configuration() || st.is_jogging() {
                return Err(self.fail(
                    i,
                    AxisError::WrongState {
                        state: st,
                        operation: "homing",
                    },
                ));
            }
        }
        let start = self.clock.now();
        while !searching.is_empty() {
            if self.abort.is_raised() {
                let i = searching[0];
                return Err(self.fail(i, AxisError::Aborted));
            }
            self.clock.sleep(self.policy.poll_interval);
            let mut still = Vec::new();
            for &i in &searching {
                let s = self.status_of(i).map_err(|e| self.fail(i, e))?;
                if s.state.is_ready() {
                    continue;
                }
                if s.state.is_homing() {
                    let limit = Duration::from_secs_f64(self.axes[i].home_timeout_s.max(0.0));
                    if self.clock.now().saturating_sub(start) > limit {
                        let _ = self.stop_all();
                        let position = self.number(i, Command::TellPosition).ok();
                        return Err(self.at(
                            i,
                            AxisError::Timeout {
                                operation: "home",
                                target: 0.0,
                                position,
                                waited: limit,
                            },
                        ));
                    }
                    still.push(i);
                    continue;
                }
                return Err(self.fail(
                    i,
                    AxisError::HomingFailed {
                        state: s.state,
                        errors: s.errors.0,
                    },
                ));
            }
            searching = still;
        }
        for &i in &idx {
            if let Some(v) = self.axes[i].velocity {
                self.command(i, Command::SetVelocity(v))
                    .map_err(|e| self.fail(i, e))?;
            }
            if let Some(a) = self.axes[i].acceleration {
                self.command(i, Command::SetAcceleration(a))
                    .map_err(|e| self.fail(i, e))?;
            }
        }
        Ok(())
    }

    /// Homes every axis.
    pub fn home_all(&mut self) -> Result<(), MotionError> {
        let names: Vec<String> = self.axes.iter().map(|a| a.name.clone()).collect();
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        self.home(&refs)
    }

    fn check_limits(&self, i: usize, target: f64) -> Result<(), AxisError> {
        let a = &self.axes[i];
        if target.is_finite() && target >= a.min && target <= a.max {
            Ok(())
        } else {
            Err(AxisError::OutOfLimits {
                target,
                min: a.min,
                max: a.max,
                units: a.units.clone(),
            })
        }
    }

    /// Moves the named axes to absolute targets, concurrently, and waits until every
    /// one is READY at its target. Every target is checked against its axis' limits
    /// before any byte is sent. Returns the positions read at the end.
    pub fn move_to(&mut self, targets: &[(&str, f64)]) -> Result<Vec<f64>, MotionError> {
        let mut moves = Vec::with_capacity(targets.len());
        for (name, t) in targets {
            let i = self.index(name)?;
            self.check_limits(i, *t).map_err(|e| self.at(i, e))?;
            moves.push((i, *t));
        }
        let mut deadline = Duration::ZERO;
        for &(i, t) in &moves {
            // The controller's own estimate of the move's duration (`PT`).
            let from = self
                .number(i, Command::TellPosition)
                .map_err(|e| self.fail(i, e))?;
            let dist = (t - from).abs();
            let est = if dist > 1e-6 {
                self.number(i, Command::MotionTime(dist))
                    .map_err(|e| self.fail(i, e))?
            } else {
                0.0
            };
            let allow = self.policy.move_margin
                + Duration::from_secs_f64((est * self.policy.move_factor).max(0.0));
            deadline = deadline.max(allow);
            self.command(i, Command::MoveAbsolute(t))
                .map_err(|e| self.fail(i, e))?;
        }
        self.wait_moves(&moves, deadline)
    }

    /// Moves one axis by `delta` from its current target (`PR`). Checked against the
    /// limits from the set-point (`TH`); never re-sent.
    pub fn move_by(&mut self, name: &str, delta: f64) -> Result<f64, MotionError> {
        let i = self.index(name)?;
        let from = self
            .number(i, Command::TellSetpoint)
            .map_err(|e| self.at(i, e))?;
        let target = from + delta;
        self.check_limits(i, target).map_err(|e| self.at(i, e))?;
        let est = self
            .number(i, Command::MotionTime(delta.abs().max(1e-6)))
            .map_err(|e| self.fail(i, e))?;
        let allow = self.policy.move_margin
            + Duration::from_secs_f64((est * self.policy.move_factor).max(0.0));
        self.command(i, Command::MoveRelative(delta))
            .map_err(|e| self.fail(i, e))?;
        Ok(self.wait_moves(&[(i, target)], allow)?[0])
    }

    fn wait_moves(
        &mut self,
        moves: &[(usize, f64)],
        allow: Duration,
    ) -> Result<Vec<f64>, MotionError> {
        let start = self.clock.now();
        let mut moving: Vec<usize> = (0..moves.len()).collect();
        while !moving.is_empty() {
            if self.abort.is_raised() {
                let i = moves[moving[0]].0;
                return Err(self.fail(i, AxisError::Aborted));
            }
            self.clock.sleep(self.policy.poll_interval);
            let mut still = Vec::new();
            for &k in &moving {
                let (i, target) = moves[k];
                let s = self.status_of(i).map_err(|e| self.fail(i, e))?;
                match s.state {
                    st if st.is_ready() => {}
                    st if st.is_moving() => {
                        if self.clock.now().saturating_sub(start) > allow {
                            let _ = self.stop_all();
                            let position = self.number(i, Command::TellPosition).ok();
                            return Err(self.at(
                                i,
                                AxisError::Timeout {
                                    operation: "move",
                                    target,
                                    position,
                                    waited: allow,
                                },
                            ));
                        }
                        still.push(k);
                    }
                    ControllerState::NotReferencedFromReset => {
                        return Err(self.fail(i, AxisError::ControllerReset));
                    }
                    st if st.is_not_referenced() => {
                        return Err(self.fail(i, AxisError::NotReferenced { state: st }));
                    }
                    st if st.is_disabled() => {
                        return Err(self.fail(
                            i,
                            AxisError::Disabled {
                                state: st,
                                errors: s.errors.0,
                            },
                        ));
                    }
                    st => {
                        return Err(self.fail(
                            i,
                            AxisError::WrongState {
                                state: st,
                                operation: "moving",
                            },
                        ));
                    }
                }
            }
            moving = still;
        }
        let mut out = Vec::with_capacity(moves.len());
        for &(i, target) in moves {
            let p = self
                .number(i, Command::TellPosition)
                .map_err(|e| self.fail(i, e))?;
            let tol = self.axes[i].tolerance;
            if (p - target).abs() > tol {
                return Err(self.at(
                    i,
                    AxisError::TargetNotReached {
                        target,
                        position: p,
                        tolerance: tol,
                    },
                ));
            }
            out.push(p);
        }
        Ok(out)
    }

    /// Sends `OR` to a NOT REFERENCED controller. `OR` must not be re-sent blindly,
    /// but a lost acknowledgement is not a lost command: the state tells which. HOMING
    /// (or READY) means it ran; still NOT REFERENCED means it never arrived, and it is
    /// sent again (up to `retries` times).
    fn start_home(&mut self, i: usize) -> Result<(), MotionError> {
        for _ in 0..=self.policy.retries {
            match self.command(i, Command::Home) {
                Ok(()) => return Ok(()),
                Err(AxisError::Ambiguous { .. }) => {
                    self.retried += 1;
                    let s = self.status_of(i).map_err(|e| self.fail(i, e))?;
                    if s.state.is_homing() || s.state.is_ready() {
                        return Ok(());
                    }
                    if !s.state.is_not_referenced() {
                        return Err(self.fail(
                            i,
                            AxisError::HomingFailed {
                                state: s.state,
                                errors: s.errors.0,
                            },
                        ));
                    }
                }
                Err(e) => return Err(self.fail(i, e)),
            }
        }
        let command = line_text(&Frame::addressed(self.axes[i].address, Command::Home).to_bytes());
        Err(self.fail(i, AxisError::Ambiguous { command }))
    }

    /// Resets the named controller (`RS`), waits for it to come back NOT REFERENCED
    /// from reset (power-up takes < 5 s), and homes it: the recovery after
    /// [`AxisError::ControllerReset`] or a fault that only a reset clears.
    pub fn reset_and_home(&mut self, name: &str) -> Result<(), MotionError> {
        let i = self.index(name)?;
        let frame = Frame::addressed(self.axes[i].address, Command::Reset);
        self.send_frame(&frame).map_err(|e| self.at(i, e))?;
        let start = self.clock.now();
        let boot = Duration::from_secs(10);
        loop {
            self.clock.sleep(Duration::from_millis(500));
            match self.status_of(i) {
                Ok(s) if s.state.is_not_referenced() => break,
                Ok(_) | Err(AxisError::Transport(TransportError::Timeout(_))) => {}
                Err(e) => return Err(self.at(i, e)),
            }
            if self.clock.now().saturating_sub(start) > boot {
                return Err(self.at(i, AxisError::Transport(TransportError::Timeout(boot))));
            }
        }
        self.home(&[name])
    }
}

impl<T: Transport, C: Clock> Drop for Smc100Chain<T, C> {
    fn drop(&mut self) {
        // A chain going away must not leave a stage moving.
        let _ = self.stop_all();
    }
}
