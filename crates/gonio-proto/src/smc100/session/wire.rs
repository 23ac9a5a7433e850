//! One command on the chain's line: the SMC100's receive rule (replies to other
//! commands skipped, a NUL byte is power loss, a set checked with `TE`, a `ZT` dump
//! read whole), run by the engine's [`exchange`](engine::exchange), and the chain's way
//! of reopening a vanished port.

use std::time::Duration;

use tracing::{debug, warn};

use super::{Smc100Session, line_text};
use crate::TransportError;
use crate::engine::{self, Fault, Link, Policy, Wire};
use crate::smc100::{
    AxisError, ChainPolicy, Command, DumpReader, ErrorCode, Frame, MotionError, Param, Reply,
    ReplyBody, Smc100Parameters,
};

impl Wire for Smc100Session {
    type Error = AxisError;
    const FAMILY: &'static str = "smc100";

    /// No reopening by the engine: the chain reopens at once, not after a pause, and
    /// counts every failed attempt ([`engine::reopen_at_once`]), so a vanished port comes out of
    /// [`engine::exchange`] as is and [`Smc100Session::ask`] reopens it.
    fn policy(&self) -> Policy {
        Policy {
            reconnect_attempts: 0,
            reconnect_delay: Duration::ZERO,
        }
    }

    fn port(&self) -> &str {
        "the chain's port"
    }

    fn transport(_: String, source: TransportError) -> AxisError {
        AxisError::Transport(source)
    }

    fn disconnected(&self, _: u32, source: TransportError) -> AxisError {
        AxisError::Transport(source)
    }

    fn is_transient(e: &AxisError) -> bool {
        matches!(
            e,
            AxisError::Transport(
                TransportError::Timeout(_)
                    | TransportError::LineTooLong
                    | TransportError::Garbled(_)
            ) | AxisError::Protocol { .. }
        )
    }

    fn retried(&mut self) {
        self.retried += 1;
    }

    /// Never called ([`Wire::policy`] allows no reopening); [`engine::reopen_at_once`] keeps nothing
    /// either: the session holds no state of the controllers.
    fn reopened(&mut self, _: Duration) {}
}

/// How one attempt at an exchange missed its answer.
pub(super) enum Miss {
    /// A lost, late or garbled reply: the input is cleared and, while retries remain,
    /// the command sent again.
    Again(AxisError),
    /// The end, the input left as it is: power loss (a NUL byte), another link fault,
    /// a `TE` that could not be sent.
    Final(AxisError),
}

/// Sends `bytes`, no answer read (`ST`, `RS`, `PW0`, the `TE` after a set): a vanished
/// port is reopened ([`engine::reopen_at_once`]) and the bytes sent once more.
async fn transmit(link: &Link, policy: &ChainPolicy, bytes: &[u8]) -> Result<(), AxisError> {
    let (attempts, delay) = (policy.reconnect_attempts, policy.reconnect_delay);
    Ok(engine::send_reopening(link, "smc100", attempts, delay, bytes).await?)
}

/// The next line, due by `due`.
async fn line(link: &Link, due: Duration) -> Result<Vec<u8>, Miss> {
    link.line(due).await.map_err(|e| match e {
        TransportError::Nul => {
            warn!("smc100: NUL byte on the line: a controller lost power");
            Miss::Final(AxisError::ControllerReset)
        }
        TransportError::Timeout(_) | TransportError::LineTooLong | TransportError::Garbled(_) => {
            Miss::Again(AxisError::Transport(e))
        }
        e => Miss::Final(AxisError::Transport(e)),
    })
}

/// `line`, which is not the answer to `frame`.
fn garbled(frame: &Frame, line: &[u8], reason: String) -> Miss {
    Miss::Again(AxisError::Protocol {
        sent: line_text(&frame.to_bytes()),
        reply: line_text(line),
        reason,
    })
}

