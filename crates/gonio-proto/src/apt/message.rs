//! Messages, both directions: the header, the typed [`Message`] and the data
//! structures. Layouts are the manual's, message by message (each variant names its
//! `MGMSG_` id); a data packet is little endian throughout.

use std::fmt;

use super::{HEADER_LEN, HOST, LONG_FLAG, MAX_DATA_LEN, USB_UNIT};

/// Why bytes are not a valid APT message.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AptError {
    /// Fewer bytes than the header, or than the header says.
    #[error("message truncated: {got} bytes, {need} needed")]
    Truncated {
        /// Bytes needed.
        need: usize,
        /// Bytes given.
        got: usize,
    },
    /// More bytes than the header says.
    #[error("{extra} bytes after the end of the message")]
    Trailing {
        /// Bytes beyond the message.
        extra: usize,
    },
    /// A long message whose declared length exceeds what any message has.
    #[error("data length {0} exceeds {MAX_DATA_LEN}")]
    TooLong(usize),
    /// A known message in the wrong form (a data packet where none belongs, or none
    /// where one is required), or with a data packet of the wrong size.
    #[error("message {id:#06x}: {found}, expected {expected}")]
    Form {
        /// The message id.
        id: u16,
        /// What the message must look like.
        expected: &'static str,
        /// What arrived.
        found: String,
    },
    /// A field whose value the manual does not define.
    #[error("message {id:#06x}: {field} = {value:#x} is not defined")]
    Field {
        /// The message id.
        id: u16,
        /// The field.
        field: &'static str,
        /// Its value.
        value: u32,
    },
}

/// The 6-byte header, as read from the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// The message id.
    pub id: u16,
    /// The data packet's length for a long message; `None` for a short one.
    pub data_len: Option<u16>,
    /// The two parameter bytes of a short message (zero for a long one).
    pub params: [u8; 2],
    /// The destination, without the long-message flag.
    pub dest: u8,
    /// The source.
    pub source: u8,
}

impl Header {
    /// Reads the header at the start of `bytes` (at least [`HEADER_LEN`] of them).
    pub fn parse(bytes: &[u8]) -> Result<Header, AptError> {
        let [a, b, p1, p2, d, s, ..] = *bytes else {
            return Err(AptError::Truncated {
                need: HEADER_LEN,
                got: bytes.len(),
            });
        };
        let long = d & LONG_FLAG != 0;
        Ok(Header {
            id: u16::from_le_bytes([a, b]),
            data_len: long.then(|| u16::from_le_bytes([p1, p2])),
            params: if long { [0, 0] } else { [p1, p2] },
            dest: d & !LONG_FLAG,
            source: s,
        })
    }

