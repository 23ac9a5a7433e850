//! The SR830's internal data buffer (manual Rev. 2.5, ch. 5 "Data Storage", p. 5-14
//! … 5-18): its parameters, the binary formats `TRCB?` and `TRCL?` return, the framer
//! that cuts a binary reply out of the line stream, and the cost model that says when
//! reading through the buffer is faster than `SNAP?` polling.
//!
//! The facts used (the page beside each):
//! - The buffer holds up to [`BUFFER_POINTS`] points of each of the CH1 and CH2
//!   displays, "the quantities which are displayed" (Data Storage, p. 5-14): `DDEF 1,0,0`
//!   and `DDEF 2,0,0` make them X and Y (DDEF, p. 5-8 … 5-9).
//! - `SRAT i` sets the sample rate, 62.5 mHz × 2^i for i = 0 … 13 (512 Hz), or 14 for
//!   triggered ([`SampleRate`]); both displays are sampled "at the same rate (and at the
//!   same times)" (p. 5-14).
//! - `SEND i`: 1 Shot (0) stops storing when the buffer is full; Loop (1) wraps
//!   ([`EndOfScan`]). "If data storage is set to Loop mode, make sure that storage is
//!   paused before reading any data" (TRCA?, p. 5-16): in 1 Shot mode the bins keep
//!   their numbers, so Gonio reads them while storage goes on (assumed from that
//!   sentence: the manual names no other reason to pause).
//! - `STRT` starts or resumes storage (ignored while storing), `PAUS` pauses it, `REST`
//!   resets the buffer, "at any time" (p. 5-15).
//! - `SPTS?` returns the points stored, N; bins are numbered 0 (oldest) to N − 1; it
//!   "can be sent at any time, even while storage is in progress" (p. 5-16).
//! - `TRCA? i,j,k`, `TRCB? i,j,k`, `TRCL? i,j,k` read k ≥ 1 points of channel i from bin
//!   j ≥ 0; "if j+k exceeds the number of stored points ... an error occurs" (p. 5-16,
//!   5-17). TRCA? answers ASCII values, each followed by a comma ("-1.234567e-009,
//!   +7.654321e-009,"), then the terminator. TRCB? answers IEEE single floats and TRCL?
//!   the instrument's own format ([`StoredValue`]), 4 bytes a point, "not separated by
//!   any delimiter", no terminator on RS-232 (p. 5-17). TRCL? is the faster: "The data
//!   within the SR830 is stored in this format" (p. 5-17).
//! - On RS-232, "the binary transfer does not pause between bytes ... the host must
//!   always be ready to receive the next byte. In general, using binary transfers on
//!   the RS232 interface is not recommended" (p. 5-17 … 5-18). Gonio handles it as the
//!   page asks: the framer takes exactly 4k bytes, the reply's deadline allows their
//!   time at the baud rate, and a short or late transfer is a garbled reply, asked
//!   again.

use std::collections::VecDeque;

use super::{Command, FilterSlope, REPLY_TERMINATOR, TimeConstant, parse_line};
use crate::codec::coded_enum;
use crate::framing::{FrameError, Framer, LineFramer};

/// Points the buffer holds per channel (Data Storage, p. 5-14).
pub const BUFFER_POINTS: u16 = 16383;

/// Bytes per point of a binary transfer, `TRCB?` or `TRCL?` (p. 5-17).
pub const POINT_BYTES: usize = 4;

