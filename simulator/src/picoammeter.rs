//! The simulated Keithley 6485 picoammeter with a silicon photodiode on its input,
//! device side: command lines in, the exact reply bytes a real 6485 sends on RS-232
//! (set to CR) out. Wire format and facts: [`gonio_proto::k6485`] (Model 6485
//! Instruction Manual, 6485-901-01).
//!
//! # Protocol
//! - Lines are parsed with [`parse_line`]: `;`-separated rooted commands, short or long
//!   forms, case ignored. Only queries reply, each with its own CR-terminated line. A
//!   refused command queues its SCPI error (`SYST:ERR?`) and sets CME or EXE in
//!   `*ESR?`, silently.
//! - Commands run in order, and a measurement keeps the instrument busy: `INIT` and
//!   `READ?` take `conversions × NPLC / line frequency`; every command is handled when
//!   the one before has finished. [`Picoammeter::handle_line`] appends the replies at
//!   once, but they are due only at [`Picoammeter::busy_until`]: a transport must hold
//!   them until then (on virtual time, deliver them at that time).
//! - Power-up and `*RST`: 20 mA, instrument autorange on, zero check **on**, zero
//!   correct off (acquired value 0), filter off (count 10, repeat), NPLC 5 (50 Hz) or 6
//!   (60 Hz), the `SLOW` rate of p. 4-6, trigger count 1; `*ESR?` carries PON after
//!   power-up. (The manual's reset table was not checked for every item: UNCONFIRMED.)
//! - Readings are always sent as `FORM:ELEM READ,TIME,STAT`, the only list the codec
//!   knows; the timestamp is seconds since power-up, wrapping at 100 000 s.
//!
//! # Physics
//! - Photocurrent = responsivity × optical power + dark current, piecewise constant
//!   from each [`Picoammeter::set_input`]. The front end follows it as one pole whose
//!   10–90 % rise time is the range's (Appendix A: 8 ms on 2 nA and 20 nA, 500 µs
//!   above): τ = rise / ln 9. Each conversion averages the front end's output over its
//!   integration window, exactly.
//! - Noise of one conversion of length T = NPLC / line frequency (a boxcar integrator,
//!   noise bandwidth B = 1/(2T)): shot 2qIB, Johnson 4kTB/R of the photodiode's shunt
//!   resistance, and the meter's own noise, `meter_noise_a` of the range at 1 PLC
//!   scaled as white noise by 1/NPLC in variance (the manual's Figure 4-1 shows it
//!   rising again at long integrations: not modelled). The repeat filter averages
//!   `count` conversions; the moving filter averages the last `count` (fewer until its
//!   stack fills; cleared by a range or filter change). `count` is 1 to 100: "Both are
//!   a simple average of one to 100 reading conversions" (p. 4-8).
//! - The meter adds an input offset current, `input_offset_a`, the same on every
//!   range. Zero check shunts the input: readings are the offset and the meter's
//!   noise only. `SYST:ZCOR:ACQ` stores the last zero-checked reading (or takes one),
//!   and zero correct subtracts it.
//! - A conversion whose current exceeds 1.05 × full scale overflows: `+9.9E37`, status
//!   bit 0. With the instrument's autorange on, each conversion first picks the most
//!   sensitive range whose full scale holds the present current.
//! - Not modelled: range-change transients, the overvoltage condition, limits, math,
//!   buffers, the voltage burden.

use std::collections::VecDeque;

use gonio_proto::k6485::{
    Command, Current, EventStatus, FILTER_COUNT, FilterType, Identity, LineFrequency, MIN_NPLC,
    OVERRANGE_FACTOR, REPLY_TERMINATOR, Range, Reply, Sample, ScpiError, StatusWord, parse_line,
};
use rand::{Rng, SeedableRng};

use crate::twin::{FieldError, ensure};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// The elementary charge, C.
pub const ELEMENTARY_CHARGE: f64 = 1.602_176_634e-19;

/// Boltzmann's constant, J/K.
pub const BOLTZMANN: f64 = 1.380_649e-23;

/// The timestamp wraps after this many seconds (FORMat:ELEMents, p. 13-6).
const TIMESTAMP_WRAP_S: f64 = 100_000.0;

