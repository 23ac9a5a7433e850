//! What each message is: its id, its manual name, which side sends it, and the
//! form (short, or the data length) each known id has on the wire.

use super::{Message, id};

/// What a known message looks like on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(in crate::apt) enum Form {
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
    /// The form in words, for errors.
    pub(super) fn describe(self) -> String {
        match self {
            Form::Short => "a short message".into(),
            Form::Long(n) => format!("{n} data bytes"),
            Form::Either(n) => format!("a short message or {n} data bytes"),
            Form::Lengths(a, b) => format!("{a} or {b} data bytes"),
        }
    }

    /// True when a header of `data_len` fits.
    pub(in crate::apt) fn admits(self, data_len: Option<u16>) -> bool {
        match (self, data_len) {
            (Form::Short, None) | (Form::Either(_), None) => true,
            (Form::Long(n) | Form::Either(n), Some(l)) => n == l,
            (Form::Lengths(a, b), Some(l)) => l == a || l == b,
            _ => false,
        }
    }
}

/// The form of a known message id; `None` for an id this codec does not know.
pub(in crate::apt) fn form_of(message_id: u16) -> Option<Form> {
    use super::id::*;
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
}
