//! Arbitrary bytes as a CSV sample or table file (read, write, read again).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gonio_io::formats::fuzz::csv_read(data));