/// The error queue's depth; a fuller queue drops new errors (SCPI: −350 "Queue
/// overflow" is not modelled).
const ERROR_QUEUE: usize = 10;

/// The photodiode and the meter, as a config file writes them (`[picoammeter]`, as in
/// `config/sim-mixed.toml`). Every field is optional (the defaults are [`Default`]'s)
/// and unknown fields are refused.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PicoammeterConfig {
    /// Photocurrent per optical watt, A/W. A silicon photodiode near 550 nm: about 0.3.
    pub responsivity_a_per_w: f64,
    /// The photodiode's dark current, amps (at the meter's near-zero bias).
    pub dark_current_a: f64,
    /// The photodiode's shunt resistance, ohms: its Johnson noise current.
    pub shunt_resistance_ohm: f64,
    /// The photodiode's temperature, kelvin, for the Johnson noise.
    pub temperature_k: f64,
    /// The meter's input offset current, amps: what zero check reads and zero
    /// correct removes.
    pub input_offset_a: f64,
    /// The meter's rms noise per range, 2 nA first, amps, for one conversion at 1 PLC.
    /// Default: the manual's typical rms noise (Appendix A, [`Range::noise_rms_a`]).
    pub meter_noise_a: [f64; 8],
    /// The front end's 10–90 % rise time per range, 2 nA first, seconds. Default:
    /// Appendix A ([`Range::rise_time_s`]).
    pub rise_time_s: [f64; 8],
    /// The mains frequency, Hz (50 or 60): what `SYST:LFR?` answers and 1 PLC is.
    pub line_frequency_hz: u32,
    /// Serial number field of `*IDN?`.
    pub serial: String,
    /// Firmware field of `*IDN?`.
    pub firmware: String,
}

impl Default for PicoammeterConfig {
    fn default() -> Self {
        PicoammeterConfig {
            responsivity_a_per_w: 0.3,
            dark_current_a: 10e-12,
            shunt_resistance_ohm: 1e9,
            temperature_k: 295.0,
            input_offset_a: 2e-12,
            meter_noise_a: Range::all()
                .map(Range::noise_rms_a)
                .collect::<Vec<_>>()
                .try_into()
                .unwrap_or([0.0; 8]),
            rise_time_s: Range::all()
                .map(Range::rise_time_s)
                .collect::<Vec<_>>()
                .try_into()
                .unwrap_or([0.0; 8]),
            line_frequency_hz: 50,
            serial: "1234567".into(),
            firmware: "B03   Sep 25 2002 10:53:29/A02  /E".into(),
        }
    }
}

impl PicoammeterConfig {
    /// Checks that every number is finite and in range, and the `*IDN?` fields are
    /// printable ASCII without commas.
    pub fn validate(&self) -> Result<(), FieldError> {
        let within = |v: f64, lo: f64, hi: f64| v.is_finite() && v >= lo && v <= hi;
        for (field, v, lo, hi) in [
            ("responsivity_a_per_w", self.responsivity_a_per_w, 0.0, 10.0),
            ("dark_current_a", self.dark_current_a, -1e-3, 1e-3),
            ("shunt_resistance_ohm", self.shunt_resistance_ohm, 1.0, 1e16),
            ("temperature_k", self.temperature_k, 1.0, 1000.0),
            ("input_offset_a", self.input_offset_a, -1e-3, 1e-3),
        ] {
            FieldError::within(field, v, lo, hi)?;
        }
        let noise = self.meter_noise_a.iter().all(|v| within(*v, 0.0, 1e-3));
        ensure!(noise; "meter_noise_a", "each must be in [0, 1e-3] A");
        let rise = self.rise_time_s.iter().all(|v| within(*v, 1e-9, 10.0));
        ensure!(rise; "rise_time_s", "each must be in [1e-9, 10] s");
        let hz = self.line_frequency_hz;
        let ok = LineFrequency::from_hz(hz).is_some();
        ensure!(ok; "line_frequency_hz", "{hz} is not 50 or 60");
        FieldError::identity("serial", &self.serial, true)?;
        FieldError::identity("firmware", &self.firmware, true)
    }

