//! One simulated SMC100 controller with its rotation stage, as the manual describes it:
//! boots NOT REFERENCED, homes, refuses what its state does not allow with the manual's
//! error letter, moves along a trapezoidal velocity profile, quantises positions to
//! motor steps, reports positions that change during motion, stops with its
//! deceleration.
//!
//! The stage has a *mechanical* angle (what the optics see) and the controller a
//! *counter* (what `TP` reports). At power-up the counter reads 0 wherever the stage
//! is; a home search drives the stage to its home switch and sets the counter to the
//! home position. So positions mean something only after homing, as on real hardware.
//!
//! Each controller keeps its configuration as the manual's PW and ZT commands describe:
//! a saved copy (the controller's memory), loaded at power-up and `RS`, and the copy in
//! force, which `PW1` (CONFIGURATION, from NOT REFERENCED only) lets the configuration
//! commands change, `PW0` saves (silent meanwhile, then NOT REFERENCED from
//! CONFIGURATION), and `ZT` lists. Changes not saved are lost at the next boot.
//!
//! # Sources
//! "The manual" is Newport's *SMC100CC & SMC100PP User's Manual* EDH0206En2054 (06/23),
//! the edition `docs/instruments/smc100.md` cites; its pages are those checked in
//! `/work/shared/reference/protocol-findings.md` §3. Every behaviour below names its
//! source beside the code; "assumed" marks the twin's own choice where no source
//! says, with the reason. `docs/instruments/smc100.md` ("The twin") keeps the same
//! list.

use gonio_proto::smc100::{
    Command, ControllerState, ErrorCode, Frame, Param, PositionerErrors, Reply, ReplyBody,
    Smc100Parameters, Status,
};

pub use crate::motion::Profile;

/// How one simulated controller and stage behave.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerConfig {
    /// Address on the chain.
    pub address: u8,
    /// Stage name (`ID?`).
    pub stage: String,
    /// Firmware text (`VE`).
    pub version: String,
    /// Velocity at power-up, units/s.
    pub velocity: f64,
    /// Acceleration at power-up, units/s².
    pub acceleration: f64,
    /// Largest velocity `VA` accepts.
    pub max_velocity: f64,
    /// Largest acceleration `AC` accepts.
    pub max_acceleration: f64,
    /// Home search velocity, units/s.
    pub home_velocity: f64,
    /// Counter value set at the end of a home search.
    pub home_position: f64,
    /// Mechanical angle of the home switch.
    pub home_switch: f64,
    /// Longest a home search may take before it fails, s.
    pub home_timeout_s: f64,
    /// Software limits at power-up (`SL`, `SR`), counter units.
    pub negative_limit: f64,
    /// See `negative_limit`.
    pub positive_limit: f64,
    /// Motor steps (or encoder counts) per unit: positions are multiples of 1/this.
    pub counts_per_unit: f64,
    /// Mechanical angle of the stage when the simulation starts.
    pub start_position: f64,
    /// Time to boot after power-up or `RS`, during which the controller is silent, s.
    /// The manual gives "less than 5 s" (§5.2); the default 3 s is pySMC100's wait
    /// after `RS` (instruments.md §1.3). Silence meanwhile is assumed: the manual says
    /// nothing of the interface while it initialises, and drivers retry `TS` on
    /// timeouts after `RS` (pySMC100).
    pub boot_time_s: f64,
    /// How long a stalled stage lags its set-point before the controller disables
    /// (following error), s. Assumed: the manual's following-error limit `FE` is not
    /// for a PP (its page: error `W`), so how a PP notices a stall is not documented;
    /// pySMC100 reports a stuck move ending in DISABLE from MOVING (`3D`), which the
    /// twin reproduces after this lag.
    pub following_error_s: f64,
    /// How long `PW0` keeps the controller silent while it saves, s: the manual's
    /// "up to 10 s" (PW command), taken whole.
    pub save_time_s: f64,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        ControllerConfig {
            address: 1,
            stage: "URS100PP".into(),
            version: "SMC_PP - Controller-driver version  3. 1. 2".into(),
            velocity: 20.0,
            acceleration: 80.0,
            max_velocity: 40.0,
            max_acceleration: 160.0,
            home_velocity: 10.0,
            home_position: 0.0,
            home_switch: 0.0,
            home_timeout_s: 60.0,
            negative_limit: -170.0,
            positive_limit: 170.0,
            // A URS100 with a 1/100 micro-stepped 1.8° motor and 1:... gearing resolves
            // about 0.0005°: 2000 counts a degree (assumed: a nominal resolution; the
            // manual's PA page says only that targets round to an encoder count).
            counts_per_unit: 2000.0,
            start_position: 0.0,
            boot_time_s: 3.0,
            following_error_s: 0.5,
            save_time_s: 10.0,
        }
    }
}

