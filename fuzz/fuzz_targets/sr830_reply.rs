//! Arbitrary bytes as an SR830 reply to each kind of query (what the driver parses).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gonio_proto::sr830::fuzz::fuzz_parse_reply(data));