/// The reply to `frame`, due `timeout` from now. Replies to other commands (a late
/// one to an earlier command, another controller's) are skipped until then.
async fn reply(link: &Link, frame: &Frame, timeout: Duration) -> Result<ReplyBody, Miss> {
    let due = link.now().saturating_add(timeout);
    loop {
        let line = line(link, due).await?;
        match Reply::parse(&line) {
            Ok(r) if r.answers(frame) => return Ok(r.body),
            Ok(_) if link.now() < due => {
                debug!(reply = %line_text(&line), "smc100: skipping a reply to another command");
            }
            Ok(_) => return Err(garbled(frame, &line, "answers another command".into())),
            Err(e) => return Err(garbled(frame, &line, e.to_string())),
        }
    }
}

/// Whether `code` is what a `PA` sent while the stage moves may store: the PA page
/// (p. 41-42) names no letter for MOVING, so `M` ("not allowed in MOVING", by analogy
/// with the other commands) and `D` ("execution not allowed") are taken alike
/// (UNCONFIRMED).
fn refused_while_moving(code: ErrorCode) -> bool {
    matches!(code, ErrorCode::InMoving | ErrorCode::NotAllowed)
}

impl Smc100Session {
    /// Sends `frame` and returns what `receive` makes of the answer, sending it again
    /// up to `retries` times after a [`Miss::Again`] ([`engine::exchange`]). A
    /// vanished port is reopened ([`engine::reopen_at_once`]) and the frame sent again in the same
    /// attempt; that send failing is the end.
    async fn ask<T>(
        &mut self,
        link: &Link,
        frame: &Frame,
        retries: usize,
        mut receive: impl AsyncFnMut() -> Result<T, Miss>,
    ) -> Result<T, AxisError> {
        let bytes = frame.to_bytes();
        let name = line_text(&bytes);
        let mut retries = u32::try_from(retries).unwrap_or(u32::MAX);
        let mut reopened = false;
        loop {
            let before = self.retried;
            let mut answered = false;
            let r = engine::exchange(self, link, &name, &bytes, retries, async |_| {
                answered = true;
                match receive().await {
                    Ok(v) => Ok(Ok(v)),
                    Err(Miss::Final(e)) => Ok(Err(e)),
                    Err(Miss::Again(e)) => Err(Fault::Answer(e)),
                }
            })
            .await;
            match r {
                // Only a send loses the port: `line` makes a loss while reading final.
                Err(AxisError::Transport(lost @ TransportError::Disconnected { .. }))
                    if answered || !reopened =>
                {
                    let spent = self.retried - before;
                    retries = retries.saturating_sub(u32::try_from(spent).unwrap_or(u32::MAX));
                    let (attempts, delay) =
                        (self.policy.reconnect_attempts, self.policy.reconnect_delay);
                    engine::reopen_at_once(link, "smc100", attempts, delay, &lost).await?;
                    reopened = true;
                }
                r => return r.and_then(|r| r),
            }
        }
    }

    /// `command` to axis `i` and its reply, asked again after a lost, late or garbled
    /// reply up to `retries` times.
    pub(super) async fn query_with(
        &mut self,
        link: &Link,
        i: usize,
        command: Command,
        retries: usize,
    ) -> Result<ReplyBody, AxisError> {
        let frame = self.frame(i, command);
        let timeout = self.policy.reply_timeout;
        self.ask(link, &frame, retries, async || {
            reply(link, &frame, timeout).await
        })
        .await
    }

    /// `command` to axis `i` and its reply, asked again as the policy allows.
    pub(super) async fn query(
        &mut self,
        link: &Link,
        i: usize,
        command: Command,
    ) -> Result<ReplyBody, AxisError> {
        self.query_with(link, i, command, self.policy.retries).await
    }

