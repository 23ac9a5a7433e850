//! Thorlabs APT codec and session: byte-exact transcripts (the manual's worked
//! examples where it gives bytes, the layouts field by field elsewhere), round trips,
//! the framer on arbitrary chunk boundaries and on garbage, the stage scales, and the
//! session stepped message by message.

use std::time::Duration;

use gonio_proto::apt::{
    AptAxisConfig, AptError, AptFramer, AptInfo, AptSession, DcStatus, Direction, GenMoveParams,
    HomeParams, JogParams, LimSwitchParams, Message, Packet, StageKind, StepperStatus, StopMode,
    VelParams, fuzz, status,
};
use gonio_proto::link::{Deadline, Io, Operation};
use gonio_proto::motion::{AxisError, MotionError};
use gonio_proto::smc100::ChainPolicy;
use gonio_proto::{FrameError, Framer};
use proptest::prelude::*;

fn bytes(m: &Message) -> Vec<u8> {
    m.to_bytes()
}

/// Header-only messages, host to unit (`50 01`) or unit to host (`01 50`).
#[test]
fn short_messages_byte_for_byte() {
    let cases: Vec<(Message, [u8; 6])> = vec![
        // The manual's MOD_IDENTIFY example.
        (
            Message::Identify { chan: 0 },
            [0x23, 0x02, 0, 0, 0x50, 0x01],
        ),
        (Message::HwDisconnect, [0x02, 0x00, 0, 0, 0x50, 0x01]),
        (Message::HwReqInfo, [0x05, 0x00, 0, 0, 0x50, 0x01]),
        (Message::HwStartUpdateMsgs, [0x11, 0x00, 0, 0, 0x50, 0x01]),
        (Message::HwStopUpdateMsgs, [0x12, 0x00, 0, 0, 0x50, 0x01]),
        (
            Message::HwNoFlashProgramming,
            [0x18, 0x00, 0, 0, 0x50, 0x01],
        ),
        (
            Message::HwYesFlashProgramming,
            [0x17, 0x00, 0, 0, 0x01, 0x50],
        ),
        (Message::HwResponse, [0x80, 0x00, 0, 0, 0x01, 0x50]),
        (
            Message::SetChanEnableState {
                chan: 1,
                enable: true,
            },
            [0x10, 0x02, 1, 1, 0x50, 0x01],
        ),
        (
            Message::SetChanEnableState {
                chan: 1,
                enable: false,
            },
            [0x10, 0x02, 1, 2, 0x50, 0x01],
        ),
        (
            Message::ReqChanEnableState { chan: 1 },
            [0x11, 0x02, 1, 0, 0x50, 0x01],
        ),
        (
            Message::GetChanEnableState {
                chan: 1,
                enabled: true,
            },
            [0x12, 0x02, 1, 1, 0x01, 0x50],
        ),
        (
            Message::ReqPosCounter { chan: 1 },
            [0x11, 0x04, 1, 0, 0x50, 0x01],
        ),
        (
            Message::ReqVelParams { chan: 1 },
            [0x14, 0x04, 1, 0, 0x50, 0x01],
        ),
        (
            Message::ReqJogParams { chan: 1 },
            [0x17, 0x04, 1, 0, 0x50, 0x01],
        ),
        (
            Message::ReqLimSwitchParams { chan: 1 },
            [0x24, 0x04, 1, 0, 0x50, 0x01],
        ),
        (
            Message::ReqStatusBits { chan: 1 },
            [0x29, 0x04, 1, 0, 0x50, 0x01],
        ),
        (
            Message::ReqGenMoveParams { chan: 1 },
            [0x3B, 0x04, 1, 0, 0x50, 0x01],
        ),
        (
            Message::ReqHomeParams { chan: 1 },
            [0x41, 0x04, 1, 0, 0x50, 0x01],
        ),
        // The manual's (and thorlabs-apt-protocol's README) MOT_MOVE_HOME example.
        (
            Message::MoveHome { chan: 1 },
            [0x43, 0x04, 1, 0, 0x50, 0x01],
        ),
        (
            Message::MoveHomed { chan: 1 },
            [0x44, 0x04, 1, 0, 0x01, 0x50],
        ),
        (
            Message::MoveRelative {
                chan: 1,
                distance: None,
            },
            [0x48, 0x04, 1, 0, 0x50, 0x01],
        ),
        (
            Message::MoveAbsolute {
                chan: 1,
                position: None,
            },
            [0x53, 0x04, 1, 0, 0x50, 0x01],
        ),
        (
            Message::MoveVelocity {
                chan: 1,
                direction: Direction::Forward,
            },
            [0x57, 0x04, 1, 1, 0x50, 0x01],
        ),
        (
            Message::MoveVelocity {
                chan: 1,
                direction: Direction::Reverse,
            },
            [0x57, 0x04, 1, 2, 0x50, 0x01],
        ),
        (
            Message::MoveStop {
                chan: 1,
                mode: StopMode::Immediate,
            },
            [0x65, 0x04, 1, 1, 0x50, 0x01],
        ),
        (
            Message::MoveStop {
                chan: 1,
                mode: StopMode::Profiled,
            },
            [0x65, 0x04, 1, 2, 0x50, 0x01],
        ),
        (
            Message::MoveCompleted {
                chan: 1,
                status: None,
            },
            [0x64, 0x04, 1, 0, 0x01, 0x50],
        ),
        (
            Message::ReqStatusUpdate { chan: 1 },
            [0x80, 0x04, 1, 0, 0x50, 0x01],
        ),
        (
            Message::ReqDcStatusUpdate { chan: 1 },
            [0x90, 0x04, 1, 0, 0x50, 0x01],
        ),
        (Message::AckDcStatusUpdate, [0x92, 0x04, 0, 0, 0x50, 0x01]),
        (
            Message::ReqMoveRelParams { chan: 1 },
            [0x46, 0x04, 1, 0, 0x50, 0x01],
        ),
        (
            Message::ReqMoveAbsParams { chan: 1 },
            [0x51, 0x04, 1, 0, 0x50, 0x01],
        ),
        (
            Message::MoveJog {
                chan: 1,
                direction: Direction::Reverse,
            },
            [0x6A, 0x04, 1, 2, 0x50, 0x01],
        ),
    ];
    for (m, want) in cases {
        assert_eq!(bytes(&m), want, "{m:?}");
        assert_eq!(Message::parse(&want), Ok(m.clone()), "{want:02x?}");
    }
}

