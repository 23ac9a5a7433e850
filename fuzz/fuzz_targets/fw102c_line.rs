//! Arbitrary bytes as a Thorlabs FW102C command line (what the simulated wheel
//! parses), and as a received line answering a query chosen by the first byte.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    gonio_proto::fw102c::fuzz::fuzz_parse_line(data);
    gonio_proto::fw102c::fuzz::fuzz_parse_reply(data);
});
