//! Fuzz target `decode_response`: see [`yosemitech_fuzz::decode_response`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| yosemitech_fuzz::decode_response(data));