coded_enum! {
    /// The sample rate, `SRAT i` (p. 5-15): 62.5 mHz × 2^i, or triggered.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
    pub enum SampleRate: u8, index / from_index {
        /// 62.5 mHz.
        Hz0_0625 = 0,
        /// 125 mHz.
        Hz0_125 = 1,
        /// 250 mHz.
        Hz0_25 = 2,
        /// 500 mHz.
        Hz0_5 = 3,
        /// 1 Hz.
        Hz1 = 4,
        /// 2 Hz.
        Hz2 = 5,
        /// 4 Hz.
        Hz4 = 6,
        /// 8 Hz.
        Hz8 = 7,
        /// 16 Hz.
        Hz16 = 8,
        /// 32 Hz.
        Hz32 = 9,
        /// 64 Hz.
        Hz64 = 10,
        /// 128 Hz.
        Hz128 = 11,
        /// 256 Hz.
        Hz256 = 12,
        /// 512 Hz.
        Hz512 = 13,
        /// A point per trigger (rear panel or `TRIG`).
        Trigger = 14,
    }
}

impl SampleRate {
    /// Samples a second; `None` when triggered.
    pub fn hz(self) -> Option<f64> {
        (self != SampleRate::Trigger).then(|| 0.0625 * f64::from(1u32 << self.index()))
    }
}

coded_enum! {
    /// What storage does when the buffer is full, `SEND i` (p. 5-15).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum EndOfScan: u8, index / from_index {
        /// Storage stops at the end of the buffer.
        OneShot = 0,
        /// Storage wraps round and keeps the latest points.
        Loop = 1,
    }
}

coded_enum! {
    /// A display channel, whose buffer `TRCA?`/`TRCB?`/`TRCL?` read and `DDEF` sets.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
    pub enum TraceChannel: u8, code / from_code {
        /// CH1 (X, R, X noise, Aux In 1 or 2).
        Ch1 = 1,
        /// CH2 (Y, θ, Y noise, Aux In 3 or 4).
        Ch2 = 2,
    }
}

/// `DDEF i,j,k`: channel i shows quantity j (0 = X on CH1, Y on CH2; 1 = R, θ; 2 = X,
/// Y noise; 3, 4 = Aux In) divided by ratio k (0 = none) (DDEF, p. 5-8).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct DisplayDef {
    /// The channel.
    pub channel: TraceChannel,
    /// The quantity, 0..=4.
    pub quantity: u8,
    /// The ratio, 0..=2.
    pub ratio: u8,
}

impl DisplayDef {
    /// X on CH1 and Y on CH2, no ratio: what a magnitude reading stores.
    pub const XY: [DisplayDef; 2] = [
        DisplayDef {
            channel: TraceChannel::Ch1,
            quantity: 0,
            ratio: 0,
        },
        DisplayDef {
            channel: TraceChannel::Ch2,
            quantity: 0,
            ratio: 0,
        },
    ];

    /// The definition, if the manual lists its numbers.
    pub fn new(channel: TraceChannel, quantity: u8, ratio: u8) -> Option<Self> {
        (quantity <= 4 && ratio <= 2).then_some(DisplayDef {
            channel,
            quantity,
            ratio,
        })
    }
}

/// `i,j,k` of the trace queries: `count` points of `channel` from bin `start`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TraceRange {
    /// The channel.
    pub channel: TraceChannel,
    /// The first bin, 0 = oldest.
    pub start: u16,
    /// Points, at least 1.
    pub count: u16,
}

impl TraceRange {
    /// The range, if it can lie within a full buffer.
    pub fn new(channel: TraceChannel, start: u16, count: u16) -> Option<Self> {
        (count >= 1 && u32::from(start) + u32::from(count) <= u32::from(BUFFER_POINTS)).then_some(
            TraceRange {
                channel,
                start,
                count,
            },
        )
    }

    /// Bytes of its binary reply.
    pub fn binary_len(&self) -> usize {
        usize::from(self.count) * POINT_BYTES
    }
}

/// A point as the SR830 stores it and `TRCL?` sends it: value = m × 2^(exp − 124),
/// m a signed 16-bit mantissa (bytes 0 and 1, LSB first), exp 0 … 248 (byte 2), byte 3
/// always zero (TRCL?, p. 5-17).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct StoredValue {
    /// m.
    pub mantissa: i16,
    /// exp, 0..=248.
    pub exponent: u8,
}