/// Messages with a data packet: the header's length, the destination's long flag,
/// and each field little endian.
#[test]
fn long_messages_byte_for_byte() {
    // thorlabs-apt-protocol's README example: an absolute move to 2048 counts.
    let m = Message::MoveAbsolute {
        chan: 1,
        position: Some(2048),
    };
    let want = [
        0x53, 0x04, 0x06, 0x00, 0xD0, 0x01, 0x01, 0x00, 0x00, 0x08, 0x00, 0x00,
    ];
    assert_eq!(bytes(&m), want);
    assert_eq!(Message::parse(&want), Ok(m));

    // The manual's MOT_SET_VELPARAMS example, to bay 1 (0x22) of a rack: channel 2,
    // minimum 0, acceleration 13744, maximum 13421773.
    let p = Packet {
        dest: 0x22,
        source: 0x01,
        message: Message::SetVelParams(VelParams {
            chan: 2,
            min_velocity: 0,
            acceleration: 13744,
            max_velocity: 13_421_773,
        }),
    };
    let want = [
        0x13, 0x04, 0x0E, 0x00, 0xA2, 0x01, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0xB0, 0x35, 0x00,
        0x00, 0xCD, 0xCC, 0xCC, 0x00,
    ];
    let mut out = Vec::new();
    p.encode(&mut out);
    assert_eq!(out, want);
    assert_eq!(Packet::parse(&want), Ok(p));

    let cases: Vec<(Message, Vec<u8>)> = vec![
        (
            Message::MoveRelative {
                chan: 1,
                distance: Some(-19196),
            },
            vec![0x48, 0x04, 6, 0, 0xD0, 0x01, 1, 0, 0x04, 0xB5, 0xFF, 0xFF],
        ),
        (
            Message::GetPosCounter {
                chan: 1,
                position: 172_768,
            },
            vec![0x12, 0x04, 6, 0, 0x81, 0x50, 1, 0, 0xE0, 0xA2, 0x02, 0x00],
        ),
        (
            Message::SetMoveAbsParams {
                chan: 1,
                position: 2048,
            },
            vec![0x50, 0x04, 6, 0, 0xD0, 0x01, 1, 0, 0x00, 0x08, 0, 0],
        ),
        (
            Message::GetMoveRelParams {
                chan: 1,
                distance: -1,
            },
            vec![0x47, 0x04, 6, 0, 0x81, 0x50, 1, 0, 0xFF, 0xFF, 0xFF, 0xFF],
        ),
        (
            Message::SetPosCounter {
                chan: 1,
                position: 0,
            },
            vec![0x10, 0x04, 6, 0, 0xD0, 0x01, 1, 0, 0, 0, 0, 0],
        ),
        (
            Message::SetGenMoveParams(GenMoveParams {
                chan: 1,
                backlash: 1920,
            }),
            vec![0x3A, 0x04, 6, 0, 0xD0, 0x01, 1, 0, 0x80, 0x07, 0, 0],
        ),
        (
            Message::GetStatusBits {
                chan: 1,
                bits: status::HOMED | status::CHANNEL_ENABLED,
            },
            vec![0x2A, 0x04, 6, 0, 0x81, 0x50, 1, 0, 0x00, 0x04, 0x00, 0x80],
        ),
        (
            Message::SetHomeParams(HomeParams {
                chan: 1,
                direction: 2,
                limit_switch: 1,
                velocity: 429_417,
                offset: 7679,
            }),
            vec![
                0x40, 0x04, 14, 0, 0xD0, 0x01, 1, 0, 2, 0, 1, 0, 0x69, 0x8D, 0x06, 0x00, 0xFF,
                0x1D, 0, 0,
            ],
        ),
        (
            Message::GetDcStatusUpdate(DcStatus {
                chan: 1,
                position: -2,
                velocity: -3,
                reserved: 0,
                bits: status::MOVING_REV | status::HOMED | status::CHANNEL_ENABLED,
            }),
            vec![
                0x91, 0x04, 14, 0, 0x81, 0x50, 1, 0, 0xFE, 0xFF, 0xFF, 0xFF, 0xFD, 0xFF, 0, 0,
                0x20, 0x04, 0x00, 0x80,
            ],
        ),
        (
            Message::MoveCompleted {
                chan: 1,
                status: Some(DcStatus {
                    chan: 1,
                    position: 19196,
                    velocity: 0,
                    reserved: 0,
                    bits: status::HOMED | status::SETTLED,
                }),
            },
            vec![
                0x64, 0x04, 14, 0, 0x81, 0x50, 1, 0, 0xFC, 0x4A, 0, 0, 0, 0, 0, 0, 0x00, 0x24, 0, 0,
            ],
        ),
        (
            Message::GetStatusUpdate(StepperStatus {
                chan: 1,
                position: 136_533,
                encoder: 0,
                bits: status::HOMED,
                extra: None,
            }),
            vec![
                0x81, 0x04, 14, 0, 0x81, 0x50, 1, 0, 0x55, 0x15, 0x02, 0x00, 0, 0, 0, 0, 0x00,
                0x04, 0, 0,
            ],
        ),
        // The manual's form (p. 123: "34 bytes", `81 04 1C 00`): the same 14 bytes, then
        // channel 2's ident and three reserved words.
        (
            Message::GetStatusUpdate(StepperStatus {
                chan: 1,
                position: 136_533,
                encoder: 0,
                bits: status::HOMED,
                extra: Some([2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]),
            }),
            vec![
                0x81, 0x04, 0x1C, 0, 0x81, 0x50, 1, 0, 0x55, 0x15, 0x02, 0x00, 0, 0, 0, 0, 0x00,
                0x04, 0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
            ],
        ),
        (
            Message::SetJogParams(JogParams {
                chan: 1,
                mode: 2,
                step: 1920,
                min_velocity: 0,
                acceleration: 147,
                max_velocity: 429_417,
                stop_mode: 2,
            }),
            vec![
                0x16, 0x04, 22, 0, 0xD0, 0x01, 1, 0, 2, 0, 0x80, 0x07, 0, 0, 0, 0, 0, 0, 0x93, 0,
                0, 0, 0x69, 0x8D, 0x06, 0x00, 2, 0,
            ],
        ),
        (
            Message::GetLimSwitchParams(LimSwitchParams {
                chan: 1,
                cw_hard: 1,
                ccw_hard: 1,
                cw_soft: 0,
                ccw_soft: 0,
                soft_mode: 1,
            }),
            vec![
                0x25, 0x04, 16, 0, 0x81, 0x50, 1, 0, 1, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0,
            ],
        ),
    ];
    for (m, want) in cases {
        assert_eq!(bytes(&m), want, "{m:?}");
        assert_eq!(Message::parse(&want), Ok(m.clone()), "{want:02x?}");
    }
}