    /// The whole message's length, header included.
    pub fn total_len(&self) -> usize {
        HEADER_LEN + self.data_len.map_or(0, usize::from)
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

/// A direction of motion (`MGMSG_MOT_MOVE_VELOCITY`, `MGMSG_MOT_SET_HOMEPARAMS`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// `0x01`: forward (increasing position).
    Forward,
    /// `0x02`: reverse.
    Reverse,
}

impl Direction {
    fn code(self) -> u8 {
        match self {
            Direction::Forward => 1,
            Direction::Reverse => 2,
        }
    }
    fn from_code(id: u16, field: &'static str, c: u16) -> Result<Self, AptError> {
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
/// acceleration are in the controller's units (see [`StageKind`](super::StageKind)).
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
    /// Status bits ([`status`](super::status)).
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

/// One APT message, typed: what the sessions send and read, and what the simulated
/// controllers read and send. Each variant names its manual `MGMSG_` id. Parameters
/// that the manual marks unused are written as 0 and ignored when read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Message {
    /// `MOD_IDENTIFY` `0x0223` (manual Issue 25 p. 41): flash the front panel LED.
    Identify {
        /// The channel (0 for a single-channel unit).
        chan: u8,
    },
    /// `HW_DISCONNECT` `0x0002`: the host is about to close the port.
    HwDisconnect,
    /// `HW_REQ_INFO` `0x0005` (p. 47).
    HwReqInfo,
    /// `HW_GET_INFO` `0x0006` (p. 47).
    HwGetInfo(AptInfo),
    /// `HW_START_UPDATEMSGS` `0x0011` (p. 46): status updates every 100 ms until
    /// stopped.
    HwStartUpdateMsgs,
    /// `HW_STOP_UPDATEMSGS` `0x0012` (p. 46).
    HwStopUpdateMsgs,
    /// `HW_YES_FLASH_PROGRAMMING` `0x0017` (deprecated; sent by some controllers at start).
    HwYesFlashProgramming,
    /// `HW_NO_FLASH_PROGRAMMING` `0x0018`: part of a host's initialisation.
    HwNoFlashProgramming,
    /// `HW_RESPONSE` `0x0080` (p. 44): the controller reports an error, unspecified.
    HwResponse,
    /// `HW_RICHRESPONSE` `0x0081` (p. 45; 68 bytes): an error, with the message that
    /// caused it, a code and a text.
    HwRichResponse {
        /// The id of the message that caused it (0 for a spontaneous fault).
        msg_id: u16,
        /// The error code.
        code: u16,
        /// The description (64 bytes, NUL padded, on the wire).
        notes: String,
    },
    /// `MOD_SET_CHANENABLESTATE` `0x0210` (p. 42).
    SetChanEnableState {
        /// The channel.
        chan: u8,
        /// Enable (`0x01`) or disable (`0x02`).
        enable: bool,
    },
    /// `MOD_REQ_CHANENABLESTATE` `0x0211`.
    ReqChanEnableState {
        /// The channel.
        chan: u8,
    },
    /// `MOD_GET_CHANENABLESTATE` `0x0212`.
    GetChanEnableState {
        /// The channel.
        chan: u8,
        /// Enabled (`0x01`) or not (`0x02`).
        enabled: bool,
    },
    /// `MOT_SET_POSCOUNTER` `0x0410`.
    SetPosCounter {
        /// The channel.
        chan: u16,
        /// The new position, counts.
        position: i32,
    },
    /// `MOT_REQ_POSCOUNTER` `0x0411`.
    ReqPosCounter {
        /// The channel.
        chan: u8,
    },
    /// `MOT_GET_POSCOUNTER` `0x0412`.
    GetPosCounter {
        /// The channel.
        chan: u16,
        /// Position, counts.
        position: i32,
    },
    /// `MOT_SET_VELPARAMS` `0x0413`.
    SetVelParams(VelParams),
    /// `MOT_REQ_VELPARAMS` `0x0414`.
    ReqVelParams {
        /// The channel.
        chan: u8,
    },
    /// `MOT_GET_VELPARAMS` `0x0415`.
    GetVelParams(VelParams),
    /// `MOT_SET_JOGPARAMS` `0x0416`.
    SetJogParams(JogParams),
    /// `MOT_REQ_JOGPARAMS` `0x0417`.
    ReqJogParams {
        /// The channel.
        chan: u8,
    },
    /// `MOT_GET_JOGPARAMS` `0x0418`.
    GetJogParams(JogParams),
    /// `MOT_SET_LIMSWITCHPARAMS` `0x0423`.
    SetLimSwitchParams(LimSwitchParams),
    /// `MOT_REQ_LIMSWITCHPARAMS` `0x0424`.
    ReqLimSwitchParams {
        /// The channel.
        chan: u8,
    },
    /// `MOT_GET_LIMSWITCHPARAMS` `0x0425`.
    GetLimSwitchParams(LimSwitchParams),
    /// `MOT_REQ_STATUSBITS` `0x0429`.
    ReqStatusBits {
        /// The channel.
        chan: u8,
    },
    /// `MOT_GET_STATUSBITS` `0x042A`.
    GetStatusBits {
        /// The channel.
        chan: u16,
        /// Status bits.
        bits: u32,
    },
    /// `MOT_SET_GENMOVEPARAMS` `0x043A`.
    SetGenMoveParams(GenMoveParams),
    /// `MOT_REQ_GENMOVEPARAMS` `0x043B`.
    ReqGenMoveParams {
        /// The channel.
        chan: u8,
    },
    /// `MOT_GET_GENMOVEPARAMS` `0x043C`.
    GetGenMoveParams(GenMoveParams),
    /// `MOT_SET_HOMEPARAMS` `0x0440`.
    SetHomeParams(HomeParams),
    /// `MOT_REQ_HOMEPARAMS` `0x0441`.
    ReqHomeParams {
        /// The channel.
        chan: u8,
    },
    /// `MOT_GET_HOMEPARAMS` `0x0442`.
    GetHomeParams(HomeParams),
    /// `MOT_MOVE_HOME` `0x0443`.
    MoveHome {
        /// The channel.
        chan: u8,
    },
    /// `MOT_MOVE_HOMED` `0x0444`: the home search finished.
    MoveHomed {
        /// The channel.
        chan: u8,
    },
    /// `MOT_SET_MOVERELPARAMS` `0x0445`: the distance a short-form relative move goes.
    SetMoveRelParams {
        /// The channel.
        chan: u16,
        /// Distance, counts.
        distance: i32,
    },
    /// `MOT_REQ_MOVERELPARAMS` `0x0446`.
    ReqMoveRelParams {
        /// The channel.
        chan: u8,
    },
    /// `MOT_GET_MOVERELPARAMS` `0x0447`.
    GetMoveRelParams {
        /// The channel.
        chan: u16,
        /// Distance, counts.
        distance: i32,
    },
    /// `MOT_SET_MOVEABSPARAMS` `0x0450`: the target of a short-form absolute move.
    SetMoveAbsParams {
        /// The channel.
        chan: u16,
        /// Position, counts.
        position: i32,
    },
    /// `MOT_REQ_MOVEABSPARAMS` `0x0451`.
    ReqMoveAbsParams {
        /// The channel.
        chan: u8,
    },
    /// `MOT_GET_MOVEABSPARAMS` `0x0452`.
    GetMoveAbsParams {
        /// The channel.
        chan: u16,
        /// Position, counts.
        position: i32,
    },
    /// `MOT_MOVE_JOG` `0x046A`: a jog (step or continuous, as the jog parameters say).
    MoveJog {
        /// The channel.
        chan: u8,
        /// The direction.
        direction: Direction,
    },
    /// `MOT_MOVE_RELATIVE` `0x0448`: by `distance` counts (long form), or by the
    /// stored relative move parameters (short form, `None`).
    MoveRelative {
        /// The channel.
        chan: u16,
        /// The distance, counts.
        distance: Option<i32>,
    },
    /// `MOT_MOVE_ABSOLUTE` `0x0453`: to `position` counts (long form), or to the
    /// stored absolute move parameters (short form, `None`).
    MoveAbsolute {
        /// The channel.
        chan: u16,
        /// The target, counts.
        position: Option<i32>,
    },
    /// `MOT_MOVE_VELOCITY` `0x0457`: move at the maximum velocity until stopped.
    MoveVelocity {
        /// The channel.
        chan: u8,
        /// The direction.
        direction: Direction,
    },
    /// `MOT_MOVE_COMPLETED` `0x0464`: a move ended; the long form carries the status.
    MoveCompleted {
        /// The channel.
        chan: u16,
        /// The status at the end (long form), or `None` (short form).
        status: Option<DcStatus>,
    },
    /// `MOT_MOVE_STOP` `0x0465`.
    MoveStop {
        /// The channel.
        chan: u8,
        /// Immediate or profiled.
        mode: StopMode,
    },
    /// `MOT_MOVE_STOPPED` `0x0466`: a stop (or a limit switch) ended a move.
    MoveStopped {
        /// The channel.
        chan: u16,
        /// The status at the end (long form), or `None` (short form).
        status: Option<DcStatus>,
    },
    /// `MOT_REQ_STATUSUPDATE` `0x0480` (stepper controllers).
    ReqStatusUpdate {
        /// The channel.
        chan: u8,
    },
    /// `MOT_GET_STATUSUPDATE` `0x0481`.
    GetStatusUpdate(StepperStatus),
    /// `MOT_REQ_DCSTATUSUPDATE` `0x0490` (DC servo controllers).
    ReqDcStatusUpdate {
        /// The channel.
        chan: u8,
    },
    /// `MOT_GET_DCSTATUSUPDATE` `0x0491`.
    GetDcStatusUpdate(DcStatus),
    /// `MOT_ACK_DCSTATUSUPDATE` `0x0492`: the host's keep-alive ("server alive").
    AckDcStatusUpdate,
    /// A message this codec does not know, kept whole so that it can be skipped (or
    /// relayed) rather than taken for garbage.
    Unknown {
        /// The id.
        id: u16,
        /// The parameter bytes (short form).
        params: [u8; 2],
        /// The data packet (long form).
        data: Option<Vec<u8>>,
    },
}

/// A message with its addresses: what is on the wire.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packet {
    /// The destination (without the long-message flag).
    pub dest: u8,
    /// The source.
    pub source: u8,
    /// The message.
    pub message: Message,
}

/// Message ids.
pub(super) mod id {
    pub const IDENTIFY: u16 = 0x0223;
    pub const HW_DISCONNECT: u16 = 0x0002;
    pub const HW_REQ_INFO: u16 = 0x0005;
    pub const HW_GET_INFO: u16 = 0x0006;
    pub const HW_START_UPDATEMSGS: u16 = 0x0011;
    pub const HW_STOP_UPDATEMSGS: u16 = 0x0012;
    pub const HW_YES_FLASH: u16 = 0x0017;
    pub const HW_NO_FLASH: u16 = 0x0018;
    pub const HW_RESPONSE: u16 = 0x0080;
    pub const HW_RICHRESPONSE: u16 = 0x0081;
    pub const SET_CHANENABLESTATE: u16 = 0x0210;
    pub const REQ_CHANENABLESTATE: u16 = 0x0211;
    pub const GET_CHANENABLESTATE: u16 = 0x0212;
    pub const SET_POSCOUNTER: u16 = 0x0410;
    pub const REQ_POSCOUNTER: u16 = 0x0411;
    pub const GET_POSCOUNTER: u16 = 0x0412;
    pub const SET_VELPARAMS: u16 = 0x0413;
    pub const REQ_VELPARAMS: u16 = 0x0414;
    pub const GET_VELPARAMS: u16 = 0x0415;
    pub const SET_JOGPARAMS: u16 = 0x0416;
    pub const REQ_JOGPARAMS: u16 = 0x0417;
    pub const GET_JOGPARAMS: u16 = 0x0418;
    pub const SET_LIMSWITCHPARAMS: u16 = 0x0423;
    pub const REQ_LIMSWITCHPARAMS: u16 = 0x0424;
    pub const GET_LIMSWITCHPARAMS: u16 = 0x0425;
    pub const REQ_STATUSBITS: u16 = 0x0429;
    pub const GET_STATUSBITS: u16 = 0x042A;
    pub const SET_GENMOVEPARAMS: u16 = 0x043A;
    pub const REQ_GENMOVEPARAMS: u16 = 0x043B;
    pub const GET_GENMOVEPARAMS: u16 = 0x043C;
    pub const SET_HOMEPARAMS: u16 = 0x0440;
    pub const REQ_HOMEPARAMS: u16 = 0x0441;
    pub const GET_HOMEPARAMS: u16 = 0x0442;
    pub const MOVE_HOME: u16 = 0x0443;
    pub const MOVE_HOMED: u16 = 0x0444;
    pub const SET_MOVERELPARAMS: u16 = 0x0445;
    pub const REQ_MOVERELPARAMS: u16 = 0x0446;
    pub const GET_MOVERELPARAMS: u16 = 0x0447;
    pub const SET_MOVEABSPARAMS: u16 = 0x0450;
    pub const REQ_MOVEABSPARAMS: u16 = 0x0451;
    pub const GET_MOVEABSPARAMS: u16 = 0x0452;
    pub const MOVE_JOG: u16 = 0x046A;
    pub const MOVE_RELATIVE: u16 = 0x0448;
    pub const MOVE_ABSOLUTE: u16 = 0x0453;
    pub const MOVE_VELOCITY: u16 = 0x0457;
    pub const MOVE_COMPLETED: u16 = 0x0464;
    pub const MOVE_STOP: u16 = 0x0465;
    pub const MOVE_STOPPED: u16 = 0x0466;
    pub const REQ_STATUSUPDATE: u16 = 0x0480;
    pub const GET_STATUSUPDATE: u16 = 0x0481;
    pub const REQ_DCSTATUSUPDATE: u16 = 0x0490;
    pub const GET_DCSTATUSUPDATE: u16 = 0x0491;
    pub const ACK_DCSTATUSUPDATE: u16 = 0x0492;
}

/// What a known message looks like on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Form {
    /// Header only.
    Short,
    /// A data packet of this length.
    Long(u16),
    /// Either header only or this data packet (moves, completions).
    Either(u16),
    /// A data packet of either length (the stepper status: 14 or 28 bytes).
    Lengths(u16, u16),
}