/// The largest exponent of a [`StoredValue`] (p. 5-17).
pub const MAX_EXPONENT: u8 = 248;

impl StoredValue {
    /// The value it stands for.
    pub fn value(self) -> f64 {
        f64::from(self.mantissa) * 2f64.powi(i32::from(self.exponent) - 124)
    }

    /// Its four bytes.
    pub fn to_bytes(self) -> [u8; 4] {
        let [m0, m1] = self.mantissa.to_le_bytes();
        [m0, m1, self.exponent, 0]
    }

    /// The point of four bytes, if the exponent is in range and byte 3 is zero.
    pub fn from_bytes(b: [u8; 4]) -> Option<Self> {
        (b[2] <= MAX_EXPONENT && b[3] == 0).then(|| StoredValue {
            mantissa: i16::from_le_bytes([b[0], b[1]]),
            exponent: b[2],
        })
    }

    /// The nearest stored point to `v`, normalised so that the mantissa keeps 15
    /// significant bits (|m| ≥ 16384) where the exponent range allows; a non-finite `v`
    /// is 0. How the firmware normalises is not in the manual (assumed: a relative
    /// resolution of 2^−15, about 3e-5, the finest the format offers).
    pub fn from_value(v: f64) -> Self {
        if !v.is_finite() || v == 0.0 {
            return StoredValue {
                mantissa: 0,
                exponent: 124,
            };
        }
        // Exponent e with |v|·2^(124−e) in [16384, 32768).
        let k = (32767.0 / v.abs()).log2().floor() as i32;
        let mut e = (124 - k).clamp(0, i32::from(MAX_EXPONENT));
        loop {
            let m = (v * 2f64.powi(124 - e)).round();
            if m.abs() <= 32767.0 || e >= i32::from(MAX_EXPONENT) {
                let m = m.clamp(-32768.0, 32767.0);
                return StoredValue {
                    // Exact: an integral value clamped to i16's range; e in 0..=248.
                    mantissa: m as i16,
                    exponent: e as u8,
                };
            }
            e += 1;
        }
    }
}

