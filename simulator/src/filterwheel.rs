//! The simulated Thorlabs FW102C (FW212C) filter wheel, device side: command bytes in,
//! the exact bytes the wheel sends out, on virtual time (seconds). Wire format:
//! [`gonio_proto::fw102c`].
//!
//! # Sources
//! The FW102C manual Rev H (2014), §5.2 (terminal settings, the empty line's answer)
//! and §5.2.3, p. 11 (the command table); the FW102C User Guide Rev M (2023) as quoted
//! by ISIS's EPICS driver; drivers written against real wheels (ISIS, Odemis) where
//! the manual is silent, named as "driver only"; "assumed" marks the twin's own choice,
//! with the reason (`/work/shared/reference/protocol-findings.md` §7 checked these).
//! `docs/instruments/fw102c.md` ("The twin") keeps the same list.
//!
//! # Protocol
//! - At power-up the wheel sends its prompt `"> "`, once: "The prompt symbol '>' will
//!   appear on power-up and after a command is accepted" (User Guide Rev M). It waits
//!   in the host's input until read; its exact bytes are the post-command prompt's
//!   (assumed, UNCONFIRMED).
//! - Every byte received is echoed as the wheel reads it, CR included (driver only:
//!   ISIS, "each read returns the sent query string, too"; Odemis strips it); at CR the
//!   line is run (§5.2: "All strings ... must be terminated by a carriage return"). A
//!   query answers its value and CR (ISIS: terminator CR, driver only); a refusal
//!   answers `Command error CMD_NOT_DEFINED` (unknown word, empty line: §5.2, p. 11) or
//!   `Command error CMD_ARG_INVALID` (bad value, a position beyond `pcount`: Odemis
//!   only, UNCONFIRMED) and CR; then the prompt `"> "`, unterminated (`>`: User Guide
//!   Rev M; the space: Odemis only).
//! - "All commands and queries are in lower case letters" (p. 11): a line with an
//!   upper-case letter is not a defined command, `CMD_NOT_DEFINED` ("If the keyword,
//!   format, or argument are incorrect ... the unit will return an error string",
//!   p. 11; which string is the twin's reading). The manual's own table prints `Trig?`;
//!   the twin holds the rule. Surrounding spaces are ignored (assumed).
//! - `pos=n` turns the wheel the shortest way round and sends its prompt when it
//!   stops. Bytes received meanwhile wait, unechoed, and are read when it stops (the
//!   firmware is taken as busy while it turns: the twin's choice, UNCONFIRMED; so a
//!   `pos?` sent during a move answers the new position, late). `pos=` of the present
//!   position does not move.
//! - A move takes `slots × slot time` of the speed (`slot_time_high_s`,
//!   `slot_time_low_s`): the per-slot times and the linear model are the twin's,
//!   **UNCONFIRMED** (no manual figure was available).
//! - `pcount=`, `speed=`, `trig=`, `sensors=`, `baud=` are stored and read back with
//!   their queries (p. 11); `save` answers the prompt (power cycles are not modelled).
//!   `baud=0|1` (9600 | 115200, p. 11) is recorded and read back by `baud?`, but the
//!   line keeps its speed: a pseudo-terminal or an in-memory line has no baud rate to
//!   change, so the prompt after `baud=` is sent as if at the old speed (assumed:
//!   whether a real wheel answers at the old or the new speed is UNCONFIRMED).
//! - Not modelled: the arrow keys' special functions (p. 11), the trigger input, the
//!   front-panel buttons.
//!
//! # Optics
//! [`Fw102cDevice::transmittance`] is the transmittance of the filter in the beam:
//! band-pass, `peak · exp(−4 ln 2 (λ − centre)² / FWHM²)` (a Gaussian of the stated
//! FWHM); long-pass, `peak / (1 + exp(−(λ − cut_on) / s))` with `s` such that it rises
//! from 10 % to 90 % of `peak` over `longpass_rise_nm` (`s = rise / (2 ln 9)`); half the
//! peak at the cut-on; open 1; dark 0; a position with no filter listed is an empty
//! aperture, 1. While the wheel turns the beam is taken as blocked, 0 (the twin's
//! choice). Real filters' out-of-band leakage and angle dependence are not modelled.

use gonio_proto::fw102c::{
    Command, DeviceError, ErrorCode, Filter, Fw102cConfig, PROMPT, Reply, SensorMode, Speed,
    TERMINATOR, TriggerMode,
};

use crate::twin::{Echo, FieldError, LineDevice, LineTwin, Outbox, ensure};

