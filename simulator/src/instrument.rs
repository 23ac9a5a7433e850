//! The simulated instrument: the SMC100 chain, the SR830, the optics between them,
//! the kinematics that turn stage angles into directions, faults, and the wire.
//!
//! Bytes in, bytes out: [`SimInstrument::motion_bytes`] and
//! [`SimInstrument::lockin_bytes`] take what a driver wrote and return what the
//! instruments answer, at the simulated time read from the shared [`SimClock`]. Every
//! transport (in memory, pseudo-terminal) is a thin layer around these two calls.

use gonio_core::DirPair;
use gonio_core::kinematics::Layout;
use gonio_core::rng::splitmix64;
use gonio_proto::smc100::{Frame, MAX_LINE};
use gonio_proto::{FrameError, LineFramer};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::apt::AptDevice;
use crate::clock::SimClock;
use crate::config::{RoleStage, SimConfig, SimConfigError};
use crate::controller::{Controller, addressed_to};
use crate::faults::{FaultConfig, Port};
use crate::filterwheel::Fw102cTwin;
use crate::lockin::{LockIn, PointStart};
use crate::monochromator::Cs130Twin;
use crate::optics::{LightPath, Optics};
use crate::picoammeter::Picoammeter;
use crate::spectral;
use crate::twin::TimedLine;
use gonio_brdf::Brdf;

/// The 10–90 % width of the lamp's and optics' UV edge, nm.
const LAMP_EDGE_NM: f64 = 20.0;
/// The 10–90 % width of an order-sorting filter's edge, nm (a coloured-glass
/// long-pass).
const ORDER_FILTER_EDGE_NM: f64 = 15.0;
/// An order-sorting filter's transmittance well above its cut-on.
const ORDER_FILTER_PEAK: f64 = 0.9;
/// The monochromator line's baud rate (`gonio_driver::spectral::MonochromatorConfig`).
const MONOCHROMATOR_BAUD: u32 = 9_600;
/// The longest line the lock-in's wire framer hands on: well beyond the SR830's
/// 256-character input buffer, so that an over-long line reaches the twin, which
/// models the overflow ([`LockIn::handle_line`]); a longer one is dropped here and
/// reported to it as an overflow ([`LockIn::input_overflow`]).
const LOCKIN_WIRE_MAX: usize = 16 * gonio_proto::sr830::MAX_LINE;

/// Counters of what the simulator did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SimStats {
    /// Command lines received on the motion line.
    pub motion_lines: u64,
    /// Command lines received on the detector line.
    pub detector_lines: u64,
    /// Reply lines dropped by the `drop_reply` fault.
    pub dropped: u64,
    /// Reply lines corrupted by the `corrupt_reply` fault.
    pub corrupted: u64,
    /// Power losses that fired.
    pub power_losses: u64,
}

/// What drives a role's stage: an index into the SMC100 controllers or the APT ones.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum RoleRef {
    Smc(usize),
    Apt(usize),
}

/// The whole simulated goniometer.
pub struct SimInstrument {
    clock: SimClock,
    layout: Layout,
    controllers: Vec<Controller>,
    /// The APT controllers, each on its own line, in the layout's role order.
    apt: Vec<AptDevice>,
    /// What drives each kinematic role's stage.
    roles: [RoleRef; 4],
    lockin: LockIn,
    /// The picoammeter, when it is the detector instead of the lock-in.
    pico: Option<Picoammeter>,
    /// The monochromator between the lamp and the sample, if any.
    mono: Option<Cs130Twin>,
    /// The filter wheel between the lamp and the sample, if any.
    wheel: Option<Fw102cTwin>,
    optics: Optics,
    faults: FaultConfig,
    fired_power_losses: Vec<bool>,
    rng: ChaCha8Rng,
    motion_framer: LineFramer,
    lockin_framer: LineFramer,
    last_sync: f64,
    link: crate::config::LinkConfig,
    stats: SimStats,
    seed: u64,
}

impl std::fmt::Debug for SimInstrument {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimInstrument")
            .field("layout", &self.layout)
            .field("now_s", &self.clock.seconds())
            .field("stats", &self.stats)
            .finish()
    }
}

