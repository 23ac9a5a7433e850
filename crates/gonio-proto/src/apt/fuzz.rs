//! Bodies for the `cargo fuzz` target `apt_message` in `fuzz/`: arbitrary bytes
//! through the framer and the parser. They must never panic; whatever parses must
//! re-encode into bytes that parse to the same value.

use super::{AptFramer, Packet};
use crate::Framer;

/// Parses `data` as one message and round-trips it.
pub fn message(data: &[u8]) {
    if let Ok(p) = Packet::parse(data) {
        let mut bytes = Vec::new();
        p.encode(&mut bytes);
        let again = Packet::parse(&bytes);
        assert_eq!(again.as_ref().ok(), Some(&p), "re-encoded {bytes:02x?}");
    }
}

/// Frames `data` as a stream, split at the position its first byte chooses, and
/// parses and round-trips each message.
pub fn stream(data: &[u8]) {
    let split = data.first().map_or(0, |&b| usize::from(b)).min(data.len());
    let mut f = AptFramer::new();
    f.push(&data[..split]);
    f.push(&data[split..]);
    while let Some(frame) = f.next_frame() {
        if let Ok(m) = frame {
            assert!(
                m.len() >= super::HEADER_LEN && m.len() <= super::HEADER_LEN + super::MAX_DATA_LEN
            );
            message(&m);
        }
    }
}
