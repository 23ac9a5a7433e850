//! The simulated Newport Cornerstone 130 monochromator, device side: bytes in, the
//! exact bytes a real CS130 sends on RS-232 out, on simulated time (seconds). Wire
//! format and facts: [`gonio_proto::cs130`] (Cornerstone 130B manual, 90088262,
//! Appendix I, §15).
//!
//! # Protocol
//! - Echo (§15.4): every byte received is sent back at once, terminators included, so
//!   `GOWAVE 500\r\n` comes back as `GOWAVE 500\r\n` the moment it arrives. A line
//!   ends at LF (a CR before it is dropped) and is parsed with [`Command::parse`];
//!   a query's answer follows as its own CR LF line.
//! - Standard mode only: no status byte after statements (`HANDSHAKE 1`, §15.5, is
//!   not modelled, nor USB).
//! - Errors (§15.9): a statement it cannot run sets the status byte to 32 and the
//!   error code (1 not understood, 2 bad parameter, 3 destination not allowed, 6
//!   accessory not present); `STB?` answers `32` and clears it, `00` when clear, in
//!   decimal ("The response will be 32 when an error occurred or 00 when no error is
//!   present. Reading this code clears the status byte", Model 74000 command table;
//!   see [`StatusByte`]), and `ERROR?` answers the code and resets it to 0. One code
//!   is kept, the latest (the manual's `SYSTEM:ERROR?` queue is not modelled).
//! - Filter wheel (`filter_wheel`, default on): `FILTER n` takes 1 to 6 ("Acceptable
//!   values range from 1 through 6", Model 74000 command table; else error 2).
//!   Without a wheel, `FILTER?` answers `0` and sets the status byte: "if there is no
//!   filter wheel connected, or if the wheel is out of position, 0 is returned and an
//!   error is set in the status byte" (same table). The table does not give the code;
//!   the twin sets 6, §15.9's "accessory not present (usually filter wheel)"
//!   (**assumed**: the code list's own example). `FILTER n` without a wheel sets the
//!   same error (**assumed**: the table is silent; code 6 is the one that names the
//!   wheel) and moves nothing. A wheel out of position is not modelled.
//! - Timing: statements run when they arrive, also during a move, except after
//!   `*WAI`, which holds every later statement until the moves under way have ended
//!   (§15.8); a held query is answered then. Moves run one after the other: a
//!   `GRAT` change takes `grating_change_s`, a `FILTER` change `filter_change_s`, a
//!   `GOWAVE` |Δλ| / the grating's `slew_nm_per_s`. All three times are the twin's
//!   own (**UNCONFIRMED**: no timing was found in the stored manual).
//! - `WAVE?` answers the *actual* position, two decimals (§15.4's `500.01`), linearly
//!   interpolated during a move. The real instrument reports where it believes the
//!   drive is; the twin reports where the light is, so that a driver can be tested
//!   against a known error (the twin's choice).
//! - `ABORT` stops the drive where it is ("Stops any wavelength motion immediately");
//!   `SHUTTER O|C` acts at once and `SHUTTER?` answers `O` or `C`; `UNITS NM|UM|WN`
//!   converts `GOWAVE` and `WAVE?`; `GRAT?` answers `n,lines,label` with the label
//!   `BLAZEnnn` ("three parameters separated by commas without spaces … grating
//!   number, then the lines/mm, then the label"): all from the Model 74000 command
//!   table. `INFO?` answers `info` (the 74000 answers `Oriel, Model 74000 Cornerstone
//!   130,SNXXX,VYY.YY.YY`; the CS130B's form was not found, so the twin's is its own).
//!
//! # Optics
//! The actual wavelength is the one asked for, plus `accuracy_nm` (a fixed
//! calibration error, with a seeded draw of `accuracy_sigma_nm` added: [`MonochromatorSim::unit`]), plus `backlash_nm` when the drive approached from above (moving
//! down: the slack in the drive leaves it `backlash_nm` short of the target, i.e.
//! above it). [`Cs130Device::optical`] gives the light model what it needs: the actual
//! wavelength, grating, filter, shutter and bandwidth. The bandwidth (FWHM) is
//! `bandwidth_nm` with a 1200 l/mm grating, scaled by 1200 / lines per mm (the
//! reciprocal linear dispersion is proportional to the groove spacing, at small
//! angles). The light itself (lamp, efficiencies, second order) is not modelled here.