impl SimInstrument {
    /// Builds the instrument a config describes, on `clock`.
    pub fn new(cfg: &SimConfig, clock: SimClock) -> Result<Self, SimConfigError> {
        let stages = cfg
            .role_stages()
            .map_err(|(field, message)| SimConfigError {
                field: Some(field),
                ..SimConfigError::whole("sim config", None, message)
            })?;
        let mut sorted = cfg.role_addresses().unwrap_or_default();
        sorted.sort_unstable();
        let controllers: Vec<Controller> = sorted
            .iter()
            .map(|a| Controller::new(cfg.controller(*a)))
            .collect();
        let apt_roles = cfg.apt_roles();
        let apt: Vec<AptDevice> = apt_roles
            .iter()
            .filter_map(|r| cfg.apt.get(*r))
            .map(AptDevice::new)
            .collect();
        let role_names = cfg.kinematics.layout.roles();
        let roles: [RoleRef; 4] = std::array::from_fn(|i| match stages[i] {
            RoleStage::Smc100(a) => RoleRef::Smc(sorted.iter().position(|b| *b == a).unwrap_or(0)),
            RoleStage::Apt => RoleRef::Apt(
                apt_roles
                    .iter()
                    .position(|r| *r == role_names[i])
                    .unwrap_or(0),
            ),
        });
        // Its own stream, like the lock-in's, so that wire faults do not shift it.
        let pico = cfg
            .picoammeter
            .as_ref()
            .map(|p| Picoammeter::new(p, splitmix64(cfg.seed ^ 0x9c0a_3e7e)));
        let mono = cfg
            .monochromator
            .as_ref()
            .map(|m| Cs130Twin::new(&m.unit(splitmix64(cfg.seed ^ 0x3c5a_17e0))));
        let wheel = cfg.filter_wheel.as_ref().map(Fw102cTwin::new);
        let (sample, channel) = cfg.load_sample()?;
        // Separate streams, so that faults drawn on the wire do not shift the noise.
        let lockin = LockIn::new(cfg.lockin.clone(), cfg.seed);
        Ok(SimInstrument {
            clock,
            layout: cfg.kinematics.layout,
            controllers,
            apt,
            roles,
            lockin,
            pico,
            mono,
            wheel,
            optics: Optics::new(cfg.optics.clone(), sample, channel),
            fired_power_losses: vec![false; cfg.faults.power_loss.len()],
            faults: cfg.faults.clone(),
            rng: ChaCha8Rng::seed_from_u64(cfg.seed ^ 0x5eed_fa17),
            motion_framer: LineFramer::new(b'\n', MAX_LINE),
            // The lock-in's own buffer decides what an over-long line does; the
            // picoammeter's line keeps the framer's bound.
            lockin_framer: LineFramer::new(
                b'\n',
                if cfg.picoammeter.is_some() {
                    gonio_proto::sr830::MAX_LINE
                } else {
                    LOCKIN_WIRE_MAX
                },
            ),
            last_sync: 0.0,
            link: cfg.link.clone(),
            stats: SimStats::default(),
            seed: cfg.seed,
        })
    }

    /// The shared clock.
    pub fn clock(&self) -> &SimClock {
        &self.clock
    }

    /// Counters.
    pub fn stats(&self) -> &SimStats {
        &self.stats
    }

    /// The optics.
    pub fn optics(&self) -> &Optics {
        &self.optics
    }

    /// Sets what is in the light path from now on (a calibration's set-up).
    pub fn set_light_path(&mut self, path: LightPath) {
        self.at(self.clock.seconds(), |s| s.optics.set_light_path(path));
    }

    /// Measures the band `name` of the sample from now on (a filter wheel); false
    /// when the sample has no such channel.
    pub fn select_channel(&mut self, name: &str) -> bool {
        self.at(self.clock.seconds(), |s| s.optics.select_channel(name))
    }

    /// Mounts another sample (a reference standard) from now on; returns the one
    /// taken off and its channel.
    pub fn swap_sample(&mut self, sample: Box<dyn Brdf>, channel: usize) -> (Box<dyn Brdf>, usize) {
        self.at(self.clock.seconds(), |s| {
            s.optics.swap_sample(sample, channel)
        })
    }

    /// Runs `f` at `now` with the detector's input brought up to it before and
    /// after: what `f` changes (the light, a move) changes the input at once.
    fn at<R>(&mut self, now: f64, f: impl FnOnce(&mut Self) -> R) -> R {
        self.sync(now);
        let r = f(self);
        self.sync(now);
        r
    }

