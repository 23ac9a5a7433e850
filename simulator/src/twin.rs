//! The machinery the simulated line devices share, on simulated time (seconds): bytes
//! from the host queued at their arrival, read when the device is free, echoed, cut
//! into lines that the device's own state machine runs, and its output queued, each
//! piece at the time it leaves. A device implements [`LineDevice`]; [`LineTwin`] does
//! the rest. Every twin that sends on its own time, the APT controller's too, is a
//! [`TimedLine`] to the simulator.

use std::collections::VecDeque;

/// When a device echoes the bytes it receives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Echo {
    /// Not at all.
    Off,
    /// Each chunk whole as it arrives, before any line in it runs.
    Arrival,
    /// Each byte as the device reads it, so an answer follows its line's echo.
    Read,
}

/// Bytes a device sends, each with the time it leaves, in time order.
#[derive(Clone, Debug, Default)]
pub struct Outbox(VecDeque<(f64, Vec<u8>)>);

impl Outbox {
    /// Queues `bytes` to leave at `t`, after everything due by then: an echo is not
    /// held behind an answer that waits for a move.
    pub fn send(&mut self, t: f64, bytes: impl Into<Vec<u8>>) {
        let at = self.0.partition_point(|(due, _)| *due <= t);
        self.0.insert(at, (t, bytes.into()));
    }
}

/// A simulated instrument's own state machine on a text line, which [`LineTwin`]
/// feeds.
pub trait LineDevice {
    /// The byte that ends a line.
    const END: u8;
    /// The longest line, its end excluded: a longer one is dropped up to its end, and
    /// [`overflow`](Self::overflow) told when it passes the limit.
    const MAX_LINE: usize = usize::MAX;
    /// How it echoes.
    fn echo(&self) -> Echo;
    /// Received bytes wait unread until then (a firmware busy while it moves).
    fn reads_from(&self) -> f64 {
        f64::NEG_INFINITY
    }
    /// Runs one line (its end removed) read at `t`, queuing what it sends on `out`.
    fn execute(&mut self, t: f64, line: &[u8], out: &mut Outbox);
    /// A line passed [`MAX_LINE`](Self::MAX_LINE) at `t`.
    fn overflow(&mut self, _t: f64) {}
}

/// A [`LineDevice`] on its line: what it has received and not read, and what it has
/// to send. It dereferences to the device, for its state and physics.
#[derive(Clone, Debug)]
pub struct LineTwin<D> {
    device: D,
    /// Bytes received and not yet read, with their arrival times.
    input: VecDeque<(f64, u8)>,
    /// The line read so far.
    line: Vec<u8>,
    /// Inside an over-long line: dropped up to its end.
    discarding: bool,
    outbox: Outbox,
}

impl<D: LineDevice> LineTwin<D> {
    /// `device` on a quiet line, with `first` to send at time 0 (a power-up prompt).
    pub fn wrap(device: D, first: Option<&[u8]>) -> Self {
        let mut outbox = Outbox::default();
        if let Some(bytes) = first {
            outbox.send(0.0, bytes);
        }
        LineTwin {
            device,
            input: VecDeque::new(),
            line: Vec::new(),
            discarding: false,
            outbox,
        }
    }

    /// Bytes from the host at `now`, in any chunks: echoed and read as the device
    /// does; what it sends waits for [`poll`](TimedLine::poll). A time before 0 or not
    /// finite is taken as 0.
    pub fn push(&mut self, now: f64, bytes: &[u8]) {
        let now = if now.is_finite() { now.max(0.0) } else { 0.0 };
        if self.device.echo() == Echo::Arrival && !bytes.is_empty() {
            self.outbox.send(now, bytes);
        }
        self.input.extend(bytes.iter().map(|b| (now, *b)));
        self.run(now);
    }

    /// Reads every byte the device can read by `now`: each once it has arrived and
    /// the device is free.
    fn run(&mut self, now: f64) {
        while let Some(&(arrived, byte)) = self.input.front() {
            let t = arrived.max(self.device.reads_from());
            if t > now {
                break;
            }
            self.input.pop_front();
            if self.device.echo() == Echo::Read {
                self.outbox.send(t, [byte]);
            }
            if byte == D::END {
                let line = std::mem::take(&mut self.line);
                if !std::mem::replace(&mut self.discarding, false) {
                    self.device.execute(t, &line, &mut self.outbox);
                }
            } else if !self.discarding {
                self.line.push(byte);
                if self.line.len() > D::MAX_LINE {
                    self.line.clear();
                    self.discarding = true;
                    self.device.overflow(t);
                }
            }
        }
    }
}

