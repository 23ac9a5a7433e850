//! The simulated SR830 DSP lock-in amplifier, device side: command lines in, the exact
//! reply bytes a real SR830 sends on RS-232 out (facts: manual Rev. 2.5, ch. 5, as
//! summarised in `instruments.md` §2 and checked in `protocol-findings.md` §4; wire
//! format: [`gonio_proto::sr830`]). Each behaviour names its source beside the code
//! ("assumed" where none says, with the reason); `docs/instruments/sr830.md` ("The
//! twin") keeps the same list.
//!
//! # Protocol
//! - Lines are parsed with [`parse_line`]: `;`-separated commands, case and spaces
//!   ignored (manual p. 5-1, 5-2: "Commands may be in either UPPER or lower case and
//!   may contain any number of embedded space characters ... Multiple commands may be
//!   sent on one command line by separating them with semicolons"). Only queries
//!   reply, each with its own `\r`-terminated line (p. 5-2); set commands reply
//!   nothing. An illegal command sets CMD (bit 5) of `*ESR?`, an out-of-range or
//!   unexecutable one sets EXE (bit 4), silently (SR850 manual p. 1-10, the SR830's
//!   page not found; [`gonio_proto::sr830::CommandError::event_status`]). An illegal
//!   query answers nothing (assumed: the manual leaves it open; see `instruments.md`).
//! - The 256-character input buffer (p. 5-2, quoted second-hand): a line that, with
//!   its terminator, does not fit overflows it, sets INP and loses what it held; the
//!   characters after the overflow fill it afresh (`input_buffer`, which lists the
//!   twin's assumptions).
//! - Power-up is the `*RST` state (p. 4-4, not re-checked: UNCONFIRMED) with replies
//!   going to **GPIB**: every command runs, but no reply reaches RS-232 until `OUTX 0`
//!   (OUTX: "sets the output interface to RS232 (i=0) or GPIB (i=1) ... should be sent
//!   before any query", a driver quoting the manual; GPIB the factory default, p. 4-4).
//!   `*ESR?` carries PON (bit 7) after power-up until read or `*CLS`ed (SR850 p. 1-10).
//! - Float replies are rounded to 6 significant digits, the resolution of every value the
//!   manual prints (`0.951359`, `-1.01026`, `1000.00`, `-4.17234e-007`), then written by
//!   [`Reply::encode`] (so `1000.00` is sent as `1000`, which every parser reads the same):
//!   assumed, the firmware's printing rule is UNCONFIRMED.
//!
//! # Physics
//! - The detector signal (volts, amplitude of the chopped signal) becomes the lock-in
//!   magnitude `chop_gain × volts`, at phase `phase_deg`: X = R cos φ, Y = R sin φ.
//! - Each of X and Y passes through 4 cascaded first-order RC stages of time constant T;
//!   the output is stage N = 1..4 for 6/12/18/24 dB/oct. The cascade is advanced exactly
//!   for the piecewise-constant input ([`advance_cascade`]). `SENS` leaves it alone; `OFLT`
//!   changes T from then on. Its ENBW is the manual's 1/(4T), 1/(8T), 3/(32T), 5/(64T).
//!   A step leaves 0.67 %, 0.73 %, 0.62 % after 5, 7, 9 T (6, 12, 18 dB/oct), but 1.03 %
//!   after 10 T at 24 dB/oct (99 % at 10.05 T): the manual's settling table rounds.
//!   (Identical first-order stages are assumed: the manual's tables, p. 3-21 and
//!   p. 3-25, were read only second-hand, UNCONFIRMED; the cascade reproduces them.)
//! - A point's start ([`LockIn::restart`], [`LockIn::restart_from`]; chosen by
//!   [`LockInConfig::point_start`]): see "Where a point starts" below.
//! - Noise: an Ornstein–Uhlenbeck process per channel with correlation time T and
//!   standard deviation density·√ENBW, density = √(amplifier² + shot²·R_signal), advanced
//!   exactly with normals from a `ChaCha8Rng` seeded at construction: the same seed and
//!   the same calls give the same bytes.
//! - Status (`LIAS?`, bits and latching p. 5-23), latched at every event instant (each
//!   [`LockIn::set_input`], each command): INPUT (bit 0) while the detector amplitude
//!   exceeds `input_overload_v` (1.4 V peak, `instruments.md` §2.5, UNCONFIRMED) or the
//!   fault is forced; OUTPUT (bit 2) while |X|, |Y| or R (noise included) exceeds
//!   1.09 × full scale (§2.5, UNCONFIRMED); UNLOCK (bit 3) while the unlock fault is on;
//!   RANGE (bit 4) and TC (bit 5) when the reference frequency crosses 200 Hz (p. 5-23).
//!   Bits "stay set until cleared by reading or by the CLS command" (p. 5-23): reading
//!   clears what it reads.
//!
//! # Where a point starts
//! A run reads each point after a move; a resumed run must read what the uninterrupted
//! one read, so the filters' state at a point's start may depend only on what the run
//! file records, never on the history of polls and moves that led there. Two
//! idealisations, chosen by [`LockInConfig::point_start`]:
//! - [`PointStart::Settled`] (the default): the filters start settled on the present
//!   input; the outputs are flat at the new value from the start.
//! - [`PointStart::Previous`]: every stage of X and of Y starts at the previous
//!   reading's mean X and Y (zero for a run's first reading, a dark output), and the
//!   input is the present signal from then on, so each output is the cascade's exact
//!   step response y(t) = u + (y₀ − u)·e^(−a)·Σ_{j<N} a^j/j!, a = (t − t₀)/T, from
//!   t₀ = the call's time. What this leaves out: the light swept during the move (the
//!   filters' real path through it), the time between the move's end and the call, and
//!   the difference between a reading's mean and the filters' state at its end (noise,
//!   or a residue of the previous transient averaged in). It is exact when the filters
//!   had settled on the previous reading and the move is short against T; after a move
//!   long against T the real filters are already partly on their way (and may carry a
//!   residue of a peak swept through), so the real transient differs from this one.
//!
//! # Choices where the manual is silent (or that are not modelled)
//! - During an output overload the manual does not say what the outputs read
//!   (UNCONFIRMED): here X, Y and R each **clip** at ±1.09 × full scale.
//! - FILTER overload (bit 1), RESERVE overload, the dynamic reserve, the minimum time
//!   constant for a slope and reserve, the harmonic, and the output-queue overflow (QRY)
//!   are not modelled.
//! - While the reference is unlocked the signal is not demodulated: the filters see zero
//!   input (the outputs decay to noise), and the status bit latches.
//! - An input overload does not change the readings: only the status bit shows it.
//! - `AGAN` is instantaneous: it picks the most sensitive range with R ≤ 0.9 × full scale,
//!   which puts R between 36 % and 90 % of full scale (1-2-5 steps are at most 2.5×);
//!   it does nothing when T > 1 s (the AGAN command as `instruments.md` §2.4 reads it;
//!   found only in second-hand code comments, UNCONFIRMED). Its timing and the 0.9
//!   target are assumed (the manual says only that it "can take long").
//! - `OFLT` above 30 s while the detection frequency is above 200 Hz is refused with EXE
//!   (manual, OFLT: "cannot be set"; LIAS RANGE, p. 5-23: "TCs > 30 s ... are turned
//!   off in the upper range"; EXE as "cannot execute", assumed). `FREQ` is refused with
//!   EXE on the external reference (FREQ sets the internal oscillator only; EXE
//!   assumed), where `FREQ?` reads [`LockInConfig::chopper_hz`].
//! - `ERRS?` always reads 0: no self-test failure is modelled (assumed).
//! - Commands run as soon as their line arrives: the manual's "processes commands in the
//!   order received" holds, but a command's own run time (`*RST` "takes some time",
//!   `AGAN`) is not modelled.
//! - Time never runs backwards: a `now_s` before the last one is taken as the last one.

