//! Messages, both directions: the header, the typed [`Message`] and the data
//! structures. The table below is the manual's messages, one row each (see `codec`'s
//! `messages!` for what a row says); a data packet is little endian throughout.

use super::{HEADER_LEN, LONG_FLAG, MAX_DATA_LEN};

mod codec;
mod params;

use codec::messages;
pub use params::{
    AptInfo, DcStatus, Direction, GenMoveParams, HomeParams, JogParams, LimSwitchParams,
    STEPPER_STATUS_EXTRA, StepperStatus, StopMode, VelParams,
};

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

messages! {
    /// Flash the front panel LED (manual Issue 25 p. 41).
    Identify {
        /// The channel (0 for a single-channel unit).
        chan: u8,
    } = MOD_IDENTIFY 0x0223 host short;
    /// The host is about to close the port.
    HwDisconnect = HW_DISCONNECT 0x0002 host short;
    /// (p. 47)
    HwReqInfo = HW_REQ_INFO 0x0005 host short;
    /// (p. 47)
    HwGetInfo(info: AptInfo) = HW_GET_INFO 0x0006 controller long(84);
    /// Status updates every 100 ms until stopped (p. 46).
    HwStartUpdateMsgs = HW_START_UPDATEMSGS 0x0011 host short;
    /// (p. 46)
    HwStopUpdateMsgs = HW_STOP_UPDATEMSGS 0x0012 host short;
    /// Deprecated; sent by some controllers at start.
    HwYesFlashProgramming = HW_YES_FLASH_PROGRAMMING 0x0017 controller short;
    /// Part of a host's initialisation.
    HwNoFlashProgramming = HW_NO_FLASH_PROGRAMMING 0x0018 host short;
    /// The controller reports an error, unspecified (p. 44).
    HwResponse = HW_RESPONSE 0x0080 controller short;
    /// An error, with the message that caused it, a code and a text (p. 45; 68 bytes).
    HwRichResponse {
        /// The id of the message that caused it (0 for a spontaneous fault).
        msg_id: u16,
        /// The error code.
        code: u16,
        /// The description (64 bytes, NUL padded, on the wire).
        notes: String,
    } = HW_RICHRESPONSE 0x0081 controller long(68);
    /// (p. 42)
    SetChanEnableState {
        /// The channel.
        chan: u8,
        /// Enable (`0x01`) or disable (`0x02`).
        enable: bool,
    } = MOD_SET_CHANENABLESTATE 0x0210 host short;
    ReqChanEnableState {
        /// The channel.
        chan: u8,
    } = MOD_REQ_CHANENABLESTATE 0x0211 host short;
    GetChanEnableState {
        /// The channel.
        chan: u8,
        /// Enabled (`0x01`) or not (`0x02`).
        enabled: bool,
    } = MOD_GET_CHANENABLESTATE 0x0212 controller short;
    SetPosCounter {
        /// The channel.
        chan: u16,
        /// The new position, counts.
        position: i32,
    } = MOT_SET_POSCOUNTER 0x0410 host long(6);
    ReqPosCounter {
        /// The channel.
        chan: u8,
    } = MOT_REQ_POSCOUNTER 0x0411 host short;
    GetPosCounter {
        /// The channel.
        chan: u16,
        /// Position, counts.
        position: i32,
    } = MOT_GET_POSCOUNTER 0x0412 controller long(6);
    SetVelParams(p: VelParams) = MOT_SET_VELPARAMS 0x0413 host long(14);
    ReqVelParams {
        /// The channel.
        chan: u8,
    } = MOT_REQ_VELPARAMS 0x0414 host short;
    GetVelParams(p: VelParams) = MOT_GET_VELPARAMS 0x0415 controller long(14);
    SetJogParams(p: JogParams) = MOT_SET_JOGPARAMS 0x0416 host long(22);
    ReqJogParams {
        /// The channel.
        chan: u8,
    } = MOT_REQ_JOGPARAMS 0x0417 host short;
    GetJogParams(p: JogParams) = MOT_GET_JOGPARAMS 0x0418 controller long(22);
    SetLimSwitchParams(p: LimSwitchParams) = MOT_SET_LIMSWITCHPARAMS 0x0423 host long(16);
    ReqLimSwitchParams {
        /// The channel.
        chan: u8,
    } = MOT_REQ_LIMSWITCHPARAMS 0x0424 host short;
    GetLimSwitchParams(p: LimSwitchParams) =
        MOT_GET_LIMSWITCHPARAMS 0x0425 controller long(16);
    ReqStatusBits {
        /// The channel.
        chan: u8,
    } = MOT_REQ_STATUSBITS 0x0429 host short;
    GetStatusBits {
        /// The channel.
        chan: u16,
        /// Status bits.
        bits: u32,
    } = MOT_GET_STATUSBITS 0x042A controller long(6);
    SetGenMoveParams(p: GenMoveParams) = MOT_SET_GENMOVEPARAMS 0x043A host long(6);
    ReqGenMoveParams {
        /// The channel.
        chan: u8,
    } = MOT_REQ_GENMOVEPARAMS 0x043B host short;
    GetGenMoveParams(p: GenMoveParams) = MOT_GET_GENMOVEPARAMS 0x043C controller long(6);
    SetHomeParams(p: HomeParams) = MOT_SET_HOMEPARAMS 0x0440 host long(14);
    ReqHomeParams {
        /// The channel.
        chan: u8,
    } = MOT_REQ_HOMEPARAMS 0x0441 host short;
    GetHomeParams(p: HomeParams) = MOT_GET_HOMEPARAMS 0x0442 controller long(14);
    MoveHome {
        /// The channel.
        chan: u8,
    } = MOT_MOVE_HOME 0x0443 host short;
    /// The home search finished.
    MoveHomed {
        /// The channel.
        chan: u8,
    } = MOT_MOVE_HOMED 0x0444 controller short;
    /// The distance a short-form relative move goes.
    SetMoveRelParams {
        /// The channel.
        chan: u16,
        /// Distance, counts.
        distance: i32,
    } = MOT_SET_MOVERELPARAMS 0x0445 host long(6);
    ReqMoveRelParams {
        /// The channel.
        chan: u8,
    } = MOT_REQ_MOVERELPARAMS 0x0446 host short;
    GetMoveRelParams {
        /// The channel.
        chan: u16,
        /// Distance, counts.
        distance: i32,
    } = MOT_GET_MOVERELPARAMS 0x0447 controller long(6);
    /// The target of a short-form absolute move.
    SetMoveAbsParams {
        /// The channel.
        chan: u16,
        /// Position, counts.
        position: i32,
    } = MOT_SET_MOVEABSPARAMS 0x0450 host long(6);
    ReqMoveAbsParams {
        /// The channel.
        chan: u8,
    } = MOT_REQ_MOVEABSPARAMS 0x0451 host short;
    GetMoveAbsParams {
        /// The channel.
        chan: u16,
        /// Position, counts.
        position: i32,
    } = MOT_GET_MOVEABSPARAMS 0x0452 controller long(6);
    /// A jog (step or continuous, as the jog parameters say).
    MoveJog {
        /// The channel.
        chan: u8,
        /// The direction.
        direction: Direction,
    } = MOT_MOVE_JOG 0x046A host short;
    /// By `distance` counts (long form), or by the stored relative move parameters
    /// (short form, `None`).
    MoveRelative {
        /// The channel.
        chan: u16,
        /// The distance, counts.
        distance: Option<i32>,
    } = MOT_MOVE_RELATIVE 0x0448 host either(6);
    /// To `position` counts (long form), or to the stored absolute move parameters
    /// (short form, `None`).
    MoveAbsolute {
        /// The channel.
        chan: u16,
        /// The target, counts.
        position: Option<i32>,
    } = MOT_MOVE_ABSOLUTE 0x0453 host either(6);
    /// Move at the maximum velocity until stopped.
    MoveVelocity {
        /// The channel.
        chan: u8,
        /// The direction.
        direction: Direction,
    } = MOT_MOVE_VELOCITY 0x0457 host short;
    /// A move ended; the long form carries the status.
    MoveCompleted {
        /// The channel.
        chan: u16,
        /// The status at the end (long form), or `None` (short form).
        status: Option<DcStatus>,
    } = MOT_MOVE_COMPLETED 0x0464 controller ended(14);
    MoveStop {
        /// The channel.
        chan: u8,
        /// Immediate or profiled.
        mode: StopMode,
    } = MOT_MOVE_STOP 0x0465 host short;
    /// A stop (or a limit switch) ended a move.
    MoveStopped {
        /// The channel.
        chan: u16,
        /// The status at the end (long form), or `None` (short form).
        status: Option<DcStatus>,
    } = MOT_MOVE_STOPPED 0x0466 controller ended(14);
    /// Stepper controllers.
    ReqStatusUpdate {
        /// The channel.
        chan: u8,
    } = MOT_REQ_STATUSUPDATE 0x0480 host short;
    GetStatusUpdate(s: StepperStatus) = MOT_GET_STATUSUPDATE 0x0481 controller lengths(14, 28);
    /// DC servo controllers.
    ReqDcStatusUpdate {
        /// The channel.
        chan: u8,
    } = MOT_REQ_DCSTATUSUPDATE 0x0490 host short;
    GetDcStatusUpdate(s: DcStatus) = MOT_GET_DCSTATUSUPDATE 0x0491 controller long(14);
    /// The host's keep-alive ("server alive").
    AckDcStatusUpdate = MOT_ACK_DCSTATUSUPDATE 0x0492 host short;
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
