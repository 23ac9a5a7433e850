//! Fuzz bodies: feed arbitrary bytes to the parsers. Each must return normally on
//! every input; a panic means a codec bug. A `cargo fuzz` target is one line:
//! `fuzz_target!(|d: &[u8]| gonio_proto::cs130::fuzz::fuzz_parse_line(d));`.

use super::{Command, Reply, is_echo};

/// Parses `data` as a received statement (what the twin does); a statement that
/// parses must be its own echo once encoded, and its encoding must parse and encode
/// to the same bytes (`GOWAVE` is written with three decimals, so the first encoding
/// may round).
pub fn fuzz_parse_line(data: &[u8]) {
    if let Ok(command) = Command::parse(data) {
        let bytes = command.to_bytes();
        let body = &bytes[..bytes.len() - 2];
        assert!(is_echo(&command, body), "echo of {bytes:?}");
        let again = Command::parse(body).unwrap_or_else(|e| panic!("re-parse of {bytes:?}: {e}"));
        assert_eq!(again.to_bytes(), bytes, "re-encode of {bytes:?}");
    }
}

/// Parses `data[1..]` as the answer to a query chosen by `data[0]`; an answer that
/// parses is encoded, and its encoding must parse and encode to the same bytes.
pub fn fuzz_parse_reply(data: &[u8]) {
    let Some((&selector, line)) = data.split_first() else {
        return;
    };
    let queries = sample_queries();
    let command = &queries[usize::from(selector) % queries.len()];
    let _ = is_echo(command, line);
    if let Ok(reply) = Reply::parse(command, line) {
        let bytes = reply.to_bytes();
        let body = &bytes[..bytes.len() - 2];
        let again =
            Reply::parse(command, body).unwrap_or_else(|e| panic!("re-parse of {bytes:?}: {e}"));
        assert_eq!(again.to_bytes(), bytes, "re-encode of {bytes:?}");
    }
}

/// One query of each answer kind, and a command that must be refused.
fn sample_queries() -> [Command; 8] {
    [
        Command::Wave,
        Command::GratQuery,
        Command::FilterQuery,
        Command::ShutterQuery,
        Command::Stb,
        Command::Error,
        Command::Info,
        Command::GoWave(500.0),
    ]
}
