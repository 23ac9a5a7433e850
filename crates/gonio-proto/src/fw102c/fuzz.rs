//! Fuzz bodies: feed arbitrary bytes to the parsers. Each must return normally on
//! every input; a panic means a codec bug. The `cargo fuzz` target is
//! `fuzz/fuzz_targets/fw102c_line.rs`.

use super::{Command, Line, Reply};
use crate::codec::{self, RoundTrip};

/// Parses `data` as a received command line (the wheel's side); a command that parses
/// encodes and parses back to itself.
pub fn fuzz_parse_line(data: &[u8]) {
    codec::fuzz_commands(data, |d| vec![Command::parse(d)], RoundTrip::Exact);
}

/// Classifies `data[1..]` and parses it as the value of the query `data[0]` picks; a
/// value that parses round-trips, and only a query has one.
pub fn fuzz_parse_reply(data: &[u8]) {
    let queries = [
        Command::Identify,
        Command::QueryPosition,
        Command::QueryPositionCount,
        Command::QuerySpeed,
        Command::QueryTrigger,
        Command::QuerySensors,
        // Not a query: must be refused, never parsed.
        Command::SetPosition(1),
    ];
    let _ = data.split_first().map(|(_, line)| Line::classify(line));
    let parse = |query: &Command, line: &[u8]| {
        let reply = Reply::parse(query, line);
        assert!(reply.is_err() || query.is_query(), "{query:?} answered");
        reply
    };
    codec::fuzz_replies(data, &queries, parse, RoundTrip::Exact);
}