use gonio_proto::sr830::{
    BitIndex, Command, EventStatus, FilterSlope, Identity, Interface, LiaStatus, MAX_LINE, Output,
    ReferenceSource, Reply, Sensitivity, SnapParam, TimeConstant, parse_line,
};
use rand::{Rng, SeedableRng};

mod config;
mod storage;
pub use config::{LockInConfig, PointStart};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// An output overloads above this multiple of full scale (manual, OUTPUT OVLD, as
/// `instruments.md` §2.5 summarises it; the page was not re-checked: UNCONFIRMED):
/// the session's and the planner's figure.
pub const OVERLOAD_FACTOR: f64 = gonio_proto::sr830::timing::OUTPUT_OVERLOAD;

/// RC stages in the time-constant filter (24 dB/oct uses all of them).
pub const STAGES: usize = 4;

/// Significant digits of a float reply (assumed: the resolution of every value the
/// manual prints; the firmware's rule is UNCONFIRMED).
pub const REPLY_DIGITS: usize = 6;

/// `AGAN` picks the most sensitive range whose full scale times this is at least R
/// (assumed: the manual does not say where auto gain leaves R).
pub const AUTO_GAIN_TARGET: f64 = 0.9;

/// `AGAN` does nothing when the time constant is over this, seconds (the AGAN command
/// as `instruments.md` §2.4 reads it; only second-hand, UNCONFIRMED).
pub const AUTO_GAIN_MAX_TC_S: f64 = 1.0;

/// The detection frequency splitting the low and high ranges, Hz (LIAS bit 4, p. 5-23).
/// The manual's hysteresis (below 199.21 Hz, above 203.12 Hz) is not modelled.
pub const RANGE_SPLIT_HZ: f64 = 200.0;

/// Longest time constant allowed above [`RANGE_SPLIT_HZ`], seconds (OFLT command;
/// p. 5-23: "TCs > 30 s ... are turned off in the upper range").
pub const MAX_TC_HIGH_RANGE_S: f64 = 30.0;

/// The `*RST` internal oscillator frequency, Hz (p. 4-4, not re-checked: UNCONFIRMED).
const RESET_FREQUENCY_HZ: f64 = 1000.0;

/// The `*RST` sine output amplitude, V rms (p. 4-4, not re-checked: UNCONFIRMED).
const RESET_AMPLITUDE_V: f64 = 1.0;