/// Micro-steps per full step of the factory configuration (`FRM`); UNCONFIRMED: the
/// manual's default for a given stage is not known here.
const MICRO_STEPS: f64 = 100.0;

impl ControllerConfig {
    /// The configuration a controller holds before anything was saved: an SMC100PP
    /// with this rotation stage. Its `VA` and `AC` are the maxima (what the manual's
    /// CONFIGURATION values are), the limits and home search those of this config, the
    /// home type 2 (MZ switch only, which is the search the twin makes), the full step
    /// `FRS` what `counts_per_unit` and `FRM` imply. No backlash, hysteresis or base
    /// velocity; the current limits and jerk time are nominal values (UNCONFIRMED).
    /// Which lines `ZT` lists, and in which order, is [`Param::in_pp_dump`] (ZT page,
    /// p. 67, and hvl_ccb's SMC100PP driver).
    pub fn factory_parameters(&self) -> Smc100Parameters {
        let values = Param::CONFIGURATION
            .iter()
            .map(|p| {
                let v = match p {
                    // In CONFIGURATION `VA` and `AC` are the maxima (VA, AC pages).
                    Param::Acceleration => self.max_acceleration,
                    Param::MicroSteps => MICRO_STEPS,
                    Param::FullStep => MICRO_STEPS / self.counts_per_unit,
                    // HT2, MZ switch only (HT page): the search this twin makes.
                    Param::HomeType => 2.0,
                    Param::JerkTime => 0.04,
                    Param::HomeVelocity => self.home_velocity,
                    Param::HomeTimeout => self.home_timeout_s,
                    Param::PeakCurrent => 1.0,
                    Param::RmsCurrent => 0.5,
                    Param::RmsTime => 1.0,
                    // The manual's range for SA is 2–31 (p. 49): the controller on
                    // RS-232 is address 1 whatever its SA, so its SA is one a chain
                    // could use, 2 (assumed; hvl_ccb's default too). The others hold
                    // the address they answer to.
                    Param::RsAddress => f64::from(self.address.max(2)),
                    Param::NegativeLimit => self.negative_limit,
                    Param::PositiveLimit => self.positive_limit,
                    Param::Velocity => self.max_velocity,
                    // ZX3, stage check at power-up (ZX page; the p. 67 example ends `1ZX3`).
                    Param::StageCheck => 3.0,
                    _ => 0.0,
                };
                (*p, v)
            })
            .collect();
        Smc100Parameters {
            stage: self.stage.clone(),
            values,
            other: Vec::new(),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Activity {
    Idle,
    Moving(Profile),
    Homing(Profile),
}

/// One simulated controller and stage.
#[derive(Clone, Debug)]
pub struct Controller {
    cfg: ControllerConfig,
    state: ControllerState,
    /// Counter − mechanical angle is fixed while the stage is referenced.
    offset: f64,
    /// Mechanical angle when idle (during motion the profile gives it).
    at_rest: f64,
    activity: Activity,
    target: f64,
    last_relative: f64,
    velocity: f64,
    acceleration: f64,
    sl: f64,
    sr: f64,
    last_error: ErrorCode,
    latched: u16,
    /// Silent (booting) until this time.
    booting_until: f64,
    /// Fault: the stage sticks at this mechanical angle.
    stall_at: Option<f64>,
    /// The configuration in the controller's memory (what boots load).
    saved: Smc100Parameters,
    /// The configuration in force (what `ZT` lists; CONFIGURATION changes it).
    params: Smc100Parameters,
}

impl Controller {
    /// A controller at power-up: NOT REFERENCED, counter 0, silent while it boots.
    pub fn new(cfg: ControllerConfig) -> Self {
        let at_rest = cfg.start_position;
        let mut c = Controller {
            state: ControllerState::NotReferencedFromReset,
            offset: 0.0,
            at_rest,
            activity: Activity::Idle,
            target: 0.0,
            last_relative: 0.0,
            velocity: cfg.velocity,
            acceleration: cfg.acceleration,
            sl: cfg.negative_limit,
            sr: cfg.positive_limit,
            last_error: ErrorCode::None,
            latched: 0,
            booting_until: 0.0,
            stall_at: None,
            saved: cfg.factory_parameters(),
            params: cfg.factory_parameters(),
            cfg,
        };
        c.boot(0.0, 0.0);
        c
    }

    /// Power-up or `RS`: the saved configuration loaded, NOT REFERENCED from reset
    /// (`0A`), silent for `boot_time` (manual §5.2: "less than 5 s"; RS page: a reset
    /// is a power-up; silence assumed, see [`ControllerConfig::boot_time_s`]).
    fn boot(&mut self, now: f64, boot_time: f64) {
        let m = self.mechanical(now);
        self.activity = Activity::Idle;
        self.at_rest = m;
        self.state = ControllerState::NotReferencedFromReset;
        // An unreferenced counter starts at 0 wherever the stage stands (assumed: an
        // SMC100PP drives a stepper open loop, so it cannot know where it stands
        // before a home search; the manual's example start-up reads `1TP0`).
        self.offset = -m;
        self.target = 0.0;
        // PW page (p. 44): the configuration saved by PW0 is what a boot loads; the
        // working values (VA, AC, SL, SR in READY/DISABLE) are lost (VA, AC, SL, SR
        // pages: "working value").
        self.params = self.saved.clone();
        self.load_working();
        self.last_error = ErrorCode::None;
        self.latched = 0;
        self.booting_until = now + boot_time;
    }

    /// The working values from the configuration in force: the limits, and the
    /// config's start-up velocity and acceleration held under the configured maxima.
    fn load_working(&mut self) {
        self.velocity = self.cfg.velocity.min(self.param(Param::Velocity));
        self.acceleration = self.cfg.acceleration.min(self.param(Param::Acceleration));
        self.sl = self.param(Param::NegativeLimit);
        self.sr = self.param(Param::PositiveLimit);
    }

    /// A configuration value in force (every one is there from the factory set).
    fn param(&self, p: Param) -> f64 {
        self.params.get(p).unwrap_or(0.0)
    }

    /// The configuration in force: what `ZT` lists.
    pub fn parameters(&self) -> &Smc100Parameters {
        &self.params
    }

    /// The configuration in the controller's memory: what the next boot loads.
    pub fn saved_parameters(&self) -> &Smc100Parameters {
        &self.saved
    }

    /// The configuration.
    pub fn config(&self) -> &ControllerConfig {
        &self.cfg
    }

    /// The controller's address.
    pub fn address(&self) -> u8 {
        self.cfg.address
    }

    /// The state at `now` (after finishing motions that ended).
    pub fn state(&mut self, now: f64) -> ControllerState {
        self.update(now);
        self.state
    }

    /// True while booting or saving its configuration: the controller does not
    /// answer.
    pub fn is_booting(&self, now: f64) -> bool {
        now < self.booting_until
    }

    /// The mechanical angle at `now`: what the optics see.
    pub fn mechanical(&self, now: f64) -> f64 {
        let raw = match self.activity {
            Activity::Idle => self.at_rest,
            Activity::Moving(p) | Activity::Homing(p) => p.position(now) - self.offset,
        };
        match (self.stall_at, self.activity) {
            (Some(s), Activity::Moving(p)) => {
                let (start, end) = (p.from - self.offset, raw);
                if (start - s) * (end - s) <= 0.0 {
                    s
                } else {
                    raw
                }
            }
            _ => raw,
        }
    }

    /// When the current motion ends, if one is under way.
    pub fn motion_end(&self) -> Option<f64> {
        match self.activity {
            Activity::Idle => None,
            Activity::Moving(p) | Activity::Homing(p) => Some(p.end()),
        }
    }

    /// Stores an error letter for `TE` (a line the controller could not parse: `A` for
    /// an unknown code or a non-integer address, `C` for a missing or bad value, as
    /// the manual's per-command error lists say; instruments.md §1.6).
    pub fn set_error(&mut self, code: ErrorCode) {
        self.last_error = code;
    }

    /// Fault: from now on the stage sticks when it reaches `angle` (mechanical).
    pub fn stall_at(&mut self, angle: Option<f64>) {
        self.stall_at = angle;
    }

    /// Fault: power loss and recovery; the controller reboots (silent for its boot
    /// time) and comes back NOT REFERENCED from reset (§5.2, as `RS`). The NUL byte the
    /// simulator puts on the line when it fires is assumed (no source; it is what a
    /// UART sees when its sender's supply collapses).
    pub fn power_cycle(&mut self, now: f64) {
        self.boot(now, self.cfg.boot_time_s);
    }

    /// A position rounded to the closest encoder (motor step) count: PA page (p. 41),
    /// "always rounds the new target position to the closest encoder position".
    fn quantise(&self, v: f64) -> f64 {
        (v * self.cfg.counts_per_unit).round() / self.cfg.counts_per_unit
    }

    fn counter(&self, now: f64) -> f64 {
        self.quantise(self.mechanical(now) + self.offset)
    }

    /// Finishes motions that ended by `now`; detects a stalled stage.
    pub fn update(&mut self, now: f64) {
        match self.activity {
            Activity::Moving(p) => {
                if let Some(s) = self.stall_at {
                    let start = p.from - self.offset;
                    let planned = p.position(now) - self.offset;
                    if (start - s) * (planned - s) < 0.0 {
                        // The set-point ran past the stuck stage: a following error after
                        // the configured lag disables the motor: DISABLE from MOVING
                        // (`3D`, TS p. 63) with bit 5 (TS p. 62). Assumed from pySMC100
                        // ("a stuck move ends in 3D"); no manual page describes it.
                        let passed = p.crossing(s + self.offset).unwrap_or(p.t0);
                        if now >= passed + self.cfg.following_error_s {
                            self.activity = Activity::Idle;
                            self.at_rest = s;
                            self.state = ControllerState::DisableFromMoving;
                            self.latched |= PositionerErrors::FOLLOWING_ERROR;
                        }
                        return;
                    }
                }
                if now >= p.end() {
                    // READY from MOVING (`33`, TS p. 63).
                    self.activity = Activity::Idle;
                    self.at_rest = p.to - self.offset;
                    self.state = ControllerState::ReadyFromMoving;
                }
            }
            Activity::Homing(p) => {
                if now >= p.end() {
                    self.activity = Activity::Idle;
                    self.at_rest = p.to - self.offset;
                    if p.duration > self.param(Param::HomeTimeout) {
                        // OT exceeded: bit 6, homing time-out (TS p. 62); the state
                        // after it, NOT REFERENCED from HOMING (`0B`), is assumed
                        // (instruments.md §1.7 infers it; UNCONFIRMED).
                        self.state = ControllerState::NotReferencedFromHoming;
                        self.latched |= PositionerErrors::HOMING_TIMEOUT;
                    } else {
                        // Referenced: the counter now reads the home position here;
                        // READY from HOMING (`32`, TS p. 63).
                        self.offset = self.cfg.home_position - self.at_rest;
                        self.target = self.cfg.home_position;
                        self.state = ControllerState::ReadyFromHoming;
                    }
                } else if now - p.t0 > self.param(Param::HomeTimeout) {
                    // The search gives up where it is (OT page: the home search
                    // time-out; `0B` and bit 6 as above).
                    self.at_rest = p.position(now) - self.offset;
                    self.activity = Activity::Idle;
                    self.state = ControllerState::NotReferencedFromHoming;
                    self.latched |= PositionerErrors::HOMING_TIMEOUT;
                }
            }
            Activity::Idle => {}
        }
    }

    /// The error letter for a command refused in the current state: `H`–`M` for NOT
    /// REFERENCED, CONFIGURATION, DISABLE, READY, HOMING, MOVING (TE page, p. 59; the
    /// letters are the manual's). Which letter a given command stores in a given state
    /// is the manual's per-command error lists where they name one; for `PA`/`PR` in
    /// MOVING or HOMING they name none (PA page, p. 41-42: A, B, C, D, G, H, I, J only),
    /// so `M`/`L` there is assumed, by analogy with the other commands (`D`, "execution
    /// not allowed", is as likely; Gonio's session accepts either). JOGGING is not
    /// modelled (keypad only), hence the `D` fallback, unused.
    fn refused(&self) -> ErrorCode {
        let s = self.state;
        [
            (s.is_not_referenced(), ErrorCode::NotReferenced),
            (s.is_configuration(), ErrorCode::InConfiguration),
            (s.is_disabled(), ErrorCode::InDisable),
            (s.is_homing(), ErrorCode::InHoming),
            (s.is_moving(), ErrorCode::InMoving),
            (s.is_ready(), ErrorCode::InReady),
        ]
        .into_iter()
        .find_map(|(is, letter)| is.then_some(letter))
        .unwrap_or(ErrorCode::NotAllowed)
    }

    /// MOVING (`28`, TS p. 63) along a trapezoidal profile at the working `VA` and `AC`
    /// (assumed: the manual gives no profile for a PP; `PT` answers this profile's
    /// time, and the moves do not block the interface, §5.4); from READY only, to a
    /// target within [SL, SR] else `G` (PA, PR pages).
    fn start_move(&mut self, now: f64, to: f64) -> Result<(), ErrorCode> {
        if !self.state.is_ready() {
            return Err(self.refused());
        }
        if to < self.sl || to > self.sr {
            return Err(ErrorCode::OutOfLimits);
        }
        let from = self.counter(now);
        let to = self.quantise(to);
        self.target = to;
        let p = Profile::new(from, to, now, self.velocity, self.acceleration);
        self.activity = Activity::Moving(p);
        self.state = ControllerState::Moving;
        Ok(())
    }

    /// Executes a command addressed to this controller at `now`, as
    /// [`handle`](Self::handle) does, and returns every reply line, terminators
    /// included: the many lines of a `ZT` dump, or the one line of a query.
    ///
    /// The dump is an SMC100PP's: `PW1`, `ID`, then `AC BA BH FRM FRS HT JR OH OT QIL SA
    /// SL SR VA VB ZX` ([`Param::in_pp_dump`]: what hvl_ccb's driver, written against real
    /// SMC100PPs, requires line for line; the manual gives only an example, p. 67),
    /// reals with six decimals as in that example, and `PW0` (hvl_ccb; the manual's
    /// example shows a second `PW1`, which Gonio's reader also takes). `ZT` answers in
    /// every state the twin has (§5.5 table: NR, CF, DIS, RDY, MOT).
    pub fn respond(&mut self, now: f64, command: &Command) -> Vec<Vec<u8>> {
        if *command == Command::DumpConfiguration {
            self.update(now);
            let listed = Smc100Parameters {
                stage: self.params.stage.clone(),
                values: Param::CONFIGURATION
                    .iter()
                    .filter(|p| p.in_pp_dump())
                    .filter_map(|p| self.params.get(*p).map(|v| (*p, v)))
                    .collect(),
                other: self.params.other.clone(),
            };
            let mut bytes = Vec::new();
            listed.encode_dump(self.cfg.address, &mut bytes);
            return bytes
                .split_inclusive(|b| *b == b'\n')
                .map(<[u8]>::to_vec)
                .collect();
        }
        self.handle(now, command)
            .map(|r| r.to_bytes())
            .into_iter()
            .collect()
    }

    /// Executes a command addressed to this controller at `now` (the caller filters by
    /// address and checks [`is_booting`](Self::is_booting)); returns the reply, if the
    /// command has one line (`ZT` has many: see [`respond`](Self::respond)). Refused
    /// commands store their error letter for `TE`.
    pub fn handle(&mut self, now: f64, command: &Command) -> Option<Reply> {
        self.update(now);
        let a = self.cfg.address;
        let reply = |body| Some(Reply { address: a, body });
        let s = self.state;
        match command {
            // TP, TH, TS, TE, VE answer in every state: the §5.5 table marks TP and TH
            // "all" (their error lists name H and I, but drivers read TP in any state:
            // instruments.md §1.4), TS (p. 62-63), TE (p. 59), VE (table: all).
            Command::TellPosition => return reply(ReplyBody::Position(self.counter(now))),
            Command::TellSetpoint => {
                let sp = match self.activity {
                    Activity::Moving(p) | Activity::Homing(p) => self.quantise(p.position(now)),
                    Activity::Idle => self.target,
                };
                return reply(ReplyBody::Setpoint(sp));
            }
            Command::TellStatus => {
                // TS p. 63: "reads the error buffer and clears the error buffer".
                let errors = PositionerErrors(self.latched);
                self.latched = 0;
                return reply(ReplyBody::Status(Status { errors, state: s }));
            }
            Command::TellError => {
                // TE p. 59: "after the execution of a TE command, the error buffer
                // gets erased"; a newer error overwrites an unread one (below).
                let e = std::mem::replace(&mut self.last_error, ErrorCode::None);
                return reply(ReplyBody::Error(e));
            }
            Command::Version => return reply(ReplyBody::Version(self.cfg.version.clone())),
            Command::DumpConfiguration => return None,
            // A query answers in every state (assumed: the §5.5 table gives states for
            // the sets; `ID?`, marked CONFIGURATION only there, is read in NOT
            // REFERENCED by drivers and field notes, instruments.md §1.4; UNCONFIRMED).
            // The reply echoes address and code, then the value (§5.5).
            Command::Query(p) => {
                let v = match p {
                    Param::StageId => return reply(ReplyBody::StageId(self.params.stage.clone())),
                    Param::Acceleration => self.acceleration,
                    Param::Velocity => self.velocity,
                    Param::NegativeLimit => self.sl,
                    Param::PositiveLimit => self.sr,
                    Param::AbsoluteTarget => self.target,
                    Param::RelativeTarget => self.last_relative,
                    Param::Enabled => f64::from(u8::from(!s.is_disabled())),
                    Param::ConfigurationMode => f64::from(u8::from(s.is_configuration())),
                    other => self.param(*other),
                };
                return reply(ReplyBody::Value(*p, v));
            }
            // PT: the time of a relative move of |d| at the working VA and AC, no
            // motion (PT page); accepted in DISABLE, READY and MOVING/HOMING (§5.5
            // table; instruments.md §1.4), else the state's letter and no reply (§5.3);
            // d in (1e-6, 1e12) else `C` (PT page).
            Command::MotionTime(d) => {
                if !(s.is_ready() || s.is_disabled() || s.is_moving() || s.is_homing()) {
                    self.last_error = self.refused();
                    return None;
                }
                if !(*d > 1e-6 && *d < 1e12) {
                    self.last_error = ErrorCode::BadParameter;
                    return None;
                }
                return reply(ReplyBody::MotionTime(Profile::duration_for(
                    *d,
                    self.velocity,
                    self.acceleration,
                )));
            }
            _ => {}
        }
        // Set and action commands: no reply, even when refused; errors go to TE
        // (§5.3, §5.5), the newest overwriting an unread one (TE p. 59).
        self.last_error = self.execute(now, command).err().unwrap_or(ErrorCode::None);
        None
    }

    fn execute(&mut self, now: f64, command: &Command) -> Result<(), ErrorCode> {
        let s = self.state;
        match command {
            Command::Home => self.home(now),
            Command::MoveAbsolute(t) => {
                // PA page (p. 41): "only accepted in READY state, AND when the new
                // target position is higher or equal to ... SL, AND lower or equal to
                // ... SR", else `G`; the target rounds to an encoder count. The letter
                // in MOVING/HOMING is assumed (see `refused`).
                self.start_move(now, *t)
            }
            Command::MoveRelative(d) => {
                // PR page: relative to the current target, READY only, the result
                // within [SL, SR] else `G` (instruments.md §1.4); letters as PA's.
                self.start_move(now, self.target + d)?;
                self.last_relative = *d;
                Ok(())
            }
            Command::Stop => self.stop(now),
            Command::Reset => {
                // RS page (p. 48) contradicts itself: its state row allows NOT
                // REFERENCED, CONFIGURATION, DISABLE, READY and MOTION, its error list
                // names H, I, L, M. Assumed: refused in CONFIGURATION (`I`), HOMING
                // (`L`) and MOVING (`M`), as the §5.5 table (NR, DIS, RDY) reads; the
                // way out of CONFIGURATION is PW0 (p. 44). UNCONFIRMED.
                if s.is_moving() || s.is_homing() || s.is_configuration() {
                    return Err(self.refused());
                }
                self.boot(now, self.cfg.boot_time_s);
                Ok(())
            }
            // MM page: MM0 READY → DISABLE (`3C`), MM1 DISABLE → READY (`34`) with the
            // set-point at the current position. MM0 in DISABLE and MM1 in READY are
            // taken as no-ops (assumed: the page names no error for them); any other
            // state stores its letter.
            Command::Enable(on) => match (on, s.is_ready(), s.is_disabled()) {
                (false, true, _) => {
                    self.state = ControllerState::DisableFromReady;
                    Ok(())
                }
                (true, _, true) => {
                    self.target = self.counter(now);
                    self.state = ControllerState::ReadyFromDisable;
                    Ok(())
                }
                (false, _, true) | (true, true, _) => Ok(()),
                _ => Err(self.refused()),
            },
            Command::SetVelocity(v) => self.set_working(Param::Velocity, *v),
            Command::SetAcceleration(v) => self.set_working(Param::Acceleration, *v),
            Command::SetNegativeLimit(v) => self.set_working(Param::NegativeLimit, *v),
            Command::SetPositiveLimit(v) => self.set_working(Param::PositiveLimit, *v),
            // Configuration parameters change in CONFIGURATION only (PW page, p. 44;
            // §5.5 table "CF"), else the state's letter.
            Command::Set(p, v) if s.is_configuration() => self.configure(*p, *v),
            Command::SetStageId(name) if s.is_configuration() => {
                self.params.stage = name.clone();
                Ok(())
            }
            Command::Set(..) | Command::SetStageId(_) => Err(self.refused()),
            Command::ConfigurationMode(true) => {
                // PW1: NOT REFERENCED to CONFIGURATION (`14`), from nowhere else (PW
                // page, p. 44: "changes the controller's state from NOT REFERENCED to
                // CONFIGURATION").
                if !s.is_not_referenced() {
                    return Err(self.refused());
                }
                self.state = ControllerState::Configuration;
                Ok(())
            }
            Command::ConfigurationMode(false) => {
                // PW0: save, silent meanwhile, then NOT REFERENCED from CONFIGURATION
                // (`0C`). PW page (p. 44): "saves them in the flash memory ... may take
                // up to 10 seconds. During that time the controller will not respond".
                if !s.is_configuration() {
                    return Err(self.refused());
                }
                self.saved = self.params.clone();
                self.load_working();
                self.state = ControllerState::NotReferencedFromConfiguration;
                self.booting_until = now + self.cfg.save_time_s;
                Ok(())
            }
            // Anything else (SE, JD, the analog and TTL I/O, CC-only commands) is
            // not modelled: stored as `A`, "unknown message code" (TE p. 59).
            _ => Err(ErrorCode::UnknownCommand),
        }
    }

    /// `OR`: a home search, or at once with HT1.
    fn home(&mut self, now: f64) -> Result<(), ErrorCode> {
        let s = self.state;
        // OR during a home search: `E`, "home sequence already started" (the
        // letter is TE p. 59's; that OR gets it rather than `L` is assumed,
        // instruments.md §1.7).
        if s.is_homing() {
            return Err(ErrorCode::HomeStarted);
        }
        // OR page (p. 39): "accepted only in NOT REFERENCED state".
        if !s.is_not_referenced() {
            return Err(self.refused());
        }
        if self.param(Param::HomeType) == 1.0 {
            // HT1: the current position is home, at once (HT page: "use
            // current position as HOME").
            self.offset = self.cfg.home_position - self.at_rest;
            self.target = self.cfg.home_position;
            self.state = ControllerState::ReadyFromHoming;
            return Ok(());
        }
        let from = self.counter(now);
        // Drive to the switch at the home velocity `OH` (OH page), counted in the
        // current counter: HOMING from RS-232 (`1E`, TS p. 63). HT2's search is
        // simplified to one pass onto the switch (assumed).
        let to = self.cfg.home_switch + self.offset;
        let oh = self.param(Param::HomeVelocity);
        let p = Profile::new(from, to, now, oh, self.acceleration);
        self.activity = Activity::Homing(p);
        self.state = ControllerState::HomingRemote;
        Ok(())
    }

    /// `ST`: a move decelerates, a home search stops.
    fn stop(&mut self, now: f64) -> Result<(), ErrorCode> {
        let s = self.state;
        match self.activity {
            Activity::Moving(p) => {
                // ST page: "decelerating the positioner immediately with the
                // acceleration defined by the AC command"; it ends READY from
                // MOVING (`33`, as drivers observe: instruments.md §1.7).
                // Decelerate with AC from the current speed: the second half of a
                // symmetric profile that peaks at that speed right now.
                let x = p.position(now);
                let v = p.speed(now);
                if v <= 0.0 {
                    self.at_rest = x - self.offset;
                    self.activity = Activity::Idle;
                    self.state = ControllerState::ReadyFromMoving;
                    self.target = self.quantise(x);
                    return Ok(());
                }
                let a = self.acceleration;
                let half = v * v / (2.0 * a);
                let dir = (p.to - p.from).signum();
                let q = Profile::new(x - dir * half, x + dir * half, now - v / a, v, a);
                self.target = self.quantise(q.to);
                self.activity = Activity::Moving(q);
                Ok(())
            }
            Activity::Homing(p) => {
                // ST in HOMING: the search stops where it is, NOT REFERENCED
                // from HOMING (`0B`): assumed (UNCONFIRMED; instruments.md
                // §1.7 "probably 0B").
                self.at_rest = p.position(now) - self.offset;
                self.activity = Activity::Idle;
                self.state = ControllerState::NotReferencedFromHoming;
                Ok(())
            }
            // §5.5 table: ST is accepted in DISABLE, READY and MOVING/HOMING.
            Activity::Idle if s.is_ready() || s.is_disabled() => Ok(()),
            Activity::Idle => Err(self.refused()),
        }
    }

    /// `VA`, `AC`, `SL`, `SR`: outside CONFIGURATION a working value, in DISABLE or
    /// READY only, else the state's letter.
    fn set_working(&mut self, param: Param, v: f64) -> Result<(), ErrorCode> {
        let s = self.state;
        if s.is_configuration() {
            // In CONFIGURATION, `VA` and `AC` set the maxima (saved by PW0): VA and AC
            // pages; `SL` and `SR` the configured limits.
            return self.configure(param, v);
        }
        if !(s.is_ready() || s.is_disabled()) {
            return Err(self.refused());
        }
        let ok = match param {
            // In DISABLE or READY, a working value in (1e-6, the configured maximum]
            // else `C` (VA, AC pages: "> 10-6 and < 1012", working value ≤ max).
            Param::Velocity | Param::Acceleration => v > 1e-6 && v <= self.param(param),
            // A working limit must bracket the set-point (assumed: PyMeasure's
            // validators and instruments.md §1.4; the SL/SR pages give SL ≤ 0 ≤ SR
            // only for the configured values).
            Param::NegativeLimit => v <= self.target,
            _ => v >= self.target,
        };
        if !ok {
            return Err(ErrorCode::BadParameter);
        }
        *match param {
            Param::Velocity => &mut self.velocity,
            Param::Acceleration => &mut self.acceleration,
            Param::NegativeLimit => &mut self.sl,
            _ => &mut self.sr,
        } = v;
        Ok(())
    }

    /// A configuration parameter set in CONFIGURATION: `C` outside the manual's range
    /// ([`Param::accepts`]: the AC, HT, JR, OT, QIL/QIR/QIT, SA, SL, SR, VA pages).
    fn configure(&mut self, p: Param, v: f64) -> Result<(), ErrorCode> {
        if !(p.is_configuration() && p.accepts(v)) {
            return Err(ErrorCode::BadParameter);
        }
        self.params.set(p, v);
        Ok(())
    }
}

/// Frames addressed to a controller: `true` when `frame` is for `address` (or for all:
/// a broadcast, which the codec allows for `ST`, `MM` and `SE` only, as their pages
/// say).
pub fn addressed_to(frame: &Frame, address: u8) -> bool {
    frame.address.is_none_or(|a| a == address)
}