    /// The stages are at the point identified by `key`: restart the lock-in's filters
    /// and noise from a seed that depends only on the config's seed and `key`, so the
    /// point reads the same however the run got there. `previous` is the lock-in's
    /// mean X and Y (V) of the reading the run committed before this point (`None`
    /// before its first): the filters start there with `point_start = "previous"`
    /// ([`LockIn::restart_from`]), settled on the present signal otherwise
    /// ([`LockIn::restart`]). The picoammeter restarts the same way in both.
    pub fn begin_point(&mut self, key: u64, previous: Option<[f64; 2]>) {
        let now = self.clock.seconds();
        self.begin_point_since(key, previous, now);
    }

    /// [`begin_point`](Self::begin_point), the stages having stopped at `since_s`
    /// (no later than now): with `point_start = "previous"` the filters' step starts
    /// there, so that by now they have followed the point's light for `now − since_s`
    /// ([`LockIn::restart_from_since`]). The light has not changed since: nothing
    /// moves between a move's end and its reading.
    pub fn begin_point_since(&mut self, key: u64, previous: Option<[f64; 2]>, since_s: f64) {
        let now = self.clock.seconds();
        self.sync(now);
        let seed = splitmix64(self.seed ^ splitmix64(key));
        match self.lockin.config().point_start {
            PointStart::Settled => self.lockin.restart(now, seed),
            PointStart::Previous => {
                self.lockin
                    .restart_from_since(since_s.min(now), now, seed, previous)
            }
        }
        if let Some(p) = &mut self.pico {
            p.restart(now, seed);
        }
    }

    /// The lock-in.
    pub fn lockin_mut(&mut self) -> &mut LockIn {
        &mut self.lockin
    }

    /// The faults in force; change them to inject faults while a test runs.
    pub fn faults_mut(&mut self) -> &mut FaultConfig {
        &mut self.faults
    }

    /// The faults in force.
    pub fn faults(&self) -> &FaultConfig {
        &self.faults
    }

    /// The serial timing.
    pub fn link(&self) -> &crate::config::LinkConfig {
        &self.link
    }

    /// The controller at `address`.
    pub fn controller_mut(&mut self, address: u8) -> Option<&mut Controller> {
        self.controllers.iter_mut().find(|c| c.address() == address)
    }

    /// The stages' mechanical angles at `t`, in the layout's role order.
    pub fn stage_angles(&self, t: f64) -> [f64; 4] {
        self.roles.map(|r| match r {
            RoleRef::Smc(i) => self.controllers[i].mechanical(t),
            RoleRef::Apt(i) => self.apt[i].mechanical(t),
        })
    }

    /// The n-th APT controller (in the layout's role order).
    pub fn apt_mut(&mut self, n: usize) -> Option<&mut AptDevice> {
        self.apt.get_mut(n)
    }

    /// The picoammeter, when it is the detector.
    pub fn picoammeter_mut(&mut self) -> Option<&mut Picoammeter> {
        self.pico.as_mut()
    }

    /// The detector's input: the lock-in's, or the picoammeter's (optical power, W,
    /// from the optics' signal through their responsivity).
    fn set_detector_input(&mut self, t: f64, volts: f64) {
        self.lockin.set_input(t, volts);
        if let Some(p) = &mut self.pico {
            let r = self.optics.config().responsivity_v_per_w;
            p.set_input(t, volts / r);
        }
    }

    /// The monochromator, when there is one.
    pub fn monochromator_mut(&mut self) -> Option<&mut Cs130Twin> {
        self.mono.as_mut()
    }

    /// The filter wheel, when there is one.
    pub fn filter_wheel_mut(&mut self) -> Option<&mut Fw102cTwin> {
        self.wheel.as_mut()
    }