#[test]
fn hw_get_info_layout() {
    let mut want = vec![0x06, 0x00, 84, 0, 0x81, 0x50];
    want.extend_from_slice(&27_000_123u32.to_le_bytes());
    want.extend_from_slice(b"KDC101\0\0");
    want.extend_from_slice(&16u16.to_le_bytes());
    // Firmware 3.0.10, sent minor, interim, major, unused.
    want.extend_from_slice(&[10, 0, 3, 0]);
    want.extend_from_slice(&[0; 60]);
    want.extend_from_slice(&[1, 0, 0, 0, 1, 0]);
    let info = AptInfo {
        serial: 27_000_123,
        model: "KDC101".into(),
        hw_type: 16,
        firmware: [3, 0, 10],
        hw_version: 1,
        mod_state: 0,
        channels: 1,
    };
    assert_eq!(want.len(), 90);
    assert_eq!(bytes(&Message::HwGetInfo(info.clone())), want);
    assert_eq!(Message::parse(&want), Ok(Message::HwGetInfo(info.clone())));
    assert_eq!(
        info.to_string(),
        "KDC101 serial 27000123 firmware 3.0.10 hardware 1 (1 channel)"
    );
}

#[test]
fn rich_response_and_unknown_pass_through() {
    let m = Message::HwRichResponse {
        msg_id: 0x0453,
        code: 3,
        notes: "position out of range".into(),
    };
    let b = bytes(&m);
    assert_eq!(&b[..6], &[0x81, 0x00, 68, 0, 0x81, 0x50]);
    assert_eq!(&b[6..10], &[0x53, 0x04, 3, 0]);
    assert_eq!(&b[10..31], b"position out of range");
    assert!(b[31..].iter().all(|&c| c == 0));
    assert_eq!(Message::parse(&b), Ok(m));

    // MOT_REQ_PIDPARAMS-like ids this codec does not know are kept whole.
    let short = [0xA1, 0x04, 1, 0, 0x50, 0x01];
    let m = Message::parse(&short).unwrap();
    assert_eq!(
        m,
        Message::Unknown {
            id: 0x04A1,
            params: [1, 0],
            data: None
        }
    );
    assert_eq!(m.encode_to(0x50, 0x01, &mut Vec::new()), ());
    let long = [0xA2, 0x04, 2, 0, 0x81, 0x50, 0xAB, 0xCD];
    let p = Packet::parse(&long).unwrap();
    assert_eq!(
        p.message,
        Message::Unknown {
            id: 0x04A2,
            params: [0, 0],
            data: Some(vec![0xAB, 0xCD])
        }
    );
    let mut out = Vec::new();
    p.encode(&mut out);
    assert_eq!(out, long);
}