use gonio_proto::cs130::{Command, ErrorCode, MAX_LINE, Reply, StatusByte, Units};

use crate::twin::{Echo, FieldError, LineDevice, LineTwin, Outbox, TimedLine, ensure};

/// One grating on the twin's turret.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimGrating {
    /// Its number (`GRAT n`), 1..=3.
    pub index: u8,
    /// Grooves per mm.
    pub lines_per_mm: u32,
    /// Blaze wavelength, nm (for the light model).
    pub blaze_nm: f64,
    /// Shortest wavelength the drive accepts with it, nm: `GOWAVE` below is error 3.
    pub min_nm: f64,
    /// Longest wavelength the drive accepts with it, nm.
    pub max_nm: f64,
    /// Slew speed, nm/s.
    pub slew_nm_per_s: f64,
}

/// One filter on the twin's wheel; positions not listed are open.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimFilter {
    /// Wheel position, 1..=6.
    pub position: u8,
    /// Cut-on wavelength, nm.
    pub cut_on_nm: f64,
}

/// The simulated monochromator, as a config file writes it (`[monochromator]`, as in
/// `config/sim-spectral.toml`). Every field is optional (the defaults are
/// [`Default`]'s) and unknown fields are refused.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MonochromatorSim {
    /// The turret. Default: 1200 l/mm blazed at 350 nm (180–1300 nm, 100 nm/s) and
    /// 600 l/mm blazed at 1000 nm (400–2800 nm, 200 nm/s).
    pub gratings: Vec<SimGrating>,
    /// The order-sorting filters. Default: cut-ons 335, 590, 1000, 1500 nm at
    /// positions 2 to 5 (1 and 6 open).
    pub filters: Vec<SimFilter>,
    /// Slit bandwidth (FWHM) with a 1200 l/mm grating, nm, in [0, 100].
    pub bandwidth_nm: f64,
    /// Fixed wavelength error, nm, in [−50, 50]: actual = asked + this.
    pub accuracy_nm: f64,
    /// The standard uncertainty of the wavelength scale after its calibration, nm,
    /// in [0, 50]: a unit's calibration error is one draw from N(0, this²), taken
    /// from the simulator's seed and added to `accuracy_nm`, so that runs over many
    /// seeds see the spread an instrument config's `wavelength_uncertainty_nm`
    /// states (0 by default: the error is `accuracy_nm` alone).
    pub accuracy_sigma_nm: f64,
    /// Backlash, nm, in [0, 50]: added when approaching from above.
    pub backlash_nm: f64,
    /// Time of a grating change, s, in [0, 600].
    pub grating_change_s: f64,
    /// Time of a filter change, s, in [0, 600].
    pub filter_change_s: f64,
    /// Wavelength at power-up (after homing), nm.
    pub home_nm: f64,
    /// Echo on RS-232 (§15.4; the factory setting).
    pub echo: bool,
    /// A filter wheel is fitted (default true). Without one, `FILTER?` answers `0`
    /// and flags error 6, `FILTER n` flags error 6 (see the module docs), `filters`
    /// is not used and the light passes no order-sorting filter.
    pub filter_wheel: bool,
    /// What `INFO?` answers: printable ASCII, 1 to 200 characters.
    pub info: String,
}

impl Default for MonochromatorSim {
    fn default() -> Self {
        MonochromatorSim {
            gratings: vec![
                SimGrating {
                    index: 1,
                    lines_per_mm: 1200,
                    blaze_nm: 350.0,
                    min_nm: 180.0,
                    max_nm: 1300.0,
                    slew_nm_per_s: 100.0,
                },
                SimGrating {
                    index: 2,
                    lines_per_mm: 600,
                    blaze_nm: 1000.0,
                    min_nm: 400.0,
                    max_nm: 2800.0,
                    slew_nm_per_s: 200.0,
                },
            ],
            filters: [(2, 335.0), (3, 590.0), (4, 1000.0), (5, 1500.0)]
                .into_iter()
                .map(|(position, cut_on_nm)| SimFilter {
                    position,
                    cut_on_nm,
                })
                .collect(),
            bandwidth_nm: 2.0,
            accuracy_nm: 0.25,
            accuracy_sigma_nm: 0.0,
            backlash_nm: 0.5,
            grating_change_s: 4.0,
            filter_change_s: 1.5,
            home_nm: 400.0,
            echo: true,
            filter_wheel: true,
            info: "CORNERSTONE 130 TWIN".into(),
        }
    }
}

