//! The xtask commands' integration tests: one binary, so the workspace links
//! once for all of them. Each module is one file of tests; run one with `cargo
//! test -p xtask --test integration import::`.

mod import;
mod import_into;
