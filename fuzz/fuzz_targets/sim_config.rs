//! A simulator config (TOML): arbitrary text, or a shipped file with hostile changes
//! (gonio_fuzz::sim_config).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gonio_fuzz::sim_config(data));
