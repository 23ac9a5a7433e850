//! Moves: absolute moves of several axes at once, or a relative move of one, each
//! waited for by polling `TS` until READY, within a deadline from the controller's own
//! estimate (`PT`).

use std::mem;
use std::time::Duration;

use tracing::{debug, warn};

use super::script::{Aborted, Next, Op, Overdue};
use super::{Smc100Session, line_text};
use crate::TransportError;
use crate::machine::{Cx, secs};
use crate::smc100::{AxisError, Command, ControllerState, ErrorCode, ReplyBody};

/// What was asked.
#[derive(Debug)]
enum Request {
    /// Absolute targets by axis name.
    To(Vec<(String, f64)>),
    /// A displacement of one axis from its set-point.
    By(String, f64),
}

/// A move. Phases: targets checked against the limits before any byte; for each
/// axis, its position (`TP`, or the set-point `TH` for a relative move), the
/// controller's estimate of the move's duration (`PT`) and the move itself (`PA` or
/// `PR`, checked with `TE`); then polling every moving axis until READY; then every
/// position read and checked against its target.
///
/// A controller refuses what its state does not allow, silently, and stores the
/// state's letter for `TE` (manual §5.3, TE p. 59): `PA` and `PR` only in READY (PA
/// page, p. 41), `PT` only in DISABLE, READY and MOVING (§5.5 table). A refused `PA`
/// or `PR` shows in its `TE`; a refused `PT` is a query that never answers, so when
/// every attempt went unanswered `TE` is read once to tell a refusal (a typed
/// [`AxisError::Controller`] naming the `PT`) from a lost link (the timeout). Either
/// way every stage is stopped and the move ends.
#[derive(Debug)]
pub(super) struct Motion<T> {
    request: Request,
    /// (axis, target) of each move.
    moves: Vec<(usize, f64)>,
    /// Position in `moves` while starting moves and reading final positions.
    k: usize,
    /// How long the moves may take.
    allow: Duration,
    /// When the wait began.
    start: Duration,
    /// Positions in `moves` of the axes still moving, and those still moving after
    /// this round.
    moving: Vec<usize>,
    still: Vec<usize>,
    /// Position in `moving` during a poll round.
    j: usize,
    /// Final positions.
    out: Vec<f64>,
    /// The `PT` last sent.
    pt: Command,
    /// The timeout a `PT` ended with, kept while `TE` says whether the controller
    /// refused it.
    silence: Option<AxisError>,
    finish: fn(Vec<f64>) -> T,
}

impl<T> Motion<T> {
    fn new(request: Request, finish: fn(Vec<f64>) -> T) -> Self {
        Motion {
            request,
            moves: Vec::new(),
            k: 0,
            allow: Duration::ZERO,
            start: Duration::ZERO,
            moving: Vec::new(),
            still: Vec::new(),
            j: 0,
            out: Vec::new(),
            pt: Command::MotionTime(0.0),
            silence: None,
            finish,
        }
    }
}

impl Motion<Vec<f64>> {
    /// Absolute moves to `targets`; the output is every final position.
    pub(super) fn to(targets: &[(&str, f64)]) -> Self {
        let targets = targets.iter().map(|(n, t)| (n.to_string(), *t)).collect();
        Motion::new(Request::To(targets), |positions| positions)
    }
}

impl Motion<f64> {
    /// A relative move of `name` by `delta`; the output is its final position.
    pub(super) fn by(name: &str, delta: f64) -> Self {
        // One move in, one position out.
        Motion::new(Request::By(name.to_string(), delta), |positions| {
            positions[0]
        })
    }
}

/// How long a move may take: the margin plus the factor times the controller's
/// estimate.
fn allowance(s: &Smc100Session, estimate: f64) -> Duration {
    let p = &s.policy;
    p.move_margin.saturating_add(secs(estimate * p.move_factor))
}

impl<T> Op for Motion<T> {
    type Value = T;

