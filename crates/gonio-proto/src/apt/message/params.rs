//! The data structures of the long messages (motion parameters, status, the hardware
//! information) and the short messages' parameter bytes (stop mode, direction), each
//! with its layout: [`Data`] writes and reads a data packet's fields in the manual's
//! order, [`ShortField`] a short message's parameter byte.

use std::fmt;

use super::AptError;
use super::id::MOD_SET_CHANENABLESTATE;

/// A little-endian reader over a data packet whose length was checked.
pub(super) struct Rd<'a> {
    pub(super) b: &'a [u8],
}

impl Rd<'_> {
    pub(super) fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut a = [0u8; N];
        // The length was checked against the message's form before reading; a short
        // packet reads as zeros rather than panicking.
        let n = N.min(self.b.len());
        a[..n].copy_from_slice(&self.b[..n]);
        self.b = &self.b[n..];
        a
    }
}

/// A field of a data packet: written and read little endian, in the manual's order.
pub(super) trait Data {
    fn put(&self, out: &mut Vec<u8>);
    fn get(r: &mut Rd<'_>) -> Self
    where
        Self: Sized;
}

macro_rules! data_ints {
    ($($t:ty),*) => {$(
        impl Data for $t {
            fn put(&self, out: &mut Vec<u8>) {
                out.extend_from_slice(&self.to_le_bytes());
            }
            fn get(r: &mut Rd<'_>) -> Self {
                <$t>::from_le_bytes(r.take())
            }
        }
    )*};
}
data_ints!(u16, i16, u32, i32);

/// Bytes kept as they came, present when the packet holds them (the stepper status'
/// second half).
impl<const N: usize> Data for Option<[u8; N]> {
    fn put(&self, out: &mut Vec<u8>) {
        if let Some(b) = self {
            out.extend_from_slice(b);
        }
    }
    fn get(r: &mut Rd<'_>) -> Self {
        (r.b.len() >= N).then(|| r.take())
    }
}

/// The only text in a message's own fields: `HW_RICHRESPONSE`'s 64-byte description.
impl Data for String {
    fn put(&self, out: &mut Vec<u8>) {
        put_text(out, self, 64);
    }
    fn get(r: &mut Rd<'_>) -> Self {
        text(&r.take::<64>())
    }
}

/// `s` in a NUL-padded field of `n` bytes (cut to `n`).
fn put_text(out: &mut Vec<u8>, s: &str, n: usize) {
    let b = s.as_bytes();
    let k = b.len().min(n);
    out.extend_from_slice(&b[..k]);
    out.resize(out.len() + (n - k), 0);
}

/// A NUL-padded ASCII field as text, up to the first NUL; a byte that is not
/// printable ASCII reads as `?`, so that the text re-encodes to the same length.
fn text(b: &[u8]) -> String {
    let end = b.iter().position(|&c| c == 0).unwrap_or(b.len());
    b[..end]
        .iter()
        .map(|&c| {
            if (0x20..0x7F).contains(&c) {
                char::from(c)
            } else {
                '?'
            }
        })
        .collect()
}

/// A data structure whose fields are its data packet, in order: the struct and its
/// [`Data`] layout from one declaration.
macro_rules! data_struct {
    ($(#[$m:meta])* pub struct $name:ident { $($(#[$fm:meta])* pub $f:ident: $t:ty,)* }) => {
        $(#[$m])*
        pub struct $name { $($(#[$fm])* pub $f: $t,)* }

        impl Data for $name {
            fn put(&self, out: &mut Vec<u8>) {
                $(self.$f.put(out);)*
            }
            fn get(r: &mut Rd<'_>) -> Self {
                $name { $($f: Data::get(r),)* }
            }
        }
    };
}

/// A short message's parameter byte.
pub(super) trait ShortField: Sized {
    fn byte(&self) -> u8;
    /// The value of byte `b` in message `id`; a code the manual does not define is
    /// [`AptError::Field`].
    fn from_byte(id: u16, b: u8) -> Result<Self, AptError>;
}

impl ShortField for u8 {
    fn byte(&self) -> u8 {
        *self
    }
    fn from_byte(_: u16, b: u8) -> Result<Self, AptError> {
        Ok(b)
    }
}

/// Reads `0x01` and `0x02` as the two values of a coded parameter.
fn one_or_two<T>(id: u16, field: &'static str, b: u8, one: T, two: T) -> Result<T, AptError> {
    match b {
        1 => Ok(one),
        2 => Ok(two),
        v => Err(AptError::Field {
            id,
            field,
            value: u32::from(v),
        }),
    }
}

/// A channel's enable state: `0x01` enabled, `0x02` disabled.
impl ShortField for bool {
    fn byte(&self) -> u8 {
        if *self { 1 } else { 2 }
    }
    fn from_byte(id: u16, b: u8) -> Result<Self, AptError> {
        // Lenient where the host sets it: anything but 0x01 disables (a public Python
        // client sends 0).
        if id == MOD_SET_CHANENABLESTATE {
            return Ok(b == 1);
        }
        one_or_two(id, "enable state", b, true, false)
    }
}

/// `MGMSG_MOT_MOVE_STOP`'s stop mode (param 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopMode {
    /// `0x01`: stop at once.
    Immediate,
    /// `0x02`: decelerate with the acceleration of the velocity parameters.
    Profiled,
}

impl ShortField for StopMode {
    fn byte(&self) -> u8 {
        match self {
            StopMode::Immediate => 1,
            StopMode::Profiled => 2,
        }
    }
    fn from_byte(id: u16, b: u8) -> Result<Self, AptError> {
        one_or_two(id, "stop mode", b, StopMode::Immediate, StopMode::Profiled)
    }
}

/// A direction of motion (`MGMSG_MOT_MOVE_VELOCITY`, `MGMSG_MOT_SET_HOMEPARAMS`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// `0x01`: forward (increasing position).
    Forward,
    /// `0x02`: reverse.
    Reverse,
}

impl ShortField for Direction {
    fn byte(&self) -> u8 {
        match self {
            Direction::Forward => 1,
            Direction::Reverse => 2,
        }
    }
    fn from_byte(id: u16, b: u8) -> Result<Self, AptError> {
        one_or_two(id, "direction", b, Direction::Forward, Direction::Reverse)
    }
}

impl Direction {
    /// The code `HOMEPARAMS` and the moves carry: `0x01` forward, `0x02` reverse.
    pub(in crate::apt) fn code(self) -> u16 {
        u16::from(self.byte())
    }
}

data_struct! {
    /// `MGMSG_MOT_SET/GET_VELPARAMS` (`0x0413`/`0x0415`): 14 bytes. Velocities and the
    /// acceleration are in the controller's units (see [`StageKind`](crate::apt::StageKind)).
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct VelParams {
        /// The channel.
        pub chan: u16,
        /// Minimum (start) velocity; the manual says it is always 0.
        pub min_velocity: i32,
        /// Acceleration.
        pub acceleration: i32,
        /// Maximum velocity.
        pub max_velocity: i32,
    }
}

data_struct! {
    /// `MGMSG_MOT_SET/GET_JOGPARAMS` (`0x0416`/`0x0418`): 22 bytes.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct JogParams {
        /// The channel.
        pub chan: u16,
        /// 1 continuous, 2 single step.
        pub mode: u16,
        /// Step size, counts.
        pub step: i32,
        /// Minimum velocity (unused, 0).
        pub min_velocity: i32,
        /// Acceleration.
        pub acceleration: i32,
        /// Maximum velocity.
        pub max_velocity: i32,
        /// 1 immediate, 2 profiled.
        pub stop_mode: u16,
    }
}

data_struct! {
    /// `MGMSG_MOT_SET/GET_HOMEPARAMS` (`0x0440`/`0x0442`): 14 bytes.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct HomeParams {
        /// The channel.
        pub chan: u16,
        /// Home direction: 1 forward, 2 reverse.
        pub direction: u16,
        /// Limit switch used: 1 reverse (hardware), 4 forward (hardware).
        pub limit_switch: u16,
        /// Homing velocity, velocity units.
        pub velocity: i32,
        /// Distance of the home position from the switch, counts.
        pub offset: i32,
    }
}

data_struct! {
    /// `MGMSG_MOT_SET/GET_GENMOVEPARAMS` (`0x043A`/`0x043C`): 6 bytes.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct GenMoveParams {
        /// The channel.
        pub chan: u16,
        /// Backlash distance, counts: how far past a target a move approaching it in
        /// reverse goes before coming back.
        pub backlash: i32,
    }
}

data_struct! {
    /// `MGMSG_MOT_SET/GET_LIMSWITCHPARAMS` (`0x0423`/`0x0425`): 16 bytes.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub struct LimSwitchParams {
        /// The channel.
        pub chan: u16,
        /// Forward (clockwise) hardware limit switch mode: 1 ignore, 2 makes on contact,
        /// 3 breaks on contact (and higher codes for home-only switches).
        pub cw_hard: u16,
        /// Reverse (counter-clockwise) hardware limit switch mode.
        pub ccw_hard: u16,
        /// Forward software limit, counts.
        pub cw_soft: i32,
        /// Reverse software limit, counts.
        pub ccw_soft: i32,
        /// Software limit mode: 1 ignore, 2 stop immediately, 3 profiled stop.
        pub soft_mode: u16,
    }
}

