//! The data structures of the long messages: motion parameters, status, the
//! hardware information, and the short messages' stop mode and direction.

use std::fmt;

use super::AptError;

/// `MGMSG_MOT_MOVE_STOP`'s stop mode (param 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopMode {
    /// `0x01`: stop at once.
    Immediate,
    /// `0x02`: decelerate with the acceleration of the velocity parameters.
    Profiled,
}

/// A direction of motion (`MGMSG_MOT_MOVE_VELOCITY`, `MGMSG_MOT_SET_HOMEPARAMS`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// `0x01`: forward (increasing position).
    Forward,
    /// `0x02`: reverse.
    Reverse,
}

impl Direction {
    pub(super) fn code(self) -> u8 {
        match self {
            Direction::Forward => 1,
            Direction::Reverse => 2,
        }
    }
    pub(super) fn from_code(id: u16, field: &'static str, c: u16) -> Result<Self, AptError> {
        match c {
            1 => Ok(Direction::Forward),
            2 => Ok(Direction::Reverse),
            v => Err(AptError::Field {
                id,
                field,
                value: u32::from(v),
            }),
        }
    }
}

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

/// `MGMSG_MOT_SET/GET_GENMOVEPARAMS` (`0x043A`/`0x043C`): 6 bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GenMoveParams {
    /// The channel.
    pub chan: u16,
    /// Backlash distance, counts: how far past a target a move approaching it in
    /// reverse goes before coming back.
    pub backlash: i32,
}

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

/// The 14-byte status of a DC servo channel: `MGMSG_MOT_GET_DCSTATUSUPDATE`
/// (`0x0491`), and the data of `MGMSG_MOT_MOVE_COMPLETED`, `MOVE_STOPPED` in the long
/// form the K-Cubes send.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
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

/// The status of a stepper channel: `MGMSG_MOT_GET_STATUSUPDATE` (`0x0481`).
///
/// It comes in two lengths. The manual (Issue 28, p. 123) gives 28 data bytes: the
/// channel, position, encoder count and status bits, then a second channel ident and
/// three words "for future use". A K10CR1 sends only the first 14 (PnPQ, tested on
/// K10CR1s: "K10CR1 uses a 20-byte message; K10CR2 uses a 34-byte message"). Both are
/// read; the second half is kept as it came, so a message re-encodes to its bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
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