/// Decodes a `TRCL?` reply: one value per 4 bytes. `None` if the length is not a
/// multiple of 4 or a point is malformed (exponent over 248, byte 3 not zero).
pub fn decode_trcl(bytes: &[u8]) -> Option<Vec<StoredValue>> {
    if !bytes.len().is_multiple_of(POINT_BYTES) {
        return None;
    }
    bytes
        .chunks_exact(POINT_BYTES)
        .map(|c| StoredValue::from_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// Decodes a `TRCB?` reply: IEEE single floats, least significant byte first (p. 5-17:
/// "IEEE format binary floating point numbers"; the byte order is the PC's, as the
/// manual's own examples read them into a float array; assumed little-endian). `None`
/// if the length is not a multiple of 4.
pub fn decode_trcb(bytes: &[u8]) -> Option<Vec<f32>> {
    if !bytes.len().is_multiple_of(POINT_BYTES) {
        return None;
    }
    Some(
        bytes
            .chunks_exact(POINT_BYTES)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect(),
    )
}

/// What the next reply of the line is, as [`Sr830Framer`] expects it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Expect {
    /// A line ended by CR.
    Line,
    /// Exactly this many bytes, no terminator.
    Binary(usize),
}

/// The SR830's framer: lines ended by CR, except the replies to `TRCB?` and `TRCL?`,
/// which are exactly 4k bytes with no terminator (p. 5-17). It learns which reply
/// comes next from the lines the host sends ([`Framer::sent`]), parsed as the
/// instrument parses them; while no binary query is outstanding it is exactly a
/// [`LineFramer`], so every other reply is framed as before.
#[derive(Debug, Clone)]
pub struct Sr830Framer {
    lines: LineFramer,
    /// The replies still due, in order, while a binary one is among them.
    expect: VecDeque<Expect>,
    /// The binary frame being gathered.
    binary: Vec<u8>,
    /// Frames cut out of binary replies, delivered in order with the lines.
    ready: VecDeque<Result<Vec<u8>, FrameError>>,
}

impl Sr830Framer {
    /// A framer for replies of at most `max_line` bytes (binary replies excepted).
    pub fn new(max_line: usize) -> Self {
        Sr830Framer {
            lines: LineFramer::new(REPLY_TERMINATOR, max_line),
            expect: VecDeque::new(),
            binary: Vec::new(),
            ready: VecDeque::new(),
        }
    }

    /// The replies a sent line asks for, if one of them is binary.
    fn replies(sent: &[u8]) -> Option<Vec<Expect>> {
        let mut any_binary = false;
        let mut out = Vec::new();
        for part in sent
            .split(|b| *b == b'\n' || *b == b'\r')
            .filter(|l| !l.is_empty())
        {
            for c in parse_line(part).into_iter().flatten() {
                match c {
                    Command::TraceBinary(r) | Command::TraceStored(r) => {
                        any_binary = true;
                        out.push(Expect::Binary(r.binary_len()));
                    }
                    c if c.is_query() => out.push(Expect::Line),
                    _ => {}
                }
            }
        }
        any_binary.then_some(out)
    }
}

impl Framer for Sr830Framer {
    fn push(&mut self, mut bytes: &[u8]) {
        while !bytes.is_empty() {
            match self.expect.front().copied() {
                Some(Expect::Binary(n)) => {
                    let take = (n - self.binary.len()).min(bytes.len());
                    self.binary.extend_from_slice(&bytes[..take]);
                    bytes = &bytes[take..];
                    if self.binary.len() == n {
                        self.ready.push_back(Ok(std::mem::take(&mut self.binary)));
                        self.expect.pop_front();
                    }
                }
                Some(Expect::Line) => {
                    // One line at a time, so that a binary reply after it is not read
                    // as text.
                    let end = bytes.iter().position(|b| *b == REPLY_TERMINATOR);
                    let cut = end.map_or(bytes.len(), |i| i + 1);
                    self.lines.push(&bytes[..cut]);
                    bytes = &bytes[cut..];
                    while let Some(l) = self.lines.next_line() {
                        self.ready.push_back(l);
                        if end.is_some() {
                            self.expect.pop_front();
                        }
                    }
                }
                None => {
                    self.lines.push(bytes);
                    bytes = &[];
                    while let Some(l) = self.lines.next_line() {
                        self.ready.push_back(l);
                    }
                }
            }
        }
    }

    fn next_frame(&mut self) -> Option<Result<Vec<u8>, FrameError>> {
        self.ready.pop_front()
    }

    fn clear(&mut self) {
        self.lines.clear();
        self.expect.clear();
        self.binary.clear();
        self.ready.clear();
    }

    fn sent(&mut self, bytes: &[u8]) {
        match Self::replies(bytes) {
            Some(r) => self.expect.extend(r),
            None if !self.expect.is_empty() => {
                // Keep the order of the replies still due behind a binary one.
                let queries = parse_line(bytes)
                    .into_iter()
                    .flatten()
                    .filter(Command::is_query)
                    .count();
                self.expect
                    .extend(std::iter::repeat_n(Expect::Line, queries));
            }
            None => {}
        }
    }
}

/// Seconds `bytes` characters take on the wire at `baud`, 10 bits a character (start,
/// 8 data, stop).
pub fn wire_seconds(bytes: usize, baud: u32) -> f64 {
    bytes as f64 * 10.0 / f64::from(baud.max(1))
}

/// The variance of the mean of many samples of first-order noise (correlation
/// e^(−Δ/T)) taken `spacing_tc` = Δ/T apart, relative to continuous averaging over the
/// same time: (Δ/2T)·(1 + ρ)/(1 − ρ), ρ = e^(−Δ/T). It tends to 1 as Δ → 0 and grows
/// as Δ/2T once the samples are independent.
pub fn sampling_penalty(spacing_tc: f64) -> f64 {
    if spacing_tc <= 0.0 || !spacing_tc.is_finite() {
        return 1.0;
    }
    let rho = (-spacing_tc).exp();
    0.5 * spacing_tc * (1.0 + rho) / (1.0 - rho)
}

/// How a buffered reading samples: the rate, and the expected seconds it adds per
/// second of averaging over continuous averaging.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BufferPlan {
    /// The sample rate.
    pub rate: SampleRate,
    /// Samples a second.
    pub hz: f64,
    /// [`sampling_penalty`] at this rate and time constant.
    pub penalty: f64,
}

