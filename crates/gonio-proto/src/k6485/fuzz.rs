//! Fuzz bodies: feed arbitrary bytes to the parsers. Each must return normally on
//! every input; a panic means a codec bug. A `cargo fuzz` target is one line:
//! `fuzz_target!(|d: &[u8]| gonio_proto::k6485::fuzz::fuzz_parse_line(d));`.

use super::{Command, FilterType, Range, Reply, parse_line};
use crate::codec::{self, RoundTrip};

/// Parses `data` as a received command line; every command that parses is encoded
/// and parsed again and must come back equal.
pub fn fuzz_parse_line(data: &[u8]) {
    codec::fuzz_commands(data, parse_line, RoundTrip::Exact);
}

/// Parses `data[1..]` as the reply to a query chosen by `data[0]`; a reply that
/// parses is encoded, and its encoding must parse and encode to the same bytes (the
/// instrument writes 7 significant digits, so the first encoding may round).
pub fn fuzz_parse_reply(data: &[u8]) {
    let queries = [
        Command::Identify,
        Command::EventStatus,
        Command::NextError,
        Command::QueryRange,
        Command::LineFrequency,
        Command::Read,
        Command::Fetch,
        // Not queries: must be refused, not parsed.
        Command::Reset,
        Command::SetRange(Range::MOST),
        Command::FilterType(FilterType::Moving),
    ];
    codec::fuzz_replies(data, &queries, Reply::parse, RoundTrip::Stable);
}
