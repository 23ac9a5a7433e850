//! The SR830's data buffer commands (manual p. 5-14 … 5-18) byte for byte, the binary
//! trace formats against the manual's definitions, the framer that cuts them out of
//! the line stream, and property tests: every point survives encode → decode, and a
//! stream cut anywhere frames the same.

use crate::sr830::host_line;
use gonio_proto::Framer;
use gonio_proto::sr830::buffer::{self, decode_trcb, decode_trcl};
use gonio_proto::sr830::{
    self, Command, DisplayDef, EndOfScan, Reply, ReplyError, SampleRate, Sr830Framer, StoredValue,
    TraceChannel, TraceRange,
};
use proptest::prelude::*;

fn range(ch: u8, j: u16, k: u16) -> TraceRange {
    TraceRange::new(TraceChannel::from_code(ch).expect("channel"), j, k).expect("range")
}

#[test]
fn the_data_storage_commands_are_written_as_the_manual_lists_them() {
    host_line("SRAT 10", &[Command::SetSampleRate(SampleRate::Hz64)]);
    host_line("SRAT?", &[Command::QuerySampleRate]);
    host_line("SEND 0", &[Command::SetEndOfScan(EndOfScan::OneShot)]);
    host_line("SEND 1", &[Command::SetEndOfScan(EndOfScan::Loop)]);
    host_line(
        "STRT;PAUS;REST",
        &[
            Command::StartStorage,
            Command::PauseStorage,
            Command::ResetStorage,
        ],
    );
    host_line("SPTS?", &[Command::StoredPoints]);
    host_line(
        "DDEF 1,0,0;DDEF 2,0,0",
        &DisplayDef::XY.map(Command::SetDisplay),
    );
    host_line("TRCA? 1,0,2", &[Command::TraceAscii(range(1, 0, 2))]);
    host_line("TRCB? 2,5,1", &[Command::TraceBinary(range(2, 5, 1))]);
    host_line(
        "TRCL? 1,16382,1",
        &[Command::TraceStored(range(1, 16382, 1))],
    );
}

#[test]
fn out_of_range_storage_parameters_are_refused_as_execution_errors() {
    for (line, bit) in [
        ("SRAT 15", 4),
        ("SEND 2", 4),
        ("TRCL? 3,0,1", 4),
        ("TRCL? 1,0,0", 4),
        ("TRCL? 1,16383,1", 4),
        ("TRCL? 1,0", 5),
        ("DDEF 1,5,0", 4),
    ] {
        let e = sr830::parse_line(line.as_bytes())
            .remove(0)
            .expect_err(line);
        assert_eq!(e.bit(), bit, "{line}: {e}");
    }
}

#[test]
fn the_manuals_ascii_trace_parses_with_its_trailing_comma() {
    // TRCA?, p. 5-16: "the response with two points might be
    // "-1.234567e-009,+7.654321e-009,"".
    let q = Command::TraceAscii(range(1, 0, 2));
    let r = Reply::parse(&q, b"-1.234567e-009,+7.654321e-009,").expect("valid");
    assert_eq!(r, Reply::TraceAscii(vec![-1.234567e-9, 7.654321e-9]));
    assert!(matches!(
        Reply::parse(&q, b"-1.234567e-009,"),
        Err(ReplyError::WrongCount {
            expected: 2,
            got: 1
        })
    ));
}

#[test]
fn a_non_normalized_trace_decodes_as_m_times_2_to_the_exp_minus_124() {
    // TRCL?, p. 5-17: bytes 0-1 the mantissa (LSB first), byte 2 the exponent, byte 3
    // zero; value = m × 2^(exp − 124).
    let q = Command::TraceStored(range(1, 0, 3));
    let bytes = [
        0x00, 0x40, 110, 0, // 16384 × 2^−14 = 1
        0x00, 0xC0, 111, 0, // −16384 × 2^−13 = −2
        0x01, 0x00, 124, 0, // 1 × 2^0 = 1
    ];
    let Reply::TraceStored(v) = Reply::parse(&q, &bytes).expect("valid") else {
        panic!("not a trace")
    };
    let values: Vec<f64> = v.iter().map(|p| p.value()).collect();
    assert_eq!(values, [1.0, -2.0, 1.0]);
    // Not trimmed as a line is: a CR or a space is data.
    let q1 = Command::TraceStored(range(1, 0, 1));
    let r = Reply::parse(&q1, &[0x0D, 0x20, 124, 0]).expect("valid");
    assert_eq!(
        r,
        Reply::TraceStored(vec![StoredValue {
            mantissa: 0x200D,
            exponent: 124
        }])
    );
    // A short transfer is a wrong count; byte 3 not zero is a bad value.
    assert!(matches!(
        Reply::parse(&q, &bytes[..8]),
        Err(ReplyError::WrongCount {
            expected: 3,
            got: 2
        })
    ));
    assert_eq!(
        Reply::parse(&q1, &[0, 0x40, 110, 7]),
        Err(ReplyError::BadValue)
    );
    // And written back without a terminator.
    assert_eq!(Reply::parse(&q, &bytes).expect("valid").to_bytes(), bytes);
}

