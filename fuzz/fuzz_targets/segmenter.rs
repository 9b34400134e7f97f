//! Fuzz target `segmenter`: see [`yosemitech_fuzz::segmenter`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| yosemitech_fuzz::segmenter(data));