data_struct! {
    /// The 14-byte status of a DC servo channel: `MGMSG_MOT_GET_DCSTATUSUPDATE`
    /// (`0x0491`), and the data of `MGMSG_MOT_MOVE_COMPLETED`, `MOVE_STOPPED` in the long
    /// form the K-Cubes send.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
    pub struct DcStatus {
        /// The channel.
        pub chan: u16,
        /// Position, counts.
        pub position: i32,
        /// Velocity, in the manual's scaled units. The manual calls it a word; it is read
        /// signed, as a stage moving in reverse reports a negative value.
        pub velocity: i16,
        /// Reserved (some firmware puts the motor current here).
        pub reserved: u16,
        /// Status bits ([`status`](crate::apt::status)).
        pub bits: u32,
    }
}

data_struct! {
    /// The status of a stepper channel: `MGMSG_MOT_GET_STATUSUPDATE` (`0x0481`).
    ///
    /// It comes in two lengths. The manual (Issue 28, p. 123) gives 28 data bytes: the
    /// channel, position, encoder count and status bits, then a second channel ident and
    /// three words "for future use". A K10CR1 sends only the first 14 (PnPQ, tested on
    /// K10CR1s: "K10CR1 uses a 20-byte message; K10CR2 uses a 34-byte message"). Both are
    /// read; the second half is kept as it came, so a message re-encodes to its bytes.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
    pub struct StepperStatus {
        /// The channel.
        pub chan: u16,
        /// Position, counts (microsteps).
        pub position: i32,
        /// Encoder count (0 without an encoder, as on the K10CR1).
        pub encoder: i32,
        /// Status bits.
        pub bits: u32,
        /// The 28-byte form's second half (a second channel ident and three reserved
        /// words), as received; `None` for the 14-byte form.
        pub extra: Option<[u8; STEPPER_STATUS_EXTRA]>,
    }
}

