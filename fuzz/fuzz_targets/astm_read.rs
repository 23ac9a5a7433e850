//! Arbitrary bytes as ASTM E1392-style BRDF text (read, write, read again).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gonio_io::formats::fuzz::astm_read(data));