/// The sample rate a buffered reading at `tc` uses on a port at `baud`: the fastest
/// whose points (X and Y, 8 bytes a sample) the port carries in at most `load` of the
/// time they take to store, so that the transfer keeps up with storage, and no faster
/// than four samples a time constant (denser samples add almost nothing:
/// [`sampling_penalty`] is within 2 % of 1 at T/4). `None` when even the slowest
/// useful rate (one sample per two time constants) is too fast for the port.
pub fn buffer_plan(tc: TimeConstant, baud: u32, load: f64) -> Option<BufferPlan> {
    let t = tc.seconds();
    let pair_s = wire_seconds(2 * POINT_BYTES, baud);
    SampleRate::ALL
        .iter()
        .rev()
        .filter_map(|r| Some((*r, r.hz()?)))
        .find(|(_, hz)| hz * pair_s <= load && *hz <= 4.0 / t)
        .filter(|(_, hz)| 1.0 / hz <= 2.0 * t)
        .map(|(rate, hz)| BufferPlan {
            rate,
            hz,
            penalty: sampling_penalty(1.0 / (hz * t)),
        })
}

/// The `SNAP?` spacing's penalty at `tc`: snapshots one exchange (`exchange_s`) apart.
pub fn snapshot_penalty(tc: TimeConstant, exchange_s: f64) -> f64 {
    sampling_penalty(exchange_s / tc.seconds())
}

/// Whether a reading at `tc` and `slope` is faster through the buffer than by `SNAP?`:
/// the averaging costs `penalty` × its continuous time either way, and the buffer adds
/// a fixed `overhead_s` per reading (the set-up line, `SPTS?`, the last transfer's
/// wait). With an expected continuous averaging time of `averaging_s`, the buffer wins
/// when `averaging_s`·(p_snap − p_buffer) > `overhead_s`.
pub fn buffer_is_faster(
    tc: TimeConstant,
    baud: u32,
    exchange_s: f64,
    averaging_s: f64,
    overhead_s: f64,
) -> Option<BufferPlan> {
    let plan = buffer_plan(tc, baud, BUFFER_LOAD)?;
    let gain = averaging_s * (snapshot_penalty(tc, exchange_s) - plan.penalty);
    (gain > overhead_s).then_some(plan)
}

/// The share of the storage time a buffered reading lets the transfer take, so that
/// the commands between transfers fit in the rest.
pub const BUFFER_LOAD: f64 = 0.6;

