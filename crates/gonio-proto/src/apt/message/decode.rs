//! Reading messages: the framing checks, the header's form against the id's, and
//! each data packet's layout.

use super::describe::{Form, form_of};
use super::params::{
    AptInfo, DcStatus, Direction, GenMoveParams, HomeParams, JogParams, LimSwitchParams,
    STEPPER_STATUS_EXTRA, StepperStatus, StopMode, VelParams,
};
use super::{AptError, Header, Message, Packet, id};
use crate::apt::{HEADER_LEN, MAX_DATA_LEN};

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

impl Message {
    /// Parses one whole message (header and data packet, nothing more), ignoring its
    /// addresses. See [`Packet::parse`] for them.
    pub fn parse(bytes: &[u8]) -> Result<Message, AptError> {
        Packet::parse(bytes).map(|p| p.message)
    }
}

impl Packet {
    /// Parses one whole message (header and data packet, nothing more).
    pub fn parse(bytes: &[u8]) -> Result<Packet, AptError> {
        let h = framed(bytes)?;
        let data = &bytes[HEADER_LEN..];
        let message = match form_of(h.id) {
            None => unknown(&h, data),
            Some(form) => {
                check_form(&h, form)?;
                if h.data_len.is_some() {
                    from_data(&h, data)
                } else {
                    from_params(&h)?
                }
            }
        };
        Ok(Packet {
            dest: h.dest,
            source: h.source,
            message,
        })
    }
}

/// The header of `bytes` when they are exactly one message: a data length within
/// [`MAX_DATA_LEN`], and as many bytes as the header says, no fewer, no more.
fn framed(bytes: &[u8]) -> Result<Header, AptError> {
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
    Ok(h)
}

/// A message this codec does not know (or, by `form_of`, cannot be), kept whole so
/// that it passes through.
fn unknown(h: &Header, data: &[u8]) -> Message {
    Message::Unknown {
        id: h.id,
        params: h.params,
        data: h.data_len.map(|_| data.to_vec()),
    }
}

/// Refuses a known message whose header is not of its id's form.
fn check_form(h: &Header, form: Form) -> Result<(), AptError> {
    if form.admits(h.data_len) {
        return Ok(());
    }
    Err(AptError::Form {
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
    })
}

/// A move's end, completed or stopped by `id`, with its status when it had one.
fn move_ended(id: u16, chan: u16, status: Option<DcStatus>) -> Message {
    if id == id::MOVE_COMPLETED {
        Message::MoveCompleted { chan, status }
    } else {
        Message::MoveStopped { chan, status }
    }
}

/// A known short message (header only), from its two parameter bytes; refuses a
/// parameter the manual does not define.
fn from_params(h: &Header) -> Result<Message, AptError> {
    use Message as M;
    let [p1, p2] = h.params;
    let undefined = |field, v: u8| AptError::Field {
        id: h.id,
        field,
        value: u32::from(v),
    };
    Ok(match h.id {
        id::IDENTIFY => M::Identify { chan: p1 },
        id::HW_DISCONNECT => M::HwDisconnect,
        id::HW_REQ_INFO => M::HwReqInfo,
        id::HW_START_UPDATEMSGS => M::HwStartUpdateMsgs,
        id::HW_STOP_UPDATEMSGS => M::HwStopUpdateMsgs,
        id::HW_YES_FLASH => M::HwYesFlashProgramming,
        id::HW_NO_FLASH => M::HwNoFlashProgramming,
        id::HW_RESPONSE => M::HwResponse,
        // Lenient: anything but 0x01 disables (a public Python client sends 0).
        id::SET_CHANENABLESTATE => M::SetChanEnableState {
            chan: p1,
            enable: p2 == 1,
        },
        id::REQ_CHANENABLESTATE => M::ReqChanEnableState { chan: p1 },
        id::GET_CHANENABLESTATE => M::GetChanEnableState {
            chan: p1,
            enabled: match p2 {
                1 => true,
                2 => false,
                v => return Err(undefined("enable state", v)),
            },
        },
        id::REQ_POSCOUNTER => M::ReqPosCounter { chan: p1 },
        id::REQ_VELPARAMS => M::ReqVelParams { chan: p1 },
        id::REQ_JOGPARAMS => M::ReqJogParams { chan: p1 },
        id::REQ_LIMSWITCHPARAMS => M::ReqLimSwitchParams { chan: p1 },
        id::REQ_STATUSBITS => M::ReqStatusBits { chan: p1 },
        id::REQ_GENMOVEPARAMS => M::ReqGenMoveParams { chan: p1 },
        id::REQ_HOMEPARAMS => M::ReqHomeParams { chan: p1 },
        id::MOVE_HOME => M::MoveHome { chan: p1 },
        id::MOVE_HOMED => M::MoveHomed { chan: p1 },
        id::REQ_MOVERELPARAMS => M::ReqMoveRelParams { chan: p1 },
        id::REQ_MOVEABSPARAMS => M::ReqMoveAbsParams { chan: p1 },
        id::MOVE_JOG => M::MoveJog {
            chan: p1,
            direction: Direction::from_code(h.id, "direction", u16::from(p2))?,
        },
        id::MOVE_RELATIVE => M::MoveRelative {
            chan: u16::from(p1),
            distance: None,
        },
        id::MOVE_ABSOLUTE => M::MoveAbsolute {
            chan: u16::from(p1),
            position: None,
        },
        id::MOVE_VELOCITY => M::MoveVelocity {
            chan: p1,
            direction: Direction::from_code(h.id, "direction", u16::from(p2))?,
        },
        id::MOVE_COMPLETED | id::MOVE_STOPPED => move_ended(h.id, u16::from(p1), None),
        id::MOVE_STOP => M::MoveStop {
            chan: p1,
            mode: match p2 {
                1 => StopMode::Immediate,
                2 => StopMode::Profiled,
                v => return Err(undefined("stop mode", v)),
            },
        },
        id::REQ_STATUSUPDATE => M::ReqStatusUpdate { chan: p1 },
        id::REQ_DCSTATUSUPDATE => M::ReqDcStatusUpdate { chan: p1 },
        id::ACK_DCSTATUSUPDATE => M::AckDcStatusUpdate,
        // `form_of` admits a short header for exactly the ids matched above.
        _ => unknown(h, &[]),
    })
}