/// Advances a cascade of first-order RC stages (`stages[0]` fed by `u`, each next stage
/// fed by the previous one, all with time constant `tc`) exactly over `dt` for a constant
/// input `u`.
///
/// With zₖ = yₖ − u, the cascade is ż₁ = −z₁/T, żₖ = (zₖ₋₁ − zₖ)/T, whose solution is
/// zₖ(t) = e^(−a) Σ_{j=0}^{k−1} zₖ₋ⱼ(0)·a^j/j! with a = t/T (induction on k: the j-th term
/// is stage k−j's free decay passed through j more stages). Stages are updated from the
/// last down, so each uses the old values of the stages before it. Nothing changes for
/// `dt ≤ 0` (or NaN); beyond 700 time constants every stage equals `u`.
pub fn advance_cascade(stages: &mut [f64], u: f64, dt: f64, tc: f64) {
    if dt.is_nan() || dt <= 0.0 {
        return;
    }
    let a = dt / tc;
    if a.is_nan() || a > 700.0 {
        stages.fill(u);
        return;
    }
    let e = (-a).exp();
    for k in (0..stages.len()).rev() {
        let mut sum = 0.0;
        let mut term = 1.0; // a^j / j!
        for j in 0..=k {
            sum += (stages[k - j] - u) * term;
            term *= a / (j + 1) as f64;
        }
        stages[k] = u + e * sum;
    }
}

/// Rounds `v` to [`REPLY_DIGITS`] significant digits (a negative zero becomes zero;
/// a non-finite value, which only a config failing [`LockInConfig::validate`] can
/// produce, becomes zero rather than a reply no parser reads).
fn round_reply(v: f64) -> f64 {
    if !v.is_finite() {
        return 0.0;
    }
    let text = format!("{:.*e}", REPLY_DIGITS - 1, v);
    let r = text.parse::<f64>().unwrap_or(v);
    if r == 0.0 { 0.0 } else { r }
}

/// The internal oscillator frequency as the instrument stores it: 5 significant digits
/// or 0.0001 Hz, whichever is coarser (manual, FREQ command; instruments.md §2.4).
fn round_frequency(f: f64) -> f64 {
    let step = 10f64.powi(f.log10().floor() as i32 - 4).max(1e-4);
    (f / step).round() * step
}

/// The sine output amplitude as stored: a multiple of 2 mV (manual, SLVL command;
/// instruments.md §2.4).
fn round_amplitude(x: f64) -> f64 {
    (x / 0.002).round() * 0.002
}

/// The outputs at one instant, volts (θ in degrees), clipped as the instrument reads them.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Outputs {
    x: f64,
    y: f64,
    r: f64,
    theta: f64,
}

/// The simulated SR830. Time is virtual: every call says when it happens (`now_s`,
/// seconds), and the filters and noise are advanced exactly to it.
#[derive(Clone, Debug)]
pub struct LockIn {
    config: LockInConfig,
    rng: ChaCha8Rng,
    /// The time the state below describes, seconds.
    now: f64,
    /// Detector signal amplitude, volts.
    input_v: f64,
    /// Filter stages of X and Y (noise-free), volts.
    x_stages: [f64; STAGES],
    y_stages: [f64; STAGES],
    /// Output noise of X and Y, volts.
    noise: [f64; 2],
    sensitivity: Sensitivity,
    time_constant: TimeConstant,
    slope: FilterSlope,
    interface: Interface,
    reference: ReferenceSource,
    /// Internal oscillator frequency, Hz.
    frequency: f64,
    /// Sine output amplitude, V rms.
    amplitude: f64,
    lias: u8,
    esr: u8,
    unlocked: bool,
    forced_overload: bool,
    /// The data buffer (`storage`'s docs).
    storage: storage::Storage,
}

impl LockIn {
    /// A lock-in just powered up: the `*RST` state (1 V, 100 ms, 12 dB/oct, internal
    /// reference at 1 kHz: p. 4-4, UNCONFIRMED), replies to GPIB (silent on RS-232
    /// until `OUTX 0`: GPIB is the factory default, p. 4-4), no signal, PON set in
    /// `*ESR?` (SR850 p. 1-10), the noise drawn from its stationary distribution.
    pub fn new(config: LockInConfig, seed: u64) -> Self {
        let mut lockin = LockIn {
            config,
            rng: ChaCha8Rng::seed_from_u64(seed),
            now: 0.0,
            input_v: 0.0,
            x_stages: [0.0; STAGES],
            y_stages: [0.0; STAGES],
            noise: [0.0; 2],
            sensitivity: Sensitivity::default(),
            time_constant: TimeConstant::default(),
            slope: FilterSlope::default(),
            interface: Interface::Gpib,
            reference: ReferenceSource::Internal,
            frequency: RESET_FREQUENCY_HZ,
            amplitude: RESET_AMPLITUDE_V,
            lias: 0,
            esr: EventStatus::PON,
            unlocked: false,
            forced_overload: false,
            storage: storage::Storage::default(),
        };
        lockin.redraw_noise(seed);
        lockin
    }

    /// The detector signal (volts, amplitude of the chopped signal before `chop_gain`)
    /// from virtual time `now_s` on, until the next call. Advances the filters to `now_s`
    /// first.
    pub fn set_input(&mut self, now_s: f64, volts: f64) {
        self.advance(now_s);
        self.latch();
        self.input_v = if volts.is_finite() { volts } else { 0.0 };
        self.latch();
    }

