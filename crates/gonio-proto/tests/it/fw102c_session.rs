//! The FW102C session driven by hand, byte for byte: each command sent, the echo,
//! prompt and value lines the wheel answers, and the deadlines.

use std::time::Duration;

use gonio_proto::TransportError;
use gonio_proto::fw102c::{ErrorCode, Fw102cConfig, Fw102cError, Fw102cSession, Speed};
use gonio_proto::link::{Deadline, Io, Operation};

fn ms(v: u64) -> Duration {
    Duration::from_millis(v)
}

fn config() -> Fw102cConfig {
    Fw102cConfig {
        timeout_ms: 500,
        move_timeout_ms: 5000,
        poll_interval_ms: 200,
        retries: 1,
        reconnect_attempts: 1,
        reconnect_delay_ms: 300,
        ..Fw102cConfig::default()
    }
}

/// Expects `tx` to be sent at `now`.
fn sent<O: Operation>(op: &mut O, now: Duration, tx: &[u8]) {
    assert_eq!(op.poll_io(), Some(Io::Transmit(tx)), "expected {tx:?}");
    op.handle_sent(now, Ok(()));
}

/// Hands in `lines` at `now`.
fn lines<O: Operation>(op: &mut O, now: Duration, lines: &[&[u8]]) {
    for l in lines {
        assert!(
            matches!(op.poll_timeout(), Some(Deadline::Reply(_))),
            "at {l:?}"
        );
        op.handle_line(now, l);
    }
}

#[test]
fn init_transcript_byte_for_byte() {
    let mut s = Fw102cSession::new(config(), "p").unwrap();
    let mut op = s.start_init(ms(0));
    sent(&mut op, ms(0), b"*idn?\r");
    lines(
        &mut op,
        ms(1),
        &[
            b"*idn?",
            b"THORLABS FW102C/FW212C Filter Wheel version 1.04",
        ],
    );
    sent(&mut op, ms(1), b"pcount?\r");
    lines(&mut op, ms(2), &[b"> pcount?", b"6"]);
    sent(&mut op, ms(2), b"speed=1\r");
    lines(&mut op, ms(3), &[b"> speed=1"]);
    sent(&mut op, ms(3), b"speed?\r");
    lines(&mut op, ms(4), &[b"> speed?", b"1"]);
    sent(&mut op, ms(4), b"sensors=0\r");
    lines(&mut op, ms(5), &[b"> sensors=0"]);
    sent(&mut op, ms(5), b"sensors?\r");
    lines(&mut op, ms(6), &[b"> sensors?", b"0"]);
    sent(&mut op, ms(6), b"pos?\r");
    lines(&mut op, ms(7), &[b"> pos?", b"4"]);
    assert_eq!(
        op.poll_output(),
        Some(Ok(
            "THORLABS FW102C/FW212C Filter Wheel version 1.04".to_string()
        ))
    );
    drop(op);
    assert_eq!(s.position(), Some(4));
}

#[test]
fn init_refuses_another_instrument_and_a_wrong_count() {
    let mut s = Fw102cSession::new(config(), "p").unwrap();
    let mut op = s.start_init(ms(0));
    sent(&mut op, ms(0), b"*idn?\r");
    lines(&mut op, ms(1), &[b"*idn?", b"THORLABS LCC25"]);
    assert!(matches!(
        op.poll_output(),
        Some(Err(Fw102cError::NotAFilterWheel { .. }))
    ));
    drop(op);
    let mut op = s.start_init(ms(0));
    sent(&mut op, ms(0), b"*idn?\r");
    lines(
        &mut op,
        ms(1),
        &[
            b"*idn?",
            b"THORLABS FW102C/FW212C Filter Wheel version 1.04",
        ],
    );
    sent(&mut op, ms(1), b"pcount?\r");
    lines(&mut op, ms(2), &[b"> pcount?", b"12"]);
    assert_eq!(
        op.poll_output(),
        Some(Err(Fw102cError::PositionCountMismatch {
            config: 6,
            device: 12
        }))
    );
}

#[test]
fn a_refused_set_is_reported_from_the_line_before_the_read_back() {
    let c = Fw102cConfig {
        speed: Speed::Low,
        ..config()
    };
    let mut s = Fw102cSession::new(c, "p").unwrap();
    let mut op = s.start_init(ms(0));
    sent(&mut op, ms(0), b"*idn?\r");
    lines(
        &mut op,
        ms(1),
        &[
            b"*idn?",
            b"THORLABS FW102C/FW212C Filter Wheel version 1.04",
        ],
    );
    sent(&mut op, ms(1), b"pcount?\r");
    lines(&mut op, ms(2), &[b"> pcount?", b"6"]);
    sent(&mut op, ms(2), b"speed=0\r");
    lines(&mut op, ms(3), &[b"> speed=0"]);
    sent(&mut op, ms(3), b"speed?\r");
    lines(&mut op, ms(4), &[b"Command error CMD_ARG_INVALID"]);
    assert_eq!(op.poll_io(), Some(Io::ClearInput));
    assert_eq!(
        op.poll_output(),
        Some(Err(Fw102cError::Refused {
            command: "speed=0".into(),
            code: ErrorCode::ArgInvalid
        }))
    );
}