/// The continuous-averaging variance factor of a filter: the variance of X averaged
/// over τ seconds is density² × this / τ (2T·ENBW; 5/32 at 24 dB/oct).
pub fn continuous_factor(slope: FilterSlope, tc: TimeConstant) -> f64 {
    2.0 * tc.seconds() * slope.enbw_hz(tc)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stored_values_decode_as_the_manual_defines_them() {
        // m = 16384 (0x4000), exp = 110: 16384 × 2^−14 = 1.
        let one = StoredValue::from_bytes([0x00, 0x40, 110, 0]).expect("valid");
        assert_eq!(one.value(), 1.0);
        // m = −1 (0xFFFF), exp = 124: −1.
        assert_eq!(
            StoredValue::from_bytes([0xFF, 0xFF, 124, 0])
                .expect("valid")
                .value(),
            -1.0
        );
        // Byte 3 is always zero; the exponent is at most 248.
        assert_eq!(StoredValue::from_bytes([0, 0x40, 110, 1]), None);
        assert_eq!(StoredValue::from_bytes([0, 0x40, 249, 0]), None);
        assert_eq!(StoredValue::from_value(1.0), one);
        assert_eq!(one.to_bytes(), [0x00, 0x40, 110, 0]);
    }

    #[test]
    fn ieee_points_decode_little_endian() {
        let bytes = [0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x00, 0xC0];
        assert_eq!(decode_trcb(&bytes), Some(vec![1.0, -2.0]));
        assert_eq!(decode_trcb(&bytes[..7]), None);
    }

    #[test]
    fn the_sample_rates_double_from_62_5_mhz_to_512_hz() {
        assert_eq!(SampleRate::Hz0_0625.hz(), Some(0.0625));
        assert_eq!(SampleRate::Hz1.hz(), Some(1.0));
        assert_eq!(SampleRate::Hz512.hz(), Some(512.0));
        assert_eq!(SampleRate::Trigger.hz(), None);
    }

    #[test]
    fn the_sampling_penalty_is_one_when_continuous_and_dt_over_2t_when_sparse() {
        assert!((sampling_penalty(1e-4) - 1.0).abs() < 1e-6);
        assert!((sampling_penalty(20.0) - 10.0).abs() < 1e-6);
        // Independent check at Δ = T: (1/2)(1 + e^−1)/(1 − e^−1).
        let e = (-1f64).exp();
        assert!((sampling_penalty(1.0) - 0.5 * (1.0 + e) / (1.0 - e)).abs() < 1e-12);
    }

    #[test]
    fn the_buffer_rate_keeps_the_transfer_within_the_port() {
        // 300 ms: four samples a time constant, 13.3 Hz, caps it at 8 Hz.
        let tc = TimeConstant::new(9).expect("valid");
        assert_eq!(tc.seconds(), 0.3);
        assert_eq!(
            buffer_plan(tc, 9600, 0.6).expect("valid").rate,
            SampleRate::Hz8
        );
        // 9600 baud: 8 bytes a sample take 8.33 ms, so at most 72 Hz at a 0.6 load.
        let p = buffer_plan(TimeConstant::new(6).expect("valid"), 9600, 0.6).expect("valid");
        assert_eq!(p.rate, SampleRate::Hz64);
        // 30 ms: four samples a time constant is 133 Hz, the port allows 64.
        let p = buffer_plan(TimeConstant::new(7).expect("valid"), 9600, 0.6).expect("valid");
        assert_eq!(p.rate, SampleRate::Hz64);
        // 10 µs: no rate samples twice a time constant.
        assert_eq!(
            buffer_plan(TimeConstant::new(0).expect("valid"), 9600, 0.6),
            None
        );
    }

    #[test]
    fn the_framer_cuts_binary_replies_by_length_and_lines_by_cr() {
        let mut f = Sr830Framer::new(256);
        f.sent(b"SPTS?;TRCL? 1,0,2\n");
        // A CR inside the binary reply is data, not a terminator.
        f.push(b"2\r\x0d\x40\x6e\x00");
        f.push(b"\x00\x00\x7c\x00");
        f.push(b"7\r");
        assert_eq!(f.next_frame(), Some(Ok(b"2".to_vec())));
        assert_eq!(
            f.next_frame(),
            Some(Ok(vec![0x0d, 0x40, 0x6e, 0, 0, 0, 0x7c, 0]))
        );
        assert_eq!(f.next_frame(), Some(Ok(b"7".to_vec())));
        assert_eq!(f.next_frame(), None);
    }
}