impl Form {
    fn describe(self) -> String {
        match self {
            Form::Short => "a short message".into(),
            Form::Long(n) => format!("{n} data bytes"),
            Form::Either(n) => format!("a short message or {n} data bytes"),
            Form::Lengths(a, b) => format!("{a} or {b} data bytes"),
        }
    }

    /// True when a header of `data_len` fits.
    pub(super) fn admits(self, data_len: Option<u16>) -> bool {
        match (self, data_len) {
            (Form::Short, None) | (Form::Either(_), None) => true,
            (Form::Long(n) | Form::Either(n), Some(l)) => n == l,
            (Form::Lengths(a, b), Some(l)) => l == a || l == b,
            _ => false,
        }
    }
}

/// The form of a known message id; `None` for an id this codec does not know.
pub(super) fn form_of(message_id: u16) -> Option<Form> {
    use id::*;
    Some(match message_id {
        IDENTIFY | HW_DISCONNECT | HW_REQ_INFO | HW_START_UPDATEMSGS | HW_STOP_UPDATEMSGS
        | HW_YES_FLASH | HW_NO_FLASH | HW_RESPONSE | SET_CHANENABLESTATE | REQ_CHANENABLESTATE
        | GET_CHANENABLESTATE | REQ_POSCOUNTER | REQ_VELPARAMS | REQ_JOGPARAMS
        | REQ_LIMSWITCHPARAMS | REQ_STATUSBITS | REQ_GENMOVEPARAMS | REQ_HOMEPARAMS | MOVE_HOME
        | MOVE_HOMED | MOVE_VELOCITY | MOVE_STOP | REQ_STATUSUPDATE | REQ_DCSTATUSUPDATE
        | ACK_DCSTATUSUPDATE | REQ_MOVERELPARAMS | REQ_MOVEABSPARAMS | MOVE_JOG => Form::Short,
        HW_GET_INFO => Form::Long(84),
        HW_RICHRESPONSE => Form::Long(68),
        SET_POSCOUNTER | GET_POSCOUNTER | GET_STATUSBITS | SET_GENMOVEPARAMS
        | GET_GENMOVEPARAMS | SET_MOVERELPARAMS | GET_MOVERELPARAMS | SET_MOVEABSPARAMS
        | GET_MOVEABSPARAMS => Form::Long(6),
        SET_VELPARAMS | GET_VELPARAMS | SET_HOMEPARAMS | GET_HOMEPARAMS | GET_DCSTATUSUPDATE => {
            Form::Long(14)
        }
        GET_STATUSUPDATE => Form::Lengths(14, 28),
        SET_JOGPARAMS | GET_JOGPARAMS => Form::Long(22),
        SET_LIMSWITCHPARAMS | GET_LIMSWITCHPARAMS => Form::Long(16),
        MOVE_RELATIVE | MOVE_ABSOLUTE => Form::Either(6),
        MOVE_COMPLETED | MOVE_STOPPED => Form::Either(14),
        _ => return None,
    })
}