    /// One received command line (terminator removed), at virtual time `now_s`: executes
    /// it like the instrument (several `;`-separated commands, errors setting ESR CMD/EXE
    /// bits silently, no reply to set commands) and appends reply bytes (each terminated
    /// by CR) to `out` — none while replies go to GPIB (`OUTX 1`).
    ///
    /// The line passes through the 256-character input buffer first (see
    /// `input_buffer`): a line of 256 characters or more overflows it, which sets INP
    /// and loses what the buffer held.
    pub fn handle_line(&mut self, now_s: f64, line: &[u8], out: &mut Vec<u8>) {
        self.advance(now_s);
        self.latch();
        let (overflows, line) = input_buffer(line);
        if overflows > 0 {
            self.esr |= EventStatus::INP;
        }
        let Some(line) = line else {
            return;
        };
        for parsed in parse_line(line) {
            self.latch();
            let reply = match parsed {
                Ok(command) => self.execute(&command),
                Err(e) => Err(e.event_status().0),
            };
            match reply {
                Ok(Some(reply)) if self.interface == Interface::Rs232 => reply.encode(out),
                Ok(_) => {}
                Err(bits) => self.esr |= bits,
            }
        }
        self.latch();
    }

    /// A line longer than the wire's framer keeps (far beyond the 256-character input
    /// buffer) arrived at `now_s` and was dropped before reaching
    /// [`handle_line`](Self::handle_line): it overflowed the buffer, so INP is set
    /// (manual p. 5-2; see `input_buffer`). Its tail is not run.
    pub fn input_overflow(&mut self, now_s: f64) {
        self.advance(now_s);
        self.latch();
        self.esr |= EventStatus::INP;
    }

    /// Starts a measurement afresh at `now_s`: the filters as if settled on the
    /// present input, the noise redrawn from its stationary law with a generator
    /// seeded by `seed` ([`PointStart::Settled`]).
    ///
    /// An idealisation for reproducibility: a real lock-in keeps a residue of its
    /// history (the driver waits until it is below `settle_residual`); here a reading
    /// depends only on where it is taken and on `seed`, so a run resumed after a kill
    /// reads exactly what the uninterrupted run read.
    pub fn restart(&mut self, now_s: f64, seed: u64) {
        self.advance(now_s);
        let (ux, uy) = self.filter_input();
        self.x_stages = [ux; STAGES];
        self.y_stages = [uy; STAGES];
        self.redraw_noise(seed);
        self.latch();
    }

    /// Starts a measurement at `now_s` with every filter stage of X and Y at `from`
    /// (the previous reading's X and Y, volts; `None`, a run's first reading, is a
    /// dark output, zero), the noise redrawn as [`restart`](Self::restart) does
    /// ([`PointStart::Previous`]). From then on the outputs follow the cascade's step
    /// response from `from` to the present input (module docs, "Where a point
    /// starts"); the same `from`, `seed` and calls give the same bytes.
    ///
    /// No output reads beyond ±1.09 × the largest full scale (1 V), so a `from` beyond
    /// that (only a damaged run file can hold one) is taken at that limit, and a
    /// non-finite one as zero.
    pub fn restart_from(&mut self, now_s: f64, seed: u64, from: Option<[f64; 2]>) {
        self.advance(now_s);
        let limit = OVERLOAD_FACTOR * Sensitivity::LEAST.volts();
        let start = |v: f64| {
            if v.is_finite() {
                v.clamp(-limit, limit)
            } else {
                0.0
            }
        };
        let [x0, y0] = from.unwrap_or([0.0, 0.0]);
        self.x_stages = [start(x0); STAGES];
        self.y_stages = [start(y0); STAGES];
        self.redraw_noise(seed);
        self.latch();
    }

    /// [`restart_from`](Self::restart_from) at `now_s`, the step having begun at
    /// `since_s` ≤ `now_s` (the stages stopped then): every stage then follows the
    /// cascade's exact step response to the present input for `now_s − since_s`, the
    /// input unchanged meanwhile. The noise is drawn at `now_s` from its stationary law,
    /// as at a restart, so the same `from`, `seed`, interval and calls give the same
    /// bytes.
    pub fn restart_from_since(
        &mut self,
        since_s: f64,
        now_s: f64,
        seed: u64,
        from: Option<[f64; 2]>,
    ) {
        self.restart_from(now_s, seed, from);
        let dt = now_s - since_s;
        if dt > 0.0 {
            let tc = self.time_constant.seconds();
            let (ux, uy) = self.filter_input();
            advance_cascade(&mut self.x_stages, ux, dt, tc);
            advance_cascade(&mut self.y_stages, uy, dt, tc);
            self.latch();
        }
    }

    /// Reseeds the generator with `seed` and draws both noise channels from their
    /// stationary law.
    fn redraw_noise(&mut self, seed: u64) {
        self.rng = ChaCha8Rng::seed_from_u64(seed);
        let sigma = self.noise_sigma();
        for k in 0..2 {
            let xi: f64 = self.rng.sample(StandardNormal);
            self.noise[k] = sigma * xi;
        }
    }

    /// Fault: reference unlock. LIAS bit 3 (p. 5-23) latches at once and at every event
    /// while on; the signal is not demodulated meanwhile (assumed: the filters see zero). There is no time argument: the change
    /// applies from the last event (call [`set_input`](Self::set_input) first to make
    /// that now).
    pub fn set_unlocked(&mut self, on: bool) {
        self.unlocked = on;
        self.latch();
    }

    /// Fault: input overload (LIAS bit 0, p. 5-23) regardless of the signal: latches at
    /// once and at every event while on. The readings are not changed (assumed: the
    /// manual does not say what an overloaded input reads).
    pub fn force_overload(&mut self, on: bool) {
        self.forced_overload = on;
        self.latch();
    }

    /// The sensitivity (full scale).
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