impl MonochromatorSim {
    /// This unit: `accuracy_nm` with the calibration error drawn from `seed`
    /// ([`MonochromatorSim::accuracy_sigma_nm`]); the config itself when that is 0.
    pub fn unit(&self, seed: u64) -> MonochromatorSim {
        use rand::SeedableRng;
        let mut unit = self.clone();
        if self.accuracy_sigma_nm > 0.0 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let z: f64 = rand::Rng::sample(&mut rng, rand_distr::StandardNormal);
            unit.accuracy_nm += self.accuracy_sigma_nm * z;
        }
        unit
    }

    /// Checks every field; the first bad one is named.
    pub fn validate(&self) -> Result<(), FieldError> {
        let within = |v: f64, lo: f64, hi: f64| v >= lo && v <= hi;
        let up_to = |v: f64| within(v, f64::MIN_POSITIVE, 100_000.0);
        ensure!(!self.gratings.is_empty(); "gratings", "at least one grating is needed");
        for (i, g) in self.gratings.iter().enumerate() {
            let f = |name: &str| format!("gratings[{i}].{name}");
            let new = !self.gratings[..i].iter().any(|o| o.index == g.index);
            let (n, lines, blaze, slew) = (g.index, g.lines_per_mm, g.blaze_nm, g.slew_nm_per_s);
            let (lo, hi) = (g.min_nm, g.max_nm);
            ensure!((1..=3).contains(&n) && new; f("index"), "{n} is not a new number in 1..=3");
            let ok = (1..=10_000).contains(&lines);
            ensure!(ok; f("lines_per_mm"), "{lines} is not in 1..=10000");
            ensure!(up_to(blaze); f("blaze_nm"), "{blaze} is not in (0, 100000]");
            let ok = lo > 0.0 && lo < hi && hi <= 100_000.0;
            ensure!(ok; f("max_nm"), "{lo}..={hi} is not 0 < min < max <= 100000");
            ensure!(up_to(slew); f("slew_nm_per_s"), "{slew} is not in (0, 100000]");
        }
        for (i, fl) in self.filters.iter().enumerate() {
            let f = |name: &str| format!("filters[{i}].{name}");
            let new = !self.filters[..i].iter().any(|o| o.position == fl.position);
            let (at, cut_on) = (fl.position, fl.cut_on_nm);
            let ok = (1..=6).contains(&at) && new;
            ensure!(ok; f("position"), "{at} is not a new position in 1..=6");
            ensure!(up_to(cut_on); f("cut_on_nm"), "{cut_on} is not in (0, 100000]");
        }
        let ranges = [
            ("bandwidth_nm", self.bandwidth_nm, 0.0, 100.0),
            ("accuracy_nm", self.accuracy_nm, -50.0, 50.0),
            ("accuracy_sigma_nm", self.accuracy_sigma_nm, 0.0, 50.0),
            ("backlash_nm", self.backlash_nm, 0.0, 50.0),
            ("grating_change_s", self.grating_change_s, 0.0, 600.0),
            ("filter_change_s", self.filter_change_s, 0.0, 600.0),
            ("home_nm", self.home_nm, 0.0, 100_000.0),
        ];
        for (field, v, lo, hi) in ranges {
            FieldError::within(field, v, lo, hi)?;
        }
        let info = &self.info;
        let printable = info.bytes().all(|b| b.is_ascii_graphic() || b == b' ');
        let ok = !info.is_empty() && info.len() <= 200 && printable;
        ensure!(ok; "info", "must be 1 to 200 printable ASCII characters");
        Ok(())
    }
}

/// What the light model needs of the monochromator at one time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MonoOptical {
    /// The wavelength the light leaves at, nm (during a move, where the drive is).
    pub actual_nm: f64,
    /// The grating in the beam.
    pub grating: u8,
    /// The filter wheel position; 0 without a wheel.
    pub filter: u8,
    /// True when the shutter is open.
    pub shutter_open: bool,
    /// The bandpass, FWHM, nm.
    pub bandwidth_nm: f64,
}

/// The wavelength drive's present or last move: from `from_nm` at `t0` to `to_nm` at
/// `t1`, linearly.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Motion {
    t0: f64,
    t1: f64,
    from_nm: f64,
    to_nm: f64,
}

