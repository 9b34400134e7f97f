//! Fuzz target `frame_reader`: see [`yosemitech_fuzz::frame_reader`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| yosemitech_fuzz::frame_reader(data));
