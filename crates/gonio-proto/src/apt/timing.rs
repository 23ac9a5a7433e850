//! What a move costs on an APT controller's line, for planning: the exchanges of the
//! session's move (`session/ops.rs`), with the bytes of its own messages.

use std::time::Duration;

use gonio_core::motion::AxisExchanges;

use super::{DcStatus, Message, StageKind, StepperStatus};
use crate::timing::{exchange_s, wire_s};

/// The line's baud rate (the manual's USB virtual serial port settings).
pub const BAUD: u32 = 115_200;

/// A controller's time to answer a request beyond the bytes' own time on the wire, s.
/// No manual page gives it; 2 ms is assumed, and the simulated controllers answer in
/// the same.
pub const REPLY_LATENCY_S: f64 = 0.002;

/// A status request and its answer on `stage`'s controller, s.
fn status_s(stage: StageKind) -> f64 {
    let (ask, answer) = if stage.is_dc_servo() {
        let st = DcStatus {
            chan: 1,
            ..DcStatus::default()
        };
        (
            Message::ReqDcStatusUpdate { chan: 1 },
            Message::GetDcStatusUpdate(st),
        )
    } else {
        let st = StepperStatus {
            chan: 1,
            ..StepperStatus::default()
        };
        (
            Message::ReqStatusUpdate { chan: 1 },
            Message::GetStatusUpdate(st),
        )
    };
    exchange_s(
        ask.to_bytes().len(),
        answer.to_bytes().len(),
        BAUD,
        REPLY_LATENCY_S,
    )
}

/// An axis' part in a move on its own line `line` (the session's `motion`): a status
/// for where it stands; the move message, whose arrival starts the stage; then,
/// every `poll`, a status until the stage is still at its target, whose position is
/// the move's answer.
pub fn move_exchanges(stage: StageKind, line: usize, poll: Duration) -> AxisExchanges {
    let command = Message::MoveAbsolute {
        chan: 1,
        position: Some(0),
    };
    AxisExchanges {
        line,
        before_s: status_s(stage),
        estimate_s: 0.0,
        command_s: wire_s(command.to_bytes().len(), BAUD),
        check_s: 0.0,
        status_s: status_s(stage),
        poll_s: poll.as_secs_f64(),
        after_s: 0.0,
    }
}