    /// The light between the lamp and the sample at `t`: a monochromator's passband
    /// (with its order-sorting filter) or the lamp through the wheel's filter, both
    /// cut below the lamp's cut-on; `None` without either.
    pub fn spectrum_at(&self, t: f64) -> Option<Vec<(f64, f64)>> {
        let o = self.optics.config();
        let lamp_k = o.lamp_colour_temperature_k;
        let cut_on = o.lamp_cut_on_nm;
        let lamp = move |nm: f64| spectral::longpass(nm, cut_on, LAMP_EDGE_NM, 1.0);
        if let Some(m) = &self.mono {
            let now = m.optical(t);
            let cfg = m.config();
            let blaze_nm = cfg
                .gratings
                .iter()
                .find(|g| g.index == now.grating)
                .map_or(500.0, |g| g.blaze_nm);
            let order = cfg
                .filters
                .iter()
                .find(|f| f.position == now.filter)
                .map(|f| f.cut_on_nm);
            let setting = spectral::Setting {
                actual_nm: now.actual_nm,
                fwhm_nm: now.bandwidth_nm,
                blaze_nm,
                lamp_k,
                shutter_open: now.shutter_open,
            };
            return Some(spectral::passband(&setting, &|nm| {
                lamp(nm)
                    * order.map_or(1.0, |c| {
                        spectral::longpass(nm, c, ORDER_FILTER_EDGE_NM, ORDER_FILTER_PEAK)
                    })
            }));
        }
        let w = self.wheel.as_ref()?;
        Some(spectral::white(lamp_k, &|nm| {
            lamp(nm) * w.transmittance(nm, t)
        }))
    }

    /// The directions the stages point at `t`.
    pub fn directions(&self, t: f64) -> DirPair {
        self.layout.forward(self.stage_angles(t))
    }

    /// The detector signal at `t`, V, in the light path as the optics hold it.
    pub fn signal(&self, t: f64) -> f64 {
        self.optics.signal(t, self.directions(t))
    }

    /// Brings the optics' light to `t` (a band selector's state), then the signal.
    fn signal_now(&mut self, t: f64) -> f64 {
        if self.mono.is_some() || self.wheel.is_some() {
            let s = self.spectrum_at(t);
            self.optics.set_spectrum(s);
        }
        self.signal(t)
    }

    /// Brings the lock-in's input up to `now`: the signal at the end of every motion
    /// that finished since the last event, then the signal now. The input is
    /// piecewise constant between events; during a move the driver's status polls
    /// are the events, which samples the changing signal at the polling rate.
    fn sync(&mut self, now: f64) {
        if now < self.last_sync {
            return;
        }
        let mut ends: Vec<f64> = self
            .controllers
            .iter()
            .filter_map(Controller::motion_end)
            .chain(self.apt.iter().filter_map(AptDevice::motion_end))
            .chain(self.mono.iter().map(|m| m.motion_until()))
            .chain(self.wheel.iter().map(|w| w.busy_until()))
            .filter(|t| *t > self.last_sync && *t <= now)
            .collect();
        ends.sort_by(f64::total_cmp);
        for t in ends {
            let v = self.signal_now(t);
            self.set_detector_input(t, v);
        }
        let over = self.faults.overload.iter().any(|w| w.contains(now));
        self.lockin.force_overload(over);
        let unlocked = self.faults.unlock.iter().any(|w| w.contains(now));
        self.lockin.set_unlocked(unlocked);
        let v = self.signal_now(now);
        self.set_detector_input(now, v);
        self.last_sync = now;
    }

    /// Power losses due by `now`: each sends a NUL on the line and reboots its
    /// controller.
    fn fire_power_losses(&mut self, now: f64, out: &mut Vec<u8>) {
        // Faults injected through `faults_mut` since the last event.
        self.fired_power_losses
            .resize(self.faults.power_loss.len(), false);
        for k in 0..self.faults.power_loss.len() {
            let pl = self.faults.power_loss[k];
            if !self.fired_power_losses[k] && now >= pl.at_s {
                self.fired_power_losses[k] = true;
                if let Some(c) = self.controller_mut(pl.address) {
                    c.power_cycle(pl.at_s);
                    out.extend_from_slice(b"\0\r\n");
                    self.stats.power_losses += 1;
                }
            }
        }
        for s in self.faults.stall.clone() {
            if let Some(c) = self.controller_mut(s.address) {
                c.stall_at(Some(s.at));
            }
        }
    }

