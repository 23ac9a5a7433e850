//! Bodies for the `cargo fuzz` targets in `fuzz/`: feed arbitrary bytes to every
//! parser of this protocol. They must never panic; they also check that whatever
//! parses re-encodes into something that parses to the same value.

use super::{DumpReader, Frame, Reply, Smc100Parameters};
use crate::LineFramer;

/// Parses `data` as a command line (the simulator's side), and round-trips it.
pub fn command_line(data: &[u8]) {
    if let Ok(f) = Frame::parse(data) {
        let bytes = f.to_bytes();
        let again = Frame::parse(&bytes[..bytes.len() - 2]);
        assert_eq!(again.as_ref().ok(), Some(&f), "re-encoded {bytes:?}");
    }
}

/// Parses `data` as a reply line (the driver's side), and round-trips it.
pub fn reply_line(data: &[u8]) {
    if let Ok(r) = Reply::parse(data) {
        let bytes = r.to_bytes();
        let again = Reply::parse(&bytes[..bytes.len() - 2]);
        assert_eq!(again.as_ref().ok(), Some(&r), "re-encoded {bytes:?}");
    }
}

/// Frames `data` as a stream of reply lines and parses each, and reads the stream as
/// a `ZT` dump of controller 1: whatever dump it holds re-encodes into the same dump.
pub fn stream(data: &[u8]) {
    let mut f = LineFramer::new(b'\n', super::MAX_LINE);
    f.push(data);
    let mut dump = DumpReader::new(1);
    while let Some(line) = f.next_line() {
        let Ok(l) = line else { continue };
        reply_line(&l);
        let l = l.strip_suffix(b"\r").unwrap_or(&l);
        match dump.push(l) {
            Ok(Some(params)) => dump_round_trip(&params),
            Ok(None) => {}
            Err(_) => dump = DumpReader::new(1),
        }
    }
}

/// A dump re-encoded reads back to the same parameters.
fn dump_round_trip(params: &Smc100Parameters) {
    let mut bytes = Vec::new();
    params.encode_dump(1, &mut bytes);
    let lines = bytes
        .split(|b| *b == b'\n')
        .filter(|l| !l.is_empty())
        .map(|l| l.strip_suffix(b"\r").unwrap_or(l));
    let again = Smc100Parameters::parse_dump(1, lines);
    assert_eq!(again.as_ref().ok(), Some(params), "re-encoded {bytes:?}");
}
