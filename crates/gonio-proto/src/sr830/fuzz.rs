//! Fuzz bodies: feed arbitrary bytes to the parsers. Each must return normally on
//! every input; a panic means a codec bug (a parser that panics, or a value that does
//! not survive encode → parse). A `cargo fuzz` target is one line:
//! `fuzz_target!(|d: &[u8]| gonio_proto::sr830::fuzz::fuzz_parse_line(d));`.

use super::{
    BitIndex, Command, Output, REPLY_TERMINATOR, Reply, SnapParam, SnapParams, parse_line,
};

/// Parses `data` as a received command line; every command that parses is
/// encoded and parsed again and must come back equal.
pub fn fuzz_parse_line(data: &[u8]) {
    for command in parse_line(data).into_iter().flatten() {
        let mut out = Vec::new();
        command.encode_body(&mut out);
        assert_eq!(parse_line(&out), vec![Ok(command)], "re-parse of {out:?}");
    }
}

/// Parses `data[1..]` as the reply to a query chosen by `data[0]`; a reply that
/// parses is encoded and parsed again and must come back equal.
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
        assert_eq!(
            Reply::parse(command, body),
            Ok(reply),
            "re-parse of {bytes:?}"
        );
    }
}

/// One query of each reply kind.
fn sample_queries() -> Vec<Command> {
    let mut q = vec![
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
        // Not a query: must be refused, not parsed.
        Command::Clear,
    ];
    for n in SnapParams::MIN..=SnapParams::MAX {
        if let Some(p) = SnapParams::new(&SnapParam::ALL[..n]) {
            q.push(Command::Snap(p));
        }
    }
    q
}
