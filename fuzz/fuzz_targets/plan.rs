//! A measurement plan (TOML): arbitrary text, or a shipped file with hostile changes
//! (gonio_fuzz::plan).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gonio_fuzz::plan(data));