    /// The line frequency (50 Hz for a value [`validate`](Self::validate) refuses).
    fn line_frequency(&self) -> LineFrequency {
        LineFrequency::from_hz(self.line_frequency_hz).unwrap_or_default()
    }
}

/// The instrument's settings (what `*RST` restores).
#[derive(Clone, Debug, PartialEq)]
struct Settings {
    range: Range,
    autorange: bool,
    nplc: f64,
    filter_on: bool,
    filter_count: u32,
    filter_type: FilterType,
    trigger_count: u32,
    zero_check: bool,
    zero_correct: bool,
}

impl Settings {
    fn reset(lf: LineFrequency) -> Self {
        Settings {
            range: Range::LEAST,
            autorange: true,
            nplc: match lf {
                LineFrequency::Hz50 => 5.0,
                LineFrequency::Hz60 => 6.0,
            },
            filter_on: false,
            filter_count: 10,
            filter_type: FilterType::Repeat,
            trigger_count: 1,
            zero_check: true,
            zero_correct: false,
        }
    }
}

/// The simulated 6485 with its photodiode. Time is virtual: every call says when it
/// happens (seconds since the simulation's origin, which is power-up).
#[derive(Clone, Debug)]
pub struct Picoammeter {
    config: PicoammeterConfig,
    rng: ChaCha8Rng,
    settings: Settings,
    /// Optical power from each time on: (time, watts), times increasing.
    input: Vec<(f64, f64)>,
    /// The front end's output current and the time it describes.
    front_t: f64,
    front_a: f64,
    /// When the instrument will have finished what it was asked.
    busy_until: f64,
    /// The moving filter's stack (raw conversion values, before zero correction).
    stack: VecDeque<f64>,
    /// The acquired zero correction value, amps.
    zero_value: f64,
    /// The last reading taken with zero check on, raw.
    last_zero_checked: Option<f64>,
    /// The last reading, for `FETC?`.
    last: Vec<Sample>,
    errors: VecDeque<ScpiError>,
    esr: u8,
}

impl Picoammeter {
    /// An instrument just powered up at time 0 (see the module docs), with no light, its
    /// front end settled on the dark current, noise from a generator seeded by `seed`.
    pub fn new(config: &PicoammeterConfig, seed: u64) -> Self {
        let settings = Settings::reset(config.line_frequency());
        Picoammeter {
            rng: ChaCha8Rng::seed_from_u64(seed),
            settings,
            input: vec![(0.0, 0.0)],
            front_t: 0.0,
            front_a: config.dark_current_a,
            busy_until: 0.0,
            stack: VecDeque::new(),
            zero_value: 0.0,
            last_zero_checked: None,
            last: Vec::new(),
            errors: VecDeque::new(),
            esr: EventStatus::PON,
            config: config.clone(),
        }
    }

    /// The optical power on the photodiode from time `t` on, watts, until the next
    /// call: piecewise constant. A `t` before earlier changes replaces them (the light
    /// history is rewritten from `t`), but never before what was already measured.
    pub fn set_input(&mut self, t: f64, optical_power_w: f64) {
        let t = if t.is_finite() {
            t.max(self.front_t)
        } else {
            self.front_t
        };
        let p = if optical_power_w.is_finite() {
            optical_power_w
        } else {
            0.0
        };
        self.input.retain(|(s, _)| *s < t);
        self.input.push((t, p));
        // Changes the front end has passed matter only through the last of them: drop
        // the rest, so that a long run's history does not grow without bound.
        let front_t = self.front_t;
        if let Some(k) = self.input.iter().rposition(|(s, _)| *s <= front_t) {
            self.input.drain(..k);
        }
    }

    /// One received command line (terminator removed) at time `now`: runs its
    /// commands in order, each when the instrument is free, and appends each query's
    /// reply (CR-terminated) to `out`. The replies are due at
    /// [`busy_until`](Self::busy_until).
    pub fn handle_line(&mut self, now: f64, line: &[u8], out: &mut Vec<u8>) {
        if now.is_finite() {
            self.busy_until = self.busy_until.max(now);
        }
        for parsed in parse_line(line) {
            match parsed {
                Ok(command) => {
                    if let Some(reply) = self.execute(&command, out) {
                        reply.encode(out);
                    }
                }
                Err(e) => {
                    self.esr |= e.event_status().0;
                    self.queue(e.code(), e.message());
                }
            }
        }
    }