/// The identification string the twin answers to `*idn?`: "Returns the model number
/// and firmware version" (p. 11), in the form Odemis quotes from a real wheel (driver
/// only).
pub const IDENTITY: &str = "THORLABS FW102C/FW212C Filter Wheel version 1.04";

/// The simulated wheel, as a sim config file writes it. Every field is optional and
/// unknown fields are refused:
///
/// ```toml
/// positions = 6
/// speed = "high"
/// initial_position = 1
/// slot_time_high_s = 0.5
/// slot_time_low_s = 1.0
/// longpass_rise_nm = 10.0
/// latency_s = 0.001
/// [[filters]]
/// position = 2
/// kind = "bandpass"
/// centre_nm = 550
/// fwhm_nm = 10
/// ```
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FilterWheelSim {
    /// The mechanical wheel's positions, 6 or 12; also the firmware's `pcount` at
    /// power-up.
    pub positions: u8,
    /// The speed at power-up.
    pub speed: Speed,
    /// Where the wheel stands at power-up, 1..=positions.
    pub initial_position: u8,
    /// The filters mounted, described as the driver's config describes them.
    pub filters: Vec<Filter>,
    /// Seconds per slot travelled at high speed, (0, 10] (UNCONFIRMED).
    pub slot_time_high_s: f64,
    /// Seconds per slot travelled at low speed, (0, 10] (UNCONFIRMED).
    pub slot_time_low_s: f64,
    /// A long-pass filter's 10–90 % rise, nm, (0, 200].
    pub longpass_rise_nm: f64,
    /// The wheel's time to answer a byte, s, [0, 1] (assumed: no manual figure).
    pub latency_s: f64,
}

impl Default for FilterWheelSim {
    fn default() -> Self {
        FilterWheelSim {
            positions: 6,
            speed: Speed::High,
            initial_position: 1,
            filters: Vec::new(),
            slot_time_high_s: 0.5,
            slot_time_low_s: 1.0,
            longpass_rise_nm: 10.0,
            latency_s: 0.001,
        }
    }
}

impl FilterWheelSim {
    /// Checks every field's range; the first bad field is named in the error. The
    /// positions and filters are checked as the driver's config checks them.
    pub fn validate(&self) -> Result<(), FieldError> {
        let driver = Fw102cConfig {
            positions: self.positions,
            filters: self.filters.clone(),
            ..Fw102cConfig::default()
        };
        driver
            .validate()
            .map_err(|e| FieldError::new(e.field, e.reason))?;
        let (at, n) = (self.initial_position, self.positions);
        ensure!((1..=n).contains(&at); "initial_position", "{at} is not in 1..={n}");
        for (field, v, hi) in [
            ("slot_time_high_s", self.slot_time_high_s, 10.0),
            ("slot_time_low_s", self.slot_time_low_s, 10.0),
            ("longpass_rise_nm", self.longpass_rise_nm, 200.0),
        ] {
            let ok = v.is_finite() && v > 0.0 && v <= hi;
            ensure!(ok; field, "{v} is not in (0, {hi}]");
        }
        FieldError::within("latency_s", self.latency_s, 0.0, 1.0)
    }

    /// The filter at `position`, if one is listed.
    pub fn filter_at(&self, position: u8) -> Option<&Filter> {
        self.filters.iter().find(|f| f.position() == position)
    }
}

/// Band-pass transmittance: `peak · exp(−4 ln 2 (λ − centre)² / FWHM²)`.
pub fn bandpass_transmittance(nm: f64, centre_nm: f64, fwhm_nm: f64, peak: f64) -> f64 {
    let x = (nm - centre_nm) / fwhm_nm;
    peak * (-4.0 * std::f64::consts::LN_2 * x * x).exp()
}

/// Long-pass transmittance: `peak / (1 + exp(−(λ − cut_on) / s))`, `s = rise / (2 ln 9)`
/// (the light model's own edge, [`crate::spectral::longpass`]).
pub use crate::spectral::longpass as longpass_transmittance;

/// The simulated wheel on its line. Time is virtual: every call says when it happens
/// (seconds since power-up).
pub type Fw102cTwin = LineTwin<Fw102cDevice>;

/// The wheel's firmware and mechanics, which [`Fw102cTwin`] feeds.
#[derive(Clone, Debug)]
pub struct Fw102cDevice {
    config: FilterWheelSim,
    pcount: u8,
    speed: Speed,
    trigger: TriggerMode,
    sensors: SensorMode,
    /// Where the wheel stands, or is heading while it turns.
    position: u8,
    /// The move under way or last made: from, start, end.
    from: u8,
    move_start: f64,
    move_end: f64,
    /// The rate `baud=` last chose: 0 for 9600, 1 for 115200 (p. 11). Recorded only:
    /// the line keeps its speed (module docs).
    baud: u8,
}

