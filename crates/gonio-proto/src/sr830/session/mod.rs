//! The lock-in's policy as a sans-IO state machine: [`Sr830Session`].
//!
//! Each operation is an `async fn` the engine runs: `ops` holds the exchange (a
//! command and, for a query, its reply; the settings it changes tracked) with the
//! link policy it takes from the engine (`OUTX 0` re-sent on a reopened port), and
//! set-up, any command, the status bytes; `read` the settled, averaged, autoranged
//! reading; `targeted` the reading to a precision target.

mod ops;
mod read;
mod targeted;

use std::time::Duration;

use super::{
    Command, EventStatus, FilterSlope, Identity, LiaStatus, Reply, Sensitivity, Sr830Config,
    Sr830Error, TimeConstant,
};
use crate::engine::{Task, secs};

/// The SR830 as a state machine: its configuration, the settings it was last set to,
/// when its filters will have settled, and everything its operations decide: which
/// command goes out next, what an answer means, when to wait, ask again, reopen the
/// port or range. It does no I/O and reads no clock.
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
    config: Sr830Config,
    /// The port's name, for errors.
    port: String,
    sensitivity: Sensitivity,
    time_constant: TimeConstant,
    slope: FilterSlope,
    /// From this time on, readings are trustworthy.
    settled_at: Duration,
    /// When the light or a setting last changed: where a targeted reading's transient
    /// starts.
    changed_at: Duration,
    reconnects: usize,
    retried: u64,
    identity: Option<Identity>,
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
            port: port.into(),
            sensitivity: config.sensitivity,
            time_constant: config.time_constant,
            slope: config.slope,
            config,
            settled_at: now,
            changed_at: now,
            reconnects: 0,
            retried: 0,
            identity: None,
        })
    }

    /// Takes the link and applies the configuration: input cleared, `OUTX 0`, `*IDN?`
    /// (must be an SR830), `*CLS`, `SENS`, `OFLT`, `OFSL`, then `*ESR?`, whose reply also
    /// proves every earlier command has run. Starts the settling wait.
    pub fn start_setup(&mut self, now: Duration) -> Task<'_, Identity, Sr830Error> {
        Task::new(
            "sr830.setup",
            now,
            |link| async move { self.setup(&link).await },
        )
    }

    /// One averaged reading: the settling wait, `LIAS?` to clear latched bits, `samples`
    /// × `SNAP? 1,2` one time constant apart, `LIAS?` for the flags; with autoranging,
    /// a range change and a new reading on an overload or a small signal. Faults are
    /// errors; an overloaded or unlocked reading is returned flagged.
    pub fn start_read(&mut self, now: Duration) -> Task<'_, super::Reading, Sr830Error> {
        Task::new(
            "sr830.read",
            now,
            |link| async move { self.read(&link).await },
        )
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
        Task::new("sr830.read_targeted", now, move |link| async move {
            self.read_targeted(&link, target, expected).await
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
        Task::new("sr830.execute", now, move |link| async move {
            self.execute(&link, Some(command)).await
        })
    }

    /// Reads back `SENS?`, `OFLT?`, `OFSL?` into the settings the session tracks (after
    /// `AGAN`, or a change from the front panel); restarts the settling wait.
    pub fn start_refresh_settings(&mut self, now: Duration) -> Task<'_, (), Sr830Error> {
        Task::new("sr830.refresh_settings", now, |link| async move {
            self.execute(&link, None).await.map(drop)
        })
    }

    /// Sets the sensitivity (`SENS`); readings wait for the filters to settle again.
    pub fn start_set_sensitivity(
        &mut self,
        sensitivity: Sensitivity,
        now: Duration,
    ) -> Task<'_, (), Sr830Error> {
        self.start_set(
            "sr830.set_sensitivity",
            Command::SetSensitivity(sensitivity),
            now,
        )
    }

    /// Sets the time constant (`OFLT`); readings wait for the filters to settle again.
    pub fn start_set_time_constant(
        &mut self,
        time_constant: TimeConstant,
        now: Duration,
    ) -> Task<'_, (), Sr830Error> {
        let command = Command::SetTimeConstant(time_constant);
        self.start_set("sr830.set_time_constant", command, now)
    }

    /// Sets the slope (`OFSL`); readings wait for the filters to settle again.
    pub fn start_set_slope(
        &mut self,
        slope: FilterSlope,
        now: Duration,
    ) -> Task<'_, (), Sr830Error> {
        self.start_set("sr830.set_slope", Command::SetSlope(slope), now)
    }

    /// `LIAS?`: the LIA status byte (reading clears it).
    pub fn start_lia_status(&mut self, now: Duration) -> Task<'_, LiaStatus, Sr830Error> {
        Task::new("sr830.lia_status", now, |link| async move {
            self.lia_status(&link).await
        })
    }

    /// `*ESR?`: the standard event status byte (reading clears it).
    pub fn start_event_status(&mut self, now: Duration) -> Task<'_, EventStatus, Sr830Error> {
        Task::new("sr830.event_status", now, |link| async move {
            self.event_status(&link).await
        })
    }

    /// `command`, a set whose success has no reply of its own.
    fn start_set(
        &mut self,
        name: &'static str,
        command: Command,
        now: Duration,
    ) -> Task<'_, (), Sr830Error> {
        Task::new(name, now, move |link| async move {
            self.ask(&link, &command).await.map(drop)
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

    /// The time constant.
    pub fn time_constant(&self) -> TimeConstant {
        self.time_constant
    }

    /// The filter slope.
    pub fn slope(&self) -> FilterSlope {
        self.slope
    }

    /// The configuration.
    pub fn config(&self) -> &Sr830Config {
        &self.config
    }

    /// The identity set-up read, once it has run.
    pub fn identity(&self) -> Option<&Identity> {
        self.identity.as_ref()
    }

    /// How many times the port was reopened.
    pub fn reconnects(&self) -> usize {
        self.reconnects
    }

    /// Queries asked again (or read cycles restarted) after a lost, late or garbled
    /// reply: what a run log reports as retries.
    pub fn retried(&self) -> u64 {
        self.retried
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
}
