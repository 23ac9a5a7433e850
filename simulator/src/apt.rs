//! Simulated Thorlabs APT controllers with their stages: a KDC101 driving a PRM1-Z8,
//! or a K10CR1. Bytes in, bytes out, on simulated time (seconds), speaking the
//! messages of `gonio_proto::apt` byte for byte.
//!
//! As on the hardware: the position counter reads 0 at power-up wherever the stage
//! stands, and means something only after a home search (which turns the stage in
//! reverse onto its home switch and then to the home offset, where the counter is
//! zeroed); moves follow a trapezoidal profile with the velocity parameters; a move
//! ends with `MOT_MOVE_COMPLETED`, a home search with `MOT_MOVE_HOMED`, a stop with
//! `MOT_MOVE_STOPPED`; positions are whole counts. After `HW_START_UPDATEMSGS` the
//! controller sends its status every `update_period_s` (APT protocol manual, Issue 28,
//! p. 51: "every 100 msec").
//!
//! The server-alive rule (p. 130, `MOT_ACK_DCSTATUSUPDATE`): "this message … must be
//! sent by the server to the controller at least once a second or the controller will
//! stop responding after ~50 commands. The controller keeps track of the number of
//! 'status update' type of messages (e.g. move complete message) and if it has sent 50
//! of these without the server sending a 'server alive' message, it will stop sending
//! any more 'status update' messages." The twin counts the status-type messages it
//! sends since the last server-alive ([`KeepAliveRule`] says which count) and, past
//! `status_without_ack` of them, sends none: no status reply, no update, no move
//! completion. A server-alive resets the count (assumed: the manual says no more).
//! The once-a-second obligation itself is the host's: the twin records every gap
//! between server-alive messages longer than `keepalive_timeout_s`, for tests to
//! hold a driver to it.
//!
//! The stepper status (`0x0481`) has 28 data bytes in the manual (p. 123) and 14 from a
//! K10CR1 (PnPQ, tested on K10CR1s); `stepper_status_bytes` chooses.
//!
//! Both stages turn continuously, so there are no limit switches unless the config
//! places some.

use gonio_proto::Framer;
use gonio_proto::apt::{
    AptFramer, AptInfo, CHANNEL, DcStatus, Direction, GenMoveParams, HomeParams, JogParams,
    LimSwitchParams, Message, Packet, STEPPER_STATUS_EXTRA, StageKind, StepperStatus, StopMode,
    USB_UNIT, VelParams, status,
};

use crate::motion::Profile;
use crate::twin::TimedLine;

/// Stores a parameter set as the host sent it, on the controller's one channel.
macro_rules! store {
    ($slot:expr, $sent:expr) => {{
        $slot = *$sent;
        $slot.chan = CHANNEL;
    }};
}

/// Which controller and stage.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
pub enum AptModel {
    /// A KDC101 K-Cube with a PRM1-Z8 rotation stage.
    #[serde(rename = "kdc101-prm1z8")]
    Kdc101Prm1z8,
    /// A K10CR1 rotation mount.
    #[serde(rename = "k10cr1")]
    K10cr1,
}

impl AptModel {
    /// The stage, for its scales.
    pub fn stage(self) -> StageKind {
        match self {
            AptModel::Kdc101Prm1z8 => StageKind::Prm1Z8,
            AptModel::K10cr1 => StageKind::K10cr1,
        }
    }
}

/// Which messages count towards the server-alive limit (p. 130).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum KeepAliveRule {
    /// The status messages the controller sends on its own: periodic updates, and the
    /// move-completed, homed and stopped messages (the manual's example). Replies to
    /// status requests do not count, but are withheld once the limit is passed. A
    /// public client used with real KDC101s, thorlabs-apt-device in its "polled" mode,
    /// polls the status 100 times a second and never sends the server-alive, which a
    /// controller counting its replies would not survive for a second.
    #[default]
    Unsolicited,
    /// Every status message, replies to status requests included: the manual read
    /// literally.
    All,
}