impl Fw102cTwin {
    /// A wheel just powered up at time 0, at `initial_position`, its power-up prompt
    /// waiting to be read (module docs). `config` should have passed
    /// [`FilterWheelSim::validate`]; an initial position out of range is taken as 1.
    /// At power-up: `pcount` = `positions`, trigger input, sensors on, 115200 baud
    /// (§5.2: the factory settings; what `save` would change is not modelled).
    pub fn new(config: &FilterWheelSim) -> Self {
        let position = if (1..=config.positions).contains(&config.initial_position) {
            config.initial_position
        } else {
            1
        };
        let wheel = Fw102cDevice {
            pcount: config.positions,
            speed: config.speed,
            trigger: TriggerMode::Input,
            sensors: SensorMode::AlwaysOn,
            position,
            from: position,
            move_start: 0.0,
            move_end: 0.0,
            baud: 1,
            config: config.clone(),
        };
        // The power-up prompt (User Guide Rev M), sent once at time 0.
        LineTwin::wrap(wheel, Some(PROMPT))
    }
}

impl LineDevice for Fw102cDevice {
    // CR runs the line (§5.2: "All strings ... must be terminated by a carriage
    // return").
    const END: u8 = TERMINATOR;

    /// Every byte echoed as it is read (driver only: ISIS, "each read returns the sent
    /// query string, too"; Odemis strips it).
    fn echo(&self) -> Echo {
        Echo::Read
    }

    /// Bytes received while the wheel turns wait, unechoed, until it stops (the twin's
    /// choice, UNCONFIRMED: module docs).
    fn reads_from(&self) -> f64 {
        self.move_end
    }

    /// Runs one line at `t`: its answer, then the prompt (at the end of a move). An LF
    /// is echoed and ignored (assumed: a host ending lines CR LF).
    fn execute(&mut self, t: f64, line: &[u8], out: &mut Outbox) {
        let line: Vec<u8> = line.iter().copied().filter(|b| *b != b'\n').collect();
        let mut answer = Vec::new();
        let mut prompt_at = t;
        if line.iter().any(u8::is_ascii_uppercase) {
            // p. 11: "All commands and queries are in lower case letters".
            DeviceError {
                code: ErrorCode::NotDefined,
            }
            .encode(&mut answer);
        } else if let Some(reply) = self.baud_command(&line) {
            // `baud=` and `baud?` (p. 11), which Gonio's codec does not encode.
            match reply {
                Ok(Some(digit)) => answer.extend_from_slice(&[b'0' + digit, TERMINATOR]),
                Ok(None) => {}
                Err(code) => DeviceError { code }.encode(&mut answer),
            }
        } else {
            prompt_at = self.run_command(t, &line, &mut answer);
        }
        out.send(t, answer);
        // The prompt follows every answer, a refusal's too (§5.2: "This message will
        // be followed immediately by the prompt").
        out.send(prompt_at, PROMPT);
    }
}

impl Fw102cDevice {
    /// When the move under way ends (or the last one ended): bytes received before it
    /// are answered then, not before.
    pub fn busy_until(&self) -> f64 {
        self.move_end
    }

    /// The wheel's time to answer a byte, s: a transport delays each answer by it.
    pub fn latency(&self) -> f64 {
        self.config.latency_s
    }

    /// Whether the wheel is turning at `t`.
    pub fn is_moving(&self, t: f64) -> bool {
        t >= self.move_start && t < self.move_end
    }

    /// The position in the beam at `t`; `None` while turning. Only the last move is
    /// remembered: a time before it reads the position that move left.
    pub fn position_at(&self, t: f64) -> Option<u8> {
        if self.is_moving(t) {
            None
        } else if t < self.move_start {
            Some(self.from)
        } else {
            Some(self.position)
        }
    }

    /// The firmware's position count.
    pub fn pcount(&self) -> u8 {
        self.pcount
    }

    /// The present speed setting.
    pub fn speed(&self) -> Speed {
        self.speed
    }

    /// The position sensors' mode.
    pub fn sensors(&self) -> SensorMode {
        self.sensors
    }

    /// The baud rate `baud=` last chose, 0 (9600) or 1 (115200): recorded, not applied.
    pub fn baud(&self) -> u8 {
        self.baud
    }

    /// The configuration.
    pub fn config(&self) -> &FilterWheelSim {
        &self.config
    }

