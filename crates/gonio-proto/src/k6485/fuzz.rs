//! Fuzz bodies: feed arbitrary bytes to the parsers. Each must return normally on
//! every input; a panic means a codec bug. A `cargo fuzz` target is one line:
//! `fuzz_target!(|d: &[u8]| gonio_proto::k6485::fuzz::fuzz_parse_line(d));`.

use super::{Command, FilterType, REPLY_TERMINATOR, Range, Reply, parse_line};

/// Parses `data` as a received command line; every command that parses is encoded
/// and parsed again and must come back equal.
pub fn fuzz_parse_line(data: &[u8]) {
    for command in parse_line(data).into_iter().flatten() {
        let mut out = Vec::new();
        command.encode_body(&mut out);
        assert_eq!(parse_line(&out), vec![Ok(command)], "re-parse of {out:?}");
    }
}

/// Parses `data[1..]` as the reply to a query chosen by `data[0]`; a reply that
/// parses is encoded, and its encoding must parse and encode to the same bytes (the
/// instrument writes 7 significant digits, so the first encoding may round).
pub fn fuzz_parse_reply(data: &[u8]) {
    let Some((&selector, line)) = data.split_first() else {
        return;
    };
    let queries = sample_queries();
    let Some(command) = queries.get(usize::from(selector) % queries.len()) else {
        return;
    };
    if let Ok(reply) = Reply::parse(command, line) {
        let bytes = reply.to_bytes();
        let body = bytes.strip_suffix(&[REPLY_TERMINATOR]).unwrap_or(&bytes);
        let again =
            Reply::parse(command, body).unwrap_or_else(|e| panic!("re-parse of {bytes:?}: {e}"));
        assert_eq!(again.to_bytes(), bytes, "re-encode of {bytes:?}");
    }
}

/// One query of each reply kind, and set commands that must be refused.
fn sample_queries() -> Vec<Command> {
    vec![
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
    ]
}