/// How one simulated APT controller and its stage behave.
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct AptDeviceConfig {
    /// `"kdc101-prm1z8"` or `"k10cr1"`.
    pub model: AptModel,
    /// The serial number `HW_GET_INFO` reports (KDC101s begin with 27, K10CR1s with 55).
    pub serial_number: u32,
    /// Firmware version reported: major, interim, minor.
    pub firmware: [u8; 3],
    /// Mechanical angle of the stage when the simulation starts, deg.
    pub start_position_deg: f64,
    /// Mechanical angle of the home switch, deg.
    pub home_switch_deg: f64,
    /// Mechanical angles of the reverse and forward hardware limit switches, deg, or
    /// none: the PRM1-Z8 and the K10CR1 both turn continuously.
    pub limit_switches_deg: Option<[f64; 2]>,
    /// Maximum velocity at power-up, deg/s.
    pub velocity: f64,
    /// Acceleration at power-up, deg/s².
    pub acceleration: f64,
    /// Period of the status updates after `HW_START_UPDATEMSGS`, s.
    pub update_period_s: f64,
    /// The longest gap between server-alive messages the manual allows, s ("at
    /// least once a second", p. 130); longer ones are recorded.
    pub keepalive_timeout_s: f64,
    /// Status messages sent without a server-alive before the controller sends no
    /// more (p. 130: "if it has sent 50 of these"); 0 never stops.
    pub status_without_ack: u32,
    /// Which status messages count towards it.
    pub keepalive_rule: KeepAliveRule,
    /// Data bytes of the stepper status `0x0481`: 14 (a K10CR1, as PnPQ saw it) or 28
    /// (the manual, p. 123).
    pub stepper_status_bytes: u16,
}

impl Default for AptDeviceConfig {
    fn default() -> Self {
        AptDeviceConfig {
            model: AptModel::Kdc101Prm1z8,
            serial_number: 27_000_001,
            firmware: [3, 0, 10],
            start_position_deg: 0.0,
            home_switch_deg: 0.0,
            limit_switches_deg: None,
            velocity: 10.0,
            acceleration: 10.0,
            update_period_s: 0.1,
            keepalive_timeout_s: 1.0,
            status_without_ack: 50,
            keepalive_rule: KeepAliveRule::Unsolicited,
            stepper_status_bytes: 14,
        }
    }
}

/// What a motion is, for the message that ends it and the status bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Move,
    Home,
    Velocity,
    /// A move cut short by a limit switch at its end.
    ToLimit(u32),
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Activity {
    Idle,
    /// Along a profile, in mechanical degrees.
    Profile(Profile, Kind),
    /// Decelerating to rest after a profiled stop.
    Decel {
        from: f64,
        /// +1 or −1.
        dir: f64,
        v0: f64,
        a: f64,
        t0: f64,
    },
}

/// One simulated APT controller and stage. Sans-IO: the caller hands in the bytes the
/// host wrote ([`receive`](TimedLine::receive)) and collects what the controller sends on
/// its own ([`poll`](TimedLine::poll), due by [`next_event`](TimedLine::next_event)), all at
/// simulated times in seconds.
#[derive(Clone, Debug)]
pub struct AptDevice {
    cfg: AptDeviceConfig,
    stage: StageKind,
    framer: AptFramer,
    activity: Activity,
    /// Mechanical angle while idle.
    at_rest: f64,
    /// Counter degrees − mechanical degrees.
    offset: f64,
    homed: bool,
    enabled: bool,
    motion_error: bool,
    limit_bits: u32,
    vel: VelParams,
    jog: JogParams,
    home: HomeParams,
    genmove: GenMoveParams,
    lim: LimSwitchParams,
    /// `MOVERELPARAMS` and `MOVEABSPARAMS`, counts: what short-form moves use.
    move_rel: i32,
    move_abs: i32,
    updates: bool,
    next_update: f64,
    stall_at: Option<f64>,
    keepalive: KeepAliveRecord,
}

