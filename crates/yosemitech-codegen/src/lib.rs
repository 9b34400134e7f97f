//! Generates typed Rust codecs from Yosemitech spec files (a library for build.rs).
