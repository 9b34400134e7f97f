//! The station's integration tests: one binary, so the workspace links once for
//! all of them. Each module is one file of tests; run one with `cargo test -p
//! yosemitech-station --test integration calibration::`.

mod calibration;
mod derived;
mod logger_pty;
mod store;
mod units;