/// A little-endian reader over a data packet whose length was checked.
struct Rd<'a> {
    b: &'a [u8],
}

impl Rd<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut a = [0u8; N];
        // The length was checked against the message's form before reading; a short
        // packet reads as zeros rather than panicking.
        let n = N.min(self.b.len());
        a[..n].copy_from_slice(&self.b[..n]);
        self.b = &self.b[n..];
        a
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take())
    }
    fn i16(&mut self) -> i16 {
        i16::from_le_bytes(self.take())
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    fn i32(&mut self) -> i32 {
        i32::from_le_bytes(self.take())
    }
}

fn dc_status(r: &mut Rd<'_>) -> DcStatus {
    DcStatus {
        chan: r.u16(),
        position: r.i32(),
        velocity: r.i16(),
        reserved: r.u16(),
        bits: r.u32(),
    }
}

fn put_dc_status(out: &mut Vec<u8>, s: &DcStatus) {
    out.extend_from_slice(&s.chan.to_le_bytes());
    out.extend_from_slice(&s.position.to_le_bytes());
    out.extend_from_slice(&s.velocity.to_le_bytes());
    out.extend_from_slice(&s.reserved.to_le_bytes());
    out.extend_from_slice(&s.bits.to_le_bytes());
}

fn vel(r: &mut Rd<'_>) -> VelParams {
    VelParams {
        chan: r.u16(),
        min_velocity: r.i32(),
        acceleration: r.i32(),
        max_velocity: r.i32(),
    }
}

fn jog(r: &mut Rd<'_>) -> JogParams {
    JogParams {
        chan: r.u16(),
        mode: r.u16(),
        step: r.i32(),
        min_velocity: r.i32(),
        acceleration: r.i32(),
        max_velocity: r.i32(),
        stop_mode: r.u16(),
    }
}

fn home(r: &mut Rd<'_>) -> HomeParams {
    HomeParams {
        chan: r.u16(),
        direction: r.u16(),
        limit_switch: r.u16(),
        velocity: r.i32(),
        offset: r.i32(),
    }
}

fn lim(r: &mut Rd<'_>) -> LimSwitchParams {
    LimSwitchParams {
        chan: r.u16(),
        cw_hard: r.u16(),
        ccw_hard: r.u16(),
        cw_soft: r.i32(),
        ccw_soft: r.i32(),
        soft_mode: r.u16(),
    }
}