    /// How long a move from `from` to `to` takes at the present speed: the slots of
    /// the shortest way round × the speed's slot time (assumed: no manual figure;
    /// Odemis counts slots the shortest way round; UNCONFIRMED).
    pub fn move_time(&self, from: u8, to: u8) -> f64 {
        let n = i32::from(self.config.positions);
        let d = (i32::from(to) - i32::from(from)).rem_euclid(n);
        let slots = d.min(n - d);
        let per = match self.speed {
            Speed::High => self.config.slot_time_high_s,
            Speed::Low => self.config.slot_time_low_s,
        };
        f64::from(slots) * per
    }

    /// The transmittance at `nm` of what is in the beam at `now` (see the module docs).
    pub fn transmittance(&self, nm: f64, now: f64) -> f64 {
        if !nm.is_finite() {
            return 0.0;
        }
        let Some(p) = self.position_at(now) else {
            return 0.0;
        };
        match self.config.filter_at(p) {
            None | Some(Filter::Open { .. }) => 1.0,
            Some(Filter::Dark { .. }) => 0.0,
            Some(Filter::Bandpass {
                centre_nm,
                fwhm_nm,
                peak_transmittance,
                ..
            }) => bandpass_transmittance(nm, *centre_nm, *fwhm_nm, *peak_transmittance),
            Some(Filter::Longpass {
                cut_on_nm,
                peak_transmittance,
                ..
            }) => longpass_transmittance(
                nm,
                *cut_on_nm,
                self.config.longpass_rise_nm,
                *peak_transmittance,
            ),
        }
    }

    /// Runs a lower-case line the codec parses at `t`, its answer appended to `out`;
    /// returns when its prompt is due (a move's end, or `t`).
    fn run_command(&mut self, t: f64, line: &[u8], out: &mut Vec<u8>) -> f64 {
        let mut prompt_at = t;
        match Command::parse(line) {
            // Unknown word or empty line: CMD_NOT_DEFINED (§5.2); a bad value:
            // CMD_ARG_INVALID (Odemis only).
            Err(e) => DeviceError {
                code: ErrorCode::from(e),
            }
            .encode(out),
            Ok(command) => match command {
                // A position beyond `pcount`: CMD_ARG_INVALID (Odemis only).
                Command::SetPosition(n) if n > self.pcount => DeviceError {
                    code: ErrorCode::ArgInvalid,
                }
                .encode(out),
                // "Moves the wheel to filter position n" (p. 11); the prompt when it
                // stops (Odemis; UNCONFIRMED).
                Command::SetPosition(n) => {
                    if n != self.position {
                        let d = self.move_time(self.position, n);
                        tracing::debug!(
                            from = self.position,
                            to = n,
                            seconds = d,
                            "filter wheel: moving"
                        );
                        self.from = self.position;
                        self.position = n;
                        self.move_start = t;
                        self.move_end = t + d;
                        prompt_at = self.move_end;
                    }
                }
                // The settings of p. 11, stored and read back by their queries.
                Command::SetPositionCount(n) => self.pcount = n,
                Command::SetSpeed(s) => self.speed = s,
                Command::SetTrigger(m) => self.trigger = m,
                Command::SetSensors(m) => self.sensors = m,
                // "save all the settings as default on power up" (p. 11): power
                // cycles are not modelled, so nothing to keep.
                Command::Save => {}
                Command::Identify => Reply::Identity(IDENTITY.into()).encode(out),
                Command::QueryPosition => Reply::Position(self.position).encode(out),
                Command::QueryPositionCount => Reply::PositionCount(self.pcount).encode(out),
                Command::QuerySpeed => Reply::Speed(self.speed).encode(out),
                Command::QueryTrigger => Reply::Trigger(self.trigger).encode(out),
                Command::QuerySensors => Reply::Sensors(self.sensors).encode(out),
            },
        }
        prompt_at
    }

    /// `baud=0`, `baud=1` (stored; no answer) and `baud?` (the digit), p. 11; `None`
    /// for any other line. Another value is `CMD_ARG_INVALID`, as for the other
    /// commands' values (Odemis only).
    fn baud_command(&mut self, line: &[u8]) -> Option<Result<Option<u8>, ErrorCode>> {
        let text = line.trim_ascii();
        if text == b"baud?" {
            return Some(Ok(Some(self.baud)));
        }
        let value = text.strip_prefix(b"baud=")?;
        Some(match value {
            b"0" | b"1" => {
                self.baud = value[0] - b'0';
                Ok(None)
            }
            _ => Err(ErrorCode::ArgInvalid),
        })
    }
}
