//! The spec crate's integration tests: one binary, so the workspace links once
//! for all of them. Each module is one file of tests; run one with `cargo test
//! -p yosemitech-spec --test integration interp_roundtrip::`.

mod interp_roundtrip;
mod real_spec;
mod units;
mod validation;
