//! Faults on demand: in the config (`[faults]`) or injected through the API while a
//! test runs. Random faults draw from the simulator's seeded generator, so a seed
//! reproduces them exactly.

/// Which serial line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Port {
    /// The SMC100 chain.
    Motion,
    /// The detector (the SR830, or the picoammeter).
    Detector,
    /// The line of the n-th APT controller, in the layout's role order
    /// (`port = { apt = 0 }`).
    Apt(u8),
    /// The monochromator's line.
    Monochromator,
    /// The filter wheel's line.
    #[serde(rename = "filter_wheel")]
    FilterWheel,
}

impl Port {
    /// The line's name: `motion`, `detector`, `apt0`, …, `monochromator`,
    /// `filter_wheel`.
    pub fn name(self) -> String {
        match self {
            Port::Motion => "motion".into(),
            Port::Detector => "detector".into(),
            Port::Apt(n) => format!("apt{n}"),
            Port::Monochromator => "monochromator".into(),
            Port::FilterWheel => "filter_wheel".into(),
        }
    }
}

/// A span of physical time, s.
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Window {
    /// Start, s.
    pub from_s: f64,
    /// End, s.
    pub to_s: f64,
}

impl Window {
    /// True at time `t`.
    pub fn contains(&self, t: f64) -> bool {
        t >= self.from_s && t < self.to_s
    }
}

/// A controller that loses power at a time: it sends a NUL byte, reboots (silent for
/// its boot time) and comes back NOT REFERENCED.
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct PowerLoss {
    /// Controller address.
    pub address: u8,
    /// When, s.
    pub at_s: f64,
}

/// A stage that sticks when it reaches a mechanical angle.
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Stall {
    /// Controller address.
    pub address: u8,
    /// Mechanical angle, units.
    pub at: f64,
}

/// A port that closes and reopens.
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct PortOutage {
    /// Which port.
    pub port: Port,
    /// When it is gone.
    pub window: Window,
}

/// Every fault the simulator can produce.
#[derive(Clone, Debug, Default, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct FaultConfig {
    /// Probability that a reply line is lost.
    pub drop_reply: f64,
    /// Probability that one byte of a reply line is corrupted (replaced by a non-ASCII
    /// byte, as framing errors and line noise produce).
    pub corrupt_reply: f64,
    /// Replies arrive this much later, s (beyond a driver's timeout they arrive stale).
    pub reply_delay_s: f64,
    /// Command lines (without terminator, e.g. `1TP`) that never get a reply.
    pub silent: Vec<String>,
    /// Controllers that lose power.
    pub power_loss: Vec<PowerLoss>,
    /// Stages that stall.
    pub stall: Vec<Stall>,
    /// The detector overloads during these windows.
    pub overload: Vec<Window>,
    /// The lock-in loses its reference during these windows.
    pub unlock: Vec<Window>,
    /// Ports that vanish for a while.
    pub outage: Vec<PortOutage>,
}

impl FaultConfig {
    /// True when `port` is closed at `t`.
    pub fn port_closed(&self, port: Port, t: f64) -> bool {
        self.outage
            .iter()
            .any(|o| o.port == port && o.window.contains(t))
    }
}