    /// The interface replies go to.
    pub fn interface(&self) -> Interface {
        self.interface
    }

    /// The configuration.
    pub fn config(&self) -> &LockInConfig {
        &self.config
    }

    /// The filtered (noise-free, unclipped) R at `now_s`, for tests.
    pub fn settled_r(&mut self, now_s: f64) -> f64 {
        self.advance(now_s);
        let n = self.order() - 1;
        self.x_stages[n].hypot(self.y_stages[n])
    }

    /// Number of active RC stages, 1..=4.
    fn order(&self) -> usize {
        usize::from(self.slope.index()) + 1
    }

    /// The detection (reference) frequency, Hz.
    fn detection_hz(&self) -> f64 {
        match self.reference {
            ReferenceSource::Internal => self.frequency,
            ReferenceSource::External => self.config.chopper_hz,
        }
    }

    /// The demodulated signal the filters see: (X, Y) volts.
    fn filter_input(&self) -> (f64, f64) {
        if self.unlocked {
            return (0.0, 0.0);
        }
        let r = self.signal_r();
        let (s, c) = self.config.phase_deg.to_radians().sin_cos();
        (r * c, r * s)
    }

    /// The signal's lock-in magnitude, volts.
    fn signal_r(&self) -> f64 {
        self.config.chop_gain * self.input_v.abs()
    }

    /// The stationary standard deviation of each noise channel, volts.
    fn noise_sigma(&self) -> f64 {
        let c = &self.config;
        let density = (c.amplifier_noise.powi(2) + c.shot_noise.powi(2) * self.signal_r()).sqrt();
        density * self.slope.enbw_hz(self.time_constant).sqrt()
    }

    /// Moves filters and noise from the last event to `now_s` (constant input
    /// meanwhile), storing a buffer point at each sample instant on the way.
    fn advance(&mut self, now_s: f64) {
        while let Some(t) = self.storage.next.filter(|t| *t <= now_s) {
            self.advance_to(t);
            let v = self.outputs();
            let ch1 = match self.storage.display[0] {
                0 => v.x,
                1 => v.r,
                _ => 0.0,
            };
            let ch2 = match self.storage.display[1] {
                0 => v.y,
                1 => v.theta,
                _ => 0.0,
            };
            self.storage.store([ch1, ch2]);
        }
        self.advance_to(now_s);
    }

    /// Moves filters and noise from the last event to `now_s`.
    fn advance_to(&mut self, now_s: f64) {
        let dt = now_s - self.now;
        if dt.is_nan() || dt <= 0.0 {
            return;
        }
        let tc = self.time_constant.seconds();
        let (ux, uy) = self.filter_input();
        advance_cascade(&mut self.x_stages, ux, dt, tc);
        advance_cascade(&mut self.y_stages, uy, dt, tc);
        // Ornstein–Uhlenbeck, exact: n' = n·e^(−Δt/T) + σ·√(1 − e^(−2Δt/T))·ξ.
        let decay = (-dt / tc).exp();
        let spread = self.noise_sigma() * (-(-2.0 * dt / tc).exp_m1()).sqrt();
        for k in 0..2 {
            let xi: f64 = self.rng.sample(StandardNormal);
            self.noise[k] = self.noise[k] * decay + spread * xi;
        }
        self.now = now_s;
    }

    /// The outputs now, noise included, before clipping: (X, Y).
    fn raw_xy(&self) -> (f64, f64) {
        let n = self.order() - 1;
        (
            self.x_stages[n] + self.noise[0],
            self.y_stages[n] + self.noise[1],
        )
    }

    /// The outputs as read: each of X, Y, R clipped at ±1.09 × full scale (assumed: what
    /// an overloaded output reads is UNCONFIRMED).
    fn outputs(&self) -> Outputs {
        let (x, y) = self.raw_xy();
        let limit = OVERLOAD_FACTOR * self.sensitivity.volts();
        Outputs {
            x: x.clamp(-limit, limit),
            y: y.clamp(-limit, limit),
            r: x.hypot(y).min(limit),
            theta: y.atan2(x).to_degrees(),
        }
    }

    /// Latches the status bits whose condition holds now.
    fn latch(&mut self) {
        if self.forced_overload || self.input_v.abs() > self.config.input_overload_v {
            self.lias |= LiaStatus::INPUT_OVERLOAD;
        }
        let (x, y) = self.raw_xy();
        let limit = OVERLOAD_FACTOR * self.sensitivity.volts();
        if x.abs() > limit || y.abs() > limit || x.hypot(y) > limit {
            self.lias |= LiaStatus::OUTPUT_OVERLOAD;
        }
        if self.unlocked {
            self.lias |= LiaStatus::UNLOCK;
        }
    }

    /// Changes the reference source or frequency; crossing 200 Hz latches RANGE, and
    /// entering the high range with T > 30 s shortens T to 30 s and latches TC.
    fn set_reference(&mut self, source: ReferenceSource, frequency: f64) {
        let was_high = self.detection_hz() > RANGE_SPLIT_HZ;
        self.reference = source;
        self.frequency = frequency;
        let high = self.detection_hz() > RANGE_SPLIT_HZ;
        if high != was_high {
            self.lias |= LiaStatus::RANGE;
        }
        if high && self.time_constant.seconds() > MAX_TC_HIGH_RANGE_S {
            self.time_constant = TimeConstant::all()
                .filter(|t| t.seconds() <= MAX_TC_HIGH_RANGE_S)
                .last()
                .unwrap_or_default();
            self.lias |= LiaStatus::TIME_CONSTANT_CHANGED;
        }
    }

