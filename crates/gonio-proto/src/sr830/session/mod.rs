//! The lock-in's policy as a sans-IO state machine, [`Sr830Session`]. Each operation
//! is an `async fn` the engine runs: here the exchange (a command and, for a query,
//! its reply; the settings it changes tracked; `OUTX 0` re-sent on a reopened port),
//! set-up, any command and the status bytes; in `read` the settled, averaged,
//! autoranged reading; in `targeted` the reading to a precision target.

mod read;

use std::time::Duration;

use tracing::debug;

use super::{
    Command, EventStatus, FilterSlope, Identity, Interface, LiaStatus, Reply, ReplyError,
    Sensitivity, Sr830Config, Sr830Error, TimeConstant,
};
use crate::engine::{self, Fault, Link, SessionCore, Task, secs};

/// The SR830 as a state machine: its configuration, the settings it was last set to,
/// when its filters will have settled, and its operations' decisions. It does no I/O
/// and reads no clock.
///
/// Each `start_*` method starts an [`Operation`](crate::link::Operation) that borrows the session until it
/// finishes; its caller hands in bytes, lines, faults and times, and polls out what to
/// do next (see [`Operation`](crate::link::Operation) for the order):
///
/// ```
/// use std::time::Duration;
/// use gonio_proto::link::{Deadline, Io, Operation};
/// use gonio_proto::sr830::{LiaStatus, Sr830Config, Sr830Session};
///
/// let mut session = Sr830Session::new(Sr830Config::default(), "sim", Duration::ZERO).unwrap();
/// let mut op = session.start_lia_status(Duration::ZERO);
/// assert_eq!(op.poll_io(), Some(Io::Transmit(b"LIAS?\n")));
/// op.handle_sent(Duration::ZERO, Ok(()));
/// assert_eq!(op.poll_timeout(), Some(Deadline::Reply(Duration::from_secs(1))));
/// op.handle_line(Duration::from_millis(5), b"4");
/// assert_eq!(op.poll_output().map(|r| r.ok()), Some(Some(LiaStatus(4))));
/// ```
///
/// `gonio_driver::sr830::Sr830` is the pump that runs these operations over a serial
/// port.
#[derive(Clone, Debug, PartialEq)]
pub struct Sr830Session {
    core: SessionCore<Sr830Config, Identity>,
    sensitivity: Sensitivity,
    time_constant: TimeConstant,
    slope: FilterSlope,
    /// From this time on, readings are trustworthy.
    settled_at: Duration,
    /// When the light or a setting last changed: where a targeted reading's transient
    /// starts.
    changed_at: Duration,
    /// The sample rate the data buffer was set up at (`DDEF`, `SEND`, `SRAT` sent),
    /// until the port is reopened.
    buffer_rate: Option<super::SampleRate>,
    /// The settings a targeted reading chose ahead of it
    /// ([`start_prepare_targeted`](Self::start_prepare_targeted)), already sent.
    prepared: Option<read::Prepared>,
}

// Replies go to GPIB until `OUTX 0` is sent again.
engine::line_session! {
    Sr830Session: "sr830", Sr830Config, Identity, Sr830Error; Command, Reply, ReplyError;
    after_reopen: ("OUTX 0", Command::SetInterface(Interface::Rs232).to_bytes())
}

impl Sr830Session {
    /// A session for the lock-in on `port` (its name, for errors), at `now`; nothing is
    /// sent until [`start_setup`](Self::start_setup). Fails if `config` does not
    /// [`validate`](Sr830Config::validate).
    pub fn new(
        config: Sr830Config,
        port: impl Into<String>,
        now: Duration,
    ) -> Result<Self, Sr830Error> {
        config.validate()?;
        Ok(Sr830Session {
            sensitivity: config.sensitivity,
            time_constant: config.time_constant,
            slope: config.slope,
            core: SessionCore::new(config, port),
            settled_at: now,
            changed_at: now,
            buffer_rate: None,
            prepared: None,
        })
    }

