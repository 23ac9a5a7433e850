//! The chain's one-exchange operations: identify, status, position and stops.

use std::mem;

use super::Smc100Session;
use super::script::{Next, Op};
use crate::machine::Cx;
use crate::smc100::{AxisError, Command, ControllerInfo, MotionError, Param, ReplyBody, Status};

/// `VE`, `ID?` and `TS` of every controller, in order; the first failure ends it.
#[derive(Debug, Default)]
pub(super) struct Identify {
    axis: usize,
    version: String,
    stage: String,
    infos: Vec<ControllerInfo>,
}

impl Op for Identify {
    type Value = Vec<ControllerInfo>;

    fn start(&mut self, s: &mut Smc100Session, _: &mut Cx) -> Next<Self> {
        self.ask_version(s)
    }
}

/// The text of a reply expected to be text; another reply is kept as its debug form.
fn text(body: ReplyBody) -> String {
    match body {
        ReplyBody::Version(v) | ReplyBody::StageId(v) => v,
        other => format!("{other:?}"),
    }
}

impl Identify {
    fn ask_version(&mut self, s: &Smc100Session) -> Next<Self> {
        if self.axis >= s.axes.len() {
            return Next::Done(Ok(mem::take(&mut self.infos)));
        }
        Next::query(self.axis, Command::Version, Self::got_version)
    }

    fn got_version(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        match r {
            Ok(body) => self.version = text(body),
            Err(e) => return Next::Done(Err(s.at(self.axis, e))),
        }
        Next::query(self.axis, Command::Query(Param::StageId), Self::got_stage)
    }

    fn got_stage(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        match r {
            Ok(body) => self.stage = text(body),
            Err(e) => return Next::Done(Err(s.at(self.axis, e))),
        }
        Next::query(self.axis, Command::TellStatus, Self::got_status)
    }

    fn got_status(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        match s.status(self.axis, r) {
            Ok(status) => {
                tracing::debug!(
                    axis = %s.axes[self.axis].name,
                    version = %self.version,
                    stage = %self.stage,
                    state = %status.state,
                    "smc100: controller identified"
                );
                self.infos.push(ControllerInfo {
                    version: mem::take(&mut self.version),
                    stage: mem::take(&mut self.stage),
                    state: status.state,
                });
                self.axis += 1;
                self.ask_version(s)
            }
            Err(e) => Next::Done(Err(s.at(self.axis, e))),
        }
    }
}

/// One axis by name, resolved when the operation starts.
#[derive(Debug)]
pub(super) struct Named {
    name: String,
    pub(super) axis: usize,
}

impl Named {
    pub(super) fn new(name: &str) -> Self {
        Named {
            name: name.to_string(),
            axis: 0,
        }
    }

    /// Resolves the name; `Err` is the operation's end.
    pub(super) fn resolve(&mut self, s: &Smc100Session) -> Result<usize, MotionError> {
        self.axis = s.index(&self.name)?;
        Ok(self.axis)
    }
}

/// How a query's reply is read: as a status, a number.
type Read<T> = fn(&Smc100Session, usize, Result<ReplyBody, AxisError>) -> Result<T, AxisError>;

/// One query to one axis, its reply read as a `T`.
#[derive(Debug)]
pub(super) struct AxisQuery<T> {
    axis: Named,
    command: Command,
    read: Read<T>,
}

impl AxisQuery<Status> {
    /// `TS`.
    pub(super) fn status(name: &str) -> Self {
        AxisQuery {
            axis: Named::new(name),
            command: Command::TellStatus,
            read: |s, i, r| s.status(i, r),
        }
    }
}

impl AxisQuery<f64> {
    /// `TP`, units.
    pub(super) fn position(name: &str) -> Self {
        AxisQuery {
            axis: Named::new(name),
            command: Command::TellPosition,
            read: |s, i, r| s.number(i, "TP", r),
        }
    }

    /// `PT`: the time, s, the controller's profile takes for a move of `distance`.
    pub(super) fn motion_time(name: &str, distance: f64) -> Self {
        AxisQuery {
            axis: Named::new(name),
            command: Command::MotionTime(distance),
            read: |s, i, r| s.number(i, "PT", r),
        }
    }
}

impl<T> AxisQuery<T> {
    fn got(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<ReplyBody, AxisError>,
    ) -> Next<Self> {
        let i = self.axis.axis;
        Next::Done((self.read)(s, i, r).map_err(|e| s.at(i, e)))
    }
}

impl<T> Op for AxisQuery<T> {
    type Value = T;

    fn start(&mut self, s: &mut Smc100Session, _: &mut Cx) -> Next<Self> {
        match self.axis.resolve(s) {
            Ok(i) => Next::query(i, self.command.clone(), Self::got),
            Err(e) => Next::Done(Err(e)),
        }
    }
}

/// `ST` to one axis, checked with `TE`.
#[derive(Debug)]
pub(super) struct StopOne(Named);

impl StopOne {
    pub(super) fn new(name: &str) -> Self {
        StopOne(Named::new(name))
    }

    fn stopped(
        &mut self,
        s: &mut Smc100Session,
        _: &mut Cx,
        r: Result<(), AxisError>,
    ) -> Next<Self> {
        let i = self.0.axis;
        Next::Done(r.map_err(|e| s.at(i, e)))
    }
}

impl Op for StopOne {
    type Value = ();

    fn start(&mut self, s: &mut Smc100Session, _: &mut Cx) -> Next<Self> {
        match self.0.resolve(s) {
            Ok(i) => Next::command(i, Command::Stop, Self::stopped),
            Err(e) => Next::Done(Err(e)),
        }
    }
}

/// Every stage stopped.
#[derive(Debug)]
pub(super) struct StopEvery;

impl StopEvery {
    fn stopped(
        &mut self,
        _: &mut Smc100Session,
        _: &mut Cx,
        r: Result<(), MotionError>,
    ) -> Next<Self> {
        Next::Done(r)
    }
}

impl Op for StopEvery {
    type Value = ();

    fn start(&mut self, _: &mut Smc100Session, _: &mut Cx) -> Next<Self> {
        Next::StopAll {
            then: Self::stopped,
        }
    }
}
