//! The chain's operations as the manual's procedures, each an `async fn` the engine
//! runs: identify, one-axis queries and stops, homing (after a reset, optionally),
//! moves, and the configuration (`ZT`; `PW1`, the sets, `PW0`).

use std::time::Duration;

use tracing::{debug, warn};

use super::{Smc100Session, line_text};
use crate::TransportError;
use crate::engine::motion::{self, Motion};
use crate::engine::{Link, secs};
use crate::smc100::{
    AxisError, Command, ControllerInfo, ControllerState, ErrorCode, MotionError, Param, ReplyBody,
    Status,
};
use crate::smc100::{Halt, stop};

/// Pause between status polls while a reset controller boots.
const BOOT_POLL: Duration = Duration::from_millis(500);
/// Longest a reset controller may stay silent or busy.
const BOOT_LIMIT: Duration = Duration::from_secs(10);
/// Pause between status polls while the controller saves its configuration.
const SAVE_POLL: Duration = Duration::from_millis(500);
/// Longest a save may keep the controller silent: the manual's "up to 10 s" for `PW0`,
/// and a margin.
const SAVE_LIMIT: Duration = Duration::from_secs(15);

/// The text of a reply expected to be text; another reply is kept as its debug form.
fn text(body: ReplyBody) -> String {
    match body {
        ReplyBody::Version(v) | ReplyBody::StageId(v) => v,
        other => format!("{other:?}"),
    }
}

impl Smc100Session {
    /// `TS` of axis `i`.
    pub(super) async fn read_status(&mut self, link: &Link, i: usize) -> Result<Status, AxisError> {
        let r = self.query(link, i, Command::TellStatus).await;
        self.status(i, r)
    }

    /// `command`'s reply read as a number (`TP`, `TH`, `PT`, `xxAA?`).
    pub(super) async fn read_number(
        &mut self,
        link: &Link,
        i: usize,
        command: Command,
    ) -> Result<f64, AxisError> {
        let code = command.code();
        match self.query(link, i, command).await? {
            ReplyBody::Position(v)
            | ReplyBody::Setpoint(v)
            | ReplyBody::MotionTime(v)
            | ReplyBody::Value(_, v) => Ok(v),
            other => Err(self.unexpected(i, code, other, "not a number")),
        }
    }

    /// `op` on the named axis, its failure reported at that axis.
    pub(super) async fn on<T>(
        &mut self,
        name: &str,
        op: impl AsyncFnOnce(&mut Self, usize) -> Result<T, AxisError>,
    ) -> Result<T, MotionError> {
        let i = self.index(name)?;
        let r = op(self, i).await;
        r.map_err(|e| self.at(i, e))
    }

    /// `VE`, `ID?` and `TS` of every controller, in order; the first failure ends it.
    pub(super) async fn identify(
        &mut self,
        link: &Link,
    ) -> Result<Vec<ControllerInfo>, MotionError> {
        let mut infos = Vec::new();
        for a in self.axes.clone() {
            let info = self.on(&a.name, async |s, i| {
                let version = text(s.query(link, i, Command::Version).await?);
                let stage = text(s.query(link, i, Command::Query(Param::StageId)).await?);
                let state = s.read_status(link, i).await?.state;
                debug!(axis = %a.name, %version, %stage, %state, "smc100: controller identified");
                Ok(ControllerInfo {
                    version,
                    stage,
                    state,
                })
            });
            infos.push(info.await?);
        }
        Ok(infos)
    }

    /// Polls `TS` of a controller that is silent while busy (booting after `RS`, saving
    /// after `PW0`) every `pause`, asking again after silence up to `retries` times,
    /// until `done` says how it ended; silence or `None` waits on, for at most `limit`.
    async fn await_state(
        &mut self,
        link: &Link,
        i: usize,
        (pause, limit, retries): (Duration, Duration, usize),
        done: impl Fn(&Self, Status) -> Option<Result<(), AxisError>>,
    ) -> Result<(), AxisError> {
        let start = link.now();
        loop {
            link.sleep(link.now().saturating_add(pause)).await;
            let r = self.query_with(link, i, Command::TellStatus, retries).await;
            match self.status(i, r) {
                Ok(status) => {
                    if let Some(end) = done(self, status) {
                        return end;
                    }
                }
                Err(AxisError::Transport(TransportError::Timeout(_))) => {}
                Err(e) => return Err(e),
            }
            if link.now().saturating_sub(start) > limit {
                return Err(AxisError::Transport(TransportError::Timeout(limit)));
            }
        }
    }