    /// Applies the reply faults to one reply line (terminator included).
    fn deliver(&mut self, command: &[u8], line: Vec<u8>, out: &mut Vec<u8>) {
        let cmd = String::from_utf8_lossy(command);
        if self
            .faults
            .silent
            .iter()
            .any(|s| s.eq_ignore_ascii_case(cmd.trim()))
        {
            self.stats.dropped += 1;
            return;
        }
        if self.faults.drop_reply > 0.0 && self.rng.random::<f64>() < self.faults.drop_reply {
            self.stats.dropped += 1;
            return;
        }
        let mut line = line;
        if self.faults.corrupt_reply > 0.0
            && self.rng.random::<f64>() < self.faults.corrupt_reply
            && line.len() > 2
        {
            // A byte lost to a framing error or line noise arrives as some non-ASCII
            // value (a UART's typical garbage), replacing one character.
            let k = self.rng.random_range(0..line.len() - 2);
            line[k] = self.rng.random_range(0x80..=0xFF);
            self.stats.corrupted += 1;
        }
        out.extend_from_slice(&line);
    }

    /// Bytes the driver wrote on the motion line; returns the controllers' answers.
    pub fn motion_bytes(&mut self, bytes: &[u8]) -> Vec<u8> {
        let now = self.clock.seconds();
        let mut out = Vec::new();
        self.fire_power_losses(now, &mut out);
        self.sync(now);
        self.motion_framer.push(bytes);
        while let Some(line) = self.motion_framer.next_line() {
            let Ok(line) = line else { continue };
            self.stats.motion_lines += 1;
            match Frame::parse(&line) {
                Ok(frame) => {
                    let mut replies = Vec::new();
                    for c in self.controllers.iter_mut() {
                        if addressed_to(&frame, c.address()) && !c.is_booting(now) {
                            // One line a reply; a `ZT` dump is many, each its own.
                            replies.extend(c.respond(now, &frame.command));
                        }
                    }
                    for r in replies {
                        self.deliver(&line, r, &mut out);
                    }
                }
                Err(e) => {
                    // The addressed controller (if any answers to that address) stores
                    // the error letter for TE, as the manual's per-command lists say.
                    let digits: String = line
                        .iter()
                        .take_while(|b| b.is_ascii_digit())
                        .map(|b| *b as char)
                        .collect();
                    if let Ok(a) = digits.parse::<u8>()
                        && let Some(c) = self.controller_mut(a)
                    {
                        c.set_error(e.error_code());
                    }
                }
            }
        }
        // Moves change the light: keep the lock-in's input current.
        self.sync(now);
        out
    }

    /// Bytes the driver wrote on `port`; returns the instrument's answers.
    pub fn port_bytes(&mut self, port: Port, bytes: &[u8]) -> Vec<u8> {
        match port {
            Port::Motion => self.motion_bytes(bytes),
            Port::Detector => self.detector_bytes(bytes, self.pico.is_some()),
            // Each on its own time: its echo at once, an answer held by `*WAI` or a
            // move's prompt later, unasked.
            // A shutter, a filter or a move changes the light at once.
            _ => {
                let now = self.clock.seconds();
                self.at(now, |s| {
                    let mut out = Vec::new();
                    if let Some(d) = s.timed(port) {
                        d.receive(now, bytes, &mut out);
                    }
                    out
                })
            }
        }
    }

    /// The device on `port` when it sends on its own time (an APT controller, the
    /// band selector).
    fn timed(&mut self, port: Port) -> Option<&mut dyn TimedLine> {
        match port {
            Port::Apt(n) => self.apt.get_mut(usize::from(n)).map(|d| d as _),
            Port::Monochromator => self.mono.as_mut().map(|d| d as _),
            Port::FilterWheel => self.wheel.as_mut().map(|d| d as _),
            Port::Motion | Port::Detector => None,
        }
    }

    /// When `port` next sends something nobody asked for (an APT controller's
    /// `MOVE_COMPLETED`, a status update), if ever.
    pub fn next_unsolicited(&self, port: Port) -> Option<f64> {
        match port {
            Port::Apt(n) => self.apt.get(usize::from(n))?.next_event(),
            Port::Monochromator => self.mono.as_ref()?.next_event(),
            Port::FilterWheel => self.wheel.as_ref()?.next_event(),
            Port::Motion | Port::Detector => None,
        }
    }