    /// A set command: `f` changes the state; no reply.
    fn set(&mut self, f: impl FnOnce(&mut Self)) -> Option<Reply> {
        f(self);
        None
    }

    /// Runs one parsed command: its reply, or the `*ESR?` bits it sets.
    fn execute(&mut self, command: &Command) -> Result<Option<Reply>, u8> {
        let exe = EventStatus::EXE;
        let reply = match command {
            // OUTX: where replies go (a driver quoting the manual; findings §4).
            Command::SetInterface(i) => self.set(|l| l.interface = *i),
            Command::QueryInterface => Some(Reply::Interface(self.interface)),
            Command::SetReferenceSource(s) => self.set(|l| l.set_reference(*s, l.frequency)),
            Command::QueryReferenceSource => Some(Reply::ReferenceSource(self.reference)),
            // FREQ sets the internal oscillator only (FREQ command); refused with EXE on
            // the external reference (assumed: "cannot execute").
            Command::SetFrequency(f) => {
                if self.reference != ReferenceSource::Internal {
                    return Err(exe);
                }
                self.set_reference(self.reference, round_frequency(*f));
                None
            }
            Command::QueryFrequency => Some(Reply::Frequency(round_reply(self.detection_hz()))),
            // SLVL: rounded to 2 mV (SLVL command).
            Command::SetAmplitude(x) => self.set(|l| l.amplitude = round_amplitude(*x)),
            Command::QueryAmplitude => Some(Reply::Amplitude(round_reply(self.amplitude))),
            Command::SetSensitivity(s) => self.set(|l| l.sensitivity = *s),
            Command::QuerySensitivity => Some(Reply::Sensitivity(self.sensitivity)),
            // OFLT: over 30 s "cannot be set" above 200 Hz (OFLT command); EXE assumed.
            Command::SetTimeConstant(t) => {
                if t.seconds() > MAX_TC_HIGH_RANGE_S && self.detection_hz() > RANGE_SPLIT_HZ {
                    return Err(exe);
                }
                self.time_constant = *t;
                None
            }
            Command::QueryTimeConstant => Some(Reply::TimeConstant(self.time_constant)),
            Command::SetSlope(s) => self.set(|l| l.slope = *s),
            Command::QuerySlope => Some(Reply::Slope(self.slope)),
            // AGAN: see the module docs (instantaneous, 0.9 target: assumed; nothing
            // above 1 s: UNCONFIRMED).
            Command::AutoGain => {
                if self.time_constant.seconds() <= AUTO_GAIN_MAX_TC_S {
                    let (x, y) = self.raw_xy();
                    let r = x.hypot(y);
                    self.sensitivity = Sensitivity::all()
                        .find(|s| r <= AUTO_GAIN_TARGET * s.volts())
                        .unwrap_or(Sensitivity::LEAST);
                }
                None
            }
            // OUTP?: one output, volts or degrees (p. 5-15).
            Command::ReadOutput(o) => {
                let v = self.outputs();
                let value = match o {
                    Output::X => v.x,
                    Output::Y => v.y,
                    Output::R => v.r,
                    Output::Theta => v.theta,
                };
                Some(Reply::Output(round_reply(value)))
            }
            // SNAP?: the asked values at one instant (p. 5-16). Aux inputs read 0 (assumed:
            // nothing connected); the displays read X and Y (assumed: the p. 4-4
            // default displays, CH1 X and CH2 Y).
            Command::Snap(params) => {
                let v = self.outputs();
                let values = params
                    .as_slice()
                    .iter()
                    .map(|p| match p {
                        SnapParam::X | SnapParam::Ch1Display => v.x,
                        SnapParam::Y | SnapParam::Ch2Display => v.y,
                        SnapParam::R => v.r,
                        SnapParam::Theta => v.theta,
                        SnapParam::AuxIn1
                        | SnapParam::AuxIn2
                        | SnapParam::AuxIn3
                        | SnapParam::AuxIn4 => 0.0,
                        SnapParam::Frequency => self.detection_hz(),
                    })
                    .map(round_reply)
                    .collect();
                Some(Reply::Snap(values))
            }
            // LIAS?, *ESR?: reading clears what it reads, the whole byte or one bit
            // (p. 5-23; *ESR? command).
            Command::LiaStatus(bit) => Some(read_clear(&mut self.lias, *bit, |b| {
                Reply::LiaStatus(LiaStatus(b))
            })),
            // ERRS?: always clear (assumed: no self-test failure is modelled).
            Command::ErrorStatus(bit) => Some(match bit {
                Some(_) => Reply::Bit(false),
                None => Reply::ErrorStatus(Default::default()),
            }),
            Command::EventStatus(bit) => Some(read_clear(&mut self.esr, *bit, |b| {
                Reply::EventStatus(EventStatus(b))
            })),
            // *IDN?: the manual's form, `Stanford_Research_Systems,SR830,s/n…,ver…`.
            Command::Identify => Some(Reply::Identity(Identity {
                manufacturer: "Stanford_Research_Systems".to_string(),
                model: "SR830".to_string(),
                serial: self.config.serial.clone(),
                firmware: self.config.firmware.clone(),
            })),
            Command::Reset => {
                // Factory defaults (p. 4-4, UNCONFIRMED); communication settings and
                // status bytes are kept (*RST command; instruments.md §2.4, §2.6).
                self.sensitivity = Sensitivity::default();
                self.time_constant = TimeConstant::default();
                self.slope = FilterSlope::default();
                self.reference = ReferenceSource::Internal;
                self.frequency = RESET_FREQUENCY_HZ;
                self.amplitude = RESET_AMPLITUDE_V;
                // The buffer's settings too, and its points (assumed: *RST's list,
                // p. 4-4, names the storage settings; whether it erases the points is
                // not said).
                self.storage = storage::Storage::default();
                None
            }
            // *CLS clears the status bytes (not the enable registers, not modelled).
            Command::Clear => self.set(|l| (l.lias, l.esr) = (0, 0)),
            // The data buffer: `storage`'s docs (p. 5-14 … 5-18).
            Command::SetDisplay(d) => {
                let ch = usize::from(d.channel.code() - 1);
                self.set(|l| l.storage.display[ch] = d.quantity)
            }
            Command::SetSampleRate(r) => self.set(|l| l.storage.rate = *r),
            Command::QuerySampleRate => Some(Reply::SampleRate(self.storage.rate)),
            Command::SetEndOfScan(e) => self.set(|l| l.storage.end = *e),
            Command::QueryEndOfScan => Some(Reply::EndOfScan(self.storage.end)),
            Command::StartStorage => {
                let now = self.now;
                self.set(|l| l.storage.start(now))
            }
            Command::PauseStorage => self.set(|l| l.storage.pause()),
            Command::ResetStorage => self.set(|l| l.storage.reset()),
            Command::StoredPoints => Some(Reply::StoredPoints(self.storage.len())),
            Command::TraceAscii(r) => {
                let v = self.storage.trace(r).ok_or(exe)?;
                Some(Reply::TraceAscii(
                    v.iter().map(|p| round_reply(p.value())).collect(),
                ))
            }
            // The stored value as the nearest single float (p. 5-17: IEEE format).
            Command::TraceBinary(r) => {
                let v = self.storage.trace(r).ok_or(exe)?;
                Some(Reply::TraceBinary(
                    v.iter().map(|p| p.value() as f32).collect(),
                ))
            }
            Command::TraceStored(r) => Some(Reply::TraceStored(self.storage.trace(r).ok_or(exe)?)),
        };
        Ok(reply)
    }
}