/// What the twin saw of the host's server-alive messages, and what it withheld.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct KeepAliveRecord {
    /// When the host first wrote to the controller, s.
    pub first_contact: Option<f64>,
    /// When the last server-alive came, s.
    pub last_ack: Option<f64>,
    /// Server-alive messages received.
    pub acks: u64,
    /// Status messages counted since the last server-alive.
    pub unacked: u32,
    /// Status messages withheld because the limit was passed.
    pub withheld: u64,
    /// Gaps longer than `keepalive_timeout_s` between server-alive messages (from the
    /// first contact to the first one too).
    pub late: u64,
    /// The longest such gap so far, s.
    pub longest_gap: f64,
}

impl KeepAliveRecord {
    /// The longest gap without a server-alive up to `now`, counting the one still
    /// open, s; 0 before any contact.
    pub fn longest_gap_until(&self, now: f64) -> f64 {
        match self.last_ack.or(self.first_contact) {
            Some(t) => self.longest_gap.max(now - t),
            None => 0.0,
        }
    }
}

impl AptDevice {
    /// A controller at power-up: not homed, channel enabled, counter 0.
    pub fn new(cfg: &AptDeviceConfig) -> Self {
        let stage = cfg.model.stage();
        let mut d = AptDevice {
            stage,
            framer: AptFramer::new(),
            activity: Activity::Idle,
            at_rest: cfg.start_position_deg,
            offset: 0.0,
            homed: false,
            enabled: true,
            motion_error: false,
            limit_bits: 0,
            vel: VelParams {
                chan: CHANNEL,
                min_velocity: 0,
                acceleration: 0,
                max_velocity: 0,
            },
            jog: JogParams {
                chan: CHANNEL,
                mode: 2,
                step: 0,
                min_velocity: 0,
                acceleration: 0,
                max_velocity: 0,
                stop_mode: 2,
            },
            home: HomeParams {
                chan: CHANNEL,
                direction: 2,
                limit_switch: 1,
                velocity: 0,
                offset: 0,
            },
            genmove: GenMoveParams {
                chan: CHANNEL,
                backlash: 0,
            },
            lim: LimSwitchParams {
                chan: CHANNEL,
                cw_hard: 1,
                ccw_hard: 1,
                cw_soft: 0,
                ccw_soft: 0,
                soft_mode: 1,
            },
            move_rel: 0,
            move_abs: 0,
            updates: false,
            next_update: 0.0,
            stall_at: None,
            keepalive: KeepAliveRecord::default(),
            cfg: cfg.clone(),
        };
        d.boot(cfg.start_position_deg);
        d
    }

    fn boot(&mut self, mechanical: f64) {
        let s = self.stage;
        self.activity = Activity::Idle;
        self.at_rest = mechanical;
        self.offset = -mechanical;
        self.homed = false;
        self.enabled = true;
        self.motion_error = false;
        self.limit_bits = 0;
        self.vel.max_velocity = s.velocity_to_apt(self.cfg.velocity);
        self.vel.acceleration = s.acceleration_to_apt(self.cfg.acceleration);
        self.jog.step = s.to_counts(1.0);
        self.jog.max_velocity = self.vel.max_velocity;
        self.jog.acceleration = self.vel.acceleration;
        self.home.velocity = s.velocity_to_apt(s.home_velocity());
        self.home.offset = s.to_counts(s.home_offset());
        self.genmove.backlash = 0;
        self.updates = false;
        // A controller that restarts has counted nothing yet (assumed).
        self.keepalive.unacked = 0;
        self.framer.clear();
    }

    /// What the twin saw of the server-alive messages.
    pub fn keepalive(&self) -> &KeepAliveRecord {
        &self.keepalive
    }

    /// True once the controller has stopped sending status messages.
    pub fn is_silenced(&self) -> bool {
        let n = self.cfg.status_without_ack;
        n > 0 && self.keepalive.unacked >= n
    }

    /// Sends `m`, a status-type message, under the server-alive rule: withheld once
    /// the limit is passed; counted when `counted` (see [`KeepAliveRule`]).
    fn status(&mut self, m: &Message, counted: bool, out: &mut Vec<u8>) {
        if self.is_silenced() {
            self.keepalive.withheld += 1;
            return;
        }
        if counted {
            self.keepalive.unacked += 1;
        }
        m.encode(out);
    }