fn info(r: &mut Rd<'_>) -> AptInfo {
    let serial = r.u32();
    let model: [u8; 8] = r.take();
    let hw_type = r.u16();
    let [minor, interim, major, _]: [u8; 4] = r.take();
    let _internal: [u8; 60] = r.take();
    AptInfo {
        serial,
        model: text(&model),
        hw_type,
        firmware: [major, interim, minor],
        hw_version: r.u16(),
        mod_state: r.u16(),
        channels: r.u16(),
    }
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

/// `s` in a NUL-padded field of `n` bytes (cut to `n`).
fn put_text(out: &mut Vec<u8>, s: &str, n: usize) {
    let b = s.as_bytes();
    let k = b.len().min(n);
    out.extend_from_slice(&b[..k]);
    out.resize(out.len() + (n - k), 0);
}

fn short_chan(chan: u16) -> u8 {
    u8::try_from(chan).unwrap_or(u8::MAX)
}

impl Message {
    /// The message id.
    pub fn id(&self) -> u16 {
        use Message as M;
        match self {
            M::Identify { .. } => id::IDENTIFY,
            M::HwDisconnect => id::HW_DISCONNECT,
            M::HwReqInfo => id::HW_REQ_INFO,
            M::HwGetInfo(_) => id::HW_GET_INFO,
            M::HwStartUpdateMsgs => id::HW_START_UPDATEMSGS,
            M::HwStopUpdateMsgs => id::HW_STOP_UPDATEMSGS,
            M::HwYesFlashProgramming => id::HW_YES_FLASH,
            M::HwNoFlashProgramming => id::HW_NO_FLASH,
            M::HwResponse => id::HW_RESPONSE,
            M::HwRichResponse { .. } => id::HW_RICHRESPONSE,
            M::SetChanEnableState { .. } => id::SET_CHANENABLESTATE,
            M::ReqChanEnableState { .. } => id::REQ_CHANENABLESTATE,
            M::GetChanEnableState { .. } => id::GET_CHANENABLESTATE,
            M::SetPosCounter { .. } => id::SET_POSCOUNTER,
            M::ReqPosCounter { .. } => id::REQ_POSCOUNTER,
            M::GetPosCounter { .. } => id::GET_POSCOUNTER,
            M::SetVelParams(_) => id::SET_VELPARAMS,
            M::ReqVelParams { .. } => id::REQ_VELPARAMS,
            M::GetVelParams(_) => id::GET_VELPARAMS,
            M::SetJogParams(_) => id::SET_JOGPARAMS,
            M::ReqJogParams { .. } => id::REQ_JOGPARAMS,
            M::GetJogParams(_) => id::GET_JOGPARAMS,
            M::SetLimSwitchParams(_) => id::SET_LIMSWITCHPARAMS,
            M::ReqLimSwitchParams { .. } => id::REQ_LIMSWITCHPARAMS,
            M::GetLimSwitchParams(_) => id::GET_LIMSWITCHPARAMS,
            M::ReqStatusBits { .. } => id::REQ_STATUSBITS,
            M::GetStatusBits { .. } => id::GET_STATUSBITS,
            M::SetGenMoveParams(_) => id::SET_GENMOVEPARAMS,
            M::ReqGenMoveParams { .. } => id::REQ_GENMOVEPARAMS,
            M::GetGenMoveParams(_) => id::GET_GENMOVEPARAMS,
            M::SetHomeParams(_) => id::SET_HOMEPARAMS,
            M::ReqHomeParams { .. } => id::REQ_HOMEPARAMS,
            M::GetHomeParams(_) => id::GET_HOMEPARAMS,
            M::MoveHome { .. } => id::MOVE_HOME,
            M::MoveHomed { .. } => id::MOVE_HOMED,
            M::SetMoveRelParams { .. } => id::SET_MOVERELPARAMS,
            M::ReqMoveRelParams { .. } => id::REQ_MOVERELPARAMS,
            M::GetMoveRelParams { .. } => id::GET_MOVERELPARAMS,
            M::SetMoveAbsParams { .. } => id::SET_MOVEABSPARAMS,
            M::ReqMoveAbsParams { .. } => id::REQ_MOVEABSPARAMS,
            M::GetMoveAbsParams { .. } => id::GET_MOVEABSPARAMS,
            M::MoveJog { .. } => id::MOVE_JOG,
            M::MoveRelative { .. } => id::MOVE_RELATIVE,
            M::MoveAbsolute { .. } => id::MOVE_ABSOLUTE,
            M::MoveVelocity { .. } => id::MOVE_VELOCITY,
            M::MoveCompleted { .. } => id::MOVE_COMPLETED,
            M::MoveStop { .. } => id::MOVE_STOP,
            M::MoveStopped { .. } => id::MOVE_STOPPED,
            M::ReqStatusUpdate { .. } => id::REQ_STATUSUPDATE,
            M::GetStatusUpdate(_) => id::GET_STATUSUPDATE,
            M::ReqDcStatusUpdate { .. } => id::REQ_DCSTATUSUPDATE,
            M::GetDcStatusUpdate(_) => id::GET_DCSTATUSUPDATE,
            M::AckDcStatusUpdate => id::ACK_DCSTATUSUPDATE,
            M::Unknown { id, .. } => *id,
        }
    }

    /// The manual's name, without `MGMSG_` (`MOT_MOVE_ABSOLUTE`), for logs and errors.
    pub fn name(&self) -> &'static str {
        use Message as M;
        match self {
            M::Identify { .. } => "MOD_IDENTIFY",
            M::HwDisconnect => "HW_DISCONNECT",
            M::HwReqInfo => "HW_REQ_INFO",
            M::HwGetInfo(_) => "HW_GET_INFO",
            M::HwStartUpdateMsgs => "HW_START_UPDATEMSGS",
            M::HwStopUpdateMsgs => "HW_STOP_UPDATEMSGS",
            M::HwYesFlashProgramming => "HW_YES_FLASH_PROGRAMMING",
            M::HwNoFlashProgramming => "HW_NO_FLASH_PROGRAMMING",
            M::HwResponse => "HW_RESPONSE",
            M::HwRichResponse { .. } => "HW_RICHRESPONSE",
            M::SetChanEnableState { .. } => "MOD_SET_CHANENABLESTATE",
            M::ReqChanEnableState { .. } => "MOD_REQ_CHANENABLESTATE",
            M::GetChanEnableState { .. } => "MOD_GET_CHANENABLESTATE",
            M::SetPosCounter { .. } => "MOT_SET_POSCOUNTER",
            M::ReqPosCounter { .. } => "MOT_REQ_POSCOUNTER",
            M::GetPosCounter { .. } => "MOT_GET_POSCOUNTER",
            M::SetVelParams(_) => "MOT_SET_VELPARAMS",
            M::ReqVelParams { .. } => "MOT_REQ_VELPARAMS",
            M::GetVelParams(_) => "MOT_GET_VELPARAMS",
            M::SetJogParams(_) => "MOT_SET_JOGPARAMS",
            M::ReqJogParams { .. } => "MOT_REQ_JOGPARAMS",
            M::GetJogParams(_) => "MOT_GET_JOGPARAMS",
            M::SetLimSwitchParams(_) => "MOT_SET_LIMSWITCHPARAMS",
            M::ReqLimSwitchParams { .. } => "MOT_REQ_LIMSWITCHPARAMS",
            M::GetLimSwitchParams(_) => "MOT_GET_LIMSWITCHPARAMS",
            M::ReqStatusBits { .. } => "MOT_REQ_STATUSBITS",
            M::GetStatusBits { .. } => "MOT_GET_STATUSBITS",
            M::SetGenMoveParams(_) => "MOT_SET_GENMOVEPARAMS",
            M::ReqGenMoveParams { .. } => "MOT_REQ_GENMOVEPARAMS",
            M::GetGenMoveParams(_) => "MOT_GET_GENMOVEPARAMS",
            M::SetHomeParams(_) => "MOT_SET_HOMEPARAMS",
            M::ReqHomeParams { .. } => "MOT_REQ_HOMEPARAMS",
            M::GetHomeParams(_) => "MOT_GET_HOMEPARAMS",
            M::MoveHome { .. } => "MOT_MOVE_HOME",
            M::MoveHomed { .. } => "MOT_MOVE_HOMED",
            M::SetMoveRelParams { .. } => "MOT_SET_MOVERELPARAMS",
            M::ReqMoveRelParams { .. } => "MOT_REQ_MOVERELPARAMS",
            M::GetMoveRelParams { .. } => "MOT_GET_MOVERELPARAMS",
            M::SetMoveAbsParams { .. } => "MOT_SET_MOVEABSPARAMS",
            M::ReqMoveAbsParams { .. } => "MOT_REQ_MOVEABSPARAMS",
            M::GetMoveAbsParams { .. } => "MOT_GET_MOVEABSPARAMS",
            M::MoveJog { .. } => "MOT_MOVE_JOG",
            M::MoveRelative { .. } => "MOT_MOVE_RELATIVE",
            M::MoveAbsolute { .. } => "MOT_MOVE_ABSOLUTE",
            M::MoveVelocity { .. } => "MOT_MOVE_VELOCITY",
            M::MoveCompleted { .. } => "MOT_MOVE_COMPLETED",
            M::MoveStop { .. } => "MOT_MOVE_STOP",
            M::MoveStopped { .. } => "MOT_MOVE_STOPPED",
            M::ReqStatusUpdate { .. } => "MOT_REQ_STATUSUPDATE",
            M::GetStatusUpdate(_) => "MOT_GET_STATUSUPDATE",
            M::ReqDcStatusUpdate { .. } => "MOT_REQ_DCSTATUSUPDATE",
            M::GetDcStatusUpdate(_) => "MOT_GET_DCSTATUSUPDATE",
            M::AckDcStatusUpdate => "MOT_ACK_DCSTATUSUPDATE",
            M::Unknown { .. } => "unknown",
        }
    }

    /// True for what a controller sends (replies, notifications), false for what a
    /// host sends; it decides the addresses [`encode`](Self::encode) writes.
    pub fn from_controller(&self) -> bool {
        use Message as M;
        matches!(
            self,
            M::HwGetInfo(_)
                | M::HwYesFlashProgramming
                | M::HwResponse
                | M::HwRichResponse { .. }
                | M::GetChanEnableState { .. }
                | M::GetPosCounter { .. }
                | M::GetMoveRelParams { .. }
                | M::GetMoveAbsParams { .. }
                | M::GetVelParams(_)
                | M::GetJogParams(_)
                | M::GetLimSwitchParams(_)
                | M::GetStatusBits { .. }
                | M::GetGenMoveParams(_)
                | M::GetHomeParams(_)
                | M::MoveHomed { .. }
                | M::MoveCompleted { .. }
                | M::MoveStopped { .. }
                | M::GetStatusUpdate(_)
                | M::GetDcStatusUpdate(_)
        )
    }

    /// Writes the message between a host and a USB unit: host (`0x01`) to unit
    /// (`0x50`) for what a host sends, unit to host for what a controller sends.
    pub fn encode(&self, out: &mut Vec<u8>) {
        let (dest, source) = if self.from_controller() {
            (HOST, USB_UNIT)
        } else {
            (USB_UNIT, HOST)
        };
        self.encode_to(dest, source, out);
    }

    /// The message as bytes, addressed as [`encode`](Self::encode) does.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        self.encode(&mut out);
        out
    }

    /// Writes the message from `source` to `dest`.
    pub fn encode_to(&self, dest: u8, source: u8, out: &mut Vec<u8>) {
        use Message as M;
        let short = |out: &mut Vec<u8>, p1: u8, p2: u8| {
            out.extend_from_slice(&self.id().to_le_bytes());
            out.extend_from_slice(&[p1, p2, dest & !LONG_FLAG, source]);
        };
        let mut data = Vec::new();
        match self {
            M::HwDisconnect
            | M::HwReqInfo
            | M::HwStartUpdateMsgs
            | M::HwStopUpdateMsgs
            | M::HwYesFlashProgramming
            | M::HwNoFlashProgramming
            | M::HwResponse
            | M::AckDcStatusUpdate => return short(out, 0, 0),
            M::Identify { chan }
            | M::ReqChanEnableState { chan }
            | M::ReqPosCounter { chan }
            | M::ReqVelParams { chan }
            | M::ReqJogParams { chan }
            | M::ReqLimSwitchParams { chan }
            | M::ReqStatusBits { chan }
            | M::ReqGenMoveParams { chan }
            | M::ReqHomeParams { chan }
            | M::MoveHome { chan }
            | M::MoveHomed { chan }
            | M::ReqStatusUpdate { chan }
            | M::ReqMoveRelParams { chan }
            | M::ReqMoveAbsParams { chan }
            | M::ReqDcStatusUpdate { chan } => return short(out, *chan, 0),
            M::SetChanEnableState { chan, enable: e }
            | M::GetChanEnableState { chan, enabled: e } => {
                return short(out, *chan, if *e { 1 } else { 2 });
            }
            M::MoveVelocity { chan, direction } | M::MoveJog { chan, direction } => {
                return short(out, *chan, direction.code());
            }
            M::MoveStop { chan, mode } => {
                let m = match mode {
                    StopMode::Immediate => 1,
                    StopMode::Profiled => 2,
                };
                return short(out, *chan, m);
            }
            M::MoveRelative { chan, distance: v } | M::MoveAbsolute { chan, position: v } => {
                match v {
                    None => return short(out, short_chan(*chan), 0),
                    Some(v) => {
                        data.extend_from_slice(&chan.to_le_bytes());
                        data.extend_from_slice(&v.to_le_bytes());
                    }
                }
            }
            M::MoveCompleted { chan, status } | M::MoveStopped { chan, status } => match status {
                None => return short(out, short_chan(*chan), 0),
                Some(s) => put_dc_status(&mut data, s),
            },
            M::Unknown {
                params, data: d, ..
            } => match d {
                None => return short(out, params[0], params[1]),
                Some(d) => data.extend_from_slice(d),
            },
            M::HwGetInfo(i) => {
                data.extend_from_slice(&i.serial.to_le_bytes());
                put_text(&mut data, &i.model, 8);
                data.extend_from_slice(&i.hw_type.to_le_bytes());
                let [ma, it, mi] = i.firmware;
                data.extend_from_slice(&[mi, it, ma, 0]);
                data.resize(data.len() + 60, 0);
                data.extend_from_slice(&i.hw_version.to_le_bytes());
                data.extend_from_slice(&i.mod_state.to_le_bytes());
                data.extend_from_slice(&i.channels.to_le_bytes());
            }
            M::HwRichResponse {
                msg_id,
                code,
                notes,
            } => {
                data.extend_from_slice(&msg_id.to_le_bytes());
                data.extend_from_slice(&code.to_le_bytes());
                put_text(&mut data, notes, 64);
            }
            M::SetPosCounter { chan, position }
            | M::GetPosCounter { chan, position }
            | M::SetMoveRelParams {
                chan,
                distance: position,
            }
            | M::GetMoveRelParams {
                chan,
                distance: position,
            }
            | M::SetMoveAbsParams { chan, position }
            | M::GetMoveAbsParams { chan, position } => {
                data.extend_from_slice(&chan.to_le_bytes());
                data.extend_from_slice(&position.to_le_bytes());
            }
            M::GetStatusBits { chan, bits } => {
                data.extend_from_slice(&chan.to_le_bytes());
                data.extend_from_slice(&bits.to_le_bytes());
            }
            M::SetGenMoveParams(g) | M::GetGenMoveParams(g) => {
                data.extend_from_slice(&g.chan.to_le_bytes());
                data.extend_from_slice(&g.backlash.to_le_bytes());
            }
            M::SetVelParams(v) | M::GetVelParams(v) => {
                data.extend_from_slice(&v.chan.to_le_bytes());
                data.extend_from_slice(&v.min_velocity.to_le_bytes());
                data.extend_from_slice(&v.acceleration.to_le_bytes());
                data.extend_from_slice(&v.max_velocity.to_le_bytes());
            }
            M::SetJogParams(j) | M::GetJogParams(j) => {
                data.extend_from_slice(&j.chan.to_le_bytes());
                data.extend_from_slice(&j.mode.to_le_bytes());
                data.extend_from_slice(&j.step.to_le_bytes());
                data.extend_from_slice(&j.min_velocity.to_le_bytes());
                data.extend_from_slice(&j.acceleration.to_le_bytes());
                data.extend_from_slice(&j.max_velocity.to_le_bytes());
                data.extend_from_slice(&j.stop_mode.to_le_bytes());
            }
            M::SetHomeParams(h) | M::GetHomeParams(h) => {
                data.extend_from_slice(&h.chan.to_le_bytes());
                data.extend_from_slice(&h.direction.to_le_bytes());
                data.extend_from_slice(&h.limit_switch.to_le_bytes());
                data.extend_from_slice(&h.velocity.to_le_bytes());
                data.extend_from_slice(&h.offset.to_le_bytes());
            }
            M::SetLimSwitchParams(l) | M::GetLimSwitchParams(l) => {
                data.extend_from_slice(&l.chan.to_le_bytes());
                data.extend_from_slice(&l.cw_hard.to_le_bytes());
                data.extend_from_slice(&l.ccw_hard.to_le_bytes());
                data.extend_from_slice(&l.cw_soft.to_le_bytes());
                data.extend_from_slice(&l.ccw_soft.to_le_bytes());
                data.extend_from_slice(&l.soft_mode.to_le_bytes());
            }
            M::GetDcStatusUpdate(s) => put_dc_status(&mut data, s),
            M::GetStatusUpdate(s) => {
                data.extend_from_slice(&s.chan.to_le_bytes());
                data.extend_from_slice(&s.position.to_le_bytes());
                data.extend_from_slice(&s.encoder.to_le_bytes());
                data.extend_from_slice(&s.bits.to_le_bytes());
                if let Some(extra) = &s.extra {
                    data.extend_from_slice(extra);
                }
            }
        }
        // Every data packet built above is at most 84 bytes, and an unknown message's
        // came from a parsed header; a longer one is cut rather than mis-framed.
        data.truncate(usize::from(u16::MAX));
        let len = u16::try_from(data.len()).unwrap_or(u16::MAX);
        out.extend_from_slice(&self.id().to_le_bytes());
        out.extend_from_slice(&len.to_le_bytes());
        out.extend_from_slice(&[dest | LONG_FLAG, source]);
        out.extend_from_slice(&data);
    }

    /// Parses one whole message (header and data packet, nothing more), ignoring its
    /// addresses. See [`Packet::parse`] for them.
    pub fn parse(bytes: &[u8]) -> Result<Message, AptError> {
        Packet::parse(bytes).map(|p| p.message)
    }
}