/// What of a received line (terminator removed) survives the input buffer: the number
/// of times it overflowed, and the characters left in the buffer when the terminator
/// arrived (`None` when the terminator itself overflowed it, losing the line).
///
/// Manual, ch. 5 command syntax (p. 5-2; read as quoted verbatim in a public SR830
/// driver): "The SR830 has a 256 character input buffer and processes commands in the
/// order received ... If either buffer overflows, both buffers are cleared and an
/// error reported" (INP, `*ESR?` bit 0: SR850 manual p. 1-10), and "No command
/// processing occurs until a command terminator is received", so a line's characters,
/// terminator included, fill the buffer until it runs. The twin's choices where the
/// manual is silent (assumed):
/// - every byte counts, spaces included (the front panel's queue display drops them,
///   which may or may not be how the buffer stores them);
/// - the character that finds the buffer full is lost with it, and the characters after
///   it fill the emptied buffer afresh: the tail of an over-long line runs as a line of
///   its own (the manual says the buffer is cleared, not that input is ignored until a
///   terminator);
/// - the hardware handshake that would hold the host off before an overflow (the
///   manual: "attempt to hold off handshaking on RS232") is not modelled: a three-wire
///   link, Gonio's default, has none;
/// - the output buffer's clearing is not modelled: the twin's replies leave at once,
///   so there is nothing in it to clear (nor is its own overflow, QRY).
fn input_buffer(line: &[u8]) -> (usize, Option<&[u8]>) {
    let mut held = 0;
    let mut start = 0;
    let mut overflows = 0;
    // Index `line.len()` is the terminator.
    for i in 0..=line.len() {
        if held == MAX_LINE {
            overflows += 1;
            held = 0;
            start = i + 1;
        } else {
            held += 1;
        }
    }
    (overflows, line.get(start..))
}

