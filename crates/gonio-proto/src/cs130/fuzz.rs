//! Fuzz bodies: feed arbitrary bytes to the parsers. Each must return normally on
//! every input; a panic means a codec bug. A `cargo fuzz` target is one line:
//! `fuzz_target!(|d: &[u8]| gonio_proto::cs130::fuzz::fuzz_parse_line(d));`.

use super::{Command, Reply, is_echo};
use crate::codec::{self, RoundTrip};

/// Parses `data` as a received statement (what the twin does); a statement that
/// parses must be its own echo once encoded, and its encoding must parse and encode
/// to the same bytes (`GOWAVE` is written with three decimals, so the first encoding
/// may round).
pub fn fuzz_parse_line(data: &[u8]) {
    if let Ok(command) = Command::parse(data) {
        assert!(
            is_echo(&command, &codec::Encode::body(&command)),
            "echo of {command:?}"
        );
    }
    codec::fuzz_commands(data, |d| vec![Command::parse(d)], RoundTrip::Stable);
}

/// Parses `data[1..]` as the answer to the query `data[0]` picks; an answer that
/// parses encodes to bytes that parse and encode to themselves.
pub fn fuzz_parse_reply(data: &[u8]) {
    // One query of each answer kind, and a command that must be refused.
    let queries = [
        Command::Wave,
        Command::GratQuery,
        Command::FilterQuery,
        Command::ShutterQuery,
        Command::Stb,
        Command::Error,
        Command::Info,
        Command::GoWave(500.0),
    ];
    if let Some((&selector, line)) = data.split_first() {
        let _ = is_echo(&queries[usize::from(selector) % queries.len()], line);
    }
    codec::fuzz_replies(data, &queries, Reply::parse, RoundTrip::Stable);
}
