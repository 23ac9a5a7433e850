//! Fuzz bodies: feed arbitrary bytes to the parsers. Each must return normally on
//! every input; a panic means a codec bug. The `cargo fuzz` target is
//! `fuzz/fuzz_targets/fw102c_line.rs`.

use super::{Command, Line, Reply, strip_prompt};

/// Parses `data` as a received command line (the wheel's side); a command that parses
/// encodes and parses back to itself.
pub fn fuzz_parse_line(data: &[u8]) {
    if let Ok(command) = Command::parse(data) {
        let mut out = Vec::new();
        command.encode_body(&mut out);
        assert_eq!(Command::parse(&out), Ok(command), "re-parse of {out:?}");
    }
}

/// Classifies `data[1..]` as a received line and parses it as the value of a query
/// chosen by `data[0]`; a value that parses encodes to a line that parses to the same
/// value.
pub fn fuzz_parse_reply(data: &[u8]) {
    let Some((&selector, line)) = data.split_first() else {
        return;
    };
    let _ = Line::classify(line);
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
    let command = queries[usize::from(selector) % queries.len()];
    if let Ok(reply) = Reply::parse(&command, line) {
        assert!(command.is_query());
        let bytes = reply.to_bytes();
        let body = bytes.strip_suffix(b"\r").unwrap_or(&bytes);
        let again = Reply::parse(&command, strip_prompt(body));
        assert_eq!(again, Ok(reply), "re-parse of {bytes:?}");
    }
}
