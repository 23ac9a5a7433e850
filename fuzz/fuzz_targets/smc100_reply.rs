//! Arbitrary bytes as an SMC100 reply stream (what the driver parses).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    gonio_proto::smc100::fuzz::reply_line(data);
    gonio_proto::smc100::fuzz::stream(data);
});