    /// Takes the link and applies the configuration: input cleared, `OUTX 0` (replies go
    /// to GPIB until then), `*IDN?` (must name an SR830), `*CLS`, the configured `SENS`,
    /// `OFLT`, `OFSL`, and `*ESR?`, whose answer also proves every earlier command has
    /// run. It must show no refused command (EXE, CMD) and no lost one: an overflowed
    /// input or output buffer clears both (manual p. 5-2), so INP or QRY means a command
    /// may never have run. Starts the settling wait.
    pub fn start_setup(&mut self, now: Duration) -> Task<'_, Identity, Sr830Error> {
        Task::run("sr830.setup", now, self, Self::setup)
    }

    /// One averaged reading: the settling wait, `LIAS?` to clear latched bits, `samples`
    /// × `SNAP? 1,2` one time constant apart, `LIAS?` for the flags. With autoranging, an
    /// input or output overload steps one range less sensitive, a clean signal under
    /// `min_fraction` of full scale one range more, and the reading starts again. Faults
    /// are errors; an overloaded or unlocked reading is returned flagged.
    pub fn start_read(&mut self, now: Duration) -> Task<'_, super::Reading, Sr830Error> {
        Task::run("sr830.read", now, self, Self::read)
    }

    /// One reading to a precision target (see [`super::target`]): with a noise law
    /// and a time-constant range, the time constant that reads a signal of
    /// `expected` V fastest is set first; snapshots are then taken one time constant
    /// apart from [`FIRST_SNAPSHOT_TC`](super::target::FIRST_SNAPSHOT_TC) after the
    /// last change, the filter's transient fitted from them, and a window averaged
    /// once the transient is under a fraction of the target, until its mean meets the
    /// target or the reading has taken `target.max_s` (then it is flagged capped).
    /// Autoranging steps one range less sensitive on an output clipped after the
    /// transient, and straight to the range that fits on a small signal.
    pub fn start_read_targeted(
        &mut self,
        target: super::ReadTarget,
        expected: Option<f64>,
        now: Duration,
    ) -> Task<'_, super::Reading, Sr830Error> {
        Task::run("sr830.read_targeted", now, self, async move |s, link| {
            s.read_targeted(link, target, expected).await
        })
    }

    /// The non-optical part of a targeted reading, done ahead of it (while the stages
    /// move to its point): the time constant for a signal of `expected` V chosen and
    /// sent (`OFLT`), as [`start_read_targeted`](Self::start_read_targeted) would
    /// first do. The next targeted reading to the same `target` and `expected` then
    /// starts from its snapshots; the transient is timed from the later of this and
    /// [`input_changed`](Self::input_changed).
    pub fn start_prepare_targeted(
        &mut self,
        target: super::ReadTarget,
        expected: Option<f64>,
        now: Duration,
    ) -> Task<'_, (), Sr830Error> {
        Task::run("sr830.prepare_targeted", now, self, async move |s, link| {
            s.prepare_targeted(link, target, expected).await.map(drop)
        })
    }

    /// Sends any command and, for a query, reads its reply. A vanished port is
    /// reopened (up to `reconnect_attempts` times, `reconnect_delay_ms` apart, with
    /// `OUTX 0` re-sent) and the command sent again: every command the session uses is
    /// idempotent. `SENS`, `OFLT`, `OFSL`, `*RST` and `AGAN` update the settings the
    /// session tracks and restart the settling wait (`AGAN` reads them back).
    pub fn start_execute<'s>(
        &'s mut self,
        command: &Command,
        now: Duration,
    ) -> Task<'s, Option<Reply>, Sr830Error> {
        let command = command.clone();
        Task::run("sr830.execute", now, self, async move |s, link| {
            s.execute(link, Some(command)).await
        })
    }

    /// Reads back `SENS?`, `OFLT?`, `OFSL?` into the settings the session tracks (after
    /// `AGAN`, or a change from the front panel); restarts the settling wait.
    pub fn start_refresh_settings(&mut self, now: Duration) -> Task<'_, (), Sr830Error> {
        Task::run("sr830.refresh_settings", now, self, async |s, link| {
            s.execute(link, None).await.map(drop)
        })
    }

    /// `SENS`; readings wait for the filters to settle again.
    pub fn start_set_sensitivity(
        &mut self,
        sensitivity: Sensitivity,
        now: Duration,
    ) -> Task<'_, (), Sr830Error> {
        let set = Command::SetSensitivity(sensitivity);
        self.start_set("sr830.set_sensitivity", set, now)
    }

    /// `OFLT`; readings wait for the filters to settle again.
    pub fn start_set_time_constant(
        &mut self,
        time_constant: TimeConstant,
        now: Duration,
    ) -> Task<'_, (), Sr830Error> {
        let set = Command::SetTimeConstant(time_constant);
        self.start_set("sr830.set_time_constant", set, now)
    }

    /// `OFSL`; readings wait for the filters to settle again.
    pub fn start_set_slope(
        &mut self,
        slope: FilterSlope,
        now: Duration,
    ) -> Task<'_, (), Sr830Error> {
        self.start_set("sr830.set_slope", Command::SetSlope(slope), now)
    }

    /// `LIAS?`: the LIA status byte (reading clears it).
    pub fn start_lia_status(&mut self, now: Duration) -> Task<'_, LiaStatus, Sr830Error> {
        Task::run("sr830.lia_status", now, self, Self::lia_status)
    }

    /// `*ESR?`: the standard event status byte (reading clears it).
    pub fn start_event_status(&mut self, now: Duration) -> Task<'_, EventStatus, Sr830Error> {
        Task::run("sr830.event_status", now, self, Self::event_status)
    }

    /// A set whose success has no reply of its own.
    fn start_set(
        &mut self,
        name: &'static str,
        command: Command,
        now: Duration,
    ) -> Task<'_, (), Sr830Error> {
        Task::run(name, now, self, async move |s, link| {
            s.ask(link, &command).await.map(drop)
        })
    }

    /// The light on the detector changed at `now` (a stage moved, a shutter opened):
    /// the next reading waits a full settling time from now, as after a change of
    /// settings. Without it, readings taken right after a move average the filters'
    /// response to the step — biased towards the previous point.
    pub fn input_changed(&mut self, now: Duration) {
        self.mark_unsettled(now);
    }

    /// Settling time at the current time constant and slope, to the config's
    /// `settle_residual`.
    pub fn settle_time(&self) -> Duration {
        secs(self.config.settle_seconds(self.slope, self.time_constant))
    }

    /// When the filters will have settled (readings wait until then).
    pub fn settled_at(&self) -> Duration {
        self.settled_at
    }

    /// The sensitivity the instrument is set to (as far as the session knows).
    pub fn sensitivity(&self) -> Sensitivity {
        self.sensitivity
    }

    /// Likewise the time constant.
    pub fn time_constant(&self) -> TimeConstant {
        self.time_constant
    }

    /// Likewise the slope.
    pub fn slope(&self) -> FilterSlope {
        self.slope
    }

    /// After a reopen the instrument may have restarted: its filters settle again.
    fn reopened(&mut self, now: Duration) {
        debug!(port = %self.port, reconnects = self.reconnects, "sr830: port reopened; OUTX 0 re-sent");
        self.buffer_rate = None;
        self.mark_unsettled(now);
    }

    /// Readings wait a full settling time from `now`, at the current settings. A
    /// pending longer wait is replaced, not kept: the filters now run at the new
    /// settings, so a mistaken 30 ks set and undone does not cost days.
    fn mark_unsettled(&mut self, now: Duration) {
        self.settled_at = now.saturating_add(self.settle_time());
        self.changed_at = now;
        tracing::debug!(
            settle = ?self.settle_time(),
            time_constant = %self.time_constant,
            slope = %self.slope,
            "sr830: settling wait restarts"
        );
    }

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
        let (bytes, name) = (command.to_bytes(), name(command));
        let rereadable = command.expects_reply()
            && !matches!(
                command,
                Command::LiaStatus(_) | Command::ErrorStatus(_) | Command::EventStatus(_)
            );
        let retries = if rereadable { self.config.retries } else { 0 };
        // A binary trace is due once its bytes have had time to arrive (p. 5-17: sent
        // without pauses, at the baud rate).
        let timeout = match command {
            Command::TraceBinary(r) | Command::TraceStored(r) | Command::TraceAscii(r) => {
                let bytes = r.binary_len() * if command.is_binary_trace() { 1 } else { 4 };
                self.config.timeout() + secs(super::buffer::wire_seconds(bytes, self.config.baud))
            }
            _ => self.config.timeout(),
        };
        let receive = async |_: &mut Sr830Session| {
            if !command.expects_reply() {
                return Ok(None);
            }
            let line = link.line(link.now().saturating_add(timeout)).await?;
            Reply::parse(command, &line)
                .map(Some)
                .map_err(|source| Fault::Answer(protocol(command, &line, source)))
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

    async fn lia_status(&mut self, link: &Link) -> Result<LiaStatus, Sr830Error> {
        let command = Command::LiaStatus(None);
        match self.ask(link, &command).await? {
            Some(Reply::LiaStatus(s)) => Ok(s),
            other => Err(unexpected(&command, other)),
        }
    }

    async fn event_status(&mut self, link: &Link) -> Result<EventStatus, Sr830Error> {
        let command = Command::EventStatus(None);
        match self.ask(link, &command).await? {
            Some(Reply::EventStatus(s)) => Ok(s),
            other => Err(unexpected(&command, other)),
        }
    }

    async fn setup(&mut self, link: &Link) -> Result<Identity, Sr830Error> {
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
        self.core.identity = Some(identity.clone());
        Ok(identity)
    }

    /// `command`, or none for a settings read-back alone (as after `AGAN`).
    async fn execute(
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
