//! The runtime's integration tests but those that count allocations
//! (`no_alloc`, `embedded_driver`): one binary, so the workspace links once for
//! all of them. Each module is one file of tests; run one with `cargo test -p
//! yosemitech-rtu --test integration async_links::`.

mod async_links;
mod client;
mod dispatch;
mod noise_alignment;
mod transports;