    /// Sends a reply to a status request: counted only under [`KeepAliveRule::All`].
    fn status_reply(&mut self, m: &Message, out: &mut Vec<u8>) {
        let counted = self.cfg.keepalive_rule == KeepAliveRule::All;
        self.status(m, counted, out);
    }

    /// The server-alive message came at `now`.
    fn server_alive(&mut self, now: f64) {
        let k = &mut self.keepalive;
        if let Some(t) = k.last_ack.or(k.first_contact) {
            let gap = now - t;
            if gap > self.cfg.keepalive_timeout_s {
                k.late += 1;
            }
            k.longest_gap = k.longest_gap.max(gap);
        }
        k.last_ack = Some(now);
        k.acks += 1;
        k.unacked = 0;
    }

    /// The configuration.
    pub fn config(&self) -> &AptDeviceConfig {
        &self.cfg
    }

    /// True once a home search has finished since power-up.
    pub fn is_homed(&self) -> bool {
        self.homed
    }

    /// True while status updates are being sent.
    pub fn updates_on(&self) -> bool {
        self.updates
    }

    fn velocity(&self) -> f64 {
        self.stage
            .velocity_from_apt(self.vel.max_velocity)
            .max(1e-6)
    }

    fn acceleration(&self) -> f64 {
        self.stage
            .acceleration_from_apt(self.vel.acceleration)
            .max(1e-6)
    }

    /// The stage's mechanical angle at `t`, deg (what the optics see).
    pub fn mechanical(&self, t: f64) -> f64 {
        match self.activity {
            Activity::Idle => self.at_rest,
            Activity::Profile(p, _) => p.position(t),
            Activity::Decel {
                from,
                dir,
                v0,
                a,
                t0,
            } => {
                let tau = (t - t0).clamp(0.0, v0 / a);
                from + dir * (v0 * tau - 0.5 * a * tau * tau)
            }
        }
    }

    /// Signed speed at `t`, deg/s.
    fn speed(&self, t: f64) -> f64 {
        match self.activity {
            Activity::Idle => 0.0,
            Activity::Profile(p, _) => (p.to - p.from).signum() * p.speed(t),
            Activity::Decel { dir, v0, a, t0, .. } => dir * (v0 - a * (t - t0).max(0.0)).max(0.0),
        }
    }

    /// When the motion under way ends, if one is.
    pub fn motion_end(&self) -> Option<f64> {
        match self.activity {
            Activity::Idle => None,
            Activity::Profile(p, _) => Some(p.end()),
            Activity::Decel { v0, a, t0, .. } => Some(t0 + v0 / a),
        }
    }

    /// When a stalled stage sticks, during the profile under way.
    fn stall_time(&self) -> Option<f64> {
        match self.activity {
            Activity::Profile(p, _) => p.crossing(self.stall_at?),
            _ => None,
        }
    }

    /// Fault: from now on the stage sticks when it reaches `angle` (mechanical); the
    /// controller then reports a motion error and no completion.
    pub fn stall_at(&mut self, angle: Option<f64>) {
        self.stall_at = angle;
    }

    /// Fault: power lost and back at `t`: the stage stops where it is, the controller
    /// restarts not homed with its counter at 0 and its power-up parameters, and sends
    /// no updates until asked again.
    pub fn power_cycle(&mut self, t: f64) {
        let m = self.mechanical(t);
        self.boot(m);
    }

    fn counts(&self, t: f64) -> i32 {
        self.stage.to_counts(self.mechanical(t) + self.offset)
    }

    fn bits(&self, t: f64) -> u32 {
        let mut b = self.limit_bits | status::CONNECTED | status::POWER_OK;
        if self.enabled {
            b |= status::CHANNEL_ENABLED;
        }
        if self.homed {
            b |= status::HOMED;
        }
        if self.motion_error {
            b |= status::MOTION_ERROR;
        }
        let v = self.speed(t);
        match self.activity {
            Activity::Idle if !self.motion_error => b |= status::SETTLED | status::TRACKING,
            Activity::Idle => {}
            Activity::Profile(_, Kind::Home) => b |= status::HOMING,
            _ => {}
        }
        if !matches!(self.activity, Activity::Idle) {
            b |= status::ACTIVE;
            b |= if v < 0.0 || self.direction() < 0.0 {
                status::MOVING_REV
            } else {
                status::MOVING_FWD
            };
        }
        b
    }