    fn start(&mut self, s: &mut Smc100Session, cx: &mut Cx) -> Next<Self> {
        match &self.request {
            Request::To(targets) => {
                for (name, t) in targets {
                    let i = match s.index(name) {
                        Ok(i) => i,
                        Err(e) => return Next::Done(Err(e)),
                    };
                    if let Err(e) = s.check_limits(i, *t) {
                        return Next::Done(Err(s.at(i, e)));
                    }
                    self.moves.push((i, *t));
                }
                self.next_move(s, cx)
            }
            Request::By(name, _) => match s.index(name) {
                Ok(i) => {
                    self.moves.push((i, f64::NAN));
                    Next::query(i, Command::TellSetpoint, Self::got_setpoint)
                }
                Err(e) => Next::Done(Err(e)),
            },
        }
    }
}

impl<T> Motion<T> {
    // --- absolute moves: position, estimate, PA, for each axis in turn ---

    fn next_move(&mut self, s: &Smc100Session, cx: &Cx) -> Next<Self> {
        match self.moves.get(self.k) {
            Some(&(i, _)) => Next::query(i, Command::TellPosition, Self::got_from),
            None => self.begin_wait(s, cx),
        }
    }

    fn got_from(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let (i, t) = self.moves[self.k];
        let from = match s.number(i, "TP", r) {
            Ok(v) => v,
            Err(e) => return Next::fail(i, e),
        };
        let dist = (t - from).abs();
        if dist > 1e-6 {
            self.pt = Command::MotionTime(dist);
            Next::query(i, self.pt.clone(), Self::got_estimate)
        } else {
            self.move_with_estimate(s, 0.0)
        }
    }

    fn got_estimate(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let i = self.moves[self.k].0;
        match s.number(i, "PT", r) {
            Ok(est) => self.move_with_estimate(s, est),
            Err(e) => self.explain_silence(i, e),
        }
    }

    /// `PT` failed with `e`. A silence may be a refusal (see [`Motion`]): ask `TE`
    /// once; any other failure ends the move.
    fn explain_silence(&mut self, i: usize, e: AxisError) -> Next<Self> {
        if !matches!(e, AxisError::Transport(TransportError::Timeout(_))) {
            return Next::fail(i, e);
        }
        self.silence = Some(e);
        Next::Probe {
            axis: i,
            command: Command::TellError,
            then: Self::explained,
        }
    }

    /// `TE` after an unanswered `PT`: a letter is the refusal, `@` (or no answer)
    /// leaves the timeout as the error. Both end the move, stopping every stage.
    fn explained(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let i = self.moves[self.k].0;
        let silence = self
            .silence
            .take()
            .unwrap_or(AxisError::Transport(TransportError::Timeout(
                s.policy.reply_timeout,
            )));
        match r {
            Ok(ReplyBody::Error(code)) if code != ErrorCode::None => {
                let command = line_text(&s.frame(i, self.pt.clone()).to_bytes());
                warn!(%command, %code, "smc100: PT refused; the state does not allow a move");
                Next::fail(i, AxisError::Controller { command, code })
            }
            _ => Next::fail(i, silence),
        }
    }

    fn move_with_estimate(&mut self, s: &Smc100Session, est: f64) -> Next<Self> {
        let (i, t) = self.moves[self.k];
        self.allow = self.allow.max(allowance(s, est));
        Next::command(i, Command::MoveAbsolute(t), Self::moved)
    }

    fn moved(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        r: Result<(), AxisError>,
    ) -> Next<Self> {
        let (i, t) = self.moves[self.k];
        if let Err(e) = r {
            return Next::fail(i, e);
        }
        debug!(axis = %s.axes[i].name, target = t, "smc100: move started");
        self.k += 1;
        self.next_move(s, cx)
    }

    // --- a relative move: set-point, limits, estimate, PR ---

    fn delta(&self) -> f64 {
        match self.request {
            Request::By(_, delta) => delta,
            Request::To(_) => 0.0,
        }
    }

    fn got_setpoint(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let i = self.moves[0].0;
        let from = match s.number(i, "TH", r) {
            Ok(v) => v,
            Err(e) => return Next::Done(Err(s.at(i, e))),
        };
        let delta = self.delta();
        let target = from + delta;
        if let Err(e) = s.check_limits(i, target) {
            return Next::Done(Err(s.at(i, e)));
        }
        self.moves[0].1 = target;
        self.pt = Command::MotionTime(delta.abs().max(1e-6));
        Next::query(i, self.pt.clone(), Self::got_relative_estimate)
    }

