//! Arbitrary bytes as an RGL material (tensor file): header, sizes, fields, values.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gonio_io::formats::fuzz::rgl_read(data));