    fn direction(&self) -> f64 {
        match self.activity {
            Activity::Idle => 0.0,
            Activity::Profile(p, _) => (p.to - p.from).signum(),
            Activity::Decel { dir, .. } => dir,
        }
    }

    fn dc_status(&self, t: f64) -> DcStatus {
        // The velocity word's scale is not documented consistently; the twin reports
        // mdeg/s, saturating.
        let v = (self.speed(t) * 1000.0).round().clamp(-32768.0, 32767.0) as i16;
        DcStatus {
            chan: CHANNEL,
            position: self.counts(t),
            velocity: v,
            reserved: 0,
            bits: self.bits(t),
        }
    }

    fn stepper_status(&self, t: f64) -> StepperStatus {
        StepperStatus {
            chan: CHANNEL,
            position: self.counts(t),
            encoder: 0,
            bits: self.bits(t),
            // The manual's second half: a second channel ident and three words "for
            // future use", zero here (assumed: the manual gives no values).
            extra: (self.cfg.stepper_status_bytes == 28).then_some([0; STEPPER_STATUS_EXTRA]),
        }
    }

    fn update_message(&self, t: f64) -> Message {
        if self.stage.is_dc_servo() {
            Message::GetDcStatusUpdate(self.dc_status(t))
        } else {
            Message::GetStatusUpdate(self.stepper_status(t))
        }
    }

    fn finish(&mut self, t: f64, out: &mut Vec<u8>) {
        let kind = match self.activity {
            Activity::Profile(_, k) => Some(k),
            _ => None,
        };
        self.at_rest = self.mechanical(t);
        self.activity = Activity::Idle;
        // Each end of a motion is a status-type message, counted (the manual's own
        // example is the move-complete message).
        let m = match kind {
            Some(Kind::Home) => {
                self.homed = true;
                // The home position is counter 0.
                self.offset = -self.at_rest;
                Message::MoveHomed { chan: 1 }
            }
            Some(Kind::Move) => Message::MoveCompleted {
                chan: CHANNEL,
                status: Some(self.dc_status(t)),
            },
            Some(Kind::ToLimit(_) | Kind::Velocity) | None => {
                if let Some(Kind::ToLimit(bit)) = kind {
                    self.limit_bits |= bit;
                }
                Message::MoveStopped {
                    chan: CHANNEL,
                    status: Some(self.dc_status(t)),
                }
            }
        };
        self.status(&m, true, out);
    }

    /// Starts a motion of `kind` from where the stage is to mechanical `to`, stopping
    /// at a limit switch on the way.
    fn start_motion(&mut self, now: f64, to: f64, v: f64, kind: Kind) {
        let from = self.mechanical(now);
        self.limit_bits = 0;
        self.motion_error = false;
        let (mut to, mut kind) = (to, kind);
        if let Some([rev, fwd]) = self.cfg.limit_switches_deg
            && kind != Kind::Home
        {
            if to > fwd && from <= fwd {
                (to, kind) = (fwd, Kind::ToLimit(status::FWD_HW_LIMIT));
            } else if to < rev && from >= rev {
                (to, kind) = (rev, Kind::ToLimit(status::REV_HW_LIMIT));
            }
        }
        if (to - from).abs() < 1e-12 {
            self.at_rest = from;
            self.activity = Activity::Profile(Profile::new(from, from, now, v, 1.0), kind);
            return;
        }
        let p = Profile::new(from, to, now, v, self.acceleration());
        self.activity = Activity::Profile(p, kind);
    }

