//! Fuzz target `cli_decode`: see [`yosemitech_fuzz::cli_decode`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| yosemitech_fuzz::cli_decode(data));