    /// A command whose acknowledgement was lost and that must not be sent blindly
    /// again (`OR`, `PW1`): counted as a retry, and the state read to tell whether it
    /// ran.
    async fn unacknowledged(
        &mut self,
        link: &Link,
        i: usize,
        command: &str,
    ) -> Result<Status, AxisError> {
        self.retried += 1;
        warn!(axis = %self.axes[i].name, command, "smc100: unacknowledged; reading the state");
        self.read_status(link, i).await
    }

    /// Brings `names` to READY with a reference: (with `reset`, `RS` to the first and
    /// its boot awaited;) each state read, and a home search started (`OR`) from NOT
    /// REFERENCED or the motor enabled (`MM1`) from DISABLE; the searches polled until
    /// READY; the configured velocity and acceleration set.
    pub(super) async fn home(
        &mut self,
        link: &Link,
        names: &[String],
        reset: bool,
    ) -> Result<(), Halt> {
        let idx = names
            .iter()
            .map(|n| self.index(n))
            .collect::<Result<Vec<_>, _>>()?;
        if let (true, Some(&i)) = (reset, idx.first()) {
            let r = self.reboot(link, i).await;
            r.map_err(|e| self.at(i, e))?;
        }
        let mut searching = Vec::new();
        for &i in &idx {
            let state = self.read_status(link, i).await.map_err(stop(i))?.state;
            if state.is_not_referenced() {
                self.start_search(link, i).await.map_err(stop(i))?;
                searching.push((i, 0.0));
            } else if state.is_homing() {
                searching.push((i, 0.0));
            } else if state.is_disabled() {
                self.command(link, i, Command::Enable(true))
                    .await
                    .map_err(stop(i))?;
                debug!(axis = %self.axes[i].name, "smc100: motor enabled (MM1)");
            } else if state.is_configuration() || state.is_jogging() {
                let operation = "homing";
                return Err(Halt::Stop(i, AxisError::WrongState { state, operation }));
            }
        }
        motion::poll(self, link, searching, "home", |s, i, _, st, elapsed| {
            let (state, errors) = (st.state, st.errors.0);
            if state.is_ready() {
                debug!(axis = %s.axes[i].name, %state, "smc100: stage READY");
                return Ok(false);
            }
            if !state.is_homing() {
                return Err(Halt::Stop(i, AxisError::HomingFailed { state, errors }));
            }
            let limit = secs(s.axes[i].home_timeout_s);
            if elapsed > limit {
                return Err(Halt::Overdue(i, "home", 0.0, limit));
            }
            Ok(true)
        })
        .await?;
        for &i in &idx {
            let a = &self.axes[i];
            let sets = [
                a.velocity.map(Command::SetVelocity),
                a.acceleration.map(Command::SetAcceleration),
            ];
            for set in sets.into_iter().flatten() {
                self.command(link, i, set).await.map_err(stop(i))?;
            }
        }
        Ok(())
    }

    /// `RS`, then `TS` every 500 ms until the controller is back NOT REFERENCED (it
    /// boots in under 5 s; 10 s are allowed).
    async fn reboot(&mut self, link: &Link, i: usize) -> Result<(), AxisError> {
        self.send(link, i, Command::Reset).await?;
        debug!(axis = %self.axes[i].name, "smc100: controller reset; waiting for it to boot");
        let retries = self.policy.retries;
        self.await_state(link, i, (BOOT_POLL, BOOT_LIMIT, retries), |s, st| {
            let booted = st.state.is_not_referenced();
            booted.then(|| {
                debug!(axis = %s.axes[i].name, state = %st.state, "smc100: controller booted");
                Ok(())
            })
        })
        .await
    }

    /// `OR`. A lost acknowledgement is not a lost command, and the state tells which:
    /// HOMING (or READY) means it ran; still NOT REFERENCED that it never arrived, and
    /// it is sent again (up to `retries` times).
    async fn start_search(&mut self, link: &Link, i: usize) -> Result<(), AxisError> {
        let mut tries = 0;
        loop {
            let lost = match self.command(link, i, Command::Home).await {
                Ok(()) => break,
                Err(lost @ AxisError::Ambiguous { .. }) => lost,
                Err(e) => return Err(e),
            };
            let st = self.unacknowledged(link, i, "OR").await?;
            if st.state.is_homing() || st.state.is_ready() {
                break;
            }
            if !st.state.is_not_referenced() {
                let (state, errors) = (st.state, st.errors.0);
                return Err(AxisError::HomingFailed { state, errors });
            }
            tries += 1;
            if tries > self.policy.retries {
                return Err(lost);
            }
        }
        debug!(axis = %self.axes[i].name, "smc100: home search started");
        Ok(())
    }