    fn stop(&mut self, now: f64, mode: StopMode, out: &mut Vec<u8>) {
        let m = self.mechanical(now);
        let v = self.speed(now);
        match (mode, self.activity) {
            (StopMode::Profiled, Activity::Profile(..)) if v.abs() > 1e-9 => {
                self.activity = Activity::Decel {
                    from: m,
                    dir: v.signum(),
                    v0: v.abs(),
                    a: self.acceleration(),
                    t0: now,
                };
            }
            (StopMode::Profiled, Activity::Decel { .. }) => {}
            _ => {
                self.at_rest = m;
                self.activity = Activity::Idle;
                let m = Message::MoveStopped {
                    chan: CHANNEL,
                    status: Some(self.dc_status(now)),
                };
                self.status(&m, true, out);
            }
        }
    }

    fn handle(&mut self, now: f64, m: &Message, out: &mut Vec<u8>) {
        let s = self.stage;
        match m {
            Message::HwReqInfo => Message::HwGetInfo(AptInfo {
                serial: self.cfg.serial_number,
                model: s.controller().into(),
                hw_type: 16,
                firmware: self.cfg.firmware,
                hw_version: 1,
                mod_state: 0,
                channels: 1,
            })
            .encode(out),
            Message::HwStartUpdateMsgs if !self.updates => {
                self.updates = true;
                self.next_update = now + self.cfg.update_period_s.max(1e-3);
            }
            Message::HwStopUpdateMsgs => self.updates = false,
            Message::AckDcStatusUpdate => self.server_alive(now),
            Message::SetChanEnableState { enable, .. } => {
                self.enabled = *enable;
                if !enable && !matches!(self.activity, Activity::Idle) {
                    self.stop(now, StopMode::Immediate, out);
                }
            }
            Message::ReqChanEnableState { chan } => Message::GetChanEnableState {
                chan: *chan,
                enabled: self.enabled,
            }
            .encode(out),
            Message::SetPosCounter { position, .. } => {
                self.offset = s.to_deg(*position) - self.mechanical(now);
            }
            Message::ReqPosCounter { .. } => Message::GetPosCounter {
                chan: CHANNEL,
                position: self.counts(now),
            }
            .encode(out),
            // Non-positive velocities are not applied.
            Message::SetVelParams(v) if v.max_velocity > 0 && v.acceleration > 0 => {
                store!(self.vel, v)
            }
            Message::ReqVelParams { .. } => Message::GetVelParams(self.vel).encode(out),
            Message::SetJogParams(j) => store!(self.jog, j),
            Message::ReqJogParams { .. } => Message::GetJogParams(self.jog).encode(out),
            Message::SetHomeParams(h) if h.velocity > 0 => store!(self.home, h),
            Message::ReqHomeParams { .. } => Message::GetHomeParams(self.home).encode(out),
            Message::SetGenMoveParams(g) => store!(self.genmove, g),
            Message::ReqGenMoveParams { .. } => {
                Message::GetGenMoveParams(self.genmove).encode(out);
            }
            Message::SetLimSwitchParams(l) => store!(self.lim, l),
            Message::ReqLimSwitchParams { .. } => {
                Message::GetLimSwitchParams(self.lim).encode(out);
            }
            Message::ReqStatusBits { .. } => {
                let m = Message::GetStatusBits {
                    chan: CHANNEL,
                    bits: self.bits(now),
                };
                self.status_reply(&m, out);
            }
            // Both status requests are answered, whatever the drive: clients differ in
            // which they send.
            Message::ReqDcStatusUpdate { .. } => {
                let m = Message::GetDcStatusUpdate(self.dc_status(now));
                self.status_reply(&m, out);
            }
            Message::ReqStatusUpdate { .. } => {
                let m = Message::GetStatusUpdate(self.stepper_status(now));
                self.status_reply(&m, out);
            }
            Message::SetMoveRelParams { distance, .. } => self.move_rel = *distance,
            Message::ReqMoveRelParams { .. } => Message::GetMoveRelParams {
                chan: CHANNEL,
                distance: self.move_rel,
            }
            .encode(out),
            Message::SetMoveAbsParams { position, .. } => self.move_abs = *position,
            Message::ReqMoveAbsParams { .. } => Message::GetMoveAbsParams {
                chan: CHANNEL,
                position: self.move_abs,
            }
            .encode(out),
            Message::MoveStop { mode, .. } => self.stop(now, *mode, out),
            m if self.enabled => self.start(now, m),
            // Identify flashes a LED; the rest needs no answer, or is not modelled.
            _ => {}
        }
    }

