//! Bodies for the `cargo fuzz` targets in `fuzz/`: feed arbitrary bytes to every
//! parser of this protocol. They must never panic; they also check that whatever
//! parses re-encodes into something that parses to the same value.

use super::{Frame, Reply};
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

/// Frames `data` as a stream of reply lines and parses each.
pub fn stream(data: &[u8]) {
    let mut f = LineFramer::new(b'\n', super::MAX_LINE);
    f.push(data);
    while let Some(line) = f.next_line() {
        if let Ok(l) = line {
            reply_line(&l);
        }
    }
}