#[test]
fn parse_errors_are_typed() {
    assert_eq!(
        Message::parse(&[0x43, 0x04, 1]),
        Err(AptError::Truncated { need: 6, got: 3 })
    );
    // A long MOVE_HOME: the id is known to be header-only.
    assert!(matches!(
        Message::parse(&[0x43, 0x04, 2, 0, 0xD0, 0x01, 0, 0]),
        Err(AptError::Form { id: 0x0443, .. })
    ));
    // A velocity packet one byte short.
    assert!(matches!(
        Message::parse(&[
            0x13, 0x04, 13, 0, 0xD0, 0x01, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0
        ]),
        Err(AptError::Form { id: 0x0413, .. })
    ));
    assert_eq!(
        Message::parse(&[0x12, 0x04, 6, 0, 0x81, 0x50, 1, 0]),
        Err(AptError::Truncated { need: 12, got: 8 })
    );
    assert_eq!(
        Message::parse(&[0x05, 0x00, 0, 0, 0x50, 0x01, 0xFF]),
        Err(AptError::Trailing { extra: 1 })
    );
    assert_eq!(
        Message::parse(&[0x99, 0x09, 0x00, 0x01, 0xD0, 0x01]),
        Err(AptError::TooLong(256))
    );
    assert_eq!(
        Message::parse(&[0x65, 0x04, 1, 7, 0x50, 0x01]),
        Err(AptError::Field {
            id: 0x0465,
            field: "stop mode",
            value: 7
        })
    );
}

#[test]
fn framer_resynchronises_after_garbage_and_absurd_lengths() {
    let mut f = AptFramer::new();
    let good = bytes(&Message::MoveHomed { chan: 1 });
    let mut stream = vec![0x00, 0x13, 0x37];
    stream.extend_from_slice(&good);
    // A known id declaring an absurd length.
    stream.extend_from_slice(&[0x91, 0x04, 0xFF, 0x7F, 0x81, 0x50]);
    stream.extend_from_slice(&good);
    f.push(&stream);
    let frames: Vec<_> = std::iter::from_fn(|| f.next_frame()).collect();
    assert_eq!(frames.len(), 4, "{frames:?}");
    assert!(matches!(frames[0], Err(FrameError::Desync(_))));
    assert_eq!(frames[1], Ok(good.clone()));
    assert!(matches!(frames[2], Err(FrameError::Desync(_))));
    assert_eq!(frames[3], Ok(good));
    assert!(!f.has_partial());
}

#[test]
fn stage_scales() {
    let p = StageKind::Prm1Z8;
    assert_eq!(p.to_counts(1.0), 1920);
    assert_eq!(p.to_counts(90.0), 172_768);
    assert!((p.to_deg(172_768) - 90.0).abs() < 1.0 / 1919.0);
    assert!((p.velocity_factor() - 42_941.66).abs() < 0.01);
    assert!((p.acceleration_factor() - 14.66).abs() < 0.01);
    assert_eq!(p.velocity_to_apt(10.0), 429_417);
    assert_eq!(p.acceleration_to_apt(10.0), 147);
    assert!((p.velocity_from_apt(429_417) - 10.0).abs() < 1e-5);
    let k = StageKind::K10cr1;
    assert_eq!(k.to_counts(1.0), 136_533);
    assert_eq!(k.to_counts(360.0), 49_152_000);
    assert_eq!(k.velocity_to_apt(10.0), 73_291_090);
    assert_eq!(k.acceleration_to_apt(10.0), 15_020);
    assert!((k.acceleration_from_apt(15_020) - 10.0).abs() < 1e-12);
    assert_eq!(p.controller(), "KDC101");
    assert_eq!(k.controller(), "K10CR1");
    assert!(p.is_dc_servo() && !k.is_dc_servo());
}

#[test]
fn config_validation_names_the_field() {
    let ok = AptAxisConfig::new("rot", StageKind::Prm1Z8, -170.0, 170.0);
    assert_eq!(ok.validate(), Ok(()));
    let mut c = ok.clone();
    c.velocity = Some(30.0);
    assert_eq!(c.validate().unwrap_err().0, "velocity");
    let mut c = ok.clone();
    c.max = -180.0;
    assert_eq!(c.validate().unwrap_err().0, "min");
    let mut c = ok.clone();
    c.tolerance = 1e-5;
    assert_eq!(c.validate().unwrap_err().0, "tolerance");
    let mut c = ok;
    c.backlash_deg = Some(f64::NAN);
    assert_eq!(c.validate().unwrap_err().0, "backlash_deg");
    let parsed: AptAxisConfig = toml::from_str(
        "name = 'rot'\nstage = 'k10cr1'\nmin = 0.0\nmax = 90.0\nvelocity = 5.0\nbacklash_deg = 0.5\n",
    )
    .unwrap();
    assert_eq!(parsed.stage, StageKind::K10cr1);
    assert_eq!(parsed.velocity, Some(5.0));
    assert_eq!(parsed.backlash_deg, Some(0.5));
    assert_eq!(parsed.tolerance, 0.01);
    assert_eq!(parsed.home_timeout_s, 120.0);
    assert!(!parsed.status_updates);
    let alias: AptAxisConfig =
        toml::from_str("name = 'r'\nstage = 'kdc101-prm1z8'\nmin = 0.0\nmax = 1.0\n").unwrap();
    assert_eq!(alias.stage, StageKind::Prm1Z8);
    let unknown = toml::from_str::<AptAxisConfig>(
        "name = 'r'\nstage = 'prm1z8'\nmin = 0.0\nmax = 1.0\nspeed = 3\n",
    );
    assert!(unknown.unwrap_err().to_string().contains("speed"));
}

// --- property tests ---

