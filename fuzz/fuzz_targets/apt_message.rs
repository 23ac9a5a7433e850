//! Arbitrary bytes as Thorlabs APT messages: one message parsed and re-encoded, and a
//! stream cut by the framer (either side of the host-controller link).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    gonio_proto::apt::fuzz::message(data);
    gonio_proto::apt::fuzz::stream(data);
});