    /// When the replies appended by the last [`handle_line`](Self::handle_line) are
    /// ready, seconds: after the measurements it asked for (and any still under way
    /// when it arrived). A transport delivers them then, not before.
    pub fn busy_until(&self) -> f64 {
        self.busy_until
    }

    /// Starts a measurement afresh at `now`: the front end settled on the present
    /// input, the moving filter's stack empty, nothing under way, the noise generator
    /// reseeded with `seed`. Settings and the acquired zero are kept.
    ///
    /// An idealisation for reproducibility, as for the lock-in: a reading then depends
    /// only on where it is taken and on `seed`, so a run resumed after a kill reads
    /// exactly what the uninterrupted run read.
    pub fn restart(&mut self, now: f64, seed: u64) {
        let now = if now.is_finite() { now } else { self.front_t };
        self.front_t = self.front_t.max(now);
        self.front_a = self.photocurrent_at(self.front_t);
        self.busy_until = self.front_t;
        self.stack.clear();
        self.rng = ChaCha8Rng::seed_from_u64(seed);
    }

    /// The range the instrument is on.
    pub fn range(&self) -> Range {
        self.settings.range
    }

    /// True while zero check is on.
    pub fn zero_check(&self) -> bool {
        self.settings.zero_check
    }

    /// True while zero correct is on.
    pub fn zero_correct(&self) -> bool {
        self.settings.zero_correct
    }

    /// The acquired zero correction value, amps.
    pub fn zero_value(&self) -> f64 {
        self.zero_value
    }

    /// The configuration.
    pub fn config(&self) -> &PicoammeterConfig {
        &self.config
    }

    /// The photodiode's current at `t` (responsivity × power + dark), amps, before the
    /// front end's settling: what a settled, noise-free, uncorrected reading shows
    /// (plus the meter's offset).
    pub fn photocurrent_at(&self, t: f64) -> f64 {
        let p = self
            .input
            .iter()
            .rev()
            .find(|(s, _)| *s <= t)
            .map_or(0.0, |(_, p)| *p);
        self.config.responsivity_a_per_w * p + self.config.dark_current_a
    }

    /// Seconds of one conversion.
    pub fn conversion_s(&self) -> f64 {
        self.settings.nplc * self.config.line_frequency().plc_s()
    }

    /// The standard deviation of one conversion at photocurrent `current_a` on
    /// `range`, amps: shot, Johnson and the meter's noise added in quadrature (see the
    /// module docs). With zero check on, pass `None`: the source is disconnected and
    /// only the meter's noise remains.
    pub fn conversion_sigma(&self, range: Range, current_a: Option<f64>) -> f64 {
        let t = self.conversion_s();
        let meter = self.config.meter_noise_a[usize::from(range.index())];
        let mut var = meter * meter / self.settings.nplc;
        if let Some(i) = current_a {
            // 2qIB and 4kTB/R with B = 1/(2T).
            var += ELEMENTARY_CHARGE * i.abs() / t;
            var += 2.0 * BOLTZMANN * self.config.temperature_k
                / (self.config.shunt_resistance_ohm * t);
        }
        var.sqrt()
    }

    /// Queues an error, unless the queue is full.
    fn queue(&mut self, code: i32, message: &str) {
        if self.errors.len() < ERROR_QUEUE {
            self.errors.push_back(ScpiError {
                code,
                message: message.to_string(),
            });
        }
    }

    /// A setting changed; no reply.
    fn set(&mut self, f: impl FnOnce(&mut Settings)) -> Option<Reply> {
        f(&mut self.settings);
        None
    }

    /// A setting changed that empties the moving filter's stack (a range or filter
    /// change, zero check); no reply.
    fn change(&mut self, f: impl FnOnce(&mut Settings)) -> Option<Reply> {
        self.stack.clear();
        self.set(f)
    }

    /// A command refused with SCPI error `code`: EXE in `*ESR?`, the error queued; no
    /// reply.
    fn refuse(&mut self, code: i32, message: &str) -> Option<Reply> {
        self.esr |= EventStatus::EXE;
        self.queue(code, message);
        None
    }