fn any_dc() -> impl Strategy<Value = DcStatus> {
    (
        any::<u16>(),
        any::<i32>(),
        any::<i16>(),
        any::<u16>(),
        any::<u32>(),
    )
        .prop_map(|(chan, position, velocity, reserved, bits)| DcStatus {
            chan,
            position,
            velocity,
            reserved,
            bits,
        })
}

fn any_message() -> impl Strategy<Value = Message> {
    let chan = any::<u8>();
    prop_oneof![
        chan.prop_map(|chan| Message::Identify { chan }),
        Just(Message::HwReqInfo),
        Just(Message::HwStartUpdateMsgs),
        Just(Message::HwStopUpdateMsgs),
        Just(Message::HwNoFlashProgramming),
        Just(Message::AckDcStatusUpdate),
        (any::<u16>(), any::<u16>(), "[ -~]{0,64}").prop_map(|(msg_id, code, notes)| {
            Message::HwRichResponse {
                msg_id,
                code,
                notes,
            }
        }),
        (
            any::<u32>(),
            "[A-Z0-9]{0,8}",
            any::<[u8; 3]>(),
            any::<u16>()
        )
            .prop_map(|(serial, model, firmware, hw_version)| Message::HwGetInfo(
                AptInfo {
                    serial,
                    model,
                    hw_type: 16,
                    firmware,
                    hw_version,
                    mod_state: 0,
                    channels: 1
                }
            )),
        (any::<u8>(), any::<bool>())
            .prop_map(|(chan, enable)| Message::SetChanEnableState { chan, enable }),
        (any::<u8>(), any::<bool>())
            .prop_map(|(chan, enabled)| Message::GetChanEnableState { chan, enabled }),
        (any::<u16>(), any::<i32>())
            .prop_map(|(chan, position)| Message::GetPosCounter { chan, position }),
        (any::<u16>(), any::<i32>(), any::<i32>(), any::<i32>()).prop_map(|(chan, a, b, c)| {
            Message::SetVelParams(VelParams {
                chan,
                min_velocity: a,
                acceleration: b,
                max_velocity: c,
            })
        }),
        (
            any::<u16>(),
            any::<u16>(),
            any::<u16>(),
            any::<i32>(),
            any::<i32>()
        )
            .prop_map(|(chan, direction, limit_switch, velocity, offset)| {
                Message::GetHomeParams(HomeParams {
                    chan,
                    direction,
                    limit_switch,
                    velocity,
                    offset,
                })
            }),
        (any::<u16>(), proptest::option::of(any::<i32>())).prop_map(|(chan, position)| {
            Message::MoveAbsolute {
                chan: if position.is_none() {
                    chan & 0xFF
                } else {
                    chan
                },
                position,
            }
        }),
        (any::<u16>(), proptest::option::of(any::<i32>())).prop_map(|(chan, distance)| {
            Message::MoveRelative {
                chan: if distance.is_none() {
                    chan & 0xFF
                } else {
                    chan
                },
                distance,
            }
        }),
        (any::<u8>(), any::<bool>()).prop_map(|(chan, p)| Message::MoveStop {
            chan,
            mode: if p {
                StopMode::Profiled
            } else {
                StopMode::Immediate
            }
        }),
        any_dc().prop_map(Message::GetDcStatusUpdate),
        (any::<u16>(), any::<i32>())
            .prop_map(|(chan, position)| Message::SetMoveAbsParams { chan, position }),
        (any::<u8>(), any::<bool>()).prop_map(|(chan, f)| Message::MoveJog {
            chan,
            direction: if f {
                Direction::Forward
            } else {
                Direction::Reverse
            }
        }),
        any_dc().prop_map(|s| Message::MoveCompleted {
            chan: s.chan,
            status: Some(s)
        }),
        any_dc().prop_map(|s| Message::MoveStopped {
            chan: s.chan,
            status: Some(s)
        }),
        (0x0900u16..0x0FFF, any::<[u8; 2]>()).prop_map(|(id, params)| Message::Unknown {
            id,
            params,
            data: None
        }),
        (
            0x0900u16..0x0FFF,
            proptest::collection::vec(any::<u8>(), 0..255)
        )
            .prop_map(|(id, data)| Message::Unknown {
                id,
                params: [0, 0],
                data: Some(data)
            }),
    ]
}

proptest! {
    #[test]
    fn encode_then_parse_is_identity(m in any_message()) {
        let b = m.to_bytes();
        let parsed = Message::parse(&b);
        prop_assert_eq!(parsed.as_ref(), Ok(&m));
        // And the bytes re-encode exactly.
        prop_assert_eq!(parsed.unwrap().to_bytes(), b);
    }

    #[test]
    fn parse_never_panics(b in proptest::collection::vec(any::<u8>(), 0..300)) {
        let _ = Message::parse(&b);
        fuzz::message(&b);
        fuzz::stream(&b);
    }

    #[test]
    fn framer_splits_anywhere(
        ms in proptest::collection::vec(any_message(), 1..8),
        cuts in proptest::collection::vec(0usize..2000, 0..10),
    ) {
        let mut stream = Vec::new();
        let mut want = Vec::new();
        for m in &ms {
            let b = m.to_bytes();
            stream.extend_from_slice(&b);
            want.push(b);
        }
        let mut cuts: Vec<usize> = cuts.into_iter().map(|c| c % (stream.len() + 1)).collect();
        cuts.sort_unstable();
        let mut f = AptFramer::new();
        let mut from = 0;
        for c in cuts.into_iter().chain([stream.len()]) {
            f.push(&stream[from..c]);
            from = c;
        }
        let got: Vec<_> = std::iter::from_fn(|| f.next_frame()).collect();
        prop_assert_eq!(got, want.into_iter().map(Ok).collect::<Vec<_>>());
    }
}

