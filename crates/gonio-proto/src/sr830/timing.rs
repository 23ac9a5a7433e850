//! What the lock-in's operations cost, for planning: the set-up and a fixed reading's
//! cycle, each as the session's operation makes them
//! (`session/ops.rs`, `session/read.rs`), with the bytes of the session's own
//! command encodings.

use super::{
    Command, EventStatus, Identity, Interface, LiaStatus, Reply, SnapParams, Sr830Config,
    TimeConstant,
};
use crate::timing::exchange_s;

pub use super::ranging::OUTPUT_OVERLOAD;

/// The lock-in's time to answer a query beyond the bytes' own time on the wire, s.
/// No manual page gives it; 5 ms is assumed, and the simulated lock-in answers in
/// the same.
pub const REPLY_LATENCY_S: f64 = 0.005;

/// One exchange of `command`, answered by `reply` (`None`: unanswered), s.
fn exchange(command: &Command, reply: Option<Reply>, baud: u32) -> f64 {
    let back = reply.map_or(0, |r| r.to_bytes().len());
    exchange_s(command.to_bytes().len(), back, baud, REPLY_LATENCY_S)
}

/// `LIAS?` and its answer, s.
pub fn lia_status_s(baud: u32) -> f64 {
    exchange(
        &Command::LiaStatus(None),
        Some(Reply::LiaStatus(LiaStatus(0))),
        baud,
    )
}

/// `SNAP? 1,2` and an answer of the usual length (values rounded to six digits), s.
pub fn snapshot_s(baud: u32) -> f64 {
    exchange(
        &Command::Snap(SnapParams::XY),
        Some(Reply::Snap(vec![1.23456e-3, -2.34567e-5])),
        baud,
    )
}

/// A range change (`SENS n`), unanswered, s.
pub fn range_change_s(baud: u32) -> f64 {
    exchange(&Command::SetSensitivity(Default::default()), None, baud)
}

/// A time constant change (`OFLT n`), unanswered, s: what a targeted reading sends
/// first.
pub fn time_constant_change_s(baud: u32) -> f64 {
    exchange(&Command::SetTimeConstant(Default::default()), None, baud)
}

impl Sr830Config {
    /// The set-up's exchanges (the session's `Setup`): `OUTX 0`, `*IDN?`, `*CLS`,
    /// `SENS`, `OFLT`, `OFSL` and `*ESR?`, s, at the port's baud rate
    /// ([`with_baud`](Self::with_baud)).
    pub fn setup_s(&self) -> f64 {
        let id = Identity::parse(b"Stanford_Research_Systems,SR830,s/n00111,ver1.07");
        [
            (Command::SetInterface(Interface::Rs232), None),
            (Command::Identify, id.map(Reply::Identity)),
            (Command::Clear, None),
            (Command::SetSensitivity(self.sensitivity), None),
            (Command::SetTimeConstant(self.time_constant), None),
            (Command::SetSlope(self.slope), None),
            (
                Command::EventStatus(None),
                Some(Reply::EventStatus(EventStatus(0))),
            ),
        ]
        .into_iter()
        .map(|(c, r)| exchange(&c, r, self.baud))
        .sum()
    }

    /// One cycle of a fixed reading at time constant `tc` (the session's `Read`), s:
    /// the settling wait from the last change, `LIAS?` to clear the latched bits,
    /// `samples` × `SNAP? 1,2` one time constant apart, `LIAS?` for the flags.
    pub fn cycle_s(&self, tc: TimeConstant) -> f64 {
        let snapshots = self.samples.max(1);
        self.settle_seconds(self.slope, tc)
            + 2.0 * lia_status_s(self.baud)
            + snapshots as f64 * snapshot_s(self.baud)
            + (snapshots - 1) as f64 * tc.seconds()
    }

    /// A fixed reading after a move that needs no range change, s: one
    /// [`cycle_s`](Self::cycle_s) at the configured time constant. Each range change
    /// ([`ranging`](super::ranging)) costs a [`range_change_s`] and a cycle more.
    pub fn read_s(&self) -> f64 {
        self.cycle_s(self.time_constant)
    }
}
