//! Arbitrary bytes as a MERL binary BRDF: header, length, values, bin lookup.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gonio_io::formats::fuzz::merl_read(data));
