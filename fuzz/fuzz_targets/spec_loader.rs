//! Fuzz target `spec_loader`: see [`yosemitech_fuzz::spec_loader`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| yosemitech_fuzz::spec_loader(data));