    /// Absolute moves to `targets`, all checked against the limits before any byte;
    /// for each axis in turn its position (`TP`), the controller's estimate of the
    /// move (`PT`) and the move (`PA`, checked with `TE`); then the wait.
    pub(super) async fn move_to(
        &mut self,
        link: &Link,
        targets: &[(String, f64)],
    ) -> Result<Vec<f64>, Halt> {
        let mut moves = Vec::new();
        for (name, target) in targets {
            let i = self.index(name)?;
            self.check_limits(i, *target).map_err(|e| self.at(i, e))?;
            moves.push((i, *target));
        }
        let mut allow = Duration::ZERO;
        for &(i, target) in &moves {
            let tp = Command::TellPosition;
            let from = self.read_number(link, i, tp).await.map_err(stop(i))?;
            let distance = (target - from).abs();
            let estimate = if distance > 1e-6 {
                self.estimate(link, i, distance).await?
            } else {
                0.0
            };
            allow = allow.max(self.policy.allowance(estimate));
            self.command(link, i, Command::MoveAbsolute(target))
                .await
                .map_err(stop(i))?;
            debug!(axis = %self.axes[i].name, target, "smc100: move started");
        }
        self.await_moves(link, moves, allow).await
    }

    /// A move of `name` by `delta` from its set-point (`TH`), the target checked
    /// against the limits; `PT`, `PR` (never re-sent), then the wait.
    pub(super) async fn move_by(
        &mut self,
        link: &Link,
        name: &str,
        delta: f64,
    ) -> Result<f64, Halt> {
        let i = self.index(name)?;
        let from = self.read_number(link, i, Command::TellSetpoint).await;
        let target = from.map_err(|e| self.at(i, e))? + delta;
        self.check_limits(i, target).map_err(|e| self.at(i, e))?;
        let estimate = self.estimate(link, i, delta.abs().max(1e-6)).await?;
        let allow = self.policy.allowance(estimate);
        self.command(link, i, Command::MoveRelative(delta))
            .await
            .map_err(stop(i))?;
        debug!(axis = %self.axes[i].name, target, "smc100: relative move started");
        Ok(self.await_moves(link, vec![(i, target)], allow).await?[0])
    }

    /// `PT`: how long the controller says a move of `distance` takes. A controller
    /// refuses what its state does not allow silently, storing the state's letter for
    /// `TE` (manual §5.3), and `PT` only runs in DISABLE, READY and MOVING (§5.5
    /// table): a refused `PT` is a query that never answers. So when every attempt
    /// went unanswered `TE` is read once, to tell a refusal (typed, naming the `PT`)
    /// from a lost link (the timeout). Either way the move ends.
    async fn estimate(&mut self, link: &Link, i: usize, distance: f64) -> Result<f64, Halt> {
        let pt = Command::MotionTime(distance);
        let silence = match self.read_number(link, i, pt.clone()).await {
            Ok(estimate) => return Ok(estimate),
            Err(e @ AxisError::Transport(TransportError::Timeout(_))) => e,
            Err(e) => return Err(Halt::Stop(i, e)),
        };
        match self.query_with(link, i, Command::TellError, 0).await {
            Ok(ReplyBody::Error(code)) if code != ErrorCode::None => {
                let command = line_text(&self.frame(i, pt).to_bytes());
                warn!(%command, %code, "smc100: PT refused; the state does not allow a move");
                Err(Halt::Stop(i, AxisError::Controller { command, code }))
            }
            _ => Err(Halt::Stop(i, silence)),
        }
    }

    /// Polls the moving axes until READY, within `allow` from now; then reads every
    /// position and checks it against its target.
    async fn await_moves(
        &mut self,
        link: &Link,
        moves: Vec<(usize, f64)>,
        allow: Duration,
    ) -> Result<Vec<f64>, Halt> {
        self.stopped = None;
        motion::poll(
            self,
            link,
            moves.clone(),
            "move",
            |s, i, target, st, elapsed| {
                let state = st.state;
                let e = if state.is_ready() {
                    debug!(axis = %s.axes[i].name, %state, "smc100: stage READY");
                    return Ok(false);
                } else if state.is_moving() {
                    if elapsed > allow {
                        return Err(Halt::Overdue(i, "move", target, allow));
                    }
                    return Ok(true);
                } else if state == ControllerState::NotReferencedFromReset {
                    AxisError::ControllerReset
                } else if state.is_not_referenced() {
                    AxisError::NotReferenced { state }
                } else if state.is_disabled() {
                    let errors = st.errors.0;
                    AxisError::Disabled { state, errors }
                } else {
                    let operation = "moving";
                    AxisError::WrongState { state, operation }
                };
                Err(Halt::Stop(i, e))
            },
        )
        .await?;
        self.stopped = Some(link.now());
        let mut positions = Vec::new();
        for (i, target) in moves {
            let tp = Command::TellPosition;
            let position = self.read_number(link, i, tp).await.map_err(stop(i))?;
            let tolerance = self.axes[i].tolerance;
            if (position - target).abs() > tolerance {
                let e = AxisError::TargetNotReached {
                    target,
                    position,
                    tolerance,
                };
                return Err(self.at(i, e).into());
            }
            positions.push(position);
        }
        Ok(positions)
    }

