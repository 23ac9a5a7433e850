//! The lock-in's exchange (a command and, for a query, its reply; the settings it
//! changes tracked), run by the engine's link policy, and its operations other than
//! reading: set-up, any command (with `AGAN`'s settings read back), the status bytes.

use std::time::Duration;

use tracing::debug;

use super::Sr830Session;
use crate::engine::{self, Fault, Link, Wire};
use crate::sr830::{
    Command, EventStatus, FilterSlope, Identity, Interface, LiaStatus, Reply, ReplyError,
    Sensitivity, Sr830Error, TimeConstant,
};

impl Wire for Sr830Session {
    engine::line_wire!(Sr830Error, "sr830");

    /// Replies go to GPIB until `OUTX 0` is sent again.
    fn after_reopen(&self) -> Option<(&'static str, Vec<u8>)> {
        Some(("OUTX 0", Command::SetInterface(Interface::Rs232).to_bytes()))
    }

    fn reopened(&mut self, now: Duration) {
        self.reconnects += 1;
        debug!(port = %self.port, reconnects = self.reconnects, "sr830: port reopened; OUTX 0 re-sent");
        // The instrument may have restarted: let its filters settle again.
        self.mark_unsettled(now);
    }
}

/// A reply of the wrong kind: cannot happen, since [`Reply::parse`] answers by query;
/// reported as a protocol error rather than a panic.
pub(super) fn unexpected(command: &Command, reply: Option<Reply>) -> Sr830Error {
    let mut name = Vec::new();
    command.encode_body(&mut name);
    Sr830Error::Protocol {
        command: String::from_utf8_lossy(&name).into_owned(),
        reply: reply.map(|r| r.to_bytes()).unwrap_or_default(),
        source: ReplyError::BadValue,
    }
}

impl Sr830Session {
    /// Sends `command` and, for a query, reads its reply, due `timeout` after sending
    /// (a reply carries no echo, so it is parsed as the answer to `command`).
    ///
    /// - A lost or garbled answer to a query that only reads is asked again, up to
    ///   `retries` times. The status bytes are never asked again here: reading them
    ///   clears them, so a second read could report a latched overload as gone.
    /// - `SENS`, `OFLT`, `OFSL` and `*RST` update the settings the session tracks and
    ///   restart the settling wait. (`AGAN`, whose settings are read back, is left to
    ///   [`execute`](Self::execute).)
    ///
    /// The rest is the engine's link policy ([`engine::exchange`]): the input cleared
    /// after a fault, a vanished port reopened with `OUTX 0` re-sent.
    pub(super) async fn ask(
        &mut self,
        link: &Link,
        command: &Command,
    ) -> Result<Option<Reply>, Sr830Error> {
        let bytes = command.to_bytes();
        let name = String::from_utf8_lossy(&bytes).trim_end().to_string();
        let rereadable = command.expects_reply()
            && !matches!(
                command,
                Command::LiaStatus(_) | Command::ErrorStatus(_) | Command::EventStatus(_)
            );
        let retries = if rereadable { self.config.retries } else { 0 };
        let timeout = self.config.timeout();
        let receive = async |_: &mut Sr830Session| {
            if !command.expects_reply() {
                return Ok(None);
            }
            let line = link.line(link.now().saturating_add(timeout)).await?;
            Reply::parse(command, &line).map(Some).map_err(|source| {
                Fault::Answer(Sr830Error::Protocol {
                    command: name.clone(),
                    reply: line,
                    source,
                })
            })
        };
        let reply = engine::exchange(self, link, &name, &bytes, retries, receive).await?;
        match *command {
            Command::SetSensitivity(x) => self.sensitivity = x,
            Command::SetTimeConstant(t) => self.time_constant = t,
            Command::SetSlope(x) => self.slope = x,
            Command::Reset => {
                self.sensitivity = Sensitivity::default();
                self.time_constant = TimeConstant::default();
                self.slope = FilterSlope::default();
            }
            _ => return Ok(reply),
        }
        self.mark_unsettled(link.now());
        Ok(reply)
    }

    /// `LIAS?`: the LIA status byte (reading clears it).
    pub(super) async fn lia_status(&mut self, link: &Link) -> Result<LiaStatus, Sr830Error> {
        let command = Command::LiaStatus(None);
        match self.ask(link, &command).await? {
            Some(Reply::LiaStatus(s)) => Ok(s),
            other => Err(unexpected(&command, other)),
        }
    }

    /// `*ESR?`: the standard event status byte (reading clears it).
    pub(super) async fn event_status(&mut self, link: &Link) -> Result<EventStatus, Sr830Error> {
        let command = Command::EventStatus(None);
        match self.ask(link, &command).await? {
            Some(Reply::EventStatus(s)) => Ok(s),
            other => Err(unexpected(&command, other)),
        }
    }

    /// Set-up: input cleared, `OUTX 0` (replies go to GPIB until then), `*IDN?` (must
    /// name an SR830), `*CLS`, the configured `SENS`, `OFLT`, `OFSL`, and `*ESR?`, whose
    /// answer also proves every earlier command has run. It must show no refused
    /// command (EXE, CMD) and no lost one: an overflowed input or output buffer clears
    /// both (manual p. 5-2), so INP or QRY means a command may never have run.
    pub(super) async fn setup(&mut self, link: &Link) -> Result<Identity, Sr830Error> {
        link.clear_input();
        self.ask(link, &Command::SetInterface(Interface::Rs232))
            .await?;
        let identity = match self.ask(link, &Command::Identify).await? {
            Some(Reply::Identity(id)) => id,
            other => return Err(unexpected(&Command::Identify, other)),
        };
        if !identity.is_sr830() {
            return Err(Sr830Error::WrongInstrument(identity));
        }
        debug!(identity = %identity, "sr830: identified");
        let config = &self.config;
        let settings = [
            Command::Clear,
            Command::SetSensitivity(config.sensitivity),
            Command::SetTimeConstant(config.time_constant),
            Command::SetSlope(config.slope),
        ];
        for command in &settings {
            self.ask(link, command).await?;
        }
        let esr = self.event_status(link).await?;
        if esr.has_command_error() || esr.0 & (EventStatus::INP | EventStatus::QRY) != 0 {
            return Err(Sr830Error::Rejected(esr));
        }
        self.identity = Some(identity.clone());
        Ok(identity)
    }

    /// `command` (or none, for a settings read-back alone); after `AGAN`, or alone, the
    /// settings are read back (`SENS?`, `OFLT?`, `OFSL?`) and the settling wait
    /// restarts.
    pub(super) async fn execute(
        &mut self,
        link: &Link,
        command: Option<Command>,
    ) -> Result<Option<Reply>, Sr830Error> {
        let reply = match &command {
            Some(c) => self.ask(link, c).await?,
            None => None,
        };
        match command {
            Some(Command::AutoGain) => debug!("sr830: auto gain done; reading the settings back"),
            Some(_) => return Ok(reply),
            None => {}
        }
        let settings = [
            Command::QuerySensitivity,
            Command::QueryTimeConstant,
            Command::QuerySlope,
        ];
        for query in &settings {
            match self.ask(link, query).await? {
                Some(Reply::Sensitivity(x)) => self.sensitivity = x,
                Some(Reply::TimeConstant(t)) => self.time_constant = t,
                Some(Reply::Slope(x)) => self.slope = x,
                other => return Err(unexpected(query, other)),
            }
        }
        self.mark_unsettled(link.now());
        Ok(reply)
    }
}