/// Reads a status byte and clears what was read: the whole byte (replied as `whole`
/// makes it), or only bit `bit`.
fn read_clear(byte: &mut u8, bit: Option<BitIndex>, whole: fn(u8) -> Reply) -> Reply {
    match bit {
        None => whole(std::mem::take(byte)),
        Some(b) => {
            let mask = 1u8 << b.get();
            let set = *byte & mask != 0;
            *byte &= !mask;
            Reply::Bit(set)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replies_round_to_six_significant_digits() {
        assert_eq!(round_reply(0.009000000000000001), 0.009);
        assert_eq!(round_reply(0.95135912), 0.951359);
        assert_eq!(round_reply(-4.172344e-7), -4.17234e-7);
        assert_eq!(round_reply(-0.0), 0.0);
        assert!(round_reply(-0.0).is_sign_positive());
        assert_eq!(round_reply(29.999999999999996), 30.0);
    }

    #[test]
    fn frequency_and_amplitude_round_as_the_manual_says() {
        assert_eq!(round_reply(round_frequency(1234.567)), 1234.6);
        assert_eq!(round_reply(round_frequency(0.0012345)), 0.0012);
        assert_eq!(round_reply(round_frequency(137.5)), 137.5);
        assert_eq!(round_reply(round_amplitude(0.5011)), 0.502);
    }

    #[test]
    fn the_input_buffer_holds_256_characters_terminator_included() {
        let a = |n: usize| vec![b'a'; n];
        assert_eq!(input_buffer(&a(255)), (0, Some(&a(255)[..])));
        // The terminator finds the buffer full: the line is lost.
        assert_eq!(input_buffer(&a(256)), (1, None));
        // The 257th character overflows it and is lost; the terminator then runs an
        // empty line, and a longer tail runs as a line of its own.
        assert_eq!(input_buffer(&a(257)), (1, Some(&b""[..])));
        let mut long = a(256);
        long.extend_from_slice(b"xSENS?");
        assert_eq!(input_buffer(&long), (1, Some(&b"SENS?"[..])));
        // 256 + 1 + 256 characters: the second buffer-full overflows at the terminator.
        assert_eq!(input_buffer(&a(513)), (2, None));
        assert_eq!(input_buffer(b""), (0, Some(&b""[..])));
    }

    #[test]
    fn a_long_step_settles_exactly() {
        let mut s = [0.3, -0.2, 0.7, 0.1];
        advance_cascade(&mut s, 0.25, 1e6, 1.0);
        assert_eq!(s, [0.25; 4]);
        let before = s;
        advance_cascade(&mut s, 9.0, -1.0, 1.0);
        advance_cascade(&mut s, 9.0, f64::NAN, 1.0);
        assert_eq!(s, before);
    }
}

#[cfg(test)]
mod storage_tests {
    use super::*;
    use gonio_proto::sr830::{StoredValue, TraceChannel, TraceRange};

    /// Runs `line` at `t` and returns the reply bytes.
    fn ask(l: &mut LockIn, t: f64, line: &str) -> Vec<u8> {
        let mut out = Vec::new();
        l.handle_line(t, line.as_bytes(), &mut out);
        out
    }

    fn quiet() -> LockIn {
        let config = LockInConfig {
            amplifier_noise: 0.0,
            shot_noise: 0.0,
            ..LockInConfig::default()
        };
        let mut l = LockIn::new(config, 1);
        ask(&mut l, 0.0, "OUTX 0;SENS 20;OFLT 7;OFSL 3");
        l
    }

    #[test]
    fn the_buffer_stores_the_outputs_at_the_sample_rate() {
        let mut l = quiet();
        l.set_input(0.0, 0.01);
        l.restart(0.0, 1);
        // 64 Hz: STRT at 1 s, points at 1 + k/64 s.
        ask(&mut l, 1.0, "SRAT 10;SEND 0;REST;STRT");
        assert_eq!(ask(&mut l, 1.2, "SPTS?"), b"12\r");
        let out = ask(&mut l, 1.25, "TRCL? 1,0,12");
        assert_eq!(out.len(), 48, "4 bytes a point, no terminator");
        let r = TraceRange::new(TraceChannel::Ch1, 0, 12).expect("valid");
        let Ok(Reply::TraceStored(v)) = Reply::parse(&Command::TraceStored(r), &out) else {
            panic!("not a trace: {out:?}")
        };
        // Settled, noiseless: X = 0.45 × 10 mV, to the format's resolution.
        for p in &v {
            assert!((p.value() - 0.0045).abs() < 0.0045 * 3.1e-5, "{p:?}");
        }
        assert_eq!(v[0], StoredValue::from_value(0.0045));
        // j + k beyond SPTS? answers nothing and sets EXE.
        assert_eq!(ask(&mut l, 1.26, "TRCL? 1,10,10"), b"");
        assert_eq!(ask(&mut l, 1.27, "*ESR? 4"), b"1\r");
        // Y (CH2) is zero at phase 0; PAUS stops storing, REST empties.
        assert_eq!(ask(&mut l, 1.3, "PAUS;SPTS?"), b"19\r");
        assert_eq!(ask(&mut l, 2.0, "SPTS?"), b"19\r");
        assert_eq!(ask(&mut l, 2.0, "TRCA? 2,0,2"), b"0,0,\r");
        assert_eq!(ask(&mut l, 2.0, "REST;SPTS?"), b"0\r");
    }

    #[test]
    fn the_buffer_follows_a_step_at_its_sample_instants() {
        let mut l = quiet();
        ask(&mut l, 0.0, "SRAT 13;REST;STRT");
        l.set_input(0.5, 0.01);
        let out = ask(&mut l, 1.0, "TRCB? 1,0,512");
        let Ok(Reply::TraceBinary(v)) = Reply::parse(
            &Command::TraceBinary(TraceRange::new(TraceChannel::Ch1, 0, 512).expect("valid")),
            &out,
        ) else {
            panic!("not a trace")
        };
        // Points k/512 s after STRT, k = 1 …: zero before the step at 0.5 s, then
        // the 24 dB/oct step response 0.0045·(1 − e^−a Σ_{j<4} a^j/j!), a = (t − 0.5)/T.
        for (k, x) in v.iter().enumerate() {
            let t = (k + 1) as f64 / 512.0;
            let a = ((t - 0.5) / 0.03).max(0.0);
            let expect = 0.0045 * (1.0 - (-a).exp() * (1.0 + a + a * a / 2.0 + a * a * a / 6.0));
            assert!(
                (f64::from(*x) - expect).abs() <= 0.0045 * 1e-4 + 1e-12,
                "{k}: {x} vs {expect}"
            );
        }
    }
}
