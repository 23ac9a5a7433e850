//! The twin's data buffer (manual Rev. 2.5, ch. 5 "Data Storage", p. 5-14 … 5-18; the
//! facts in [`gonio_proto::sr830::buffer`]). Each behaviour names its page, or says
//! "assumed" and why.
//!
//! - Points of the CH1 and CH2 displays are stored at the sample rate, both at the same
//!   instants (p. 5-14), from the outputs as read (noise included, clipped at 1.09 ×
//!   full scale like `SNAP?`), in the instrument's own format ([`StoredValue`], p.
//!   5-17: "The data within the SR830 is stored in this format"), so `TRCB?` and
//!   `TRCA?` return the stored point's value.
//! - The first point is stored one sample period after `STRT` (assumed: the manual
//!   does not say where in the period storage starts; the real instrument samples on
//!   its 512 Hz clock, so its first point falls within one period of this one).
//! - 1 Shot stops at [`BUFFER_POINTS`]; Loop keeps the latest [`BUFFER_POINTS`] (p.
//!   5-14). `PAUS` stops storing until `STRT`, which resumes one period later; `REST`
//!   empties the buffer and stops storage (p. 5-15).
//! - A trace query whose j + k exceeds `SPTS?` "is an error" (p. 5-16): it answers
//!   nothing and sets EXE (assumed: the manual names no bit; EXE is the "cannot
//!   execute" bit).
//! - The triggered rate (`SRAT 14`) stores nothing: `TRIG` is not modelled.
//! - Display quantities: X or Y (0), R or θ (1); X/Y noise (2) and the Aux inputs (3,
//!   4) store 0 (assumed: noise displays are not modelled, nothing is connected to the
//!   Aux inputs); a ratio is ignored (assumed: the Aux ratio inputs are unconnected).
//! - The binary transfer's time is the transport's: 4k bytes at the baud rate, with no
//!   pause between bytes (p. 5-17).

use gonio_proto::sr830::buffer::BUFFER_POINTS;
use gonio_proto::sr830::{EndOfScan, SampleRate, StoredValue, TraceChannel, TraceRange};

/// The buffer's state.
#[derive(Clone, Debug)]
pub(super) struct Storage {
    pub(super) rate: SampleRate,
    pub(super) end: EndOfScan,
    /// Display quantity (DDEF j) of CH1 and CH2.
    pub(super) display: [u8; 2],
    /// Storing: the next point's time, seconds.
    pub(super) next: Option<f64>,
    /// The points, oldest first (at most [`BUFFER_POINTS`]).
    points: Vec<[StoredValue; 2]>,
}

impl Default for Storage {
    /// The `*RST` state: 1 Hz, 1 Shot, CH1 X and CH2 Y (p. 4-4, read second-hand:
    /// UNCONFIRMED), empty.
    fn default() -> Self {
        Storage {
            rate: SampleRate::Hz1,
            end: EndOfScan::OneShot,
            display: [0, 0],
            next: None,
            points: Vec::new(),
        }
    }
}

impl Storage {
    /// The period between points, when storing at an internal rate.
    pub(super) fn period(&self) -> Option<f64> {
        self.rate.hz().map(|hz| 1.0 / hz)
    }

    /// `STRT` at `now`: starts storing unless already storing (p. 5-15).
    pub(super) fn start(&mut self, now: f64) {
        if self.next.is_none() && !self.full() {
            self.next = self.period().map(|p| now + p);
        }
    }

    /// `PAUS`.
    pub(super) fn pause(&mut self) {
        self.next = None;
    }

    /// `REST`.
    pub(super) fn reset(&mut self) {
        self.next = None;
        self.points.clear();
    }

    fn full(&self) -> bool {
        self.end == EndOfScan::OneShot && self.points.len() >= usize::from(BUFFER_POINTS)
    }

    /// Stores one point of the two channels' values, and schedules the next.
    pub(super) fn store(&mut self, values: [f64; 2]) {
        self.points.push(values.map(StoredValue::from_value));
        if self.points.len() > usize::from(BUFFER_POINTS) {
            self.points.remove(0);
        }
        self.next = match (self.next, self.period()) {
            (Some(t), Some(p)) if !self.full() => Some(t + p),
            _ => None,
        };
    }

    /// `SPTS?`.
    pub(super) fn len(&self) -> u16 {
        // At most BUFFER_POINTS, which fits.
        u16::try_from(self.points.len()).unwrap_or(BUFFER_POINTS)
    }

    /// The points a trace query asks for, or `None` when j + k exceeds `SPTS?`.
    pub(super) fn trace(&self, r: &TraceRange) -> Option<Vec<StoredValue>> {
        let (j, k) = (usize::from(r.start), usize::from(r.count));
        let ch = match r.channel {
            TraceChannel::Ch1 => 0,
            TraceChannel::Ch2 => 1,
        };
        (j + k <= self.points.len()).then(|| self.points[j..j + k].iter().map(|p| p[ch]).collect())
    }
}