    /// What `port` sends by itself up to `at` (or now, if later). A caller that slept
    /// until an event's time passes that time: the clock counts whole nanoseconds, so
    /// it may stand a hair short of it.
    pub fn unsolicited(&mut self, port: Port, at: f64) -> Vec<u8> {
        let now = self.clock.seconds().max(at);
        self.at(now, |s| {
            let mut out = Vec::new();
            if let Some(d) = s.timed(port) {
                d.poll(now, &mut out);
            }
            out
        })
    }

    /// The earliest time an answer on `port` can leave the instrument (a picoammeter
    /// answers `READ?` once its integrations are done).
    pub fn busy_until(&self, port: Port) -> f64 {
        match (port, &self.pico) {
            (Port::Detector, Some(p)) => p.busy_until(),
            _ => 0.0,
        }
    }

    /// The instrument's time to answer on `port`, s.
    pub fn latency(&self, port: Port) -> f64 {
        match port {
            Port::Motion => self.link.motion_latency_s,
            Port::Detector => self.link.detector_latency_s,
            Port::Apt(_) => self.link.apt_latency_s,
            Port::Monochromator => 0.0,
            Port::FilterWheel => self.wheel.as_ref().map_or(0.0, |w| w.latency()),
        }
    }

    /// Every line there is: motion, detector, the APT controllers', the band
    /// selector's.
    pub fn ports(&self) -> Vec<Port> {
        let apt = (0..self.apt.len()).filter_map(|n| u8::try_from(n).ok().map(Port::Apt));
        [Port::Motion, Port::Detector]
            .into_iter()
            .chain(apt)
            .chain(self.mono.is_some().then_some(Port::Monochromator))
            .chain(self.wheel.is_some().then_some(Port::FilterWheel))
            .collect()
    }

    /// Bytes the driver wrote on the detector line; returns the lock-in's answers.
    pub fn lockin_bytes(&mut self, bytes: &[u8]) -> Vec<u8> {
        self.detector_bytes(bytes, false)
    }

    /// Bytes the driver wrote on the detector line; returns the answers of the
    /// picoammeter when `pico`, else the lock-in's.
    fn detector_bytes(&mut self, bytes: &[u8], pico: bool) -> Vec<u8> {
        let now = self.clock.seconds();
        self.sync(now);
        // The SR830 ends a command at CR or LF ("a linefeed <lf> or carriage return
        // <cr> on RS232": manual p. 5-2, quoted in a public driver), as the 6485 does.
        let unified: Vec<u8> = bytes
            .iter()
            .map(|b| if *b == b'\r' { b'\n' } else { *b })
            .collect();
        self.lockin_framer.push(&unified);
        let mut out = Vec::new();
        while let Some(line) = self.lockin_framer.next_line() {
            let line = match line {
                Ok(line) => line,
                // Longer than the framer keeps: the lock-in's input buffer overflowed
                // (the picoammeter's line drops it).
                Err(FrameError::TooLong(_)) if !pico => {
                    self.stats.detector_lines += 1;
                    self.lockin.input_overflow(now);
                    continue;
                }
                // A line with a NUL byte is dropped (not modelled).
                Err(_) => continue,
            };
            if line.is_empty() {
                continue;
            }
            self.stats.detector_lines += 1;
            let mut reply = Vec::new();
            match &mut self.pico {
                Some(p) if pico => p.handle_line(now, &line, &mut reply),
                _ => self.lockin.handle_line(now, &line, &mut reply),
            }
            // One reply line per answered query, each ending in CR.
            for part in reply.split_inclusive(|b| *b == b'\r') {
                self.deliver(&line, part.to_vec(), &mut out);
            }
        }
        out
    }

    /// True when `port` is closed at the current time.
    pub fn port_closed(&self, port: Port) -> bool {
        self.faults.port_closed(port, self.clock.seconds())
    }

    /// The physical time a line of `bytes` takes on `port`'s wire (10 bits a byte, as
    /// the planner counts them).
    pub fn wire_time(&self, port: Port, bytes: usize) -> f64 {
        let baud = match port {
            Port::Motion => self.link.motion_baud,
            Port::Detector => self.link.detector_baud,
            Port::Apt(_) => gonio_driver::apt::BAUD,
            Port::Monochromator => MONOCHROMATOR_BAUD,
            Port::FilterWheel => gonio_proto::fw102c::BAUD,
        };
        gonio_proto::timing::wire_s(bytes, baud)
    }
}
