//! A microgeometry surface file (TOML): arbitrary text, or a shipped file with hostile
//! changes (gonio_fuzz::surface).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gonio_fuzz::surface(data));
