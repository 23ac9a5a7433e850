//! Arbitrary bytes as an SMC100 command line (what the simulated controller parses).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gonio_proto::smc100::fuzz::command_line(data));
