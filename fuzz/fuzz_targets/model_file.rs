//! A BRDF model file (TOML): arbitrary text, or a shipped file with hostile changes
//! (gonio_fuzz::model_file).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gonio_fuzz::model_file(data));