    /// A move message on an enabled channel (any other message is ignored here).
    fn start(&mut self, now: f64, m: &Message) {
        let s = self.stage;
        match m {
            Message::MoveHome { .. } => {
                let from = self.mechanical(now);
                // In reverse onto the switch, then forward by the offset.
                let travel = (from - self.cfg.home_switch_deg).rem_euclid(360.0);
                let to = from - travel + s.to_deg(self.home.offset);
                let v = s.velocity_from_apt(self.home.velocity).max(1e-6);
                self.homed = false;
                self.start_motion(now, to, v, Kind::Home);
            }
            Message::MoveAbsolute { position, .. } => {
                let to = s.to_deg(position.unwrap_or(self.move_abs)) - self.offset;
                self.start_motion(now, to, self.velocity(), Kind::Move);
            }
            Message::MoveRelative { distance, .. } => {
                let to = self.mechanical(now) + s.to_deg(distance.unwrap_or(self.move_rel));
                self.start_motion(now, to, self.velocity(), Kind::Move);
            }
            // A jog: one step (mode 2) or a velocity move (mode 1) at the jog velocity.
            Message::MoveJog { direction, .. } => {
                let sign = match direction {
                    Direction::Forward => 1.0,
                    Direction::Reverse => -1.0,
                };
                let v = s.velocity_from_apt(self.jog.max_velocity).max(1e-6);
                let (distance, kind) = if self.jog.mode == 1 {
                    (1.0e7, Kind::Velocity)
                } else {
                    (s.to_deg(self.jog.step).abs(), Kind::Move)
                };
                let to = self.mechanical(now) + sign * distance;
                self.start_motion(now, to, v, kind);
            }
            Message::MoveVelocity { direction, .. } => {
                let far = match direction {
                    Direction::Forward => 1.0e7,
                    Direction::Reverse => -1.0e7,
                };
                let to = self.mechanical(now) + far;
                self.start_motion(now, to, self.velocity(), Kind::Velocity);
            }
            _ => {}
        }
    }
}

impl TimedLine for AptDevice {
    /// Takes the bytes the host wrote at `now` and appends the controller's answers
    /// (after anything that fell due before them).
    fn receive(&mut self, now: f64, bytes: &[u8], out: &mut Vec<u8>) {
        self.poll(now, out);
        if !bytes.is_empty() && self.keepalive.first_contact.is_none() {
            self.keepalive.first_contact = Some(now);
        }
        self.framer.push(bytes);
        while let Some(frame) = self.framer.next_frame() {
            let Ok(frame) = frame else { continue };
            let Ok(p) = Packet::parse(&frame) else {
                continue;
            };
            if p.dest == USB_UNIT || p.dest == 0x11 || p.dest == 0x21 {
                self.handle(now, &p.message, out);
            }
        }
    }

    /// Sends what is due by `now`: the end of a motion, status updates.
    fn poll(&mut self, now: f64, out: &mut Vec<u8>) {
        while let Some(t) = self.next_event() {
            if t > now {
                break;
            }
            if let Some(ts) = self.stall_time()
                && ts <= t
            {
                self.at_rest = self.mechanical(ts);
                self.activity = Activity::Idle;
                self.motion_error = true;
                continue;
            }
            if self.motion_end() == Some(t) && !(self.updates && self.next_update < t) {
                self.finish(t, out);
                continue;
            }
            // A status update: sent unasked, so counted.
            let m = self.update_message(t);
            self.status(&m, true, out);
            self.next_update = t + self.cfg.update_period_s.max(1e-3);
        }
    }

    /// When [`poll`](TimedLine::poll) will next have something to send (or a stall to
    /// take effect).
    fn next_event(&self) -> Option<f64> {
        let motion = self.stall_time().or(self.motion_end());
        let update = self.updates.then_some(self.next_update);
        motion.into_iter().chain(update).reduce(f64::min)
    }
}