    /// Changes and saves axis `i`'s configuration (manual, PW command): every change
    /// checked before any byte; the state (`TS`): NOT REFERENCED → `PW1`,
    /// CONFIGURATION → straight on, anything else refused; each set, checked with
    /// `TE`; `PW0`, sent without `TE` since the controller is silent while it saves;
    /// `TS` every 500 ms, each asked once (the silence is expected), until NOT
    /// REFERENCED; `TE` for the save's own error (`U`, EEPROM).
    pub(super) async fn configure(
        &mut self,
        link: &Link,
        i: usize,
        changes: &[(Param, f64)],
    ) -> Result<(), AxisError> {
        for &(p, value) in changes {
            let reason = if !p.is_configuration() {
                "not a configuration parameter"
            } else if !p.accepts(value) {
                "outside the manual's range"
            } else {
                continue;
            };
            let code = p.code();
            return Err(AxisError::InvalidSetting {
                code,
                value,
                reason,
            });
        }
        let state = self.read_status(link, i).await?.state;
        if state.is_configuration() {
            debug!(axis = %self.axes[i].name, "smc100: already in CONFIGURATION");
        } else if !state.is_not_referenced() {
            // The manual allows PW1 only from NOT REFERENCED; getting there from READY
            // or DISABLE takes `RS`, which loses the reference: the caller's decision.
            let operation = "configuration (PW1 needs NOT REFERENCED: reset the controller first)";
            return Err(AxisError::WrongState { state, operation });
        } else {
            match self
                .command(link, i, Command::ConfigurationMode(true))
                .await
            {
                Ok(()) => debug!(axis = %self.axes[i].name, "smc100: in CONFIGURATION (PW1)"),
                // `PW1` must not be re-sent blindly; the state tells whether it ran.
                Err(lost @ AxisError::Ambiguous { .. }) => {
                    let st = self.unacknowledged(link, i, "PW1").await?;
                    if !st.state.is_configuration() {
                        return Err(lost);
                    }
                }
                Err(e) => return Err(e),
            }
        }
        let mut refused = None;
        for &(p, value) in changes {
            if let Err(e) = self.command(link, i, Command::set(p, value)).await {
                // Only `PW0` leaves CONFIGURATION (`RS` is refused there): leave, so the
                // controller is usable, then report. The sets before this one are saved.
                warn!(error = %e, "smc100: configuration refused; leaving CONFIGURATION");
                refused = Some(e);
                break;
            }
        }
        let pw0 = Command::ConfigurationMode(false);
        self.send(link, i, pw0.clone()).await?;
        debug!(axis = %self.axes[i].name, "smc100: PW0 sent; the controller saves");
        self.await_state(link, i, (SAVE_POLL, SAVE_LIMIT, 0), |s, st| {
            let state = st.state;
            if state.is_not_referenced() {
                debug!(axis = %s.axes[i].name, %state, "smc100: configuration saved");
                Some(Ok(()))
            } else if state.is_configuration() {
                None
            } else {
                let operation = "saving the configuration";
                Some(Err(AxisError::WrongState { state, operation }))
            }
        })
        .await?;
        let te = self.query(link, i, Command::TellError).await;
        if let Some(e) = refused {
            return Err(e);
        }
        match te? {
            ReplyBody::Error(ErrorCode::None) => Ok(()),
            ReplyBody::Error(code) => Err(AxisError::Controller {
                command: line_text(&self.frame(i, pw0).to_bytes()),
                code,
            }),
            other => Err(self.unexpected(i, "TE", other, "not an error letter")),
        }
    }
}

impl Motion for Smc100Session {
    const FAMILY: &'static str = "smc100";
    type Status = Status;
    type AxisError = AxisError;
    type Error = MotionError;

    fn poll_interval(&self) -> Duration {
        self.policy.poll_interval
    }

    fn axis_name(&self, i: usize) -> &str {
        &self.axes[i].name
    }

    fn at(&self, i: usize, e: AxisError) -> MotionError {
        Smc100Session::at(self, i, e)
    }

    async fn poll_status(&mut self, link: &Link, i: usize) -> Result<Status, AxisError> {
        self.read_status(link, i).await
    }

    async fn stop_every(&mut self, link: &Link) -> Result<(), MotionError> {
        self.stop_all(link).await
    }

    async fn position_of(&mut self, link: &Link, i: usize) -> Option<f64> {
        self.read_number(link, i, Command::TellPosition).await.ok()
    }
}