    /// Runs one parsed command at [`busy_until`](Self::busy_until): its reply, if any
    /// (readings are written to `out` directly).
    fn execute(&mut self, command: &Command, out: &mut Vec<u8>) -> Option<Reply> {
        match command {
            Command::Reset => {
                self.settings = Settings::reset(self.config.line_frequency());
                self.zero_value = 0.0;
                self.stack.clear();
                None
            }
            Command::Clear => {
                self.esr = 0;
                self.errors.clear();
                None
            }
            Command::Identify => Some(Reply::Identity(Identity {
                manufacturer: "KEITHLEY INSTRUMENTS INC.".into(),
                model: "MODEL 6485".into(),
                serial: self.config.serial.clone(),
                firmware: self.config.firmware.clone(),
            })),
            Command::EventStatus => Some(Reply::EventStatus(EventStatus(std::mem::take(
                &mut self.esr,
            )))),
            Command::NextError => Some(Reply::Error(
                self.errors.pop_front().unwrap_or_else(ScpiError::none),
            )),
            Command::ZeroCheck(on) => self.change(|s| s.zero_check = *on),
            Command::ZeroCorrectAcquire => {
                if !self.settings.zero_check {
                    // The manual: zero check must be on to acquire (−221 "Settings
                    // conflict" assumed).
                    return self.refuse(-221, "Settings conflict");
                }
                let value = match self.last_zero_checked {
                    Some(v) => v,
                    None => {
                        let s = self.measure();
                        s.first().and_then(|s| s.current.amps()).unwrap_or(0.0)
                    }
                };
                self.zero_value = value;
                None
            }
            Command::ZeroCorrect(on) => self.set(|s| s.zero_correct = *on),
            Command::SetRange(r) => self.change(|s| (s.range, s.autorange) = (*r, false)),
            Command::QueryRange => Some(Reply::Range(self.settings.range)),
            Command::AutoRange(on) => self.set(|s| s.autorange = *on),
            Command::SetNplc(n) => {
                let max = self.config.line_frequency().max_nplc();
                if !(MIN_NPLC..=max).contains(n) {
                    return self.refuse(-222, "Parameter data out of range");
                }
                self.set(|s| s.nplc = *n)
            }
            Command::FilterType(t) => self.change(|s| s.filter_type = *t),
            Command::FilterCount(n) => {
                // 1 to 100 (p. 4-8: "a simple average of one to 100 reading
                // conversions"); the codec has refused the rest with −222.
                let (lo, hi) = (*FILTER_COUNT.start(), *FILTER_COUNT.end());
                self.change(|s| s.filter_count = (*n).clamp(lo, hi))
            }
            Command::Filter(on) => self.change(|s| s.filter_on = *on),
            Command::FormatElements => None,
            Command::TriggerCount(n) => self.set(|s| s.trigger_count = *n),
            Command::Initiate => {
                self.last = self.measure();
                None
            }
            Command::Read => {
                self.last = self.measure();
                self.readings_reply(out);
                None
            }
            Command::Fetch => {
                if self.last.is_empty() {
                    // SCPI −230 "Data corrupt or stale": nothing to fetch.
                    return self.refuse(-230, "Data corrupt or stale");
                }
                self.readings_reply(out);
                None
            }
            Command::LineFrequency => Some(Reply::LineFrequency(self.config.line_frequency())),
        }
    }

    /// The last readings as one reply line: one reading is a [`Reply::Sample`]; more
    /// (a trigger count over 1) are their triples joined by commas on one line, as
    /// the instrument sends them (the codec reads only one).
    fn readings_reply(&self, out: &mut Vec<u8>) {
        for (k, sample) in self.last.iter().enumerate() {
            let mut one = Reply::Sample(*sample).to_bytes();
            one.pop();
            if k > 0 {
                out.push(b',');
            }
            out.extend_from_slice(&one);
        }
        out.push(REPLY_TERMINATOR);
    }

    /// Takes the trigger count's readings from [`busy_until`](Self::busy_until) on,
    /// and moves it past them.
    fn measure(&mut self) -> Vec<Sample> {
        let mut out = Vec::new();
        for _ in 0..self.settings.trigger_count.max(1) {
            out.push(self.reading());
        }
        out
    }