// --- the session, stepped message by message ---

const MS: Duration = Duration::from_millis(1);

fn session(stage: StageKind) -> AptSession {
    AptSession::new(
        AptAxisConfig::new("rot", stage, -170.0, 170.0),
        ChainPolicy::default(),
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

/// Expects `m` to be transmitted, and reports it sent at `now`.
fn expect_tx(op: &mut impl Operation, m: &Message, now: Duration) {
    assert_eq!(op.poll_io(), Some(Io::Transmit(&m.to_bytes())), "{m:?}");
    op.handle_sent(now, Ok(()));
}

fn dc(position: i32, bits: u32) -> Message {
    Message::GetDcStatusUpdate(DcStatus {
        chan: 1,
        position,
        velocity: 0,
        reserved: 0,
        bits,
    })
}

const READY: u32 = status::HOMED | status::CHANNEL_ENABLED;

#[test]
fn identify_checks_the_model() {
    let info = |model: &str| {
        Message::HwGetInfo(AptInfo {
            serial: 55_000_001,
            model: model.into(),
            hw_type: 16,
            firmware: [1, 2, 3],
            hw_version: 1,
            mod_state: 0,
            channels: 1,
        })
    };
    let mut s = session(StageKind::K10cr1);
    let mut op = s.start_identify(Duration::ZERO);
    expect_tx(&mut op, &Message::HwReqInfo, Duration::ZERO);
    op.handle_line(MS, &info("K10CR1").to_bytes());
    let got = op.poll_output().unwrap().unwrap();
    assert_eq!(got.serial, 55_000_001);
    drop(op);

    let mut op = s.start_identify(Duration::ZERO);
    expect_tx(&mut op, &Message::HwReqInfo, Duration::ZERO);
    op.handle_line(MS, &info("KDC101").to_bytes());
    match op.poll_output() {
        Some(Err(MotionError::AtAxis {
            source: AxisError::Device { command, reason },
            ..
        })) => {
            assert_eq!(command, "HW_REQ_INFO");
            assert!(reason.contains("K10CR1"), "{reason}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn move_transcript_and_keepalive() {
    let mut s = session(StageKind::Prm1Z8);
    let t0 = Duration::from_secs(10);
    let mut op = s.start_move(45.0, t0);
    assert_eq!(op.poll_io(), Some(Io::ClearInput));
    expect_tx(&mut op, &Message::ReqDcStatusUpdate { chan: 1 }, t0);
    assert_eq!(op.poll_timeout(), Some(Deadline::Reply(t0 + 100 * MS)));
    op.handle_line(t0 + MS, &dc(0, READY).to_bytes());
    // 45° is 86384 counts (45 × 1919.6418 = 86383.9).
    let mv = Message::MoveAbsolute {
        chan: 1,
        position: Some(86_384),
    };
    assert_eq!(mv.to_bytes()[6..], [1, 0, 0x70, 0x51, 0x01, 0x00]);
    expect_tx(&mut op, &mv, t0 + 2 * MS);
    assert_eq!(op.poll_timeout(), Some(Deadline::Poll(t0 + 52 * MS)));
    op.handle_timeout(t0 + 52 * MS);
    expect_tx(
        &mut op,
        &Message::ReqDcStatusUpdate { chan: 1 },
        t0 + 52 * MS,
    );
    // An unsolicited MOVE_HOMED and garbage are skipped; the status is taken.
    op.handle_line(t0 + 53 * MS, &Message::MoveHomed { chan: 1 }.to_bytes());
    op.handle_line(t0 + 53 * MS, &[0x99, 0x09, 0, 0, 0x01, 0x50]);
    op.handle_line(
        t0 + 54 * MS,
        &dc(40_000, READY | status::MOVING_FWD).to_bytes(),
    );
    assert_eq!(op.poll_timeout(), Some(Deadline::Poll(t0 + 104 * MS)));
    op.handle_timeout(t0 + 104 * MS);
    expect_tx(
        &mut op,
        &Message::ReqDcStatusUpdate { chan: 1 },
        t0 + 104 * MS,
    );
    op.handle_line(
        t0 + 105 * MS,
        &dc(86_384, READY | status::SETTLED).to_bytes(),
    );
    let out = op.poll_output().unwrap().unwrap();
    assert!((out - 45.0).abs() < 1e-3, "{out}");
    drop(op);

    // Unsolicited updates while a reply is awaited are counted and skipped: the
    // awaited reply ends the wait, and nothing is sent in between (the keep-alive is
    // the pump's, on its clock).
    let mut op = s.start_position(t0);
    expect_tx(&mut op, &Message::ReqPosCounter { chan: 1 }, t0);
    op.handle_line(t0 + MS, &dc(86_384, READY).to_bytes());
    assert_eq!(op.poll_io(), None);
    assert_eq!(op.poll_timeout(), Some(Deadline::Reply(t0 + 100 * MS)));
    op.handle_line(t0 + 2 * MS, &dc(86_384, READY).to_bytes());
    assert_eq!(op.poll_io(), None);
    op.handle_line(
        t0 + 3 * MS,
        &Message::GetPosCounter {
            chan: 1,
            position: 86_384,
        }
        .to_bytes(),
    );
    assert!((op.poll_output().unwrap().unwrap() - 45.0).abs() < 1e-3);
    drop(op);
    assert_eq!(s.updates_received(), 2);
}

#[test]
fn the_session_declares_the_server_alive_message_for_the_whole_session() {
    // APT manual, Issue 28, p. 130 (`MGMSG_MOT_ACK_DCSTATUSUPDATE`, 0x0492): "must be
    // sent by the server to the controller at least once a second"; header only, to
    // the generic USB unit from the host.
    let s = session(StageKind::K10cr1);
    let k = s.keepalive().expect("on by default");
    assert_eq!(k.bytes, [0x92, 0x04, 0x00, 0x00, 0x50, 0x01]);
    assert!(k.every <= Duration::from_secs(1), "{:?}", k.every);
    assert_eq!(k.name, "MOT_ACK_DCSTATUSUPDATE");
    let mut a = AptAxisConfig::new("rot", StageKind::Prm1Z8, -170.0, 170.0);
    a.keepalive = false;
    let s = AptSession::new(a, ChainPolicy::default()).unwrap();
    assert_eq!(s.keepalive(), None);
}

#[test]
fn limits_refused_before_any_byte_and_not_homed_refused_before_moving() {
    let mut s = session(StageKind::Prm1Z8);
    let mut op = s.start_move(171.0, Duration::ZERO);
    assert_eq!(op.poll_io(), None);
    assert!(matches!(
        op.poll_output(),
        Some(Err(MotionError::AtAxis {
            source: AxisError::OutOfLimits { target: 171.0, .. },
            ..
        }))
    ));
    drop(op);
    let mut op = s.start_move(10.0, Duration::ZERO);
    assert_eq!(op.poll_io(), Some(Io::ClearInput));
    expect_tx(
        &mut op,
        &Message::ReqDcStatusUpdate { chan: 1 },
        Duration::ZERO,
    );
    op.handle_line(MS, &dc(0, status::CHANNEL_ENABLED).to_bytes());
    assert_eq!(op.poll_io(), None);
    assert!(matches!(
        op.poll_output(),
        Some(Err(MotionError::AtAxis {
            source: AxisError::NotHomed,
            ..
        }))
    ));
}

#[test]
fn relative_move_with_lost_outcome_is_ambiguous_and_stops() {
    let mut s = session(StageKind::K10cr1);
    let mut op = s.start_move_by(-5.0, Duration::ZERO);
    assert_eq!(op.poll_io(), Some(Io::ClearInput));
    let req = Message::ReqStatusUpdate { chan: 1 };
    expect_tx(&mut op, &req, Duration::ZERO);
    let st = |position, bits| {
        Message::GetStatusUpdate(StepperStatus {
            chan: 1,
            position,
            encoder: 0,
            bits,
            extra: None,
        })
    };
    op.handle_line(MS, &st(136_533 * 10, READY).to_bytes());
    expect_tx(
        &mut op,
        &Message::MoveRelative {
            chan: 1,
            distance: Some(-682_667),
        },
        2 * MS,
    );
    let mut now = 2 * MS;
    op.handle_timeout(now + 50 * MS);
    now += 50 * MS;
    // Three status requests, none answered.
    for _ in 0..3 {
        expect_tx(&mut op, &req, now);
        now += 100 * MS;
        op.handle_timeout(now);
        assert_eq!(op.poll_io(), Some(Io::ClearInput));
    }
    expect_tx(
        &mut op,
        &Message::MoveStop {
            chan: 1,
            mode: StopMode::Profiled,
        },
        now,
    );
    match op.poll_output() {
        Some(Err(MotionError::AtAxis {
            source: AxisError::Ambiguous { command },
            ..
        })) => assert_eq!(command, "MOT_MOVE_RELATIVE"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn abort_stops_the_stage() {
    let mut s = session(StageKind::Prm1Z8);
    let mut op = s.start_home(Duration::ZERO);
    assert_eq!(op.poll_io(), Some(Io::ClearInput));
    expect_tx(&mut op, &Message::MoveHome { chan: 1 }, Duration::ZERO);
    assert_eq!(op.poll_timeout(), Some(Deadline::Poll(50 * MS)));
    op.handle_abort(10 * MS);
    expect_tx(
        &mut op,
        &Message::MoveStop {
            chan: 1,
            mode: StopMode::Profiled,
        },
        10 * MS,
    );
    assert!(matches!(
        op.poll_output(),
        Some(Err(MotionError::AtAxis {
            source: AxisError::Aborted,
            ..
        }))
    ));
}

#[test]
fn limit_switch_mid_move_is_a_device_fault() {
    let mut s = session(StageKind::Prm1Z8);
    let mut op = s.start_move(100.0, Duration::ZERO);
    assert_eq!(op.poll_io(), Some(Io::ClearInput));
    expect_tx(
        &mut op,
        &Message::ReqDcStatusUpdate { chan: 1 },
        Duration::ZERO,
    );
    op.handle_line(MS, &dc(0, READY).to_bytes());
    assert!(matches!(op.poll_io(), Some(Io::Transmit(_))));
    op.handle_sent(MS, Ok(()));
    op.handle_timeout(51 * MS);
    expect_tx(&mut op, &Message::ReqDcStatusUpdate { chan: 1 }, 51 * MS);
    op.handle_line(52 * MS, &dc(5000, READY | status::FWD_HW_LIMIT).to_bytes());
    expect_tx(
        &mut op,
        &Message::MoveStop {
            chan: 1,
            mode: StopMode::Profiled,
        },
        52 * MS,
    );
    match op.poll_output() {
        Some(Err(MotionError::AtAxis {
            source: AxisError::Device { command, reason },
            ..
        })) => {
            assert_eq!(command, "MOT_MOVE_ABSOLUTE");
            assert_eq!(reason, "forward limit switch");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_vanished_port_is_reopened_and_the_message_sent_again() {
    let mut s = session(StageKind::Prm1Z8);
    let mut op = s.start_position(Duration::ZERO);
    let req = Message::ReqPosCounter { chan: 1 }.to_bytes();
    assert_eq!(op.poll_io(), Some(Io::Transmit(&req)));
    let gone = gonio_proto::TransportError::Disconnected {
        port: "/dev/ttyUSB0".into(),
        reason: "unplugged".into(),
    };
    op.handle_sent(Duration::ZERO, Err(gone.clone()));
    assert_eq!(op.poll_io(), Some(Io::Reconnect));
    op.handle_reconnected(MS, Err(gone));
    // The policy's 500 ms between attempts.
    assert_eq!(op.poll_timeout(), Some(Deadline::Sleep(501 * MS)));
    op.handle_timeout(501 * MS);
    assert_eq!(op.poll_io(), Some(Io::Reconnect));
    op.handle_reconnected(502 * MS, Ok(()));
    expect_tx(&mut op, &Message::ReqPosCounter { chan: 1 }, 502 * MS);
    op.handle_line(
        503 * MS,
        &Message::GetPosCounter {
            chan: 1,
            position: -1920,
        }
        .to_bytes(),
    );
    let p = op.poll_output().unwrap().unwrap();
    assert!((p + 1920.0 / 1919.6418).abs() < 1e-12);
}

#[test]
fn an_error_report_is_a_device_fault() {
    let mut s = session(StageKind::Prm1Z8);
    let mut op = s.start_velocity_params(Duration::ZERO);
    expect_tx(&mut op, &Message::ReqVelParams { chan: 1 }, Duration::ZERO);
    let err = Message::HwRichResponse {
        msg_id: 0x0414,
        code: 42,
        notes: "bad channel".into(),
    };
    op.handle_line(MS, &err.to_bytes());
    match op.poll_output() {
        Some(Err(MotionError::AtAxis {
            source: AxisError::Device { command, reason },
            ..
        })) => {
            assert_eq!(command, "MOT_REQ_VELPARAMS");
            assert_eq!(reason, "error 42 on message 0x0414: bad channel");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn lost_status_replies_are_asked_again() {
    let mut s = session(StageKind::Prm1Z8);
    let mut op = s.start_status(Duration::ZERO);
    let req = Message::ReqDcStatusUpdate { chan: 1 };
    expect_tx(&mut op, &req, Duration::ZERO);
    op.handle_timeout(100 * MS);
    assert_eq!(op.poll_io(), Some(Io::ClearInput));
    expect_tx(&mut op, &req, 100 * MS);
    op.handle_line(101 * MS, &dc(1920, READY).to_bytes());
    let st = op.poll_output().unwrap().unwrap();
    assert!((st.position_deg - 1920.0 / 1919.6418).abs() < 1e-12);
    assert_eq!(st.velocity_raw, Some(0));
    drop(op);
    assert_eq!(s.retried(), 1);
}

/// The framer's report of garbage before a message.
mod framer_unit {
    use gonio_proto::apt::{AptFramer, Message};
    use gonio_proto::{FrameError, Framer};

    #[test]
    fn garbage_before_a_message_is_one_desync() {
        let mut f = AptFramer::new();
        let mut bytes = vec![0xFF, 0xEE, 0xDD, 0xCC, 0xBB, 0xAA, 0x99];
        Message::HwReqInfo.encode(&mut bytes);
        f.push(&bytes);
        assert!(matches!(f.next_frame(), Some(Err(FrameError::Desync(_)))));
        assert_eq!(f.next_frame(), Some(Ok(vec![0x05, 0x00, 0, 0, 0x50, 0x01])));
        assert_eq!(f.next_frame(), None);
        assert!(!f.has_partial());
    }
}

/// A channel's status read by its bits, and a session refusing a bad axis.
mod session_status {
    use gonio_proto::apt::{AptAxisConfig, AptSession, AptStatus, StageKind, status};
    use gonio_proto::motion::MotionError;
    use gonio_proto::smc100::ChainPolicy;

    fn status(bits: u32) -> AptStatus {
        AptStatus {
            position_deg: 1.0,
            velocity_raw: None,
            bits,
        }
    }

    #[test]
    fn status_predicates() {
        let s = status(status::HOMED | status::CHANNEL_ENABLED | status::MOVING_REV);
        assert!(s.is_homed() && s.is_enabled() && s.is_moving());
        assert!(s.faults().is_empty());
        let s = status(status::REV_HW_LIMIT | status::MOTION_ERROR | status::HOMED);
        assert_eq!(s.faults(), ["reverse limit switch", "motion error"]);
        assert!(!s.is_moving() && !s.is_enabled());
    }

    #[test]
    fn session_refuses_an_invalid_config() {
        let mut a = AptAxisConfig::new("rot", StageKind::K10cr1, 0.0, 90.0);
        a.home_timeout_s = 0.0;
        match AptSession::new(a, ChainPolicy::default()) {
            Err(MotionError::Config(m)) => assert!(m.contains("home_timeout_s"), "{m}"),
            other => panic!("{other:?}"),
        }
    }
}