impl Motion {
    /// The drive standing at `nm` from `t` on.
    fn still(t: f64, nm: f64) -> Motion {
        Motion {
            t0: t,
            t1: t,
            from_nm: nm,
            to_nm: nm,
        }
    }

    fn at(&self, t: f64) -> f64 {
        if t >= self.t1 || self.t1 <= self.t0 {
            self.to_nm
        } else if t <= self.t0 {
            self.from_nm
        } else {
            self.from_nm + (self.to_nm - self.from_nm) * (t - self.t0) / (self.t1 - self.t0)
        }
    }
}

/// The byte-level twin of the Cornerstone 130 on its line: see the module docs.
pub type Cs130Twin = LineTwin<Cs130Device>;

/// The Cornerstone 130's state machine and optics, which [`Cs130Twin`] feeds.
#[derive(Clone, Debug)]
pub struct Cs130Device {
    config: MonochromatorSim,
    units: Units,
    grating: u8,
    filter: u8,
    shutter_open: bool,
    /// The last wavelength asked for, nm: the direction of the next approach.
    asked_nm: f64,
    motion: Motion,
    /// When the mechanism (drive, turret, wheel) has finished what it was asked.
    motion_until: f64,
    /// Statements are held until then (`*WAI`).
    hold_until: f64,
    /// When the output of the last line is due.
    busy_until: f64,
    status: StatusByte,
    error: ErrorCode,
}

impl Cs130Twin {
    /// A monochromator just powered up and homed at `home_nm`, grating 1 (or the
    /// first listed), filter position 1 (0 without a wheel, what `FILTER?` answers
    /// then), shutter closed (**UNCONFIRMED** power-up state), at time 0. `config`
    /// should have been validated.
    pub fn new(config: &MonochromatorSim) -> Self {
        let grating = config.gratings.iter().map(|g| g.index).min().unwrap_or(1);
        let home = config.home_nm;
        LineTwin::wrap(
            Cs130Device {
                units: Units::Nm,
                grating,
                filter: if config.filter_wheel { 1 } else { 0 },
                shutter_open: false,
                asked_nm: home,
                motion: Motion::still(0.0, home),
                motion_until: 0.0,
                hold_until: 0.0,
                busy_until: 0.0,
                status: StatusByte(0),
                error: ErrorCode::NONE,
                config: config.clone(),
            },
            None,
        )
    }

    /// One line (terminator removed) received at `now`, the picoammeter's shape: its
    /// echo and answer, and anything still waiting, are appended to `out` at once and
    /// are due at [`busy_until`](Cs130Device::busy_until) (later than `now` only when a
    /// `*WAI` holds the line until a move ends). A transport that needs the echo at
    /// its real time uses [`push`](LineTwin::push) and [`poll`](LineTwin::poll).
    pub fn handle_line(&mut self, now: f64, line: &[u8], out: &mut Vec<u8>) {
        self.push(now, &[line, b"\r\n"].concat());
        self.poll(f64::INFINITY, out);
    }
}

impl LineDevice for Cs130Device {
    // A line ends at LF; a CR before it is dropped in `execute` (§15.4).
    const END: u8 = b'\n';
    const MAX_LINE: usize = MAX_LINE;

    /// Every byte received is sent back at once, terminators included (§15.4).
    fn echo(&self) -> Echo {
        if self.config.echo {
            Echo::Arrival
        } else {
            Echo::Off
        }
    }

    fn execute(&mut self, t: f64, line: &[u8], out: &mut Outbox) {
        self.run_line(t, line.strip_suffix(b"\r").unwrap_or(line), out);
    }

    fn overflow(&mut self, _t: f64) {
        self.fail(ErrorCode::NOT_UNDERSTOOD);
    }
}

impl Cs130Device {
    /// When the output of the last line is due: its arrival, or the end of the moves
    /// a `*WAI` before it waits for.
    pub fn busy_until(&self) -> f64 {
        self.busy_until
    }

    /// When the mechanism has finished every move asked of it.
    pub fn motion_until(&self) -> f64 {
        self.motion_until
    }

    /// The optics at `t`: see the module docs.
    pub fn optical(&self, t: f64) -> MonoOptical {
        let lines = self.grating_spec().map_or(1200, |g| g.lines_per_mm);
        MonoOptical {
            actual_nm: self.motion.at(t),
            grating: self.grating,
            filter: self.filter,
            shutter_open: self.shutter_open,
            bandwidth_nm: self.config.bandwidth_nm * 1200.0 / f64::from(lines.max(1)),
        }
    }

