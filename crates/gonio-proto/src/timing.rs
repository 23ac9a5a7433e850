//! How long bytes and exchanges take on a serial line: under each family's timing
//! model (what `gonio plan check` estimates a run from) and the simulator's wire, so
//! both count a byte the same way.

/// Bits one byte takes on an asynchronous line: a start bit, eight data bits, a stop
/// bit (8N1, the framing of every instrument here).
pub const BITS_PER_BYTE: f64 = 10.0;

/// Seconds `bytes` take on a line at `baud`.
pub fn wire_s(bytes: usize, baud: u32) -> f64 {
    bytes as f64 * BITS_PER_BYTE / f64::from(baud.max(1))
}

/// Seconds of one exchange: `out` bytes sent, the instrument's `latency_s` to answer,
/// `back` bytes of answer (0 for a command that is not answered, which then costs
/// only its own bytes).
pub fn exchange_s(out: usize, back: usize, baud: u32, latency_s: f64) -> f64 {
    if back == 0 {
        return wire_s(out, baud);
    }
    wire_s(out + back, baud) + latency_s
}