/// A known long message, from its data packet (of its form's length).
fn from_data(h: &Header, data: &[u8]) -> Message {
    use Message as M;
    let r = &mut Rd { b: data };
    match h.id {
        id::HW_GET_INFO => M::HwGetInfo(info(r)),
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
        id::SET_POSCOUNTER => M::SetPosCounter {
            chan: r.u16(),
            position: r.i32(),
        },
        id::GET_POSCOUNTER => M::GetPosCounter {
            chan: r.u16(),
            position: r.i32(),
        },
        id::SET_VELPARAMS => M::SetVelParams(vel(r)),
        id::GET_VELPARAMS => M::GetVelParams(vel(r)),
        id::SET_JOGPARAMS => M::SetJogParams(jog(r)),
        id::GET_JOGPARAMS => M::GetJogParams(jog(r)),
        id::SET_LIMSWITCHPARAMS => M::SetLimSwitchParams(lim(r)),
        id::GET_LIMSWITCHPARAMS => M::GetLimSwitchParams(lim(r)),
        id::GET_STATUSBITS => M::GetStatusBits {
            chan: r.u16(),
            bits: r.u32(),
        },
        id::SET_GENMOVEPARAMS => M::SetGenMoveParams(GenMoveParams {
            chan: r.u16(),
            backlash: r.i32(),
        }),
        id::GET_GENMOVEPARAMS => M::GetGenMoveParams(GenMoveParams {
            chan: r.u16(),
            backlash: r.i32(),
        }),
        id::SET_HOMEPARAMS => M::SetHomeParams(home(r)),
        id::GET_HOMEPARAMS => M::GetHomeParams(home(r)),
        id::SET_MOVERELPARAMS => M::SetMoveRelParams {
            chan: r.u16(),
            distance: r.i32(),
        },
        id::GET_MOVERELPARAMS => M::GetMoveRelParams {
            chan: r.u16(),
            distance: r.i32(),
        },
        id::SET_MOVEABSPARAMS => M::SetMoveAbsParams {
            chan: r.u16(),
            position: r.i32(),
        },
        id::GET_MOVEABSPARAMS => M::GetMoveAbsParams {
            chan: r.u16(),
            position: r.i32(),
        },
        id::MOVE_RELATIVE => M::MoveRelative {
            chan: r.u16(),
            distance: Some(r.i32()),
        },
        id::MOVE_ABSOLUTE => M::MoveAbsolute {
            chan: r.u16(),
            position: Some(r.i32()),
        },
        id::MOVE_COMPLETED | id::MOVE_STOPPED => {
            let s = dc_status(r);
            move_ended(h.id, s.chan, Some(s))
        }
        id::GET_STATUSUPDATE => M::GetStatusUpdate(StepperStatus {
            chan: r.u16(),
            position: r.i32(),
            encoder: r.i32(),
            bits: r.u32(),
            extra: (data.len() == 28).then(|| r.take::<STEPPER_STATUS_EXTRA>()),
        }),
        id::GET_DCSTATUSUPDATE => M::GetDcStatusUpdate(dc_status(r)),
        // `form_of` admits a data packet for exactly the ids matched above.
        _ => unknown(h, data),
    }
}
