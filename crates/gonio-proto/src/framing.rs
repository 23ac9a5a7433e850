//! Cutting a serial byte stream into lines.

use std::collections::VecDeque;

/// Why a chunk of the stream is not a valid line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// A NUL byte arrived: what an SMC100 emits when it loses power, and never part of
    /// a valid line of either protocol. The bytes up to the next terminator are dropped.
    #[error("NUL byte on the line (instrument power loss or line noise)")]
    Nul,
    /// More than the maximum line length arrived without a terminator; the bytes are
    /// dropped up to the next terminator.
    #[error("line longer than {0} bytes without a terminator")]
    TooLong(usize),
    /// Bytes that cannot start a frame of a binary protocol (a header no message has):
    /// the framer lost step with the stream and dropped them to find it again.
    #[error("bytes that start no frame (lost synchronisation): {0}")]
    Desync(&'static str),
}

/// Cuts a received byte stream into frames: lines for the text protocols
/// ([`LineFramer`]), messages for binary ones (`apt::AptFramer`). Transports are built
/// on one, so the same transport carries every protocol.
pub trait Framer: Send + std::fmt::Debug {
    /// Adds received bytes.
    fn push(&mut self, bytes: &[u8]);
    /// The next complete frame, or an error for bytes that make no frame.
    fn next_frame(&mut self) -> Option<Result<Vec<u8>, FrameError>>;
    /// Forgets everything buffered.
    fn clear(&mut self);
    /// The host sent `bytes`: a framer whose replies' lengths depend on the query
    /// (the SR830's binary `TRCL?`) learns them here. Line and message framers ignore it.
    fn sent(&mut self, _bytes: &[u8]) {}
}

impl Framer for LineFramer {
    fn push(&mut self, bytes: &[u8]) {
        LineFramer::push(self, bytes);
    }
    fn next_frame(&mut self) -> Option<Result<Vec<u8>, FrameError>> {
        self.next_line()
    }
    fn clear(&mut self) {
        LineFramer::clear(self);
    }
}

/// Splits a byte stream into lines ending in a terminator byte.
///
/// Sans-IO: feed it whatever the transport read with [`push`](Self::push), then take
/// complete lines with [`next_line`](Self::next_line). The terminator is removed, and
/// so is a carriage return right before it (the SMC100 ends lines with CR LF; the
/// SR830 with CR alone, which is then the terminator itself).
#[derive(Debug, Clone)]
pub struct LineFramer {
    terminator: u8,
    max_len: usize,
    partial: Vec<u8>,
    /// Inside a line that has already produced an error: drop until the terminator.
    discarding: bool,
    ready: VecDeque<Result<Vec<u8>, FrameError>>,
}

impl LineFramer {
    /// A framer for lines ending in `terminator`, refusing lines over `max_len` bytes.
    pub fn new(terminator: u8, max_len: usize) -> Self {
        LineFramer {
            terminator,
            max_len,
            partial: Vec::new(),
            discarding: false,
            ready: VecDeque::new(),
        }
    }

    /// Adds received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if b == self.terminator {
                if self.discarding {
                    self.discarding = false;
                } else {
                    let mut line = std::mem::take(&mut self.partial);
                    if self.terminator != b'\r' && line.last() == Some(&b'\r') {
                        line.pop();
                    }
                    self.ready.push_back(Ok(line));
                }
                self.partial.clear();
                continue;
            }
            if self.discarding {
                continue;
            }
            if b == 0 {
                self.ready.push_back(Err(FrameError::Nul));
                self.partial.clear();
                self.discarding = true;
            } else if self.partial.len() >= self.max_len {
                self.ready.push_back(Err(FrameError::TooLong(self.max_len)));
                self.partial.clear();
                self.discarding = true;
            } else {
                self.partial.push(b);
            }
        }
    }

    /// The next complete line (without its terminator), or an error for a bad one.
    pub fn next_line(&mut self) -> Option<Result<Vec<u8>, FrameError>> {
        self.ready.pop_front()
    }

    /// True when bytes of an unfinished line are buffered.
    pub fn has_partial(&self) -> bool {
        !self.partial.is_empty() || self.discarding
    }

    /// Forgets everything buffered (after a timeout, before a new exchange).
    pub fn clear(&mut self) {
        self.partial.clear();
        self.discarding = false;
        self.ready.clear();
    }
}
