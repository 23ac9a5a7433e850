//! Arbitrary bytes as an SR830 command line (what the simulated lock-in parses).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gonio_proto::sr830::fuzz::fuzz_parse_line(data));