/// A twin that sends on its own time as well as when asked (an answer held until a
/// move ends, a prompt, an APT controller's status): what the simulator and the
/// transports ask of its line.
pub trait TimedLine {
    /// Bytes from the host at `now`; appends to `out` what the device sends by `now`.
    fn receive(&mut self, now: f64, bytes: &[u8], out: &mut Vec<u8>);
    /// Appends to `out`, in order, what the device sends by `now`.
    fn poll(&mut self, now: f64, out: &mut Vec<u8>);
    /// When the device next sends something, if it has anything to send.
    fn next_event(&self) -> Option<f64>;
}

impl<D: LineDevice> TimedLine for LineTwin<D> {
    fn receive(&mut self, now: f64, bytes: &[u8], out: &mut Vec<u8>) {
        self.push(now, bytes);
        self.poll(now, out);
    }

    /// Answers to bytes that waited for the device included.
    fn poll(&mut self, now: f64, out: &mut Vec<u8>) {
        self.run(now);
        while self.outbox.0.front().is_some_and(|(t, _)| *t <= now) {
            if let Some((_, bytes)) = self.outbox.0.pop_front() {
                out.extend_from_slice(&bytes);
            }
        }
    }

    fn next_event(&self) -> Option<f64> {
        let queued = self.outbox.0.front().map(|(t, _)| *t);
        let waiting = self
            .input
            .front()
            .map(|(t, _)| t.max(self.device.reads_from()));
        queued.into_iter().chain(waiting).reduce(f64::min)
    }
}

impl<D> std::ops::Deref for LineTwin<D> {
    type Target = D;
    fn deref(&self) -> &D {
        &self.device
    }
}

impl<D> std::ops::DerefMut for LineTwin<D> {
    fn deref_mut(&mut self) -> &mut D {
        &mut self.device
    }
}

/// `ensure!(ok; field, reason...)` returns `Err` naming `field` with the formatted
/// reason unless `ok`: a twin's [`FieldError`], or the sim config's `(field, reason)`.
macro_rules! ensure {
    ($ok:expr; $field:expr, $($why:tt)+) => {
        let ok: bool = $ok;
        if !ok {
            return Err($crate::twin::FieldError::new($field, format!($($why)+)).into());
        }
    };
}
pub(crate) use ensure;

/// A twin's config value that cannot describe an instrument.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{field}: {reason}")]
pub struct FieldError {
    /// The field, as a config file writes it.
    pub field: String,
    /// What is wrong with it.
    pub reason: String,
}

impl From<FieldError> for (String, String) {
    fn from(e: FieldError) -> Self {
        (e.field, e.reason)
    }
}

impl FieldError {
    /// The error naming `field`.
    pub fn new(field: impl Into<String>, reason: impl Into<String>) -> Self {
        FieldError {
            field: field.into(),
            reason: reason.into(),
        }
    }

    /// `Err` unless `lo` ≤ `v` ≤ `hi`.
    pub fn within(field: &str, v: f64, lo: f64, hi: f64) -> Result<(), FieldError> {
        match v >= lo && v <= hi {
            true => Ok(()),
            false => Err(Self::new(field, format!("{v} is not in [{lo}, {hi}]"))),
        }
    }

    /// `Err` naming the first row whose value its range refuses, with the range's
    /// message.
    pub fn ranges(rows: &[(&str, f64, gonio_core::limits::Range)]) -> Result<(), FieldError> {
        for (field, v, range) in rows {
            range.check(*v).map_err(|m| Self::new(*field, m))?;
        }
        Ok(())
    }

    /// `Err` unless `text`, an `*IDN?` field, is non-empty printable ASCII without
    /// commas (the field separator), spaces allowed when `spaces`.
    pub fn identity(field: &str, text: &str, spaces: bool) -> Result<(), FieldError> {
        let ok = |b: u8| (b.is_ascii_graphic() || (spaces && b == b' ')) && b != b',';
        match !text.is_empty() && text.bytes().all(ok) {
            true => Ok(()),
            false => Err(Self::new(
                field,
                "must be non-empty printable ASCII without commas",
            )),
        }
    }

    /// As the sim config names it: the field under the twin's `table`.
    pub(crate) fn under(self, table: &str) -> (String, String) {
        (format!("{table}.{}", self.field), self.reason)
    }
}