/// Bytes of the stepper status' second half in the manual's 28-byte form.
pub const STEPPER_STATUS_EXTRA: usize = 14;

/// `MGMSG_HW_GET_INFO` (`0x0006`): 84 bytes identifying the controller.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AptInfo {
    /// The serial number (KDC101s begin with 27, K10CR1s with 55).
    pub serial: u32,
    /// The model number, ASCII, up to 8 characters (`KDC101`, `K10CR1`).
    pub model: String,
    /// The hardware type code.
    pub hw_type: u16,
    /// Firmware version: major, interim, minor (sent minor first).
    pub firmware: [u8; 3],
    /// Hardware version.
    pub hw_version: u16,
    /// Modification state.
    pub mod_state: u16,
    /// Number of channels.
    pub channels: u16,
}

/// The firmware version's bytes go minor first, and the 60 internal bytes are zeros.
impl Data for AptInfo {
    fn put(&self, out: &mut Vec<u8>) {
        self.serial.put(out);
        put_text(out, &self.model, 8);
        self.hw_type.put(out);
        let [ma, it, mi] = self.firmware;
        out.extend_from_slice(&[mi, it, ma, 0]);
        out.resize(out.len() + 60, 0);
        self.hw_version.put(out);
        self.mod_state.put(out);
        self.channels.put(out);
    }
    fn get(r: &mut Rd<'_>) -> Self {
        let serial = Data::get(r);
        let model: [u8; 8] = r.take();
        let hw_type = Data::get(r);
        let [minor, interim, major, _]: [u8; 4] = r.take();
        let _internal: [u8; 60] = r.take();
        AptInfo {
            serial,
            model: text(&model),
            hw_type,
            firmware: [major, interim, minor],
            hw_version: Data::get(r),
            mod_state: Data::get(r),
            channels: Data::get(r),
        }
    }
}

impl fmt::Display for AptInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [ma, it, mi] = self.firmware;
        write!(
            f,
            "{} serial {} firmware {ma}.{it}.{mi} hardware {} ({} channel{})",
            self.model,
            self.serial,
            self.hw_version,
            self.channels,
            if self.channels == 1 { "" } else { "s" }
        )
    }
}
