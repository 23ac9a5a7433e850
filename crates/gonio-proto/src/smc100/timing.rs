//! What the chain's operations cost on the wire, for planning: the exchanges of a
//! move, a home search and the start-up identification, each as the session's
//! operation makes them (`session/ops.rs`), with the bytes of the session's own
//! command encodings.

use std::time::Duration;

use gonio_core::motion::AxisExchanges;

use super::{
    AxisConfig, Command, ControllerState, ErrorCode, Frame, Param, PositionerErrors, Reply,
    ReplyBody, Status,
};
use crate::timing::{exchange_s, wire_s};

/// A controller's time to answer a query beyond the bytes' own time on the wire, s:
/// the manual gives about 10 ms from sending `TP` to its answer on controller 1
/// (§5.4, §2.1; about 16 ms for the controllers further down the chain, which
/// Gonio does not tell apart). The simulated controllers answer in the same time.
pub const REPLY_LATENCY_S: f64 = 0.010;

/// Stands for a position or a distance in a line: real lines carry whatever the
/// number is, a few characters either way.
const TYPICAL_POSITION: f64 = -37.5;
/// Stands for the controller's time estimate of a move (`PT`), s.
const TYPICAL_MOTION_TIME: f64 = 1.25;

/// One query to controller `address` and its answer, s.
fn query_s(address: u8, command: Command, body: ReplyBody, baud: u32) -> f64 {
    let out = Frame::addressed(address, command).to_bytes().len();
    let back = Reply { address, body }.to_bytes().len();
    exchange_s(out, back, baud, REPLY_LATENCY_S)
}

/// A set or action command to controller `address`, unanswered, s.
fn send_s(address: u8, command: Command, baud: u32) -> f64 {
    wire_s(Frame::addressed(address, command).to_bytes().len(), baud)
}

/// `TE` and its answer `@`, the check after every set or action command, s.
fn check_s(address: u8, baud: u32) -> f64 {
    query_s(
        address,
        Command::TellError,
        ReplyBody::Error(ErrorCode::None),
        baud,
    )
}

/// `TS` and its answer, s.
fn status_s(address: u8, baud: u32) -> f64 {
    let body = ReplyBody::Status(Status {
        errors: PositionerErrors(0),
        state: ControllerState::Moving,
    });
    query_s(address, Command::TellStatus, body, baud)
}

/// `TP` and its answer, s.
fn position_s(address: u8, baud: u32) -> f64 {
    let body = ReplyBody::Position(TYPICAL_POSITION);
    query_s(address, Command::TellPosition, body, baud)
}

/// An axis' part in a move of the chain on serial line `line` (the session's
/// `Motion`): `TP`; for a move that goes somewhere, `PT`; `PA`, whose arrival starts
/// the stage; `TE`; then, every `poll`, `TS` until READY; `TP` at the end.
pub fn move_exchanges(axis: &AxisConfig, line: usize, baud: u32, poll: Duration) -> AxisExchanges {
    let a = axis.address;
    AxisExchanges {
        line,
        before_s: position_s(a, baud),
        estimate_s: query_s(
            a,
            Command::MotionTime(TYPICAL_POSITION.abs()),
            ReplyBody::MotionTime(TYPICAL_MOTION_TIME),
            baud,
        ),
        command_s: send_s(a, Command::MoveAbsolute(TYPICAL_POSITION), baud),
        check_s: check_s(a, baud),
        status_s: status_s(a, baud),
        poll_s: poll.as_secs_f64(),
        after_s: position_s(a, baud),
    }
}

/// An axis' part in homing the chain (the session's `Home`, from NOT REFERENCED):
/// `TS`; `OR`, whose arrival starts the search; `TE`; then, every `poll`, `TS`
/// until READY; at the end the configured velocity and acceleration, each set and
/// checked. [`MoveExchanges::move_s`](gonio_core::motion::MoveExchanges::move_s) of
/// these, given each search's duration, is the homing's.
pub fn home_exchanges(axis: &AxisConfig, line: usize, baud: u32, poll: Duration) -> AxisExchanges {
    let a = axis.address;
    let set = |c: Command| send_s(a, c, baud) + check_s(a, baud);
    AxisExchanges {
        line,
        before_s: status_s(a, baud),
        estimate_s: 0.0,
        command_s: send_s(a, Command::Home, baud),
        check_s: check_s(a, baud),
        status_s: status_s(a, baud),
        poll_s: poll.as_secs_f64(),
        after_s: axis.velocity.map_or(0.0, |v| set(Command::SetVelocity(v)))
            + axis
                .acceleration
                .map_or(0.0, |v| set(Command::SetAcceleration(v))),
    }
}

/// The chain's identification at start-up (the session's `Identify`): `VE`, `ID?`
/// and `TS` to each controller in turn, s.
pub fn identify_s(axes: &[AxisConfig], baud: u32) -> f64 {
    axes.iter()
        .map(|axis| {
            let a = axis.address;
            // The manual's own version text and a stage name of the usual length.
            let version = ReplyBody::Version("SMC_PP - Controller-driver version  3. 1. 2".into());
            let stage = ReplyBody::StageId("URS100PP".into());
            query_s(a, Command::Version, version, baud)
                + query_s(a, Command::Query(Param::StageId), stage, baud)
                + status_s(a, baud)
        })
        .sum()
}

/// How long a home search from `from` takes, s: one pass onto the switch at `to` at
/// the home search velocity `OH` with the acceleration `AC`, on the trapezoid a move
/// takes (the simulated controller's search; a real one's is as long as its stage
/// stands from its switch).
pub fn home_search_s(from: f64, to: f64, home_velocity: f64, acceleration: f64) -> f64 {
    gonio_core::motion::trapezoid_time(to - from, home_velocity, acceleration)
}
