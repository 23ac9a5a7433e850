//! A run file (SQLite): arbitrary bytes, or a valid run file with byte edits, opened and
//! read (gonio_fuzz::run_file).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gonio_fuzz::run_file(data));
