//! Arbitrary bytes as a Keithley 6485 command line (what the simulated picoammeter
//! parses), and as the reply to a query chosen by the first byte.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    gonio_proto::k6485::fuzz::fuzz_parse_line(data);
    gonio_proto::k6485::fuzz::fuzz_parse_reply(data);
});
