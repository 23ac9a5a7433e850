//! Writing messages: the header with its addresses, and each data packet's layout.

use super::params::{
    AptInfo, DcStatus, HomeParams, JogParams, LimSwitchParams, StepperStatus, StopMode, VelParams,
};
use super::{Message, Packet};
use crate::apt::{HOST, LONG_FLAG, USB_UNIT};

// The writers of the data structures, field by field in the manual's order: each
// the mirror of its reader in `decode`.

/// Writes a DC servo status (14 bytes).
fn put_dc_status(out: &mut Vec<u8>, s: &DcStatus) {
    out.extend_from_slice(&s.chan.to_le_bytes());
    out.extend_from_slice(&s.position.to_le_bytes());
    out.extend_from_slice(&s.velocity.to_le_bytes());
    out.extend_from_slice(&s.reserved.to_le_bytes());
    out.extend_from_slice(&s.bits.to_le_bytes());
}

/// Writes a stepper status (14 bytes, or 28 with its extra bytes).
fn put_stepper_status(out: &mut Vec<u8>, s: &StepperStatus) {
    out.extend_from_slice(&s.chan.to_le_bytes());
    out.extend_from_slice(&s.position.to_le_bytes());
    out.extend_from_slice(&s.encoder.to_le_bytes());
    out.extend_from_slice(&s.bits.to_le_bytes());
    if let Some(extra) = &s.extra {
        out.extend_from_slice(extra);
    }
}

/// Writes velocity parameters (14 bytes).
fn put_vel(out: &mut Vec<u8>, v: &VelParams) {
    out.extend_from_slice(&v.chan.to_le_bytes());
    out.extend_from_slice(&v.min_velocity.to_le_bytes());
    out.extend_from_slice(&v.acceleration.to_le_bytes());
    out.extend_from_slice(&v.max_velocity.to_le_bytes());
}

/// Writes jog parameters (22 bytes).
fn put_jog(out: &mut Vec<u8>, j: &JogParams) {
    out.extend_from_slice(&j.chan.to_le_bytes());
    out.extend_from_slice(&j.mode.to_le_bytes());
    out.extend_from_slice(&j.step.to_le_bytes());
    out.extend_from_slice(&j.min_velocity.to_le_bytes());
    out.extend_from_slice(&j.acceleration.to_le_bytes());
    out.extend_from_slice(&j.max_velocity.to_le_bytes());
    out.extend_from_slice(&j.stop_mode.to_le_bytes());
}

/// Writes homing parameters (14 bytes).
fn put_home(out: &mut Vec<u8>, h: &HomeParams) {
    out.extend_from_slice(&h.chan.to_le_bytes());
    out.extend_from_slice(&h.direction.to_le_bytes());
    out.extend_from_slice(&h.limit_switch.to_le_bytes());
    out.extend_from_slice(&h.velocity.to_le_bytes());
    out.extend_from_slice(&h.offset.to_le_bytes());
}

/// Writes limit switch parameters (16 bytes).
fn put_lim(out: &mut Vec<u8>, l: &LimSwitchParams) {
    out.extend_from_slice(&l.chan.to_le_bytes());
    out.extend_from_slice(&l.cw_hard.to_le_bytes());
    out.extend_from_slice(&l.ccw_hard.to_le_bytes());
    out.extend_from_slice(&l.cw_soft.to_le_bytes());
    out.extend_from_slice(&l.ccw_soft.to_le_bytes());
    out.extend_from_slice(&l.soft_mode.to_le_bytes());
}

/// Writes the hardware information (84 bytes): the firmware version's bytes minor
/// first, and the 60 internal bytes as zeros.
fn put_info(out: &mut Vec<u8>, i: &AptInfo) {
    out.extend_from_slice(&i.serial.to_le_bytes());
    put_text(out, &i.model, 8);
    out.extend_from_slice(&i.hw_type.to_le_bytes());
    let [ma, it, mi] = i.firmware;
    out.extend_from_slice(&[mi, it, ma, 0]);
    out.resize(out.len() + 60, 0);
    out.extend_from_slice(&i.hw_version.to_le_bytes());
    out.extend_from_slice(&i.mod_state.to_le_bytes());
    out.extend_from_slice(&i.channels.to_le_bytes());
}

/// `s` in a NUL-padded field of `n` bytes (cut to `n`).
fn put_text(out: &mut Vec<u8>, s: &str, n: usize) {
    let b = s.as_bytes();
    let k = b.len().min(n);
    out.extend_from_slice(&b[..k]);
    out.resize(out.len() + (n - k), 0);
}

/// A channel as a short message's parameter byte (255 for any channel beyond it,
/// which has no short form).
fn short_chan(chan: u16) -> u8 {
    u8::try_from(chan).unwrap_or(u8::MAX)
}

impl Message {
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
            M::HwGetInfo(i) => put_info(&mut data, i),
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
            M::SetVelParams(v) | M::GetVelParams(v) => put_vel(&mut data, v),
            M::SetJogParams(j) | M::GetJogParams(j) => put_jog(&mut data, j),
            M::SetHomeParams(h) | M::GetHomeParams(h) => put_home(&mut data, h),
            M::SetLimSwitchParams(l) | M::GetLimSwitchParams(l) => put_lim(&mut data, l),
            M::GetDcStatusUpdate(s) => put_dc_status(&mut data, s),
            M::GetStatusUpdate(s) => put_stepper_status(&mut data, s),
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
}

impl Packet {
    /// The message as bytes.
    pub fn encode(&self, out: &mut Vec<u8>) {
        self.message.encode_to(self.dest, self.source, out);
    }
}