    /// One reading: its conversions (the repeat filter's count, else one), filtered,
    /// zero corrected, with its status word.
    fn reading(&mut self) -> Sample {
        let s = &self.settings;
        let repeat = s.filter_on && s.filter_type == FilterType::Repeat;
        let conversions = if repeat { s.filter_count } else { 1 };
        let mut sum = 0.0;
        let mut overflow = false;
        for _ in 0..conversions {
            match self.convert() {
                Some(v) => sum += v,
                None => overflow = true,
            }
        }
        let s = &self.settings;
        let mut raw = sum / f64::from(conversions);
        if s.filter_on && s.filter_type == FilterType::Moving && !overflow {
            self.stack.push_back(raw);
            while self.stack.len() > s.filter_count as usize {
                self.stack.pop_front();
            }
            raw = self.stack.iter().sum::<f64>() / self.stack.len() as f64;
        }
        let mut status = 0u16;
        if s.filter_on {
            status |= StatusWord::FILTER;
        }
        if s.zero_check {
            status |= StatusWord::ZERO_CHECK;
            if !overflow {
                self.last_zero_checked = Some(raw);
            }
        }
        if s.zero_correct {
            status |= StatusWord::ZERO_CORRECT;
        }
        let current = if overflow {
            status |= StatusWord::OVERFLOW;
            Current::Overflow
        } else if s.zero_correct {
            Current::Amps(raw - self.zero_value)
        } else {
            Current::Amps(raw)
        };
        Sample {
            current,
            time_s: self.busy_until.rem_euclid(TIMESTAMP_WRAP_S),
            status: StatusWord(status),
        }
    }

    /// One A/D conversion from [`busy_until`](Self::busy_until) over the integration
    /// time: the raw current (offset included), or `None` on overflow.
    fn convert(&mut self) -> Option<f64> {
        let t0 = self.busy_until;
        let t1 = t0 + self.conversion_s();
        if self.settings.autorange {
            let i = self.photocurrent_at(t0) + self.config.input_offset_a;
            self.settings.range = Range::all()
                .find(|r| i.abs() <= r.amps())
                .unwrap_or(Range::LEAST);
        }
        let range = self.settings.range;
        let mean = self.front_average(t0, t1, range);
        self.busy_until = t1;
        let (signal, sigma) = if self.settings.zero_check {
            (0.0, self.conversion_sigma(range, None))
        } else {
            (mean, self.conversion_sigma(range, Some(mean)))
        };
        let xi: f64 = self.rng.sample(StandardNormal);
        let v = signal + self.config.input_offset_a + sigma * xi;
        (v.abs() <= OVERRANGE_FACTOR * range.amps()).then_some(v)
    }

    /// The front end's mean output over [t0, t1] on `range` (its time constant), and
    /// its state advanced to t1. Before t0 it is advanced from its last time.
    fn front_average(&mut self, t0: f64, t1: f64, range: Range) -> f64 {
        let tau = self.config.rise_time_s[usize::from(range.index())] / 9f64.ln();
        self.advance_front(t0, tau);
        if t1 <= t0 {
            return self.front_a;
        }
        let integral = self.advance_front(t1, tau);
        integral / (t1 - t0)
    }

    /// Advances the front end (one pole, time constant `tau`) to `t` through the
    /// input's changes; returns the integral of its output over the time advanced.
    fn advance_front(&mut self, t: f64, tau: f64) -> f64 {
        let mut integral = 0.0;
        while self.front_t < t {
            let from = self.front_t;
            let next_change = self
                .input
                .iter()
                .map(|(s, _)| *s)
                .find(|s| *s > from)
                .unwrap_or(f64::INFINITY);
            let to = t.min(next_change);
            let u = self.photocurrent_at(from);
            let dt = to - from;
            let decay = (-dt / tau).exp();
            // ∫ u + (y0 − u) e^(−s/τ) ds over [0, dt].
            integral += u * dt + (self.front_a - u) * tau * (1.0 - decay);
            self.front_a = u + (self.front_a - u) * decay;
            self.front_t = to;
        }
        integral
    }
}