#[test]
fn select_polls_until_the_wheel_reads_the_target() {
    let mut s = Fw102cSession::new(config(), "p").unwrap();
    let mut op = s.start_select(4, ms(0));
    sent(&mut op, ms(0), b"pos=4\r");
    lines(&mut op, ms(1), &[b"> pos=4"]);
    sent(&mut op, ms(1), b"pos?\r");
    // The first poll's echo may wait for the move: due at the move deadline.
    assert_eq!(op.poll_timeout(), Some(Deadline::Reply(ms(5000))));
    lines(&mut op, ms(2), &[b"pos?", b"3"]);
    assert_eq!(op.poll_timeout(), Some(Deadline::Sleep(ms(202))));
    op.handle_timeout(ms(202));
    sent(&mut op, ms(202), b"pos?\r");
    lines(&mut op, ms(900), &[b"> pos?", b"4"]);
    assert_eq!(op.poll_output(), Some(Ok(())));
    drop(op);
    assert_eq!(s.position(), Some(4));
}

#[test]
fn select_times_out_with_the_last_position() {
    let mut s = Fw102cSession::new(config(), "p").unwrap();
    let mut op = s.start_select(2, ms(0));
    sent(&mut op, ms(0), b"pos=2\r");
    lines(&mut op, ms(1), &[b"pos=2"]);
    let mut now = ms(1);
    loop {
        sent(&mut op, now, b"pos?\r");
        lines(&mut op, now, &[b"pos?", b"1"]);
        if let Some(out) = op.poll_output() {
            assert_eq!(
                out,
                Err(Fw102cError::MoveTimeout {
                    position: 2,
                    last: Some(1),
                    waited: ms(5000)
                })
            );
            break;
        }
        let Some(Deadline::Sleep(t)) = op.poll_timeout() else {
            panic!("expected a pause")
        };
        assert!(t <= ms(5000));
        now = t;
        op.handle_timeout(now);
    }
}

#[test]
fn a_refused_move_and_a_lost_echo() {
    let mut s = Fw102cSession::new(config(), "p").unwrap();
    let mut op = s.start_select(5, ms(0));
    sent(&mut op, ms(0), b"pos=5\r");
    lines(&mut op, ms(1), &[b"pos=5"]);
    sent(&mut op, ms(1), b"pos?\r");
    lines(&mut op, ms(2), &[b"Command error CMD_ARG_INVALID"]);
    assert_eq!(op.poll_io(), Some(Io::ClearInput));
    assert_eq!(
        op.poll_output(),
        Some(Err(Fw102cError::Refused {
            command: "pos=5".into(),
            code: ErrorCode::ArgInvalid
        }))
    );
    drop(op);
    // A lost echo: the reply timeout passes, the input is cleared, sent again.
    let mut op = s.start_read_position(ms(0));
    sent(&mut op, ms(0), b"pos?\r");
    assert_eq!(op.poll_timeout(), Some(Deadline::Reply(ms(500))));
    op.handle_timeout(ms(500));
    assert_eq!(op.poll_io(), Some(Io::ClearInput));
    sent(&mut op, ms(500), b"pos?\r");
    lines(&mut op, ms(501), &[b"pos?", b"garbage"]);
    // The retry is spent: the garbled value is the error.
    assert_eq!(op.poll_io(), Some(Io::ClearInput));
    assert!(matches!(
        op.poll_output(),
        Some(Err(Fw102cError::Protocol { .. }))
    ));
    drop(op);
    assert_eq!(s.retried(), 1);
}

#[test]
fn a_vanished_port_is_reopened_and_the_command_sent_again() {
    let mut s = Fw102cSession::new(config(), "p").unwrap();
    let mut op = s.start_read_position(ms(0));
    assert_eq!(op.poll_io(), Some(Io::Transmit(b"pos?\r")));
    let gone = TransportError::Disconnected {
        port: "p".into(),
        reason: "unplugged".into(),
    };
    op.handle_sent(ms(0), Err(gone.clone()));
    assert_eq!(op.poll_timeout(), Some(Deadline::Sleep(ms(300))));
    op.handle_timeout(ms(300));
    assert_eq!(op.poll_io(), Some(Io::Reconnect));
    op.handle_reconnected(ms(310), Ok(()));
    sent(&mut op, ms(310), b"pos?\r");
    op.handle_link_error(ms(311), gone.clone());
    // One reopening allowed: the second loss is final.
    assert_eq!(
        op.poll_output(),
        Some(Err(Fw102cError::Disconnected {
            port: "p".into(),
            attempts: 1,
            source: gone
        }))
    );
    drop(op);
    assert_eq!(s.reconnects(), 1);
}
