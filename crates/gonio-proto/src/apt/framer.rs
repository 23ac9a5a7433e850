//! Cutting an APT byte stream into messages. The protocol has no start marker and no
//! checksum, so synchronisation rests on the header: a header is believed when both
//! addresses are defined ones and, for a known id, the form and data length are the
//! manual's. Anything else is line noise or a lost byte: the framer reports it once
//! ([`FrameError::Desync`]) and slides forward a byte at a time until a header is
//! believable again.

use std::collections::VecDeque;

use super::message::form_of;
use super::{HEADER_LEN, Header, MAX_DATA_LEN, is_address};
use crate::{FrameError, Framer};

/// The most complete messages held before the oldest is dropped: a host that stops
/// reading while a controller streams status updates must not grow without bound.
const MAX_READY: usize = 1024;

/// Message ids beyond the manual's range (its highest lie in `0x08xx`).
const MAX_ID: u16 = 0x1000;

/// Splits a received byte stream into whole APT messages (header and data packet),
/// sans-IO: [`push`](Framer::push) what the port read, then take messages with
/// [`next_frame`](Framer::next_frame), each ready for [`Packet::parse`](super::Packet::parse).
/// Buffering is bounded (one message being assembled, at most 1024 complete ones);
/// it never panics.
#[derive(Debug, Clone, Default)]
pub struct AptFramer {
    buf: Vec<u8>,
    /// Inside a run of bytes already reported as garbage.
    desynced: bool,
    ready: VecDeque<Result<Vec<u8>, FrameError>>,
}

/// What the start of the buffer holds.
enum Head {
    /// Too few bytes to judge.
    Incomplete,
    /// A believable header of a message this long.
    Message(usize),
    /// No message starts here.
    Garbage(&'static str),
}

impl AptFramer {
    /// An empty framer.
    pub fn new() -> Self {
        Self::default()
    }

    /// True when bytes of an unfinished message are buffered.
    pub fn has_partial(&self) -> bool {
        !self.buf.is_empty()
    }

    fn head(&self) -> Head {
        let Ok(h) = Header::parse(&self.buf) else {
            return Head::Incomplete;
        };
        if h.dest == 0 || !is_address(h.dest) || !is_address(h.source) {
            return Head::Garbage("a header with undefined addresses");
        }
        // Every id the manual defines is below 0x1000.
        if h.id >= MAX_ID {
            return Head::Garbage("a message id outside the manual's range");
        }
        if let Some(n) = h.data_len
            && usize::from(n) > MAX_DATA_LEN
        {
            return Head::Garbage("a data length no message has");
        }
        if let Some(form) = form_of(h.id)
            && !form.admits(h.data_len)
        {
            return Head::Garbage("a known message id with the wrong data length");
        }
        Head::Message(h.total_len())
    }

    fn emit(&mut self, item: Result<Vec<u8>, FrameError>) {
        if self.ready.len() >= MAX_READY {
            self.ready.pop_front();
        }
        self.ready.push_back(item);
    }

    fn drain(&mut self) {
        loop {
            match self.head() {
                Head::Incomplete => return,
                Head::Garbage(why) => {
                    if !self.desynced {
                        self.desynced = true;
                        self.emit(Err(FrameError::Desync(why)));
                    }
                    self.buf.remove(0);
                }
                Head::Message(n) => {
                    if self.buf.len() < n {
                        return;
                    }
                    self.desynced = false;
                    let rest = self.buf.split_off(n);
                    let msg = std::mem::replace(&mut self.buf, rest);
                    self.emit(Ok(msg));
                }
            }
        }
    }
}

impl Framer for AptFramer {
    fn push(&mut self, bytes: &[u8]) {
        // Feed in slices of at most one message's worth so that the buffer never holds
        // more than a header, a maximal data packet and one slice.
        for chunk in bytes.chunks(HEADER_LEN + MAX_DATA_LEN) {
            self.buf.extend_from_slice(chunk);
            self.drain();
        }
    }

    fn next_frame(&mut self) -> Option<Result<Vec<u8>, FrameError>> {
        self.ready.pop_front()
    }

    fn clear(&mut self) {
        self.buf.clear();
        self.desynced = false;
        self.ready.clear();
    }
}