#[test]
fn an_ieee_trace_decodes_little_endian_singles() {
    let q = Command::TraceBinary(range(2, 0, 2));
    let bytes = [0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x20, 0xC1];
    assert_eq!(
        Reply::parse(&q, &bytes).expect("valid"),
        Reply::TraceBinary(vec![1.0, -10.0])
    );
    // A non-finite single is no value the instrument stores.
    let nan = f32::NAN.to_le_bytes();
    assert_eq!(
        Reply::parse(
            &TraceRange::new(TraceChannel::Ch1, 0, 1)
                .map(Command::TraceBinary)
                .expect("valid"),
            &nan
        ),
        Err(ReplyError::BadValue)
    );
}

#[test]
fn the_framer_frames_lines_exactly_as_before_when_no_binary_query_is_due() {
    let mut f = Sr830Framer::new(256);
    f.sent(b"SNAP? 1,2\n");
    f.push(b"0.951359,0.0253297\r4\r");
    assert_eq!(f.next_frame(), Some(Ok(b"0.951359,0.0253297".to_vec())));
    assert_eq!(f.next_frame(), Some(Ok(b"4".to_vec())));
    assert_eq!(f.next_frame(), None);
    // After a clear, a binary expectation is forgotten.
    f.sent(b"TRCL? 1,0,1\n");
    f.clear();
    f.push(b"7\r");
    assert_eq!(f.next_frame(), Some(Ok(b"7".to_vec())));
}

#[test]
fn the_wire_time_of_a_transfer_is_ten_bits_a_byte() {
    // 4 bytes × 64 points at 9600 baud: 256 ms.
    assert!((buffer::wire_seconds(256, 9600) - 0.2666666).abs() < 1e-6);
}

proptest! {
    #[test]
    fn stored_points_round_trip_through_their_bytes(m in any::<i16>(), e in 0u8..=248) {
        let p = StoredValue { mantissa: m, exponent: e };
        prop_assert_eq!(StoredValue::from_bytes(p.to_bytes()), Some(p));
        prop_assert_eq!(decode_trcl(&p.to_bytes()), Some(vec![p]));
    }

    #[test]
    fn the_nearest_stored_point_is_within_half_a_mantissa_step(v in -1e3f64..1e3) {
        let p = StoredValue::from_value(v);
        // Normalised: 15 significant bits for any value the outputs can take.
        prop_assume!(v.abs() > 1e-12);
        prop_assert!(p.mantissa.unsigned_abs() >= 16384, "{p:?} for {v}");
        let step = 2f64.powi(i32::from(p.exponent) - 124);
        prop_assert!((p.value() - v).abs() <= 0.5 * step * (1.0 + 1e-12), "{v} → {}", p.value());
    }

    #[test]
    fn ieee_points_round_trip(v in proptest::collection::vec(-1e30f32..1e30, 1..40)) {
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        prop_assert_eq!(decode_trcb(&bytes), Some(v));
    }

    /// The same replies framed whatever chunks the stream arrives in.
    #[test]
    fn the_framer_frames_any_split_of_the_stream_alike(
        points in proptest::collection::vec((any::<i16>(), 0u8..=248), 1..20),
        cuts in proptest::collection::vec(0usize..200, 0..6),
    ) {
        let k = u16::try_from(points.len()).expect("valid");
        let trace: Vec<StoredValue> =
            points.iter().map(|(m, e)| StoredValue { mantissa: *m, exponent: *e }).collect();
        let mut stream = b"12\r".to_vec();
        stream.extend(Reply::TraceStored(trace.clone()).to_bytes());
        stream.extend(b"5\r");
        let mut f = Sr830Framer::new(256);
        f.sent(format!("SPTS?;TRCL? 2,0,{k};LIAS?\n").as_bytes());
        let mut at = 0;
        let mut cuts = cuts.clone();
        cuts.sort_unstable();
        for c in cuts.into_iter().chain([stream.len()]) {
            let c = c.min(stream.len()).max(at);
            f.push(&stream[at..c]);
            at = c;
        }
        prop_assert_eq!(f.next_frame(), Some(Ok(b"12".to_vec())));
        let q = Command::TraceStored(TraceRange::new(TraceChannel::Ch2, 0, k).expect("valid"));
        let frame = f.next_frame().expect("valid").expect("valid");
        prop_assert_eq!(Reply::parse(&q, &frame), Ok(Reply::TraceStored(trace)));
        prop_assert_eq!(f.next_frame(), Some(Ok(b"5".to_vec())));
        prop_assert_eq!(f.next_frame(), None);
    }
}