impl Packet {
    /// The message as bytes.
    pub fn encode(&self, out: &mut Vec<u8>) {
        self.message.encode_to(self.dest, self.source, out);
    }

    /// Parses one whole message (header and data packet, nothing more).
    pub fn parse(bytes: &[u8]) -> Result<Packet, AptError> {
        use Message as M;
        let h = Header::parse(bytes)?;
        if let Some(n) = h.data_len
            && usize::from(n) > MAX_DATA_LEN
        {
            return Err(AptError::TooLong(usize::from(n)));
        }
        let total = h.total_len();
        if bytes.len() < total {
            return Err(AptError::Truncated {
                need: total,
                got: bytes.len(),
            });
        }
        if bytes.len() > total {
            return Err(AptError::Trailing {
                extra: bytes.len() - total,
            });
        }
        let data = &bytes[HEADER_LEN..];
        let packet = |message| Packet {
            dest: h.dest,
            source: h.source,
            message,
        };
        let Some(form) = form_of(h.id) else {
            return Ok(packet(M::Unknown {
                id: h.id,
                params: h.params,
                data: h.data_len.map(|_| data.to_vec()),
            }));
        };
        if !form.admits(h.data_len) {
            return Err(AptError::Form {
                id: h.id,
                expected: match form {
                    Form::Short => "a short message",
                    Form::Long(_) => "a long message of its data length",
                    Form::Either(_) => "a short message or a long one of its data length",
                    Form::Lengths(..) => "a long message of one of its data lengths",
                },
                found: match h.data_len {
                    None => "a short message".into(),
                    Some(n) => format!("{n} data bytes (wanted {})", form.describe()),
                },
            });
        }
        let [p1, p2] = h.params;
        let r = &mut Rd { b: data };
        let long = h.data_len.is_some();
        let on_off = |field| match p2 {
            1 => Ok(true),
            2 => Ok(false),
            v => Err(AptError::Field {
                id: h.id,
                field,
                value: u32::from(v),
            }),
        };
        let m = match h.id {
            id::IDENTIFY => M::Identify { chan: p1 },
            id::HW_DISCONNECT => M::HwDisconnect,
            id::HW_REQ_INFO => M::HwReqInfo,
            id::HW_GET_INFO => M::HwGetInfo(info(r)),
            id::HW_START_UPDATEMSGS => M::HwStartUpdateMsgs,
            id::HW_STOP_UPDATEMSGS => M::HwStopUpdateMsgs,
            id::HW_YES_FLASH => M::HwYesFlashProgramming,
            id::HW_NO_FLASH => M::HwNoFlashProgramming,
            id::HW_RESPONSE => M::HwResponse,
            id::HW_RICHRESPONSE => {
                let msg_id = r.u16();
                let code = r.u16();
                let notes: [u8; 64] = r.take();
                M::HwRichResponse {
                    msg_id,
                    code,
                    notes: text(&notes),
                }
            }
            // Lenient: anything but 0x01 disables (a public Python client sends 0).
            id::SET_CHANENABLESTATE => M::SetChanEnableState {
                chan: p1,
                enable: p2 == 1,
            },
            id::REQ_CHANENABLESTATE => M::ReqChanEnableState { chan: p1 },
            id::GET_CHANENABLESTATE => M::GetChanEnableState {
                chan: p1,
                enabled: on_off("enable state")?,
            },
            id::SET_POSCOUNTER => M::SetPosCounter {
                chan: r.u16(),
                position: r.i32(),
            },
            id::REQ_POSCOUNTER => M::ReqPosCounter { chan: p1 },
            id::GET_POSCOUNTER => M::GetPosCounter {
                chan: r.u16(),
                position: r.i32(),
            },
            id::SET_VELPARAMS => M::SetVelParams(vel(r)),
            id::REQ_VELPARAMS => M::ReqVelParams { chan: p1 },
            id::GET_VELPARAMS => M::GetVelParams(vel(r)),
            id::SET_JOGPARAMS => M::SetJogParams(jog(r)),
            id::REQ_JOGPARAMS => M::ReqJogParams { chan: p1 },
            id::GET_JOGPARAMS => M::GetJogParams(jog(r)),
            id::SET_LIMSWITCHPARAMS => M::SetLimSwitchParams(lim(r)),
            id::REQ_LIMSWITCHPARAMS => M::ReqLimSwitchParams { chan: p1 },
            id::GET_LIMSWITCHPARAMS => M::GetLimSwitchParams(lim(r)),
            id::REQ_STATUSBITS => M::ReqStatusBits { chan: p1 },
            id::GET_STATUSBITS => M::GetStatusBits {
                chan: r.u16(),
                bits: r.u32(),
            },
            id::SET_GENMOVEPARAMS => M::SetGenMoveParams(GenMoveParams {
                chan: r.u16(),
                backlash: r.i32(),
            }),
            id::REQ_GENMOVEPARAMS => M::ReqGenMoveParams { chan: p1 },
            id::GET_GENMOVEPARAMS => M::GetGenMoveParams(GenMoveParams {
                chan: r.u16(),
                backlash: r.i32(),
            }),
            id::SET_HOMEPARAMS => M::SetHomeParams(home(r)),
            id::REQ_HOMEPARAMS => M::ReqHomeParams { chan: p1 },
            id::GET_HOMEPARAMS => M::GetHomeParams(home(r)),
            id::MOVE_HOME => M::MoveHome { chan: p1 },
            id::MOVE_HOMED => M::MoveHomed { chan: p1 },
            id::SET_MOVERELPARAMS => M::SetMoveRelParams {
                chan: r.u16(),
                distance: r.i32(),
            },
            id::REQ_MOVERELPARAMS => M::ReqMoveRelParams { chan: p1 },
            id::GET_MOVERELPARAMS => M::GetMoveRelParams {
                chan: r.u16(),
                distance: r.i32(),
            },
            id::SET_MOVEABSPARAMS => M::SetMoveAbsParams {
                chan: r.u16(),
                position: r.i32(),
            },
            id::REQ_MOVEABSPARAMS => M::ReqMoveAbsParams { chan: p1 },
            id::GET_MOVEABSPARAMS => M::GetMoveAbsParams {
                chan: r.u16(),
                position: r.i32(),
            },
            id::MOVE_JOG => M::MoveJog {
                chan: p1,
                direction: Direction::from_code(h.id, "direction", u16::from(p2))?,
            },
            id::MOVE_RELATIVE if long => M::MoveRelative {
                chan: r.u16(),
                distance: Some(r.i32()),
            },
            id::MOVE_RELATIVE => M::MoveRelative {
                chan: u16::from(p1),
                distance: None,
            },
            id::MOVE_ABSOLUTE if long => M::MoveAbsolute {
                chan: r.u16(),
                position: Some(r.i32()),
            },
            id::MOVE_ABSOLUTE => M::MoveAbsolute {
                chan: u16::from(p1),
                position: None,
            },
            id::MOVE_VELOCITY => M::MoveVelocity {
                chan: p1,
                direction: Direction::from_code(h.id, "direction", u16::from(p2))?,
            },
            id::MOVE_COMPLETED | id::MOVE_STOPPED => {
                let (chan, status) = if long {
                    let s = dc_status(r);
                    (s.chan, Some(s))
                } else {
                    (u16::from(p1), None)
                };
                if h.id == id::MOVE_COMPLETED {
                    M::MoveCompleted { chan, status }
                } else {
                    M::MoveStopped { chan, status }
                }
            }
            id::MOVE_STOP => M::MoveStop {
                chan: p1,
                mode: match p2 {
                    1 => StopMode::Immediate,
                    2 => StopMode::Profiled,
                    v => {
                        return Err(AptError::Field {
                            id: h.id,
                            field: "stop mode",
                            value: u32::from(v),
                        });
                    }
                },
            },
            id::REQ_STATUSUPDATE => M::ReqStatusUpdate { chan: p1 },
            id::GET_STATUSUPDATE => M::GetStatusUpdate(StepperStatus {
                chan: r.u16(),
                position: r.i32(),
                encoder: r.i32(),
                bits: r.u32(),
                extra: (data.len() == 28).then(|| r.take::<STEPPER_STATUS_EXTRA>()),
            }),
            id::REQ_DCSTATUSUPDATE => M::ReqDcStatusUpdate { chan: p1 },
            id::GET_DCSTATUSUPDATE => M::GetDcStatusUpdate(dc_status(r)),
            id::ACK_DCSTATUSUPDATE => M::AckDcStatusUpdate,
            // `form_of` knows exactly the ids matched above.
            other => M::Unknown {
                id: other,
                params: h.params,
                data: h.data_len.map(|_| data.to_vec()),
            },
        };
        Ok(packet(m))
    }
}