    /// `command`, a set or action, to axis `i`, then `TE`. An idempotent command whose
    /// `TE` answer is lost is sent again with a new `TE`; another is
    /// [`AxisError::Ambiguous`]. A re-sent `PA` refused as not allowed while moving
    /// (the first was accepted: the stage moves) is fine if the controller holds this
    /// very target.
    pub(super) async fn command(
        &mut self,
        link: &Link,
        i: usize,
        command: Command,
    ) -> Result<(), AxisError> {
        let frame = self.frame(i, command);
        let idempotent = frame.command.is_idempotent();
        let retries = if idempotent { self.policy.retries } else { 0 };
        let te = self.frame(i, Command::TellError);
        let (policy, timeout) = (self.policy.clone(), self.policy.reply_timeout);
        let mut sent = 0;
        let answer = self
            .ask(link, &frame, retries, async || {
                sent += 1;
                if sent > 1 {
                    let command = line_text(&frame.to_bytes());
                    warn!(%command, "smc100: acknowledgement lost; the command was sent again");
                }
                transmit(link, &policy, &te.to_bytes())
                    .await
                    .map_err(Miss::Final)?;
                reply(link, &te, timeout).await
            })
            .await;
        let command = line_text(&frame.to_bytes());
        let refused = |code| AxisError::Controller {
            command: command.clone(),
            code,
        };
        match answer {
            Ok(ReplyBody::Error(ErrorCode::None)) => Ok(()),
            Ok(ReplyBody::Error(code)) if sent > 1 && refused_while_moving(code) => {
                let Command::MoveAbsolute(target) = frame.command else {
                    return Err(refused(code));
                };
                let pa = Command::Query(Param::AbsoluteTarget);
                let held = self.read_number(link, i, pa).await?;
                if (held - target).abs() <= self.axes[i].tolerance {
                    debug!(target, "smc100: the first absolute move was accepted");
                    Ok(())
                } else {
                    Err(refused(code))
                }
            }
            Ok(ReplyBody::Error(code)) => {
                warn!(%command, %code, "smc100: command refused");
                Err(refused(code))
            }
            Ok(other) => Err(self.unexpected(i, "TE", other, "not an error letter")),
            Err(e) if !idempotent && Self::is_transient(&e) => {
                warn!(%command, "smc100: acknowledgement lost; the command must not be sent again");
                Err(AxisError::Ambiguous { command })
            }
            Err(e) => Err(e),
        }
    }

    /// `ZT` to axis `i` and its dump, up to its closing line (manual, ZT command): lines
    /// before the dump's `PW1` answer earlier commands and are skipped until the reply
    /// timeout; from `PW1` on, each line is due within the reply timeout of the one
    /// before. `ZT` changes nothing, so a broken dump is asked again, whole.
    pub(super) async fn dump(
        &mut self,
        link: &Link,
        i: usize,
    ) -> Result<Smc100Parameters, AxisError> {
        let frame = self.frame(i, Command::DumpConfiguration);
        let (address, timeout) = (self.axes[i].address, self.policy.reply_timeout);
        self.ask(link, &frame, self.policy.retries, async || {
            let mut reader = DumpReader::new(address);
            let mut due = link.now().saturating_add(timeout);
            loop {
                let line = line(link, due).await?;
                match reader.push(&line) {
                    Ok(Some(params)) => return Ok(params),
                    // A line of the dump restarts the wait; a skipped one does not.
                    Ok(None) if reader.started() => due = link.now().saturating_add(timeout),
                    Ok(None) => {}
                    Err(e) => return Err(garbled(&frame, &line, e.to_string())),
                }
            }
        })
        .await
    }

    /// Sends `command` to axis `i`, no reply read and no `TE` (`RS`, `PW0`).
    pub(super) async fn send(
        &self,
        link: &Link,
        i: usize,
        command: Command,
    ) -> Result<(), AxisError> {
        transmit(link, &self.policy, &self.frame(i, command).to_bytes()).await
    }

    /// Stops every stage: the broadcast `ST`, then, if it could not be sent, each
    /// controller's own `ST`; every stage gets its stop, the first failure is returned.
    pub(super) async fn stop_all(&mut self, link: &Link) -> Result<(), MotionError> {
        let broadcast = Frame::broadcast(Command::Stop).to_bytes();
        let Err(e) = transmit(link, &self.policy, &broadcast).await else {
            return Ok(());
        };
        warn!(error = %e, "smc100: broadcast stop not sent; stopping each controller");
        let mut first = None;
        for i in 0..self.axes.len() {
            if let Err(e) = self.send(link, i, Command::Stop).await {
                first.get_or_insert(self.at(i, e));
            }
        }
        first.map_or(Ok(()), Err)
    }
}