    fn got_relative_estimate(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let i = self.moves[0].0;
        match s.number(i, "PT", r) {
            Ok(est) => {
                self.allow = allowance(s, est);
                let pr = Command::MoveRelative(self.delta());
                Next::command(i, pr, Self::moved_relative)
            }
            Err(e) => self.explain_silence(i, e),
        }
    }

    fn moved_relative(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        r: Result<(), AxisError>,
    ) -> Next<Self> {
        let (i, t) = self.moves[0];
        if let Err(e) = r {
            return Next::fail(i, e);
        }
        debug!(axis = %s.axes[i].name, target = t, "smc100: relative move started");
        self.begin_wait(s, cx)
    }

    // --- polling every moving axis until READY ---

    fn begin_wait(&mut self, s: &Smc100Session, cx: &Cx) -> Next<Self> {
        self.start = cx.now;
        self.moving = (0..self.moves.len()).collect();
        self.wait_round(s, cx)
    }

    fn wait_round(&mut self, s: &Smc100Session, cx: &Cx) -> Next<Self> {
        if self.moving.is_empty() {
            self.k = 0;
            return self.read_final();
        }
        Next::Pause {
            until: cx.now.saturating_add(s.policy.poll_interval),
            abortable: true,
            then: Self::waited,
        }
    }

    fn waited(&mut self, s: &mut Smc100Session, cx: &mut Cx, r: Result<(), Aborted>) -> Next<Self> {
        if r.is_err() {
            warn!("smc100: move aborted");
            return Next::fail(self.moves[self.moving[0]].0, AxisError::Aborted);
        }
        self.j = 0;
        self.still.clear();
        self.wait_next(s, cx)
    }

    fn wait_next(&mut self, s: &Smc100Session, cx: &Cx) -> Next<Self> {
        match self.moving.get(self.j) {
            Some(&m) => Next::query(self.moves[m].0, Command::TellStatus, Self::wait_status),
            None => {
                self.moving = mem::take(&mut self.still);
                self.wait_round(s, cx)
            }
        }
    }

    fn wait_status(
        &mut self,
        s: &mut Smc100Session,
        cx: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let m = self.moving[self.j];
        let (i, target) = self.moves[m];
        let st = match s.status(i, r) {
            Ok(st) => st,
            Err(e) => return Next::fail(i, e),
        };
        let state = st.state;
        if state.is_ready() {
            debug!(axis = %s.axes[i].name, %state, "smc100: stage READY");
        } else if state.is_moving() {
            if cx.now.saturating_sub(self.start) > self.allow {
                return Next::Overdue(Overdue {
                    axis: i,
                    operation: "move",
                    target,
                    waited: self.allow,
                });
            }
            self.still.push(m);
        } else if state == ControllerState::NotReferencedFromReset {
            return Next::fail(i, AxisError::ControllerReset);
        } else if state.is_not_referenced() {
            return Next::fail(i, AxisError::NotReferenced { state });
        } else if state.is_disabled() {
            let errors = st.errors.0;
            return Next::fail(i, AxisError::Disabled { state, errors });
        } else {
            let operation = "moving";
            return Next::fail(i, AxisError::WrongState { state, operation });
        }
        self.j += 1;
        self.wait_next(s, cx)
    }

    // --- final positions, each checked against its target ---

    fn read_final(&mut self) -> Next<Self> {
        match self.moves.get(self.k) {
            Some(&(i, _)) => Next::query(i, Command::TellPosition, Self::got_final),
            None => Next::Done(Ok((self.finish)(mem::take(&mut self.out)))),
        }
    }

    fn got_final(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let (i, target) = self.moves[self.k];
        let position = match s.number(i, "TP", r) {
            Ok(v) => v,
            Err(e) => return Next::fail(i, e),
        };
        let tolerance = s.axes[i].tolerance;
        if (position - target).abs() > tolerance {
            let e = AxisError::TargetNotReached {
                target,
                position,
                tolerance,
            };
            return Next::Done(Err(s.at(i, e)));
        }
        self.out.push(position);
        self.k += 1;
        self.read_final()
    }
}
