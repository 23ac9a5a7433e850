//! Arbitrary bytes as a Cornerstone 130 statement (what the simulated monochromator
//! parses), and as the answer to a query chosen by the first byte.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    gonio_proto::cs130::fuzz::fuzz_parse_line(data);
    gonio_proto::cs130::fuzz::fuzz_parse_reply(data);
});