    /// The config.
    pub fn config(&self) -> &MonochromatorSim {
        &self.config
    }

    fn grating_spec(&self) -> Option<&SimGrating> {
        self.config
            .gratings
            .iter()
            .find(|g| g.index == self.grating)
    }

    fn fail(&mut self, code: ErrorCode) {
        self.status = StatusByte(StatusByte::ERROR);
        self.error = code;
    }

    /// A mechanism move of `seconds` asked at `t`: after the ones under way.
    fn occupy(&mut self, t: f64, seconds: f64) -> f64 {
        let start = self.motion_until.max(t);
        self.motion_until = start + seconds.max(0.0);
        start
    }

    fn run_line(&mut self, now: f64, line: &[u8], out: &mut Outbox) {
        let t = now.max(self.hold_until);
        self.busy_until = t;
        let command = match Command::parse(line) {
            Ok(c) => c,
            Err(e) => {
                self.fail(ErrorCode(e.code()));
                return;
            }
        };
        match command {
            Command::GoWave(v) => {
                let nm = self.units.to_nm(v);
                let Some(g) = self.grating_spec().cloned() else {
                    return self.fail(ErrorCode::SYSTEM);
                };
                if !(nm >= g.min_nm && nm <= g.max_nm) {
                    return self.fail(ErrorCode::DESTINATION);
                }
                let from_above = nm < self.asked_nm;
                let target = nm
                    + self.config.accuracy_nm
                    + if from_above {
                        self.config.backlash_nm
                    } else {
                        0.0
                    };
                let start_t = self.motion_until.max(t);
                let from = self.motion.at(start_t);
                let start = self.occupy(t, (target - from).abs() / g.slew_nm_per_s);
                self.motion = Motion {
                    t0: start,
                    t1: self.motion_until,
                    from_nm: from,
                    to_nm: target,
                };
                self.asked_nm = nm;
            }
            Command::Grat(n) => {
                if !self.config.gratings.iter().any(|g| g.index == n) {
                    return self.fail(ErrorCode::BAD_PARAMETER);
                }
                if n != self.grating {
                    self.occupy(t, self.config.grating_change_s);
                    self.grating = n;
                }
            }
            Command::Filter(n) => {
                if !self.config.filter_wheel {
                    return self.fail(ErrorCode::NO_ACCESSORY);
                }
                // "Acceptable values range from 1 through 6" (Model 74000 table).
                if !(1..=6).contains(&n) {
                    return self.fail(ErrorCode::BAD_PARAMETER);
                }
                if n != self.filter {
                    self.occupy(t, self.config.filter_change_s);
                    self.filter = n;
                }
            }
            Command::Shutter(open) => self.shutter_open = open,
            Command::Units(u) => self.units = u,
            Command::Abort => {
                self.motion = Motion::still(t, self.motion.at(t));
                self.motion_until = self.motion_until.min(t);
            }
            Command::Wai => self.hold_until = t.max(self.motion_until),
            Command::Wave => {
                let v = self.units.from_nm(self.motion.at(t));
                out.send(t, Reply::Wavelength(v).to_bytes());
            }
            Command::GratQuery => {
                let reply = Reply::Grating {
                    number: self.grating,
                    lines_per_mm: self.grating_spec().map(|g| g.lines_per_mm),
                    label: self
                        .grating_spec()
                        .map(|g| format!("BLAZE{:.0}", g.blaze_nm)),
                };
                out.send(t, reply.to_bytes());
            }
            Command::FilterQuery => {
                // No wheel: "0 is returned and an error is set in the status byte"
                // (Model 74000 table); the code, 6, is assumed (module docs).
                if !self.config.filter_wheel {
                    self.fail(ErrorCode::NO_ACCESSORY);
                }
                out.send(t, Reply::Filter(self.filter).to_bytes());
            }
            Command::ShutterQuery => out.send(t, Reply::Shutter(self.shutter_open).to_bytes()),
            Command::Stb => {
                let s = std::mem::take(&mut self.status);
                out.send(t, Reply::Status(s).to_bytes());
            }
            Command::Error => {
                let e = std::mem::replace(&mut self.error, ErrorCode::NONE);
                out.send(t, Reply::Error(e).to_bytes());
            }
            Command::Info => {
                let info = self.config.info.clone();
                out.send(t, Reply::Info(info).to_bytes());
            }
        }
    }
}
