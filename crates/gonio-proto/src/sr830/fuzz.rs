//! Fuzz bodies: feed arbitrary bytes to the parsers. Each must return normally on
//! every input; a panic means a codec bug (a parser that panics, or a value that does
//! not survive encode → parse). A `cargo fuzz` target is one line:
//! `fuzz_target!(|d: &[u8]| gonio_proto::sr830::fuzz::fuzz_parse_line(d));`.

use super::{
    BitIndex, Command, Output, Reply, SnapParam, SnapParams, TraceChannel, TraceRange, parse_line,
};
use crate::codec::{self, RoundTrip};

/// Parses `data` as a received command line; every command that parses is
/// encoded and parsed again and must come back equal.
pub fn fuzz_parse_line(data: &[u8]) {
    codec::fuzz_commands(data, parse_line, RoundTrip::Exact);
}

/// Parses `data[1..]` as the reply to a query chosen by `data[0]` (one query of each
/// reply kind); a reply that parses is encoded and parsed again and must come back
/// equal.
pub fn fuzz_parse_reply(data: &[u8]) {
    let mut queries = vec![
        Command::QueryInterface,
        Command::QueryReferenceSource,
        Command::QueryFrequency,
        Command::QueryAmplitude,
        Command::QuerySensitivity,
        Command::QueryTimeConstant,
        Command::QuerySlope,
        Command::ReadOutput(Output::R),
        Command::LiaStatus(None),
        Command::LiaStatus(BitIndex::new(2)),
        Command::ErrorStatus(None),
        Command::EventStatus(None),
        Command::Identify,
        Command::QuerySampleRate,
        Command::QueryEndOfScan,
        Command::StoredPoints,
        // Not a query: must be refused, not parsed.
        Command::Clear,
    ];
    let snaps =
        (SnapParams::MIN..=SnapParams::MAX).filter_map(|n| SnapParams::new(&SnapParam::ALL[..n]));
    queries.extend(snaps.map(Command::Snap));
    // Traces of 1 … 4 points, in each format.
    for k in 1..=4 {
        if let Some(r) = TraceRange::new(TraceChannel::Ch1, 0, k) {
            queries.extend([
                Command::TraceAscii(r),
                Command::TraceBinary(r),
                Command::TraceStored(r),
            ]);
        }
    }
    codec::fuzz_replies(data, &queries, Reply::parse, RoundTrip::Exact);
}
